"""The large-jam gap projection: augmented Lagrangian, own interior point method and PIQP, same problems.

Runs the dense room of ``scaling.py`` (N pedestrians at 3 /m² pushing into a door, baseline agents,
full model) for ``--warmup`` steps, then records the projections of the next ``--steps`` steps that
are too large for the dense path (the jam in front of the door) and solves each of them, in one run,
with:

* ``project_gaps_alm`` from zero within the solver cascade's Newton budget (``ALM_NEWTON_BUDGET``), the
  first stage of ``SolverCascade._project_large`` (misses count as its time spent);
* ``project_gaps_interior_point``, the own Mehrotra method with dual regularisation, the second stage;
* ``project_gaps_working_set``: the same method on the cascade's working set (the previous step's
  active contacts and the nearly closing candidates), grown until nothing is violated, started from
  the previous step's percussions, which is what the second stage runs when the previous step had a
  large projection; and the same with its first solve from the cold start, to show what the warm
  start gains;
* ``project_gaps_ipm`` (PIQP), its fallback.

Prints per solver the mean time per projection, the range of iterations (Newton steps for the
augmented Lagrangian, solves for the working set), the own method's speed-up over PIQP and the
working set's over the whole own method and the warm start's over the cold one (ratios of the totals,
the latter two on the projections that had a working set), and the largest velocity difference between the methods and to the augmented
Lagrangian's exact solution where that converged.

    python benchmarks/projection.py [--n 10000] [--warmup 300] [--steps 20]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from scaling import dense_room  # noqa: E402

from baselines.social_force import SocialForceAgent  # noqa: E402
from crowd_env.core import Simulator  # noqa: E402
from crowd_env.walking import ModelParams
from crowd_env.core.solvers.cascade import ALM_NEWTON_BUDGET, SolverCascade  # noqa: E402
from crowd_env.core.solvers.external import project_gaps_ipm  # noqa: E402
from crowd_env.core.solvers.graph import gap_residuals  # noqa: E402
from crowd_env.core.solvers.large_projection import (project_gaps_alm, project_gaps_interior_point,  # noqa: E402
                                                     project_gaps_working_set)
from crowd_env.core.solvers.status import STATUS_OK  # noqa: E402


class RecordingCascade(SolverCascade):
    """A solver cascade that keeps a copy of every large projection's data (and its working set and start,
    None without one) before solving it as usual."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.recorded = []
        self.working = []
        self.recording = False

    def _project_large(self, vel, mass, c_a, c_b, con, h, lam_warm=None, keys=None):
        if self.recording:
            self.recorded.append((vel.copy(), mass.copy(), c_a.copy(), c_b.copy(), con["gap"].copy(),
                                  con["nx"].copy(), con["ny"].copy(), h))
            self.working.append(self._working_set(vel, c_a, c_b, con, h, keys))
        return super()._project_large(vel, mass, c_a, c_b, con, h, lam_warm, keys)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=10000, help="pedestrians in the room")
    ap.add_argument("--warmup", type=int, default=300, help="steps before recording (the jam builds up)")
    ap.add_argument("--steps", type=int, default=20, help="steps whose large projections are recorded")
    args = ap.parse_args(argv)

    scenario = dense_room(args.n, 0)
    agent = SocialForceAgent(scenario.navigation())
    sim = Simulator(scenario.make_state(), geometry=scenario.geometry, params=ModelParams())
    sim.cascade = cascade = RecordingCascade()
    for k in range(args.warmup + args.steps):
        cascade.recording = k >= args.warmup
        intents, heading = agent(sim)
        sim.step(intents, desired_heading_rad=heading)
    problems = cascade.recorded
    if not problems:
        print(f"no projection too large for the dense path in {args.steps} steps after {args.warmup}")
        return
    _compile(problems)
    times, iterations, stats = _time_solvers(problems, cascade.working)
    _report(args, problems, times, iterations, stats)


def _compile(problems) -> None:
    """Compile every solver once outside the timings (same argument types as the timed calls)."""
    project_gaps_alm(problems[0][0].copy(), *problems[0][1:], np.zeros(problems[0][2].shape[0]), ALM_NEWTON_BUDGET)
    project_gaps_interior_point(problems[0][0].copy(), *problems[0][1:])
    project_gaps_ipm(problems[0][0].copy(), *problems[0][1:])
    m0 = problems[0][2].shape[0]
    for guess in (np.zeros(m0), None):  # both start signatures of the working set's solves
        project_gaps_working_set(problems[0][0].copy(), *problems[0][1:], np.ones(m0, bool), z0=guess)



def _time_solvers(problems, working_sets) -> tuple:
    """Each recorded projection solved by every method: (seconds per method, iterations per method, the
    largest differences, the augmented Lagrangian's successes and the smallest slack)."""
    times = {"alm": 0.0, "own": 0.0, "piqp": 0.0, "ws": 0.0, "ws_cold": 0.0, "own_ws": 0.0}
    iterations = {"alm": [], "own": [], "ws": [], "ws_cold": []}
    d_piqp, d_exact, d_ws, alm_ok, min_slack = 0.0, 0.0, 0.0, 0, np.inf
    for (vel, *rest), start in zip(problems, working_sets):
        m = rest[1].shape[0]
        v_alm = vel.copy()
        t0 = time.perf_counter()
        _, steps, status_alm = project_gaps_alm(v_alm, *rest, np.zeros(m), ALM_NEWTON_BUDGET)
        t1 = time.perf_counter()
        v_own = vel.copy()
        _, its, status_own = project_gaps_interior_point(v_own, *rest)
        t2 = time.perf_counter()
        v_piqp = vel.copy()
        _, ok = project_gaps_ipm(v_piqp, *rest)
        t3 = time.perf_counter()
        if status_own != STATUS_OK or not ok:
            raise RuntimeError("an interior point method failed on a recorded projection")
        times["alm"] += t1 - t0
        times["own"] += t2 - t1
        times["piqp"] += t3 - t2
        if start is not None:
            working, z0 = start
            times["own_ws"] += t2 - t1
            for key, guess in (("ws", z0), ("ws_cold", None)):
                v_ws = vel.copy()
                t4 = time.perf_counter()
                _, solves, status_ws = project_gaps_working_set(v_ws, *rest, working, z0=guess)
                times[key] += time.perf_counter() - t4
                if status_ws != STATUS_OK:
                    raise RuntimeError("the working set method failed on a recorded projection")
                iterations[key].append(solves)
                d_ws = max(d_ws, float(np.abs(v_ws[:, :2] - v_own[:, :2]).max()))
        iterations["alm"].append(steps)
        iterations["own"].append(its)
        d_piqp = max(d_piqp, float(np.abs(v_own[:, :2] - v_piqp[:, :2]).max()))
        mass, c_a, c_b, gap, nx, ny, h = rest
        min_slack = min(min_slack, float(gap_residuals(v_own, gap / h, c_a, c_b, nx, ny).min()))
        if status_alm == STATUS_OK:
            alm_ok += 1
            d_exact = max(d_exact, float(np.abs(v_own[:, :2] - v_alm[:, :2]).max()))
    return times, iterations, {"d_piqp": d_piqp, "d_exact": d_exact, "d_ws": d_ws, "alm_ok": alm_ok,
                               "min_slack": min_slack}


def _report(args, problems, times: dict, iterations: dict, stats: dict) -> None:
    """Print the timings per projection, the speed-ups and the differences between the methods."""
    d_piqp, d_exact, d_ws, alm_ok, min_slack = (stats[k] for k in ("d_piqp", "d_exact", "d_ws", "alm_ok", "min_slack"))
    k = len(problems)
    sizes = [p[2].shape[0] for p in problems]
    print(f"dense room N = {args.n}: {k} large projections in {args.steps} steps after {args.warmup}, "
          f"{min(sizes)}-{max(sizes)} candidates, {min(p[0].shape[0] for p in problems)}-"
          f"{max(p[0].shape[0] for p in problems)} pedestrians")
    print(f"  augmented Lagrangian (budget {ALM_NEWTON_BUDGET}): {1e3 * times['alm'] / k:7.2f} ms, "
          f"{min(iterations['alm'])}-{max(iterations['alm'])} Newton steps, converged {alm_ok}/{k}")
    print(f"  own interior point:                {1e3 * times['own'] / k:7.2f} ms, "
          f"{min(iterations['own'])}-{max(iterations['own'])} iterations, "
          f"smallest slack gap/h + B v = {min_slack:.1e} m/s")
    print(f"  PIQP:                              {1e3 * times['piqp'] / k:7.2f} ms")
    print(f"  own / PIQP speed-up: {times['piqp'] / times['own']:.2f}x; max |v_own - v_PIQP| = {d_piqp:.1e} m/s; "
          f"max |v_own - v_exact| = {d_exact:.1e} m/s over the {alm_ok} the augmented Lagrangian solved")
    n_ws = len(iterations["ws"])
    if n_ws:
        solves = np.bincount(iterations["ws"])[1:]
        print(f"  own on the working set:            {1e3 * times['ws'] / n_ws:7.2f} ms on {n_ws} projections "
              f"(whole own: {1e3 * times['own_ws'] / n_ws:.2f} ms), solves " +
              ", ".join(f"{s + 1}: {c}" for s, c in enumerate(solves) if c))
        print(f"  the same, first solve cold:        {1e3 * times['ws_cold'] / n_ws:7.2f} ms")
        print(f"  working set / whole own speed-up: {times['own_ws'] / times['ws']:.2f}x; warm / cold start "
              f"speed-up: {times['ws_cold'] / times['ws']:.2f}x; max |v_ws - v_own| = {d_ws:.1e} m/s (both starts)")


if __name__ == "__main__":
    main()
