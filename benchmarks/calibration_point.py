#!/usr/bin/env python
"""Wall time of one calibration point: the 15 bottleneck runs (5 widths × N = 20, 40, 60, one seed).

Runs exactly what a point of ``crowd-calibrate grid`` or ``crowd-bottleneck
--seeds 1`` runs (the reproduction's ``run_one`` in a process pool of ``--jobs`` workers, default 2),
into a fresh temporary folder, twice: the first pass also pays the worker processes' loading of the
compiled kernels (warm numba cache), the second is the steady figure. Prints the elapsed wall time of
each pass (target: ≤ 15 s on 2 cores), the summed run times and the simulated steps.

    python benchmarks/calibration_point.py [--jobs 2] [--preset paper|recalibrated]
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import tempfile
import time
from pathlib import Path

from crowd_env.cli.reproduce_bottleneck import main as reproduce


def one_point(jobs: int, preset: str) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            rc = reproduce(["--seeds", "1", "--jobs", str(jobs), "--no-figures", "--preset", preset, "--out", tmp])
        elapsed = time.perf_counter() - t0
        if rc != 0:
            raise SystemExit(f"reproduction failed with status {rc}")
        runs = [json.loads(p.read_text()) for p in Path(tmp, "runs").glob("*.json")]
    return {"elapsed_s": elapsed, "runs": len(runs), "run_s": sum(r["wall_time_s"] for r in runs),
            "steps": sum(r["n_steps"] for r in runs)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--preset", default="paper")
    args = ap.parse_args(argv)
    print(f"calibration point: 5 widths × N = 20, 40, 60, 1 seed, {args.jobs} worker processes, preset {args.preset}")
    for label in ("first pass (workers load the kernels)", "second pass"):
        r = one_point(args.jobs, args.preset)
        print(f"{label:<40} {r['elapsed_s']:6.2f} s elapsed | {r['runs']} runs, {r['run_s']:6.2f} s summed run time, "
              f"{r['steps']:,} steps (target: <= 15 s elapsed on 2 cores)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
