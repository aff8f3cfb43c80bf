#!/usr/bin/env python
"""The README's main job on a cold numba cache, in wall time: what a first run on a fresh machine waits.

Runs ``scripts/reproduce_bottleneck.py --quick`` (N = 60, five widths, two seeds, a pool of one worker per
core) in a fresh process with an empty ``NUMBA_CACHE_DIR`` (every kernel compiled; the project's own cache left
alone), then again with that cache filled (the warm run), and prints both wall times against issue 37's target
(cold under 60 s on 2 idle cores). ``--against PATH`` runs the same on another checkout of crowd_env
(``PYTHONPATH=PATH``, e.g. a ``git worktree`` of an older commit) alternately with this one, ``--rounds``
times, and prints their ratio. Wall time: meaningful on idle cores only.

    python benchmarks/cold_start.py
    git worktree add /tmp/old d0b11da && python benchmarks/cold_start.py --against /tmp/old --rounds 2
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TARGET_S = 60.0


def main_job(checkout: str) -> tuple[float, float, int]:
    """(cold wall s, warm wall s, notice lines printed by the cold run) of the main job in ``checkout``."""
    walls = []
    with tempfile.TemporaryDirectory() as cache:
        for _ in range(2):
            with tempfile.TemporaryDirectory() as out:
                env = {**os.environ, "NUMBA_CACHE_DIR": cache, "PYTHONPATH": checkout}
                env.pop("CROWD_ENV_QUIET", None)
                t = time.perf_counter()
                done = subprocess.run([sys.executable, os.path.join(checkout, "scripts", "reproduce_bottleneck.py"),
                                       "--quick", "--out", os.path.join(out, "b")], cwd=checkout, env=env,
                                      capture_output=True, text=True)
                walls.append(time.perf_counter() - t)
                if done.returncode:
                    sys.exit(f"the main job failed in {checkout}:\n{done.stderr[-2000:]}")
                if len(walls) == 1:
                    notices = done.stderr.count("compiling its numerical kernels")
    return walls[0], walls[1], notices


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--against", default=None, metavar="PATH", help="another checkout to compare with, alternately")
    ap.add_argument("--rounds", type=int, default=1, help="runs of each (default 1)")
    args = ap.parse_args(argv)
    runs = {"this": [], "other": []}
    for _ in range(args.rounds):
        if args.against:
            runs["other"].append(main_job(os.path.abspath(args.against)))
        runs["this"].append(main_job(ROOT))
    print(f"{os.cpu_count()} cores; the README's main job, an empty numba cache (cold), then that cache (warm)")
    print(f"{'checkout':>24} {'cold s':>8} {'warm s':>8} {'notices':>8}")
    for key, label in (("other", args.against), ("this", "this")):
        for cold, warm, notices in runs[key]:
            print(f"{str(label)[-24:]:>24} {cold:8.1f} {warm:8.1f} {notices:8d}")
    best = min(r[0] for r in runs["this"])
    print(f"cold, best of {args.rounds}: {best:.1f} s (target < {TARGET_S:.0f} s on 2 idle cores: "
          f"{'holds' if best < TARGET_S else 'NO'})")
    if args.against:
        other = min(r[0] for r in runs["other"])
        print(f"cold this / other: {best / other:.2f} ({best:.1f} s / {other:.1f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
