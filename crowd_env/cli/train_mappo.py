"""Train one policy shared by all controlled pedestrians with MAPPO or IPPO (TorchRL).

TorchRL's PettingZoo wrapper puts every agent in one group, with masks for the pedestrians that have
left (they are never trained on); the policy network is shared by all agents. The two algorithms
differ in the critic only: ``mappo`` (default) gives it the agent's observation and the environment's
global state ``env.state()`` (centralised training, decentralised execution), ``ippo`` the agent's
own observation (:mod:`crowd_env.experiments.training.marl`).

Each iteration collects ``--frames-per-batch`` environment steps (every step holds one transition per
live agent) and prints, and appends to ``progress.csv``: the mean per-agent return and the length of
the episodes that ended in it, the PPO losses (objective, critic, entropy) and the wall time. At the end
the trained policy (deterministic) and the uniform random policy run on the same ``--eval-seeds``
through the evaluation harness; ``summary.json`` holds both mean per-agent episode returns.

Outputs in ``--out``: ``progress.csv``, ``policy.pt`` (the policy's weights and shapes, data only; reload it with
``crowd_env.experiments.training.marl.load_policy(out)``, a policy of the evaluation harness, or convert it to a
policy file with ``crowd-convert-policy``),
``env_config.json``, ``summary.json`` and ``checkpoints/`` (every ``--checkpoint-every`` iterations and at
the end: networks, optimiser and progress, ``index.json`` written last). A run stopped midway continues
with ``--resume`` up to ``--frames`` in all; without it a folder holding checkpoints is refused, and so is
resuming with other environment options or the other algorithm.

Needs the ``marl`` extra (``pip install 'crowd_env[marl]'``: torchrl, tensordict). A full run on the
default problem (10 pedestrians at the 1 m Seyfried bottleneck, decisions every 0.1 s, 10 s episodes)::

    crowd-train-mappo --algorithm mappo --frames 200000 --out runs/mappo
    crowd-train-mappo --algorithm ippo --frames 200000 --out runs/ippo

(docs/training.md gives the measured wall times.)
"""
from __future__ import annotations

import argparse
import importlib.util
import sys

from ..errors import MissingDependencyError, TrainingError
from ..experiments.training.marl import ALGORITHMS, DEFAULT_PPO, train
from .train_options import add_env_arguments, add_evaluation_arguments, env_config_and_resolver


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="crowd-train-mappo", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--algorithm", choices=ALGORITHMS, default="mappo",
                    help="mappo: critic on the observation and the global state; ippo: critic on the observation")
    ap.add_argument("--frames", type=int, default=200_000, help="environment steps in all (each holds one "
                    "transition per live agent)")
    ap.add_argument("--out", default="runs/mappo", help="output directory")
    add_env_arguments(ap)
    g = ap.add_argument_group("PPO")
    g.add_argument("--frames-per-batch", type=int, default=DEFAULT_PPO["frames_per_batch"],
                   help="environment steps collected per iteration")
    g.add_argument("--num-epochs", type=int, default=DEFAULT_PPO["num_epochs"], help="passes over each batch")
    g.add_argument("--minibatch-size", type=int, default=DEFAULT_PPO["minibatch_size"],
                   help="agent transitions per gradient step")
    g.add_argument("--learning-rate", type=float, default=DEFAULT_PPO["learning_rate"])
    g.add_argument("--clip-epsilon", type=float, default=DEFAULT_PPO["clip_epsilon"])
    g.add_argument("--gamma", type=float, default=DEFAULT_PPO["gamma"])
    g.add_argument("--lmbda", type=float, default=DEFAULT_PPO["lmbda"], help="GAE lambda")
    g.add_argument("--entropy-coeff", type=float, default=DEFAULT_PPO["entropy_coeff"])
    g.add_argument("--max-grad-norm", type=float, default=DEFAULT_PPO["max_grad_norm"])
    g.add_argument("--hidden", type=int, nargs="+", default=list(DEFAULT_PPO["hidden"]),
                   help="hidden layer sizes of the policy and the critic")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=1, help="torch threads")
    ap.add_argument("--checkpoint-every", type=int, default=10, help="iterations between checkpoints (0: only at "
                    "the end)")
    ap.add_argument("--resume", action="store_true",
                    help="continue from the latest checkpoint in --out up to --frames in all")
    add_evaluation_arguments(ap)
    args = ap.parse_args(argv)
    missing = [name for name in ("torchrl", "tensordict") if importlib.util.find_spec(name) is None]
    if missing:
        raise SystemExit(f"error: crowd-train-mappo needs the 'marl' extra (missing: {', '.join(missing)}); "
                         "pip install 'crowd_env[marl]'")
    env_config, resolve = env_config_and_resolver(args)
    try:
        summary = train(env_config, args.frames, args.out, algorithm=args.algorithm, resolve=resolve, seed=args.seed,
                        frames_per_batch=args.frames_per_batch, num_epochs=args.num_epochs,
                        minibatch_size=args.minibatch_size, learning_rate=args.learning_rate,
                        clip_epsilon=args.clip_epsilon, gamma=args.gamma, lmbda=args.lmbda,
                        entropy_coeff=args.entropy_coeff, max_grad_norm=args.max_grad_norm, hidden=tuple(args.hidden),
                        eval_seeds=args.eval_seeds, threads=args.threads, checkpoint_every=args.checkpoint_every,
                        resume=args.resume)
    except (TrainingError, MissingDependencyError) as exc:
        raise SystemExit(f"error: {exc}") from None
    print(f"{args.algorithm}: mean per-agent episode return: random {summary['random']['mean_return']:.3f} -> trained "
          f"{summary['trained']['mean_return']:.3f} ({summary['frames']} frames, {summary['agent_steps']} agent steps, "
          f"{summary['train_wall_s']:.0f} s training); outputs in {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
