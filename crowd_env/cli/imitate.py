"""crowd-imitate: pedestrians learned from recorded people (crowd_env.experiments.training.human_imitation).

demonstrations: a trajectory file in PedPy's text format (id frame x y [z], a '#framerate' header line or
--frame-rate, metres or --unit cm; .gz read as such) replayed in a scenario of the registry into observation-action
pairs, one per pedestrian and decision: the observation the environment would give it, the velocity over the next
decision interval in the observation's frame (format: crowd_env.experiments.training.demonstrations). --uo-run NAME
takes the shipped recording of a Jülich corridor run and its juelich_corridor scenario.

train: behaviour cloning on the shipped Jülich corridor recordings (training runs: all but uo-100-180-180 and
uo-180-180-095, which validate), then rounds of Data as Demonstrator in the simulator; resumable (--resume), one task
per run on the executor; writes OUT/policy.npz (a policy file: crowd-evaluate --policies OUT/policy.npz,
background_policy="OUT/policy.npz", crowd-virtual-experiments --policy OUT/policy.npz), progress.csv (the learning
curves), summary.json (sizes, wall and CPU time per stage, the open-loop speed errors against the calibrated agent).

select: trained policies (files, training folders or shipped names) scored closed loop on the validation runs
(each drives every pedestrian of uo-100-180-180 and uo-180-180-095 as they were run, crowd-virtual-experiments'
runs and measurement), ranked as docs/validation/human_policy.md ranks its candidates: a candidate with a stalled
run after every one without, then one with a run that never completed (quantities its miss cannot count) after
every one with all measured, then by the mean miss of density, speed and exit flow in units of their tolerances
(crowd_env.experiments.validation.virtual_experiments.selection_rank). Writes
OUT/selection.md and OUT/policy.npz (a copy of the best); the runs are stored under OUT/runs/ (resumable). The
training's result depends on its seed: train several (--set seed=K) and keep the one this prefers. --push-below
scores each policy with the model's social force added to its intents as crowd-virtual-experiments
--policy-social-force adds it (off, always, or only for walkers slower than U m/s), so that the gate U is chosen
by the same rule, on the runs --runs names (all: the nine corridor runs, the data the policy learns from).

Examples::

    crowd-imitate demonstrations --uo-run uo-180-180-070 --out out/demos/uo-180-180-070.npz
    crowd-imitate demonstrations my_run.txt --frame-rate 16 --unit cm --scenario juelich_corridor \\
        --scenario-option entrance_width_m=1.0 exit_width_m=1.8 n_pedestrians=121 --out out/demos/mine.npz
    crowd-imitate train --quick --out out/human_quick          # seconds: the same code path
    crowd-imitate train --out out/human --backend process --jobs 2
    crowd-imitate train --out out/human_bc --set dad_rounds=0    # behaviour cloning alone
    crowd-imitate select out/human_s0 out/human_s1 out/human_s2 --out out/human_best --backend process --jobs 2
    crowd-imitate select human_juelich --runs all --seeds 5 --push-below off 0.1 0.3 always --out out/push_gate
"""
from __future__ import annotations

import argparse
import math
import resource
import sys
import time
from pathlib import Path

from ..analysis.corridor_runs import recorded_uo_trajectories, uo_scenario
from ..analysis.trajectories import Trajectories
from ..errors import CrowdEnvError, OptionError
from ..experiments.running.backends import make_backend
from ..experiments.running.crowd_policy import load_scored_policy
from ..experiments.training.demonstrations import DEFAULT_SMOOTHING_S, demonstrations_from_trajectories
from ..experiments.training.human_imitation import QUICK_HUMAN_TRAINING, VALIDATION_RUNS, train_human_policy
from ..experiments.validation.corridor_runs import CORRIDOR_RUN_NAMES
from ..experiments.validation.virtual_experiments import (VirtualPlan, corridor_miss, format_selection,
                                                          run_virtual_experiments, selection_rank, virtual_config)
from ..files import copy_atomic, write_atomic
from ..scenarios import make_scenario
from ..walking.presets import DEFAULT_PRESET, get_preset
from .options import add_key_values, key_values

PUSH_OFF, PUSH_ALWAYS = "off", "always"  # --push-below: the policy alone; the push for every walker


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="crowd-imitate", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="command", required=True, metavar="{demonstrations,train,select}")
    de = sub.add_parser("demonstrations", help="a trajectory file and a scenario into observation-action pairs",
                        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    de.add_argument("file", nargs="?", type=Path, help="trajectory file (PedPy's text format; .gz allowed)")
    de.add_argument("--uo-run", default=None, metavar="NAME",
                    help="instead of a file: the shipped recording of this Jülich corridor run, in its scenario")
    de.add_argument("--scenario", default=None, help="a registered scenario (crowd_env.scenarios.list_scenarios())")
    add_key_values(de, "--scenario-option", "its options (JSON values)", metavar="KEY=VALUE")
    de.add_argument("--frame-rate", type=float, default=None, help="frames per second when the file's header has none")
    de.add_argument("--unit", choices=["m", "cm"], default=None, help="the file's length unit (default: its header's, "
                                                                     "else metres)")
    de.add_argument("--smoothing", type=float, default=DEFAULT_SMOOTHING_S, metavar="S",
                    help="centred moving average of the positions over S seconds (default %(default)s; 0: none)")
    add_key_values(de, "--policy-option", metavar="KEY=VALUE",
                   help="observation and decision options (n_neighbors, n_rays, neighbor_radius_m, ray_range_m, "
                        "observation_frame, observation_components, frame_skip, action_max_m_s)")
    de.add_argument("--out", required=True, type=Path, help="the dataset (.npz)")
    tr = sub.add_parser("train", help="the human policy from the shipped recordings", description=__doc__,
                        formatter_class=argparse.RawDescriptionHelpFormatter)
    tr.add_argument("--out", required=True, type=Path, help="output folder (checkpoints, policies, progress)")
    tr.add_argument("--quick", action="store_true", help="two short runs, tiny budgets: the code path in seconds")
    tr.add_argument("--resume", action="store_true", help="continue the training in --out after its last stage")
    add_key_values(tr, "--set", metavar="KEY=VALUE",
                   help="training options (JSON values): hidden, bc_epochs, dad_rounds, dad_epochs, batch_size, "
                        "learning_rate, smoothing_s, seed, dad (a dict of the rollouts' options; those it does "
                        "not name keep the human policy's), policy (a dict of observation options), radius_m (the "
                        "body of the replays and rollouts; default the calibrated preset's, 0.23 m), body_depth_m (0, "
                        "the disk, or bodies of three circles that deep: crowd_env.core.body), "
                        "shoulder_turn_critical_ratio (0, no turn, or the ratio at which the heading turns at a "
                        "narrow aperture: crowd_env.walking.shoulder_turn), training_runs, validation_runs")
    tr.add_argument("--backend", choices=["ray", "process", "serial"], default="serial")
    tr.add_argument("--jobs", type=int, default=None, help="processes of the pool / CPUs of local Ray")
    se = sub.add_parser("select", help="trained policies scored closed loop on the validation runs; the best kept",
                        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    se.add_argument("policies", nargs="+", type=Path,
                    help="policy files (.npz), training folders (their policy.npz) or shipped policies by name")
    se.add_argument("--out", required=True, type=Path, help="output folder (selection.md, policy.npz, runs/)")
    se.add_argument("--runs", nargs="+", default=list(VALIDATION_RUNS), metavar="RUN",
                    help="the corridor runs that score them (default the validation runs: "
                         f"{' '.join(VALIDATION_RUNS)}; all: the nine)")
    se.add_argument("--push-below", nargs="+", default=[PUSH_OFF], metavar="U",
                    help="each policy scored with the model's social force added to its intents "
                         "(crowd-virtual-experiments --policy-social-force): 'off' (default) the policy alone, "
                         "'always' the push for every walker, a speed U in m/s only for walkers slower than U "
                         "(--policy-social-force-below U); several: every policy with each")
    se.add_argument("--seeds", type=int, default=2, help="seeds 0..S-1 of each run (default 2, as the docs' table)")
    se.add_argument("--radius", type=float, default=None, metavar="R",
                    help="every pedestrian's radius in m (default the calibrated preset's body, as the training's)")
    se.add_argument("--backend", choices=["ray", "process", "serial"], default="serial")
    se.add_argument("--jobs", type=int, default=None, help="processes of the pool / CPUs of local Ray")
    return ap


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        if args.command == "demonstrations":
            return _demonstrations(args)
        if args.command == "select":
            return _select(args)
        return _train(args)
    except CrowdEnvError as exc:
        print(f"crowd-imitate: {exc}", file=sys.stderr)
        return 2


def _demonstrations(args) -> int:
    options = key_values(args.policy_option, "--policy-option expects KEY=VALUE")
    if (args.file is None) == (args.uo_run is None):
        raise OptionError("give a trajectory file or --uo-run NAME (one of them)")
    if args.uo_run:
        trajectories = recorded_uo_trajectories(args.uo_run)
        scenario, meta = uo_scenario(args.uo_run), {"source": f"shipped recording {args.uo_run}", "run": args.uo_run}
    else:
        if not args.scenario:
            raise OptionError("a trajectory file needs --scenario (and its --scenario-option values)")
        scenario_options = key_values(args.scenario_option, "--scenario-option expects KEY=VALUE")
        trajectories = Trajectories.read_txt(args.file, default_frame_rate_per_s=args.frame_rate, unit=args.unit)
        scenario = make_scenario(args.scenario, **scenario_options)
        meta = {"source": str(args.file), "scenario": args.scenario, "scenario_options": scenario_options}
    demos = demonstrations_from_trajectories(trajectories, scenario, options=options, smoothing_s=args.smoothing,
                                             meta=meta)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    demos.save(args.out)
    print(f"{len(demos)} decisions of {demos.meta['n_pedestrians']} pedestrians every {demos.meta['decision_dt_s']:g} s, "
          f"{demos.meta['n_seen']} of them with every neighbour in view; observation size "
          f"{demos.observation.shape[1]}; wrote {args.out}")
    return 0


def _train(args) -> int:
    config = QUICK_HUMAN_TRAINING if args.quick else {}
    config = {**config, **key_values(args.set, "--set expects KEY=VALUE")}
    t0, c0 = time.perf_counter(), time.process_time()
    with make_backend(args.backend, jobs=args.jobs) as backend:
        summary = train_human_policy(args.out, config=config, backend=backend, resume=args.resume)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu_s = time.process_time() - c0 + children.ru_utime + children.ru_stime
    for run, row in summary["open_loop"].items():
        stages = ", ".join(f"{s} {row[s]:.3f}" for s in summary["stages"])
        print(f"open-loop speed error on {run} (m/s, per pedestrian and decision): calibrated {row['calibrated']:.3f}, "
              f"{stages}")
    print(f"this session: {time.perf_counter() - t0:.0f} s wall, {cpu_s:.0f} s CPU (this process and its workers); "
          f"wrote {summary['policy']}, {args.out / 'progress.csv'}, {args.out / 'summary.json'}")
    return 0


def _policy_file(spec: Path) -> Path:
    """The policy file of a ``select`` candidate: a file, a training folder's ``policy.npz``, or a shipped policy's
    file by name; :class:`OptionError` naming it otherwise."""
    path = spec / "policy.npz" if spec.is_dir() else spec
    if path.is_file():
        return path
    if not spec.suffix and not spec.parent.name:  # a bare name: a shipped policy's
        shipped = getattr(load_scored_policy(str(spec)), "path", None)
        if shipped is not None:
            return Path(shipped)
    raise OptionError(f"no policy file at {path} (give policy files, training folders or shipped policies by name)")


def _push_gate(value: str) -> tuple:
    """``(social_force, social_force_below_m_s, label)`` of a ``--push-below`` value (its help)."""
    if value == PUSH_OFF:
        return False, None, ""
    if value == PUSH_ALWAYS:
        return True, None, " + push"
    try:
        below = float(value)
    except ValueError:
        below = math.nan
    if not (math.isfinite(below) and below > 0.0):
        raise OptionError(f"--push-below takes '{PUSH_OFF}', '{PUSH_ALWAYS}' or a speed in m/s > 0, got {value!r}")
    return True, below, f" + push below {below:g} m/s"


def _select(args) -> int:
    files = [_policy_file(p) for p in args.policies]
    gates = list({gate[:2]: gate for gate in map(_push_gate, args.push_below)}.values())  # each gate once
    if args.seeds < 1:
        raise OptionError(f"--seeds must be at least 1, got {args.seeds}")
    runs = CORRIDOR_RUN_NAMES if args.runs == ["all"] else tuple(args.runs)
    preset = get_preset(DEFAULT_PRESET)  # the physics the human policy trains in
    plan = VirtualPlan(experiments=("corridor",), corridor_runs=tuple(runs), seeds=tuple(range(args.seeds)))
    candidates = [(path, gate) for path in files for gate in gates]
    scores = []
    with make_backend(args.backend, jobs=args.jobs) as backend:
        for k, (path, (pushed, below, _)) in enumerate(candidates):
            config = virtual_config(preset.params(), navigation_clearance_m=preset.navigation_clearance_m,
                                    radius_m=args.radius, policy=str(path.resolve()), policy_social_force=pushed,
                                    policy_social_force_below_m_s=below)
            records = run_virtual_experiments(args.out / "runs" / f"candidate_{k}", config, plan, backend,
                                              desc=f"candidate {k}")
            scores.append(corridor_miss(records))
    best = min(range(len(candidates)), key=lambda k: (*selection_rank(scores[k]), k))
    table = format_selection([f"{path}{label}" for path, (_, _, label) in candidates], scores, best)
    print(table)
    args.out.mkdir(parents=True, exist_ok=True)
    write_atomic(args.out / "selection.md", table + "\n")
    path, (pushed, below, label) = candidates[best]
    copy_atomic(path, args.out / "policy.npz")
    how = ""
    if pushed:  # the push is the runner's, not the file's
        how = " (run it with --policy-social-force" + (f" --policy-social-force-below {below:g})" if below else ")")
    print(f"kept candidate {best} ({path}{label}){how}; wrote {args.out / 'selection.md'}, {args.out / 'policy.npz'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
