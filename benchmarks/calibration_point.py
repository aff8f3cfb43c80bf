#!/usr/bin/env python
"""Wall time of one calibration point: the 15 bottleneck runs (5 widths × N = 20, 40, 60, one seed).

The runs are exactly those of a point of ``crowd-calibrate grid`` or ``crowd-bottleneck --seeds 1``
(the reproduction's tasks and ``run_one``, the compiled rollout by default), on ``--jobs`` worker
processes (default 2), each pass into a fresh temporary run store:

- *cold command*: ``crowd-bottleneck --seeds 1 --no-figures`` as a user runs it once: the process pool
  starts and its workers load the compiled kernels (warm numba cache on disk), then the 15 runs;
- *warm workers*: the 15 runs handed to one pool that already ran a point, as every point after the
  first of a calibration sweep is (the grid and the optimiser keep one pool, or one Ray cluster, for all
  points). Measured twice; the target (≤ 1.5 s on 2 cores) is on this figure.

Prints the elapsed wall time of each pass, the summed run times and the simulated steps.

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

from crowd_env.cli.options import config_of, model_params_from_args
from crowd_env.cli.reproduce_bottleneck import build_parser
from crowd_env.cli.reproduce_bottleneck import main as reproduce
from crowd_env.experiments.running.backends import ProcessBackend, execute
from crowd_env.experiments.validation.bottleneck import run_one
from crowd_env.experiments.running.store import RunStore


def cold_command(jobs: int, preset: str) -> dict:
    """The reproduction command, pool start and kernel loading included."""
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


def point_tasks(preset: str) -> list:
    """The 15 tasks of the reproduction's command line with ``--seeds 1`` (the same parser and config)."""
    args = build_parser().parse_args(["--seeds", "1", "--preset", preset])
    config = config_of(args, model_params_from_args(args))
    return [dict(width_m=b, n_pedestrians=n, seed=s, trajectory_fps=None, **config)
            for n in args.sizes for b in args.widths for s in range(args.first_seed, args.first_seed + args.seeds)]


def warm_point(backend, tasks: list) -> dict:
    """The tasks on an already started pool, into a fresh store."""
    with tempfile.TemporaryDirectory() as tmp:
        store = RunStore(Path(tmp))
        t0 = time.perf_counter()
        with contextlib.redirect_stderr(io.StringIO()):
            failed = execute(tasks, store, backend, run_one, desc="point", leave=False)
        elapsed = time.perf_counter() - t0
        if failed:
            raise SystemExit(f"{failed} run(s) failed")
        runs = [store.load(t) for t in tasks]
    return {"elapsed_s": elapsed, "runs": len(runs), "run_s": sum(r["wall_time_s"] for r in runs),
            "steps": sum(r["n_steps"] for r in runs)}


def _line(label: str, r: dict, target: str = "") -> str:
    return (f"{label:<42} {r['elapsed_s']:6.2f} s elapsed | {r['runs']} runs, {r['run_s']:6.2f} s summed run time, "
            f"{r['steps']:,} steps{target}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--preset", default="paper")
    args = ap.parse_args(argv)
    print(f"calibration point: 5 widths × N = 20, 40, 60, 1 seed, {args.jobs} worker processes, preset {args.preset}")
    print(_line("cold command (pool start, kernels load)", cold_command(args.jobs, args.preset)))
    tasks = point_tasks(args.preset)
    with ProcessBackend(args.jobs) as backend:
        print(_line("first point on a new pool (kernels load)", warm_point(backend, tasks)))
        for k in (1, 2):
            print(_line(f"point on warm workers ({k})", warm_point(backend, tasks),
                        " (target: <= 1.5 s elapsed on 2 cores)"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
