"""crowd-scorecard: how human is a policy? Any policy through the experiments the calibration measures the model
against (crowd_env.experiments.validation.scorecard): the Seyfried et al. (2009) bottleneck, the Jülich corridor's
fundamental diagram and the single file, one distance per experiment with its 95 % bootstrap interval over seeds,
the calibrated model's row first as the reference.

Policies: "calibrated", a shipped trained policy's name (--shipped: every one), a policy file (.npz) or an
observation policy by import path ("module:attribute"); "NAME@F" drives a fraction F of the crowd among calibrated
walkers (the mixed case). Runs are stored per policy under OUT/<policy>/ and the command resumes.

Examples::

    crowd-scorecard --quick --policies bottleneck_bc --backend serial --out out/scorecard_quick
    crowd-scorecard --shipped --policies bottleneck_ppo@0.5 --out out/scorecard     # the full plan
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..walking.presets import PRESETS, get_preset
from ..envs.background import shipped_policy_names
from ..experiments.running.backends import make_backend
from ..experiments.validation.bottleneck import bottleneck_config
from ..experiments.validation.calibration.tasks import base_config
from ..experiments.validation.scorecard import (BOOTSTRAP_DRAWS, QUICK_PLAN, ScorecardPlan, describe_plan,
                                                format_scorecard, plan_limits, run_scorecard, write_scorecard)


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="crowd-scorecard", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--policies", nargs="+", default=[], metavar="POLICY",
                    help="policies to score besides the calibrated model: names, policy files (.npz: data only, "
                         "nothing in them runs; crowd-convert-policy makes one of a trained SB3 or MAPPO model), "
                         "module:attribute, NAME@FRACTION for the mixed case")
    ap.add_argument("--shipped", action="store_true", help="also every shipped trained policy")
    ap.add_argument("--quick", action="store_true",
                    help=f"the small plan ({describe_plan(QUICK_PLAN)}): a first look, not a verdict; the command "
                         "prints what it leaves out")
    ap.add_argument("--seeds", type=int, default=3, help="seeds 0..S-1 of the full plan (default 3)")
    ap.add_argument("--preset", choices=sorted(PRESETS), default="calibrated",
                    help="the model the calibrated walkers (and the reference row) use (default calibrated)")
    ap.add_argument("--max-time", type=float, default=300.0,
                    help="simulated time limit of a bottleneck run (s; default 300, the calibration's)")
    ap.add_argument("--draws", type=int, default=BOOTSTRAP_DRAWS, help="bootstrap resamplings of the seeds")
    ap.add_argument("--out", type=Path, default=Path("out/scorecard"), help="output folder (resumable)")
    ap.add_argument("--backend", choices=["ray", "process", "serial"], default="process")
    ap.add_argument("--jobs", type=int, default=None, help="processes of the pool / CPUs of local Ray")
    ap.add_argument("--address", default=None, help="Ray cluster to join (with --backend ray)")
    ap.add_argument("--no-figure", action="store_true", help="skip scorecard.png")
    return ap


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    if args.seeds < 2 and not args.quick:
        print("crowd-scorecard: --seeds must be at least 2 (the intervals resample seeds)", file=sys.stderr)
        return 2
    plan = QUICK_PLAN if args.quick else ScorecardPlan(seeds=tuple(range(args.seeds)))
    policies = list(args.policies) + (shipped_policy_names() if args.shipped else [])
    preset = get_preset(args.preset)
    params = preset.params()
    geometry = bottleneck_config(params, navigation_clearance_m=preset.navigation_clearance_m,
                                 max_time_s=args.max_time, radius_m=preset.radius_m)["geometry"]
    config = base_config(geometry, params, args.max_time)
    print(f"scorecard of {1 + len(policies)} policies ({'quick plan' if args.quick else 'full plan'}: "
          f"{describe_plan(plan)}); distances are sums of squared relative misses, 0 inside the experiment's bands: "
          "lower is more human")
    limits = plan_limits(plan)
    if limits:
        print(f"not measured by this plan: {'; '.join(limits)}. A distance of 0 here says only that these runs meet "
              "their bands: a first look, not a verdict")
    with make_backend(args.backend, address=args.address, jobs=args.jobs) as backend:
        rows = run_scorecard(args.out, config, policies, plan, backend, draws=args.draws, progress=None)
    print(format_scorecard(rows))
    for path in write_scorecard(args.out, rows, plan, figure=not args.no_figure):
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
