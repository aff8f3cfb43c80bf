"""The solver cascade's projection schedules on the steps of a kept run, in one run.

Loads a run checkpoint (:class:`crowd_env.experiments.running.runner.RunCheckpoint`: ``crowd-rimea`` writes one
every 10 min beside each crowd_env run it is making, e.g. ``<out>/runs/rimea_4_rho_5_crowd_env.npz.checkpoint.pkl``
while the full test 4 runs) and, from the same kept state each time, runs ``--steps`` steps of the kept
policy with:

* ``interior point first``: ``ipm_skip_after_miss = 0``, every large projection tries the package's
  interior point method (working set, then all candidates) before PIQP, as the cascade did before its
  back-off;
* ``back-off``: the cascade's defaults (after a miss of the interior point method, PIQP goes first).

Prints per schedule the seconds per step, the time and calls of each projection method, and the ratio of
the two; and the largest difference of the pedestrians' velocities between the two after the steps (both
solve the same strictly convex projection, each to its tolerance). On a state where the interior point
method converges the two schedules are the same computation.

    python benchmarks/checkpoint_steps.py PATH [--steps 10]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from timing import time_calls  # noqa: E402

from crowd_env.core.solvers import cascade as cascade_module  # noqa: E402
from crowd_env.experiments.running.runner import read_checkpoint  # noqa: E402

METHODS = ("project_gaps_alm", "project_gaps_working_set", "project_gaps_interior_point", "project_gaps_ipm",
           "project_gaps_large")
COUNTERS = ("n_alm_newton_steps", "n_ipm_projections", "n_working_set_solves", "n_piqp_projections",
            "n_fallback_solves")


def run_schedule(path: str, steps: int, ipm_skip_after_miss, clocks: dict) -> dict:
    """``steps`` steps from the checkpoint at ``path`` with the cascade's ``ipm_skip_after_miss`` (None:
    its default); the times of the methods go to ``clocks``."""
    kept = read_checkpoint(path)  # unpickled only when this account's crowd_env signed it
    sim, policy = kept["sim"], kept["policy"]
    cascade = sim.cascade
    if ipm_skip_after_miss is not None:  # the schedule from this step on, whatever back-off the kept run was in
        cascade.ipm_skip_after_miss = ipm_skip_after_miss
        cascade._ipm_backoff = ipm_skip_after_miss
        cascade._skip_ipm = 0
    before = {c: getattr(cascade, c) for c in COUNTERS}
    for clock in clocks.values():
        clock[0] = 0.0
    t0 = time.perf_counter()
    for _ in range(steps):
        intents, heading = policy(sim)
        sim.step(intents, desired_heading_rad=heading)
    wall = time.perf_counter() - t0
    return {"wall_s": wall, "step": sim.step_count, "t_s": sim.time_s, "n": int(sim.state.active.sum()),
            "velocity": sim.state.velocity_m_s.copy(), "methods_s": {m: clocks[m][0] for m in METHODS},
            "counts": {c: getattr(cascade, c) - before[c] for c in COUNTERS}}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("checkpoint", help="a RunCheckpoint file (.checkpoint.pkl)")
    ap.add_argument("--steps", type=int, default=10)
    args = ap.parse_args(argv)
    if args.steps < 1:
        ap.error(f"--steps must be >= 1, got {args.steps}")
    if not os.path.exists(args.checkpoint):
        ap.error(f"no checkpoint at {args.checkpoint}")
    clocks = {m: [0.0] for m in METHODS}
    for m in METHODS:
        time_calls(cascade_module, m, clocks[m])
    rows = {name: run_schedule(args.checkpoint, args.steps, skip, clocks)
            for name, skip in (("interior point first", 0), ("back-off", None))}
    first = rows["interior point first"]
    print(f"{args.checkpoint}: {first['n']} pedestrians, {args.steps} steps to t = {first['t_s']:.2f} s")
    short = {"project_gaps_alm": "ALM", "project_gaps_working_set": "working set",
             "project_gaps_interior_point": "interior point", "project_gaps_ipm": "PIQP",
             "project_gaps_large": "last resorts"}
    print("| schedule | s/step | " + " | ".join(f"{short[m]} s" for m in METHODS) + " | IPM tries | PIQP calls |")
    print("|---|---|" + "---|" * len(METHODS) + "---|---|")
    for name, r in rows.items():
        print(f"| {name} | {r['wall_s'] / args.steps:.3f} | " + " | ".join(f"{r['methods_s'][m]:.2f}" for m in METHODS)
              + f" | {r['counts']['n_ipm_projections']} | {r['counts']['n_piqp_projections']} |")
    ratio = first["wall_s"] / rows["back-off"]["wall_s"]
    dv = float(np.max(np.abs(first["velocity"] - rows["back-off"]["velocity"])))
    print(f"interior point first / back-off: {ratio:.2f}x the time; largest velocity difference after "
          f"{args.steps} steps: {dv:.2e} m/s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
