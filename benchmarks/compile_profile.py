#!/usr/bin/env python
"""Where a cold start's time goes: numba's compilation of crowd_env's kernels, per function.

Runs the README's main job (``crowd-bottleneck --quick``, serially) in a fresh process with an empty
``NUMBA_CACHE_DIR`` (so nothing comes from the cache, and the project's own cache is left alone), listens
to numba's compile events and prints, per compiled function, the CPU time of its compilation without and
with the compilations nested in it (a kernel compiles the kernels it calls first), then the totals: process
CPU time, wall time, and the compilation's share.

    python benchmarks/compile_profile.py            # the 25 most expensive functions
    python benchmarks/compile_profile.py --top 60

Times are process CPU time (``time.process_time``), so another load on the machine changes them little;
the wall time is only meaningful on idle cores.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

_CHILD = r"""
import json, sys, time
from numba.core import event

stack, rec = [], {}


class Listener(event.Listener):
    def on_start(self, ev):
        d = ev.data.get("dispatcher") if isinstance(ev.data, dict) else None
        f = getattr(d, "py_func", None)
        stack.append([f"{getattr(f, '__module__', '?')}.{getattr(f, '__qualname__', '?')}", time.process_time(), 0.0])

    def on_end(self, ev):
        name, t0, nested = stack.pop()
        spent = time.process_time() - t0
        if stack:
            stack[-1][2] += spent
        r = rec.setdefault(name, [0, 0.0, 0.0])
        r[0] += 1
        r[1] += spent - nested
        r[2] += spent


event.register("numba:compile", Listener())
cpu0, wall0 = time.process_time(), time.perf_counter()
from crowd_env.cli.reproduce_bottleneck import main
main(["--quick", "--jobs", "1", "--out", sys.argv[1]])
print(json.dumps({"cpu_s": time.process_time() - cpu0, "wall_s": time.perf_counter() - wall0, "functions": rec}))
"""


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--top", type=int, default=25, help="how many functions to list (default 25)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as out:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache, "CROWD_ENV_QUIET": "1", "OMP_NUM_THREADS": "1",
               "OPENBLAS_NUM_THREADS": "1"}
        done = subprocess.run([sys.executable, "-c", _CHILD, out], env=env, capture_output=True, text=True)
    if done.returncode:
        print(done.stderr[-3000:], file=sys.stderr)
        return done.returncode
    result = json.loads(done.stdout.strip().splitlines()[-1])
    rows = sorted(result["functions"].items(), key=lambda kv: -kv[1][1])
    own = sum(v[1] for _, v in rows)
    print(f"{'own s':>7} {'with nested s':>13} {'times':>5}  function")
    for name, (count, alone, total) in rows[:args.top]:
        print(f"{alone:7.2f} {total:13.2f} {count:5d}  {name}")
    print(f"{len(rows)} functions compiled ({sum(v[0] for _, v in rows)} compilations): {own:.1f} s of CPU compiling, "
          f"{result['cpu_s']:.1f} s of CPU in all ({own / result['cpu_s']:.0%} compiling), {result['wall_s']:.1f} s wall "
          "(the README's main job, serial, cold cache)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
