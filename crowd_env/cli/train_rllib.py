"""Train one PPO policy shared by all controlled pedestrians with RLlib, locally or on a Ray cluster.

The PettingZoo environment goes to RLlib through ``ParallelPettingZooEnv``; every agent maps to the one
module ``"shared"`` (RLlib's new API stack; pedestrians that leave end their own single-agent episode).
Without ``--address`` Ray starts locally on ``--num-cpus`` cores (default ``--num-env-runners`` + 1);
with ``--address host:port`` (or ``ray://host:port``, or ``auto``) the same code joins a running cluster,
where ``--num-env-runners`` EnvRunners sample in parallel (every node needs crowd_env installed). An
unreachable address is refused within ``--connect-timeout`` seconds (:mod:`crowd_env.experiments.training.rllib`).

Each iteration (``--train-batch-size`` environment steps) prints, and appends to ``progress.csv``: the
mean per-agent episode return and episode length (RLlib's running means over recent episodes), the
policy, value and total losses, the entropy and the wall time. At the end the trained policy
(deterministic) and the uniform random policy run on the same ``--eval-seeds`` through the evaluation
harness; ``summary.json`` holds both mean per-agent episode returns.

Outputs in ``--out``: ``progress.csv``, ``policy/`` + ``policy.json`` (the RLModule; reload it with
``crowd_env.experiments.training.rllib.load_policy(out)``), ``env_config.json``, ``summary.json`` and
``checkpoints/`` (RLlib algorithm checkpoints every ``--checkpoint-every`` iterations and at the end,
``index.json`` written last). ``--resume`` continues from the latest checkpoint up to ``--timesteps`` in
all; without it a folder holding checkpoints is refused, and so is resuming with other environment options.

Needs the ``marl`` extra (``pip install 'crowd_env[marl]'``: ray[rllib]). A full run on the default
problem (10 pedestrians at the 1 m Seyfried bottleneck, decisions every 0.1 s, 10 s episodes)::

    crowd-train-rllib --timesteps 200000 --out runs/rllib
    crowd-train-rllib --timesteps 200000 --out runs/rllib --address head-node:6379 --num-env-runners 16
"""
from __future__ import annotations

import argparse
import importlib.util
import sys

from ..errors import BackendError, MissingDependencyError, TrainingError
from ..experiments.training.rllib import DEFAULT_PPO, train
from .train_options import add_env_arguments, add_evaluation_arguments, env_config_and_resolver


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="crowd-train-rllib", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--timesteps", type=int, default=200_000, help="environment steps sampled in all")
    ap.add_argument("--out", default="runs/rllib", help="output directory")
    add_env_arguments(ap)
    g = ap.add_argument_group("Ray")
    g.add_argument("--address", default=None, help="join this running Ray cluster (host:port, ray://host:port or "
                   "auto); default: start Ray locally")
    g.add_argument("--num-cpus", type=int, default=None, help="CPUs of a local Ray (default --num-env-runners + 1)")
    g.add_argument("--num-env-runners", type=int, default=1,
                   help="remote EnvRunner actors sampling in parallel (0: sample in the driver)")
    g.add_argument("--connect-timeout", type=float, default=5.0, help="seconds to reach --address")
    g = ap.add_argument_group("PPO")
    g.add_argument("--train-batch-size", type=int, default=DEFAULT_PPO["train_batch_size"],
                   help="environment steps per iteration")
    g.add_argument("--minibatch-size", type=int, default=DEFAULT_PPO["minibatch_size"])
    g.add_argument("--num-epochs", type=int, default=DEFAULT_PPO["num_epochs"])
    g.add_argument("--learning-rate", type=float, default=DEFAULT_PPO["learning_rate"])
    g.add_argument("--gamma", type=float, default=DEFAULT_PPO["gamma"])
    g.add_argument("--lambda", dest="lambda_", type=float, default=DEFAULT_PPO["lambda_"], help="GAE lambda")
    g.add_argument("--entropy-coeff", type=float, default=DEFAULT_PPO["entropy_coeff"])
    g.add_argument("--hidden", type=int, nargs="+", default=list(DEFAULT_PPO["hidden"]),
                   help="hidden layer sizes of the policy and value networks")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--checkpoint-every", type=int, default=10, help="iterations between checkpoints (0: only at "
                    "the end)")
    ap.add_argument("--resume", action="store_true",
                    help="continue from the latest checkpoint in --out up to --timesteps in all")
    add_evaluation_arguments(ap)
    args = ap.parse_args(argv)
    if importlib.util.find_spec("ray") is None or importlib.util.find_spec("ray.rllib") is None:
        raise SystemExit("error: crowd-train-rllib needs the 'marl' extra (ray[rllib]); pip install 'crowd_env[marl]'")
    env_config, resolve = env_config_and_resolver(args)
    try:
        summary = train(env_config, args.timesteps, args.out, resolve=resolve, address=args.address,
                        num_cpus=args.num_cpus, num_env_runners=args.num_env_runners, seed=args.seed,
                        train_batch_size=args.train_batch_size, minibatch_size=args.minibatch_size,
                        num_epochs=args.num_epochs, learning_rate=args.learning_rate, gamma=args.gamma,
                        lambda_=args.lambda_, entropy_coeff=args.entropy_coeff, hidden=tuple(args.hidden),
                        eval_seeds=args.eval_seeds, checkpoint_every=args.checkpoint_every, resume=args.resume,
                        connect_timeout_s=args.connect_timeout)
    except (TrainingError, BackendError, MissingDependencyError) as exc:
        raise SystemExit(f"error: {exc}") from None
    print(f"rllib ppo: mean per-agent episode return: random {summary['random']['mean_return']:.3f} -> trained "
          f"{summary['trained']['mean_return']:.3f} ({summary['env_steps']} environment steps, "
          f"{summary['agent_steps']} agent steps, {summary['train_wall_s']:.0f} s training); outputs in {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
