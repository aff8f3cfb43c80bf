"""crowd-virtual-experiments: every shipped experiment run as it was run, for a preset or a parameter point, beside
its data (crowd_env.experiments.validation.virtual_experiments).

Seyfried's bottleneck at its widths and group sizes, the nine Jülich corridor runs with their entrance and exit
(Voronoi density and speed in y in [−2, 0], exit flow), the single-file ring at its bins: one table row per case and
quantity with the experiment's value, the tolerance and whether the model's mean over the complete runs lies within
it; runs that stalled or stayed incomplete are counted, never averaged in. Writes ``OUT/virtual_experiments.csv``,
``.md`` and ``.png`` (the density-speed plane, each run's model and experiment points joined), and beside the
recordings measured alike: with corridor runs ``OUT/spacing.md`` and ``.png`` (how close walkers come ahead and
beside) and ``OUT/passage_lapses.md`` and ``.png`` (the time lapses between passages of each run's narrower
opening: how long it stays blocked), with a narrowed entrance or exit ``OUT/door_passage.md``, ``OUT/passing.png``
and ``OUT/entries.png`` (how it is passed, where the next walker stands as the one before leaves it) and
with a narrowed exit ``OUT/approach.png`` (the queue before it). Runs are
stored under ``OUT/runs/``: a stopped command resumes. The corridor runs are measured with PedPy (``pip install
'crowd_env[analysis]'``).

Examples::

    crowd-virtual-experiments --quick --out out/virtual_quick                # two corridor runs, one door, one bin
    crowd-virtual-experiments --preset calibrated --seeds 5 --out out/virtual
    crowd-virtual-experiments --param social_range_m=0.1 --experiments corridor --out out/virtual_B0.1
    crowd-virtual-experiments --policy human_juelich --seeds 5 --out out/virtual_human   # every pedestrian learned
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from ..walking.presets import DEFAULT_PRESET, PRESETS, get_preset
from ..errors import CrowdEnvError, InputError
from ..experiments.running.backends import make_backend
from ..experiments.validation.corridor_runs import CORRIDOR_RUN_NAMES
from ..experiments.validation.virtual_experiments import (EXPERIMENTS, QUICK_PLAN, VirtualPlan, format_rows,
                                                          run_snapshot, run_virtual_experiments, snapshot_case,
                                                          snapshot_figure, virtual_config, virtual_rows, virtual_tasks,
                                                          write_virtual_outputs)
from .options import add_key_values, add_wall_slowdown_argument, key_values


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="crowd-virtual-experiments", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--preset", choices=sorted(PRESETS), default=DEFAULT_PRESET, help="the model (default: %(default)s)")
    add_key_values(ap, "--param",
                   "ModelParams fields on top of the preset (values as JSON)")
    add_key_values(ap, "--pedestrian",
                   "per-pedestrian defaults on top of Kabalan's Table 2: tau_s, desired_speed_mean_m_s, "
                   "desired_speed_std_m_s")
    ap.add_argument("--radius", type=float, default=None, metavar="R",
                    help="every pedestrian's radius in m, in every experiment (default the preset's: Kabalan's Table 2, "
                         "0.23, unless the preset calibrated its body)")
    add_key_values(ap, "--corridor-option",
                   "options of the juelich_corridor scenario for every corridor run (the set-up's undocumented "
                   "dimensions: barrier_thickness_m, end_wall_thickness_m, floor_width_m, outflow_width_m, "
                   "waiting_width_m, waiting_density_per_m2)")
    ap.add_argument("--navigation-clearance", type=float, default=None, metavar="M",
                    help="clearance of the eikonal field (Eq. 11-13) in every bottleneck and corridor run, in m "
                         "(default: the preset's, the disk centres' field of its body; e.g. half the depth of a body "
                         "that turns its shoulders)")
    add_wall_slowdown_argument(ap, "the bottleneck's and every corridor run's fields")
    ap.add_argument("--policy", default=None, metavar="POLICY",
                    help="drive every pedestrian of every run by this learned policy: a shipped trained policy's name "
                         "(e.g. human_juelich), a policy file (.npz) or an import path module:attribute of an "
                         "observation policy (default: the preset's calibrated agent; the preset still sets the "
                         "physics)")
    ap.add_argument("--policy-social-force", action="store_true",
                    help="with --policy: add the preset's social force (Kabalan Eq. 16, as the calibrated agent adds "
                         "it to its intent) to the policy's intents: learned walking with the model's push apart "
                         "between walkers close to touching")
    ap.add_argument("--policy-social-force-below", type=float, default=None, metavar="SPEED",
                    help="with --policy-social-force: only to a walker slower than SPEED m/s, in full at rest and "
                         "falling linearly to none at SPEED (a walker held still pushes back; walking, it does not)")
    ap.add_argument("--experiments", nargs="+", choices=EXPERIMENTS, default=list(EXPERIMENTS),
                    help="which experiments (default: all three)")
    ap.add_argument("--corridor-runs", nargs="+", choices=CORRIDOR_RUN_NAMES, default=None, metavar="RUN",
                    help="only these corridor runs (default: all nine; e.g. uo-180-180-070 --seeds 20 for its clog rate)")
    ap.add_argument("--seeds", type=int, default=5, help="seeds 0..S-1, the same in every experiment (default 5)")
    ap.add_argument("--quick", action="store_true",
                    help="the reduced plan: two corridor runs (uo-070-180-180, uo-180-180-095), b = 1.0 m at N = 60, "
                         "one single-file bin, seeds 0 and 1: a first look, not a verdict")
    ap.add_argument("--max-time", type=float, default=300.0,
                    help="simulated time limit of a bottleneck or corridor run (s; default 300)")
    ap.add_argument("--out", type=Path, default=Path("out/virtual_experiments"), help="output folder (resumable)")
    ap.add_argument("--backend", choices=["ray", "process", "serial"], default="process")
    ap.add_argument("--jobs", type=int, default=None, help="processes of the pool / CPUs of local Ray")
    ap.add_argument("--address", default=None, help="Ray cluster to join (with --backend ray)")
    ap.add_argument("--no-figure", action="store_true", help="skip virtual_experiments.png")
    ap.add_argument("--snapshot", default=None, metavar="CASE",
                    help="instead: follow one run step by step to --at and write OUT/snapshot_CASE.png (with "
                         "--snapshot-seed S > 0, OUT/snapshot_CASE_seedS.png): the crowd at the narrower opening and, "
                         "over time, those out, their mean speed and mean net speed (how a crowd wedged for good "
                         "still shakes). CASE: a corridor run (" + ", ".join(CORRIDOR_RUN_NAMES) + ") or "
                         "bottleneck-B-N (Seyfried's bottleneck of width B m with N walkers, e.g. bottleneck-0.8-60)")
    ap.add_argument("--snapshot-seed", type=int, default=0, metavar="S", help="the seed of the run --snapshot follows "
                    "(default 0)")
    ap.add_argument("--at", type=float, default=60.0, help="time of the snapshot (s; default 60)")
    return ap


def config_from_args(args) -> dict:
    """The folder's configuration (:func:`virtual_config`) from the parsed options: the preset with ``--param`` on top,
    ``--pedestrian``, the body (``--radius``), the corridor's options, the navigation field's clearance and wall
    slowdown (``--navigation-clearance``, ``--navigation-wall-slowdown``: the bottleneck's and every corridor run's),
    the policy."""
    preset = get_preset(args.preset)
    params = preset.params(**key_values(args.param, "--param expects NAME=VALUE"))
    pedestrian = key_values(args.pedestrian, "--pedestrian expects NAME=VALUE")
    corridor_geometry = key_values(args.corridor_option, "--corridor-option expects NAME=VALUE")
    for what, value, flag, option in (
            ("clearance", args.navigation_clearance, "--navigation-clearance", "navigation_clearance_m"),
            ("wall slowdown", args.navigation_wall_slowdown, "--navigation-wall-slowdown", "navigation_wall_slowdown")):
        if value is None:
            continue
        if option in corridor_geometry:  # the field's options reach the bottleneck and every corridor run alike
            raise CrowdEnvError(f"give the {what} once: {flag} sets it in the corridor runs too (drop "
                                f"--corridor-option {option})")
        corridor_geometry[option] = value
    clearance = preset.navigation_clearance_m if args.navigation_clearance is None else args.navigation_clearance
    return virtual_config(params, navigation_clearance_m=clearance, pedestrian=pedestrian,
                          radius_m=preset.body_radius_m if args.radius is None else args.radius,
                          corridor_geometry=corridor_geometry, policy=args.policy,
                          navigation_wall_slowdown=args.navigation_wall_slowdown,
                          policy_social_force=args.policy_social_force,
                          policy_social_force_below_m_s=args.policy_social_force_below)


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        if args.seeds < 1:
            raise CrowdEnvError(f"--seeds must be at least 1, got {args.seeds}")
        plan = QUICK_PLAN if args.quick else VirtualPlan(seeds=tuple(range(args.seeds)))
        plan = replace(plan, experiments=tuple(args.experiments), max_time_s=args.max_time)
        if args.corridor_runs:
            plan = replace(plan, corridor_runs=tuple(args.corridor_runs))
        config = config_from_args(args)
        if args.snapshot:
            return _snapshot(args, config, plan)
        pushed = " + the social force" if args.policy_social_force else ""
        who = f"policy {args.policy}{pushed} (physics: {args.preset})" if config.get("policy") else args.preset
        field = "".join(f", navigation {what} {value}" for what, value in (
            ("clearance", args.navigation_clearance), ("wall slowdown", args.navigation_wall_slowdown))
            if value is not None)
        print(f"virtual experiments of {who}{' with ' + ' '.join(args.param) if args.param else ''}{field}: "
              f"{', '.join(plan.experiments)}; seeds {list(plan.seeds)}{' (quick plan)' if args.quick else ''}")
        with make_backend(args.backend, address=args.address, jobs=args.jobs) as backend:
            records = run_virtual_experiments(args.out, config, plan, backend)
        rows = virtual_rows(records)
        print(format_rows(rows))
        for path in write_virtual_outputs(args.out, records, rows, figure=not args.no_figure):
            print(f"wrote {path}")
    except CrowdEnvError as exc:
        print(f"crowd-virtual-experiments: {exc}", file=sys.stderr)
        return 2
    return 0


def _snapshot(args, config: dict, plan: VirtualPlan) -> int:
    keywords, case = snapshot_case(args.snapshot)
    if args.snapshot_seed < 0:
        raise InputError(f"--snapshot-seed must be an integer >= 0, got {args.snapshot_seed}")
    task = next(t for t in virtual_tasks(config, replace(plan, seeds=(args.snapshot_seed,), **keywords)))
    study = run_snapshot(task, at_s=args.at)
    args.out.mkdir(parents=True, exist_ok=True)
    suffix = f"_seed{args.snapshot_seed}" if args.snapshot_seed else ""
    path = snapshot_figure(study, args.out / f"snapshot_{case}{suffix}.png")
    s = study["series"]
    print(f"{case}, seed {args.snapshot_seed}, to t = {s['time_s'][-1]:.1f} s: {s['left'][-1]} of "
          f"{task['n_pedestrians']} out; those left move at {s['mean_speed_m_s'][-1]:.3f} m/s on average, "
          f"{s['net_displacement_m'][-1]:.3f} m net over the last 20 s")
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
