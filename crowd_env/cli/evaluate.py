"""Evaluate policies on the same scenarios and seeds; print one table of metrics and write a plot.

Policies: names the policy resolver knows (``--policy-resolver``, default the shipped baselines'
``baselines.reference_policies:as_policy``: ``baseline``, the calibrated social-force model,
``random``, ``zero``), import paths ``module:attribute`` of your own policy classes or objects, and any
number of saved SB3 models (``--model runs/ppo/model.zip``). Everything is resolved by import path at run
time: ``crowd_env`` imports no policy.

Which problem: with ``--model``, every policy is evaluated on the configuration the first model was
trained on, the ``env_config.json`` beside it (scenario and its options, observation options, decision
interval, and its episode length as ``--max-time``), so that the returns compare with training; flags given
explicitly (``--scenario``, ``--scenario-option``, ``--widths``, ``--max-time``, ``--controlled``,
``--frame-skip``) override it, and ``--no-recorded-config`` ignores it. Without a model, or a model without
one, the defaults below apply (Seyfried bottleneck, 60 pedestrians, 90 s). The command prints which
configuration it uses.

Metrics (:mod:`crowd_env.experiments.running.evaluation`): specific flow J_s (Kabalan et al. 2016, Eq. 22),
evacuation time, mean speed, number and mean size of the contact percussions, minimum gap, mean
per-agent return: their means over the episodes, then their 95 % intervals (percentile bootstrap of
the mean over the episodes; rough with few seeds).

    crowd-evaluate --seeds 0 1 2 --widths 1.0 1.6 --scenario-option n_pedestrians=20
    crowd-evaluate --model runs/ppo/model.zip --policies baseline random --out runs/eval
    crowd-evaluate --policies baseline mypackage.policies:MyPolicy
    crowd-evaluate --policies baseline random --seeds 0 --video runs/eval/episode.mp4

--video PATH (.mp4 or .gif) records the first episode of each policy (the first scenario, e.g. the first
--widths value, with the first of --seeds) into PATH with the policy's label added to the name
(runs/eval/episode-baseline.mp4, ...), as crowd-video rollout draws it: learned pedestrians blue,
background grey, headings, contact percussions. It plays in real time unless --video-fps and
--video-every say otherwise (see crowd-video --help).
"""
from __future__ import annotations

import argparse
import os
import sys

from crowd_env.files import write_atomic
from ..experiments.output.evaluation_report import format_intervals, format_table, plot_results, write_csv
from ..experiments.running.evaluation import (describe_setup, evaluate, import_object, recorded_env_config,
                                              resolve_policy, summarize)
from ..experiments.output.video import per_policy
from ..errors import CrowdEnvError, InputError, OptionError, PolicyError, ScenarioError
from .options import add_key_values, DEFAULT_POLICY_RESOLVER, DEFAULT_SCENARIO, PICKLED_MODELS_NOTE, policy_run_setup

DEFAULT_MAX_TIME_S = 90.0

def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="crowd-evaluate", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--policies", nargs="*", default=["baseline", "random", "zero"],
                    help="policies: names the resolver knows (baseline, random, zero, shipped trained policies), "
                         "policy files (.npz), saved models or import paths module:attribute")
    ap.add_argument("--model", action="append", default=[],
                    help=f"saved SB3 PPO model (.zip); repeatable. {PICKLED_MODELS_NOTE}")
    ap.add_argument("--policy-resolver", default=DEFAULT_POLICY_RESOLVER, metavar="MODULE:FUNCTION",
                    help=f"resolve(spec, name=None) -> policy for names and models (default {DEFAULT_POLICY_RESOLVER})")
    ap.add_argument("--no-recorded-config", action="store_true",
                    help="ignore the env_config.json beside the first --model (default: evaluate on it)")
    ap.add_argument("--scenario", default=None,
                    help=f"registered scenario name (default: the model's env_config.json, else {DEFAULT_SCENARIO}); "
                         "another scenario than the recorded one starts from its own default options")
    add_key_values(ap, "--scenario-option", metavar="KEY=VALUE",
                   help="scenario option (JSON values) on top of the recorded or default ones, e.g. "
                        "n_pedestrians=20")
    ap.add_argument("--widths", type=float, nargs="*", default=None,
                    help="bottleneck widths: one scenario per width (sets width_m)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="episode seeds (default 0 1 2)")
    ap.add_argument("--max-time", type=float, default=None,
                    help="simulated seconds per episode at most (default: the model's recorded episode length, "
                         f"else {DEFAULT_MAX_TIME_S:g})")
    ap.add_argument("--controlled", default=None,
                    help="'all', a count, a fraction or comma-separated ids (default: recorded, else all)")
    ap.add_argument("--frame-skip", type=int, default=None, help="decision interval in simulator steps "
                    "(default: the model's env_config.json, else 1)")
    ap.add_argument("--background", default=None, metavar="POLICY",
                    help="the policy of the pedestrians not controlled: 'calibrated' (default), a shipped trained "
                         "policy's name or a policy file (.npz)")
    ap.add_argument("--out", default="runs/eval", help="output directory (results.csv, summary.txt, metrics.png)")
    ap.add_argument("--video", default=None, metavar="PATH",
                    help="record the first episode (first scenario, first seed) of each policy to PATH (.mp4 or "
                         ".gif) with the policy's label added to the name: runs/v.mp4 -> runs/v-baseline.mp4, ...")
    ap.add_argument("--video-fps", type=float, default=None, metavar="FPS",
                    help="frames per second of the videos (default: real time, at most 25; see crowd-video --help)")
    ap.add_argument("--video-every", type=int, default=None, metavar="K",
                    help="a video frame every K environment steps (default: from --video-fps, real time)")
    return ap


def evaluation_setup(args) -> tuple:
    """``(scenarios, env_options, max_time_s, source)`` from the flags: the configuration recorded beside the
    first ``--model`` (see the module docstring) with the explicit flags on top, or the defaults; ``source``
    says which, for the printout (:func:`~crowd_env.cli.options.policy_run_setup`, which crowd-video shares)."""
    return policy_run_setup(args.model[0] if args.model else None, scenario=args.scenario,
                            scenario_option=args.scenario_option, widths=args.widths, max_time=args.max_time,
                            controlled=args.controlled, frame_skip=args.frame_skip,
                            use_recorded=not args.no_recorded_config, default_max_time_s=DEFAULT_MAX_TIME_S)


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)

    try:
        scenarios, env_options, max_time, source = evaluation_setup(args)
    except OptionError as exc:
        raise SystemExit(str(exc)) from None
    if args.background is not None:
        env_options["background_policy"] = args.background

    try:
        resolve = import_object(args.policy_resolver)
        policies = {}
        for spec in args.policies:
            p = resolve_policy(spec) if ":" in spec else resolve(spec)
            policies[getattr(p, "name", spec)] = p
        for path in args.model:
            p = resolve(path)
            label = p.name if p.name not in policies else os.path.basename(os.path.dirname(os.path.abspath(path)))
            policies[label] = p
    except (ImportError, ValueError, TypeError, OSError) as exc:  # OSError: a saved model that is not there
        raise SystemExit(f"error: {exc}") from None
    videos = []
    video = None
    if args.video:
        os.makedirs(os.path.dirname(os.path.abspath(args.video)), exist_ok=True)
        try:
            video = per_policy(args.video, fps=args.video_fps, every=args.video_every, written=videos)
        except CrowdEnvError as exc:
            raise SystemExit(f"error: --video: {exc}") from None

    print(f"evaluation configuration: {source}")
    print(f"  {describe_setup(scenarios, env_options, max_time)}; seeds {args.seeds}")
    first = recorded_env_config(args.model[0])[0] if args.model else None
    for path in args.model[1:]:
        other, other_path = recorded_env_config(path)
        if other is not None and other != first:
            print(f"note: {other_path} records another configuration than the first model's; every policy runs on "
                  "the one above")
    try:
        results = evaluate(policies, scenarios, args.seeds, env_options=env_options, max_time_s=max_time,
                           video=video)
    except (InputError, OptionError, PolicyError, ScenarioError) as exc:  # bad input met at run time
        raise SystemExit(f"error: {exc}") from None
    rows = summarize(results)
    table = (format_table(rows) + "\n\n95 % intervals of the means (percentile bootstrap over the episodes; rough "
             "with few seeds):\n" + format_intervals(rows))
    print()
    print(table)
    os.makedirs(args.out, exist_ok=True)
    write_csv(results, os.path.join(args.out, "results.csv"))
    write_atomic(os.path.join(args.out, "summary.txt"),
                 f"evaluation configuration: {source}\n{describe_setup(scenarios, env_options, max_time)}; "
                 f"seeds {args.seeds}\n\n{table}\n")
    plot_results(results, os.path.join(args.out, "metrics.png"))
    print(f"\nwrote {args.out}/results.csv, summary.txt, metrics.png")
    for rec in videos:
        i = rec.info
        print(f"wrote {i.path}: {i.n_frames} frames at {i.fps:g} fps, one per {i.frame_interval_s:g} s simulated "
              f"(x{i.speed:g} real time)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
