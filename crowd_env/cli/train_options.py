"""Command-line options shared by the training commands (``crowd-train-ppo``, ``crowd-train-mappo``,
``crowd-train-rllib``): the environment a policy is trained on, as a JSON-serialisable ``env_config``
(the options of :func:`crowd_env.envs.crowd_v0.parallel_env`), and the evaluation against the random policy."""
from __future__ import annotations

from ..errors import OptionError
from ..experiments.running.evaluation import import_object
from ..experiments.training.ppo import DEFAULT_SCENARIO_OPTIONS
from .options import add_key_values, DEFAULT_POLICY_RESOLVER, key_values

__all__ = ["add_env_arguments", "add_evaluation_arguments", "env_config_from_args", "env_config_and_resolver"]


def add_env_arguments(ap) -> None:
    """The scenario and the environment options (defaults: 10 pedestrians at the 1 m Seyfried bottleneck,
    decisions every 0.1 s, 10 s episodes, as ``crowd-train-ppo``)."""
    g = ap.add_argument_group("environment")
    g.add_argument("--scenario", default="seyfried_bottleneck", help="registered scenario name")
    add_key_values(g, "--scenario-option", metavar="KEY=VALUE",
                   help="scenario option (JSON values); defaults for seyfried_bottleneck "
                        f"{DEFAULT_SCENARIO_OPTIONS}, for other scenarios their own")
    g.add_argument("--n-pedestrians", type=int, default=None, help="shortcut for --scenario-option n_pedestrians=N")
    g.add_argument("--width", type=float, default=None, help="shortcut for --scenario-option width_m=B")
    g.add_argument("--frame-skip", type=int, default=10, help="simulator steps (0.01 s) per decision")
    g.add_argument("--max-steps", type=int, default=100, help="decisions per episode")
    g.add_argument("--n-neighbors", type=int, default=6)
    g.add_argument("--n-rays", type=int, default=8)
    g.add_argument("--observation-frame", choices=("world", "egocentric"), default="world",
                   help="frame of observations, actions and state (default world)")
    g.add_argument("--reward", choices=("default", "least_effort"), default="default",
                   help="the reward (docs/environment.md, 'The rewards'): default (progress, contacts, time, exit) or "
                        "least_effort (progress valued at the least cost of transport, metabolic effort, contacts, "
                        "exit; its optimum is the preferred walking speed)")
    g.add_argument("--fixed-start", action="store_true",
                   help="keep the scenario's start positions in every episode (default: new positions drawn "
                        "from the episode seed, see reseed_scenario)")


def add_evaluation_arguments(ap) -> None:
    """Seeds of the final evaluation and the resolver of the random policy it compares with."""
    g = ap.add_argument_group("evaluation")
    g.add_argument("--eval-seeds", type=int, nargs="+", default=[1000, 1001, 1002])
    g.add_argument("--policy-resolver", default=DEFAULT_POLICY_RESOLVER, metavar="MODULE:FUNCTION",
                   help="resolve(spec, name=None) -> policy, for the random policy of the summary "
                        f"(default {DEFAULT_POLICY_RESOLVER})")


def env_config_from_args(args) -> dict:
    """The environment options the flags describe; a malformed ``--scenario-option`` raises
    :class:`~crowd_env.errors.OptionError`."""
    base = DEFAULT_SCENARIO_OPTIONS if args.scenario == "seyfried_bottleneck" else {}
    options = {**base, **key_values(args.scenario_option, "--scenario-option needs key=value")}
    if args.n_pedestrians is not None:
        options["n_pedestrians"] = args.n_pedestrians
    if args.width is not None:
        options["width_m"] = args.width
    config = {"scenario": args.scenario, "scenario_options": options, "controlled": "all",
              "frame_skip": args.frame_skip, "max_steps": args.max_steps, "n_neighbors": args.n_neighbors,
              "n_rays": args.n_rays, "reseed_scenario": False if args.fixed_start else None,
              "observation_frame": args.observation_frame}
    if getattr(args, "reward", "default") != "default":  # the default reward stays out: old configs stay equal
        config["reward_terms"] = args.reward
    return config


def env_config_and_resolver(args) -> tuple:
    """``(env_config, resolve)`` from the parsed flags; a malformed option or resolver path exits with the
    message (``error: ...``)."""
    try:
        env_config = env_config_from_args(args)
    except OptionError as exc:
        raise SystemExit(f"error: {exc}") from None
    try:
        resolve = import_object(args.policy_resolver)
    except (ImportError, ValueError) as exc:
        raise SystemExit(f"error: --policy-resolver: {exc}") from None
    return env_config, resolve
