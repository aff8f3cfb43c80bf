#!/usr/bin/env python
"""Where a cold start's time goes: numba's compilation of crowd_env's kernels, per function.

Runs the README's main job (``crowd-bottleneck --quick``, serially) in a fresh process with an empty
``NUMBA_CACHE_DIR`` (so nothing comes from the cache, and the project's own cache is left alone), listens
to numba's compile events and prints, per compiled function, the CPU time of its compilation without and
with the compilations nested in it (a kernel compiles the kernels it calls first), then the totals: process
CPU time, wall time, and the compilation's share.

    python benchmarks/compile_profile.py            # the 25 most expensive functions
    python benchmarks/compile_profile.py --top 60
    python benchmarks/compile_profile.py --llvm-passes   # and LLVM's share of each function's own time
    NUMBA_OPT=0 python benchmarks/compile_profile.py     # the floor without LLVM's optimisation (slow kernels)

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

stack, rec, dispatchers = [], {}, {}


class Listener(event.Listener):
    def on_start(self, ev):
        d = ev.data.get("dispatcher") if isinstance(ev.data, dict) else None
        f = getattr(d, "py_func", None)
        name = f"{getattr(f, '__module__', '?')}.{getattr(f, '__qualname__', '?')}"
        if d is not None:
            dispatchers[name] = d
        stack.append([name, time.process_time(), 0.0])

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
cpu_s, wall_s = time.process_time() - cpu0, time.perf_counter() - wall0
passes = {}  # with NUMBA_LLVM_PASS_TIMINGS=1: LLVM's share of each function's own compile, by stage
for name, d in dispatchers.items():
    for sig in getattr(d, "signatures", ()):
        timings = d.get_metadata(sig).get("llvm_pass_timings") or ()
        stages = passes.setdefault(name, {"function": 0.0, "module": 0.0, "object": 0.0})
        for r in timings:
            stage = ("function" if r.name.startswith("Function passes") else
                     "module" if r.name.startswith("Module passes") else
                     "object" if r.name.startswith("Finalize object") else None)
            if stage:
                stages[stage] += r.timings.list_records()[-1].user_system_time  # CPU, as the rest
print(json.dumps({"cpu_s": cpu_s, "wall_s": wall_s, "functions": rec, "passes": passes}))
"""


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--top", type=int, default=25, help="how many functions to list (default 25)")
    ap.add_argument("--llvm-passes", action="store_true",
                    help="also LLVM's share of each function's own compile (NUMBA_LLVM_PASS_TIMINGS): its function "
                         "passes, the module passes over the module with every callee linked in, object emission")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as out:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache, "CROWD_ENV_QUIET": "1", "OMP_NUM_THREADS": "1",
               "OPENBLAS_NUM_THREADS": "1", **({"NUMBA_LLVM_PASS_TIMINGS": "1"} if args.llvm_passes else {})}
        done = subprocess.run([sys.executable, "-c", _CHILD, out], env=env, capture_output=True, text=True)
    if done.returncode:
        print(done.stderr[-3000:], file=sys.stderr)
        return done.returncode
    result = json.loads(done.stdout.strip().splitlines()[-1])
    rows = sorted(result["functions"].items(), key=lambda kv: -kv[1][1])
    own = sum(v[1] for _, v in rows)
    passes = result["passes"] if args.llvm_passes else {}
    llvm_head = f" {'LLVM: fn':>8} {'module':>7} {'object':>7}" if passes else ""
    print(f"{'own s':>7} {'with nested s':>13} {'times':>5}{llvm_head}  function")
    for name, (count, alone, total) in rows[:args.top]:
        p = passes.get(name)
        llvm = f" {p['function']:8.2f} {p['module']:7.2f} {p['object']:7.2f}" if p else (" " * 25 if passes else "")
        print(f"{alone:7.2f} {total:13.2f} {count:5d}{llvm}  {name}")
    print(f"{len(rows)} functions compiled ({sum(v[0] for _, v in rows)} compilations): {own:.1f} s of CPU compiling, "
          f"{result['cpu_s']:.1f} s of CPU in all ({own / result['cpu_s']:.0%} compiling), {result['wall_s']:.1f} s wall "
          "(the README's main job, serial, cold cache)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
