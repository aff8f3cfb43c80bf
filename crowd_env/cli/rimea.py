"""crowd-rimea: the RiMEA verification tests (RiMEA 4.1.1, Annex 1) on crowd_env, with JuPedSim beside it.

Runs each flat test (1, 4, 5, 6, 7, 9, 10, 11, 12a-d, 15, 16) as a scenario, checks its criterion and
the two conditions every test shares (no overlap beyond 1 mm, nobody outside the walkable area), and
prints one table: test, what it checks, the criterion, the figure measured and pass/fail per model.
Writes a figure per test and results.json to --out. Tests 2, 3 and 13 need stairs and 8 and 14 are
documentation only: asking for them is an error that says so.

    crowd-rimea --quick                 # the reduced versions, a few minutes
    crowd-rimea 1 6 12 --out runs/rimea # some tests, full size ("12" runs 12a-12d)
    crowd-rimea --quick --jupedsim      # with JuPedSim's CFSM and SFM columns (pip install -e '.[bench]')
    crowd-rimea --jupedsim --docs --out docs/validation/rimea --resume  # regenerate the documentation's page

Each test's result is kept in --out as soon as it is done (tests/rimea_<n>.json), and so is each scenario run
(runs/rimea_<n>_<variant>_<model>.npz); --resume reads back the kept results and runs made with the same
version (--quick or not), seed and models instead of running them again, so a long run that was stopped goes
on where it was (within a test, at its next run), and one test can be run on its own first.

The last line counts, per model, the tests passed and names those failed; the command then exits 1, and
docs/validation/rimea.md ("Reading the results") explains each failure.
"""
from __future__ import annotations

import argparse
import os
import sys

from ..errors import MissingDependencyError, NotFoundError


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="crowd-rimea", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("tests", nargs="*", help="test numbers (default: every flat test)")
    ap.add_argument("--quick", action="store_true", help="the reduced versions (seconds each)")
    ap.add_argument("--jupedsim", action="store_true",
                    help="also run JuPedSim's collision-free speed and social force models")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default="runs/rimea", help="figures and results.json go here")
    ap.add_argument("--resume", action="store_true",
                    help="read back tests already done in --out with the same version, seed and models")
    ap.add_argument("--docs", action="store_true",
                    help="also write rimea_results.md beside the figures (the documentation's page: --out docs/validation/rimea)")
    args = ap.parse_args(argv)
    from ..experiments.validation.rimea import format_table, run_suite
    from ..experiments.validation.rimea.suite import summary_line, write_markdown

    try:
        results = run_suite(args.tests, quick=args.quick, jupedsim=args.jupedsim, seed=args.seed, out_dir=args.out,
                            resume=args.resume)
    except (NotFoundError, MissingDependencyError) as exc:
        raise SystemExit(f"error: {exc.args[0] if exc.args else exc}") from None
    print(format_table(results))
    if args.docs:
        command = "crowd-rimea " + " ".join(argv if argv is not None else sys.argv[1:])
        write_markdown(results, os.path.join(args.out, "rimea_results.md"), command=command.strip(),
                       figure_prefix=os.path.basename(os.path.normpath(args.out)) + "/")
    print(f"figures and results.json in {args.out}")
    print(summary_line(results))
    return 0 if all(r.passed(b) is not False for r in results for b in r.verdicts) else 1


if __name__ == "__main__":
    sys.exit(main())
