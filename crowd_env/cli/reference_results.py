"""crowd-reference-results: learned pedestrian policies against the calibrated model, on one task suite.

Trains PPO (shared network), MAPPO (centralised critic) and a behaviour clone of the calibrated model on
each task with several training seeds, evaluates them with the calibrated model, random and zero
policies on the same unseen evaluation seeds, and writes the results table (means with 95 % intervals),
results.json, results.md, learning_curves.png and a video of each policy on the bottleneck
(videos/<task>_<policy>.mp4) to --out. Every unit of work is kept as it finishes:
rerunning the same command resumes. See docs/validation/reference_results.md for the tasks, the measures and the
cost of the full run.

    crowd-reference-results --quick --out runs/bench-quick        # the same code path, tiny budgets (< 1 minute)
    crowd-reference-results --out runs/bench                      # the full suite (Ray on all local cores)
    crowd-reference-results --out runs/bench --address auto       # on a running Ray cluster
    crowd-reference-results --out runs/bench --ship baselines/trained   # also copy the seed-0 policies to ship
    crowd-reference-results --out runs/bench --docs docs/validation/reference_results   # and the documentation's figures

With --quick the command trains for a tiny fraction of the full budgets: its learned policies are expected
to miss the targets ("holds NO"), which checks the code path, not the policies; it says so under the table.
"""
from __future__ import annotations

import argparse
import json
import os
import sys

from crowd_env.errors import BackendError, InputError, MissingDependencyError, RunStoreError
from crowd_env.files import copy_atomic, write_atomic


def _budgets(ap, texts) -> dict:
    """``--budget KEY=N`` options as a dict; a malformed one stops the command naming it (argparse's error)."""
    out = {}
    for text in texts:
        key, sep, value = text.partition("=")
        if not sep or not value.strip().lstrip("-").isdigit():
            ap.error(f"--budget takes KEY=INTEGER, got {text!r}")
        out[key] = int(value)
    return out


def budget_note(plan, budgets_full: dict) -> str | None:
    """What a NO in the targets means when the plan trains for less than the full budgets (``--quick`` or a
    smaller ``--budget``): the learned policies are not expected to meet the targets there; None otherwise."""
    small = {k: v for k, v in plan.budgets.items() if v < budgets_full.get(k, v)}
    if not (plan.quick or small):
        return None
    what = "--quick trains" if plan.quick else "these budgets train"
    return (f"note: {what} for a tiny fraction of the full budgets ({', '.join(f'{k} {v}' for k, v in small.items())}; "
            f"full: {', '.join(f'{k} {budgets_full[k]}' for k in small)}), so the learned policies are expected to "
            "miss the targets: a NO here checks the code path, not the policies. The targets are meant for the full "
            "run (crowd-reference-results without --quick; docs/validation/reference_results.md).")


def build_parser() -> argparse.ArgumentParser:
    from ..experiments.training.reference_results import BUDGETS, POLICIES, QUICK_BUDGETS, QUICK_TASKS, TASKS

    ap = argparse.ArgumentParser(prog="crowd-reference-results", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true",
                    help=f"tiny crowds and budgets ({', '.join(f'{k} {v}' for k, v in QUICK_BUDGETS.items())}), the "
                         "same code path; the learned policies are expected to miss the targets (NO)")
    ap.add_argument("--tasks", nargs="+", metavar="TASK",
                    help=f"task names (default: all: {', '.join(TASKS)}; with --quick: {', '.join(QUICK_TASKS)})")
    ap.add_argument("--policies", nargs="+", metavar="POLICY",
                    help=f"policy names (default: all: {', '.join(POLICIES)})")
    ap.add_argument("--train-seeds", type=int, nargs="+", metavar="SEED",
                    help="training seeds of the learned policies (default 0 1 2; with --quick 0 1)")
    ap.add_argument("--eval-seeds", type=int, nargs="+", metavar="SEED",
                    help="evaluation episode seeds, never used in training (default 0..9; with --quick 0 1)")
    ap.add_argument("--budget", action="append", default=[], metavar="KEY=N",
                    help="change a training budget (repeatable; full: "
                         f"{', '.join(f'{k}={v}' for k, v in BUDGETS.items())})")
    ap.add_argument("--out", default="runs/reference_results",
                    help="output folder; rerunning with the same plan resumes, another plan is refused "
                         "(default runs/reference_results)")
    ap.add_argument("--backend", default="ray", choices=("ray", "process", "serial"),
                    help="how the units of work run: ray (default; local or --address), process (a local process "
                         "pool of --jobs) or serial (this process)")
    ap.add_argument("--address", default=None, help="Ray cluster address (host:port, ray://host:port or auto)")
    ap.add_argument("--jobs", type=int, default=None, help="workers (local Ray CPUs or processes)")
    ap.add_argument("--ship", default=None, metavar="DIR", help="copy the first training seed's policies here")
    ap.add_argument("--no-videos", action="store_true",
                    help="no video of each policy on the bottleneck (they need the video extra)")
    ap.add_argument("--docs", default=None, metavar="DIR",
                    help="also copy results.md, learning_curves.png and the videos here (the documentation's "
                         "results page: docs/validation/reference_results)")
    return ap


def main(argv=None) -> int:
    ap = build_parser()
    args = ap.parse_args(argv)
    from ..experiments.running.backends import make_backend
    from ..experiments.training.reference_results import (BUDGETS, format_checks, format_results, make_plan, plot_learning_curves,
                                         run_reference_results, ship_policies, target_checks)

    try:
        plan = make_plan(quick=args.quick, tasks=args.tasks, policies=args.policies, train_seeds=args.train_seeds,
                         eval_seeds=args.eval_seeds, budgets=_budgets(ap, args.budget))
        with make_backend(args.backend, address=args.address, jobs=args.jobs) as backend:
            results = run_reference_results(plan, args.out, backend=backend, videos=not args.no_videos)
    except (InputError, RunStoreError, BackendError, MissingDependencyError) as exc:
        raise SystemExit(f"error: {exc}") from None
    checks = target_checks(results)
    compute = results["compute_s"]
    cost = (f"work: {compute['total'] / 3600:.2f} core-hours (training {compute['training'] / 3600:.2f}, evaluation "
            f"{compute['evaluation'] / 3600:.2f}, videos {compute['videos'] / 3600:.2f}): about "
            f"{compute['total'] / 3600 / 2:.2f} h on 2 cores with 2 workers")
    print(format_results(results))
    print()
    print(format_checks(checks))
    note = budget_note(plan, BUDGETS)
    if note and not all(c["holds"] for c in checks):
        print(note)
    print(cost)
    plot_learning_curves(args.out, plan, results, os.path.join(args.out, "learning_curves.png"))
    text = (f"<!-- written by `crowd-reference-results {' '.join(argv if argv is not None else sys.argv[1:])}` -->\n\n"
            + format_results(results, markdown=True) + "\n\n"
            + "Targets:\n\n" + format_checks(checks, markdown=True) + "\n\n")
    if note and not all(c["holds"] for c in checks):
        text += note[0].upper() + note[1:] + "\n\n"
    write_atomic(os.path.join(args.out, "results.md"), text + cost[0].upper() + cost[1:] + ".\n")
    if args.ship:
        for p in ship_policies(args.out, plan, args.ship):
            print(f"shipped {p}")
    if args.docs:
        os.makedirs(os.path.join(args.docs, "videos"), exist_ok=True)
        names = ["results.md", "learning_curves.png"]
        if not args.no_videos:
            names += [os.path.join("videos", f) for f in sorted(os.listdir(os.path.join(args.out, "videos")))
                      if f.endswith(".mp4")]
        for name in names:
            copy_atomic(os.path.join(args.out, name), os.path.join(args.docs, name))
        print(f"copied {', '.join(names)} to {args.docs}")
    print(f"results.json, results.md and learning_curves.png in {args.out}")
    print(json.dumps({"wall_s_this_run": round(results["wall_s_this_run"], 1)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
