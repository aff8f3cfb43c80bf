"""Train one PPO policy shared by all controlled pedestrians (Stable-Baselines3).

Every controlled pedestrian of ``--copies`` environment copies is one slot of the native vector
environment (``--vectoriser native``, default: :mod:`crowd_env.envs.vector`; agents that leave are
padding until their copy resets), so every pedestrian's experience trains the same network
(:mod:`crowd_env.experiments.training.ppo`). ``--vectoriser supersuit`` uses SuperSuit's
``black_death_v3`` → ``pettingzoo_env_to_vec_env_v1`` → ``concat_vec_envs_v1`` chain instead.

Outputs in ``--out``: ``model.zip`` (load with ``stable_baselines3.PPO.load`` or evaluate with
``crowd-evaluate --model``; SB3's archive holds pickles, which run code when loaded, so share the policy as a
policy file: ``crowd-convert-policy OUT/model.zip --out policy.npz``), ``env_config.json`` (the environment options, so that ``crowd-evaluate
--model`` evaluates on the problem trained on), ``learning_curve.csv`` / ``.png`` (per-agent
episode returns against timesteps) and ``summary.json`` with the mean per-agent episode return of a
uniform random policy and of the trained policy (deterministic) on the same evaluation seeds. The two
policies come from ``--policy-resolver`` (default: the shipped baselines' ``as_policy``), resolved by
import path at run time.

Checkpoints (``--checkpoint-every`` timesteps, at the start of a rollout, i.e. after the previous
update, and at the end): ``checkpoints/ppo_<t>_steps.zip`` (model, optimiser and step count),
``vecnormalize_<t>_steps.pkl`` when the environment is normalised, ``curve.json`` (the learning curve
so far) and ``index.json`` (the checkpoints in order, written last and atomically, so it only names
complete files). A run killed midway continues with ``--resume`` from the latest checkpoint up to
``--timesteps`` in all (the rollout in progress at the kill is collected again; the environment
streams restart from ``seed + t``). Without ``--resume`` a folder holding checkpoints is refused; with it, a
checkpoint whose digest under this account's key does not match (someone else's, or older than signed
checkpoints) is refused before anything in it is loaded.

Needs the ``train`` extra (``pip install 'crowd_env[train]'``: torch, Stable-Baselines3, SuperSuit).
``--observation-frame egocentric`` trains in the pedestrians' body frames (:mod:`crowd_env.envs.crowd_v0`).
The default problem is small: 10 pedestrians at the 1 m Seyfried bottleneck, decisions every 0.1 s,
10 s episodes::

    crowd-train-ppo --timesteps 100000 --out runs/ppo_small

While it trains it prints a line at most every ``--progress-every`` seconds: timesteps done, time
elapsed and left, the mean return of the recent episodes.
"""
from __future__ import annotations

import argparse
import importlib.util
import sys

from ..errors import EnvOptionError
from ..experiments.training.ppo import VECTORISERS, TrainingError, train
from .train_options import add_env_arguments, add_evaluation_arguments, env_config_and_resolver


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="crowd-train-ppo", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--timesteps", type=int, default=100_000, help="PPO timesteps (agent steps)")
    ap.add_argument("--out", default="runs/ppo", help="output directory")
    add_env_arguments(ap)
    ap.add_argument("--copies", type=int, default=2, help="environment copies concatenated")
    ap.add_argument("--vectoriser", choices=VECTORISERS, default="native",
                    help="native (crowd_env.envs.vector, default) or supersuit")
    ap.add_argument("--workers", type=int, default=1,
                    help="processes that step the copies (native vectoriser; 1: this process, at most --copies)")
    ap.add_argument("--n-steps", type=int, default=256, help="PPO rollout length per agent slot")
    ap.add_argument("--batch-size", type=int, default=512)
    ap.add_argument("--n-epochs", type=int, default=10)
    ap.add_argument("--learning-rate", type=float, default=3e-4)
    ap.add_argument("--gamma", type=float, default=0.99)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=1, help="torch threads")
    ap.add_argument("--verbose", type=int, default=0, help="Stable-Baselines3's own logging (0: none, 1: its tables)")
    ap.add_argument("--progress-every", type=float, default=10.0, metavar="SECONDS",
                    help="print a progress line (timesteps, time left, recent returns) at most this often (default 10)")
    ap.add_argument("--checkpoint-every", type=int, default=10_000,
                    help="save a checkpoint every this many timesteps (0: only at the end)")
    ap.add_argument("--resume", action="store_true",
                    help="continue from the latest checkpoint in --out up to --timesteps in all")
    add_evaluation_arguments(ap)
    args = ap.parse_args(argv)
    if args.checkpoint_every < 0:
        raise SystemExit("error: --checkpoint-every must be >= 0")
    if not args.progress_every >= 0:
        raise SystemExit("error: --progress-every must be >= 0")
    needed = ("torch", "stable_baselines3") + (("supersuit",) if args.vectoriser == "supersuit" else ())
    missing = [name for name in needed if importlib.util.find_spec(name) is None]
    if missing:
        raise SystemExit(f"error: crowd-train-ppo needs the 'train' extra (missing: {', '.join(missing)}); "
                         "pip install 'crowd_env[train]'")
    env_config, resolve = env_config_and_resolver(args)
    try:
        summary = train(env_config, args.timesteps, args.out, resolve=resolve, seed=args.seed, copies=args.copies,
                        n_steps=args.n_steps, batch_size=args.batch_size, n_epochs=args.n_epochs,
                        learning_rate=args.learning_rate, gamma=args.gamma, eval_seeds=args.eval_seeds,
                        threads=args.threads, verbose=args.verbose, checkpoint_every=args.checkpoint_every,
                        resume=args.resume, vectoriser=args.vectoriser, workers=args.workers,
                        progress=lambda line: print(line, flush=True), progress_every_s=args.progress_every)
    except (TrainingError, EnvOptionError) as exc:
        raise SystemExit(f"error: {exc}") from None
    print(f"mean per-agent episode return: random {summary['random']['mean_return']:.3f} -> trained "
          f"{summary['trained']['mean_return']:.3f} ({summary['timesteps']} timesteps, "
          f"{summary['train_wall_s']:.0f} s training); outputs in {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
