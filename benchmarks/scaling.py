#!/usr/bin/env python
"""Time per step and per agent-step from 100 to 10 000 pedestrians at a constant density (≈ 3 /m²).

Each size is a square walled room of area N/3 m² filled at 3 pedestrians/m² (lattice + hard-disk
relaxation), with a 2 m door in the middle of its right wall; every pedestrian runs the calibrated
baseline agent (eikonal field + social forces, Eq. 11-16) with the full model (rotation, Frémond
impacts, projection). After ``--warmup`` steps (the crowd starts pushing towards the door and the
contacts form; not timed, which also compiles the kernels) the run goes on for ``--steps`` timed
steps, twice from the same point (two copies of the warmed-up simulator, so the projection keeps what
it learnt: the last step's active contacts, the augmented Lagrangian's back-off; ``--restart`` times a
new ``Simulator`` built from the warmed-up state instead):

* ``fused``: the production path (``Simulator()``: the whole step in one compiled call), policy
  included: the figure that matters;
* ``staged``: ``Simulator(profile=True)``, the same kernels stage by stage, which splits the time into
  neighbour search (the cell grid, built once per step and shared), forces (the policy: navigation
  sampling and social forces), smooth update, contact detection, impact solve, projection,
  integration (positions, exits), plus building the RL observations of every pedestrian (``obs``,
  not part of a simulator step).

Prints ms per step and µs per agent-step for each size, the split, the ratio of the contact part
(detection + impacts + projection) to the smooth part (neighbours + forces + smooth + integration),
and the slope ratio t(10 000)/t(1 000) per step (linear scaling: 10; target ≤ 12).

    python benchmarks/scaling.py [--sizes 100 400 1000 1600 6400 10000] [--steps 30] [--warmup 300] [--restart]
"""
from __future__ import annotations

import argparse
import copy
import math
import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import time  # noqa: E402

import numpy as np  # noqa: E402

DENSITY_PER_M2 = 3.0
DOOR_WIDTH_M = 2.0
PHASES = ("neighbors", "forces", "smooth", "contacts", "impacts", "projection", "integrate", "obs")


def dense_room(n: int, seed: int = 0):
    """Scenario: n pedestrians at 3 /m² in a square room with a door on the right wall."""
    from crowd_env.core.geometry import Geometry
    from crowd_env.scenarios.placement import place_pedestrians
    from crowd_env.scenarios.scenario import Scenario

    side = math.sqrt(n / DENSITY_PER_M2) + 0.6  # the outer 0.3 m strip holds no centres
    room = [(0, 0), (side, 0), (side, side), (0, side)]
    y0, y1 = side / 2 - DOOR_WIDTH_M / 2, side / 2 + DOOR_WIDTH_M / 2
    door = [(side, y0), (side + 0.5, y0), (side + 0.5, y1), (side, y1)]
    geometry = Geometry(room, [door], name=f"room_{n}")
    pos = place_pedestrians(geometry.walkable_area, n, 0.23, np.random.default_rng(seed))
    return Scenario(geometry, pos, name=f"dense_room_{n}", seed=seed, navigation_resolution_m=0.1)


def _policy_timed(agent, sim, timings):
    p = sim.params
    t0 = time.perf_counter()
    idx = sim.active_index
    sim.neighbor_pairs(2.0 * float(sim.state.radius_m[idx].max()) + p.social_cutoff_m)
    t1 = time.perf_counter()
    out = agent(sim)  # reuses the pairs built above
    t2 = time.perf_counter()
    timings["neighbors"] = timings.get("neighbors", 0.0) + (t1 - t0)
    timings["forces"] = timings.get("forces", 0.0) + (t2 - t1)
    return out


def measure(n: int, steps: int, warmup: int, seed: int = 0, restart: bool = False) -> dict:
    from baselines.social_force import SocialForceAgent
    from crowd_env.core import Simulator
    from crowd_env.walking import ModelParams
    from crowd_env.envs.observations import ObservationBuilder

    scenario = dense_room(n, seed)
    nav = scenario.navigation()
    agent = SocialForceAgent(nav)
    sim = Simulator(scenario.make_state(), geometry=scenario.geometry, params=ModelParams())
    for _ in range(warmup):
        intents, heading = agent(sim)
        sim.step(intents, desired_heading_rad=heading)
    row = {"n": n}

    def continuation(profile):  # the run goes on: the solvers keep what they learnt in the warm-up
        if restart:  # a new Simulator from the warmed-up state instead
            return Simulator(sim.state.copy(), geometry=scenario.geometry, params=ModelParams(), profile=profile)
        run = copy.deepcopy(sim, {id(scenario.geometry): scenario.geometry})  # geometry shared, read-only
        run.profile = profile
        return run

    # fused (production) path
    fused = continuation(False)
    agent_steps = 0
    staged_before = fused.n_staged_steps
    t0 = time.perf_counter()
    for _ in range(steps):
        agent_steps += fused.active_index.shape[0]
        intents, heading = agent(fused)
        fused.step(intents, desired_heading_rad=heading)
    wall = time.perf_counter() - t0
    row["ms_per_step"] = 1e3 * wall / steps
    row["us_per_agent_step"] = 1e6 * wall / agent_steps
    row["staged_fraction"] = (fused.n_staged_steps - staged_before) / steps
    # staged path, split by stage
    staged = continuation(True)
    sparse_before = staged.n_sparse_solves
    observer = ObservationBuilder(nav, scenario.geometry.walls, n_neighbors=6, n_rays=8, neighbor_radius_m=3.0,
                                  ray_range_m=3.0, velocity_bound_m_s=3.0, travel_time_bound_s=600.0)
    timings: dict = {}
    max_cluster = contacts = 0
    t0 = time.perf_counter()
    for _ in range(steps):
        intents, heading = _policy_timed(agent, staged, timings)
        res = staged.step(intents, desired_heading_rad=heading)
        for k, v in res.timings_s.items():
            timings[k] = timings.get(k, 0.0) + v
        max_cluster = max(max_cluster, res.max_cluster_size)
        contacts += res.contact_i.shape[0]
    row["staged_ms_per_step"] = 1e3 * (time.perf_counter() - t0) / steps
    t0 = time.perf_counter()
    for _ in range(max(1, steps // 3)):
        observer.build(staged.state, staged.active_index)
    timings["obs"] = (time.perf_counter() - t0) / max(1, steps // 3) * steps
    for k in PHASES:
        row[k] = 1e3 * timings.get(k, 0.0) / steps
    smooth = row["neighbors"] + row["forces"] + row["smooth"] + row["integrate"]
    contact = row["contacts"] + row["impacts"] + row["projection"]
    row["contact_over_smooth"] = contact / smooth
    row["max_cluster"] = max_cluster
    row["contacts_per_step"] = contacts / steps
    row["sparse_solves"] = staged.n_sparse_solves - sparse_before
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 400, 1000, 1600, 6400, 10000])
    ap.add_argument("--steps", type=int, default=30)
    ap.add_argument("--warmup", type=int, default=300)
    ap.add_argument("--restart", action="store_true",
                    help="time a new Simulator built from the warmed-up state instead of the warm-up run itself")
    args = ap.parse_args(argv)
    measure(100, 5, 5)  # compile / load the kernels
    rows = []
    print(f"dense room at {DENSITY_PER_M2:g} /m², baseline agents, full model, h = 0.01 s, one thread; "
          f"{args.steps} steps after {args.warmup}")
    head = (f"{'N':>6} {'ms/step':>8} {'us/ag-st':>8} {'staged%':>7} | {'staged':>7} "
            + " ".join(f"{k:>9}" for k in PHASES) + f" | {'cont/smth':>9} {'contacts':>8} {'max_cl':>6}")
    print(head)
    for n in args.sizes:
        r = measure(n, args.steps, args.warmup, restart=args.restart)
        rows.append(r)
        print(f"{n:>6} {r['ms_per_step']:>8.2f} {r['us_per_agent_step']:>8.2f} {100 * r['staged_fraction']:>6.0f}% | "
              f"{r['staged_ms_per_step']:>7.2f} " + " ".join(f"{r[k]:>9.3f}" for k in PHASES)
              + f" | {r['contact_over_smooth']:>9.2f} {r['contacts_per_step']:>8.0f} {r['max_cluster']:>6}", flush=True)
    by_n = {r["n"]: r for r in rows}
    if 1000 in by_n and 10000 in by_n:
        ratio = by_n[10000]["ms_per_step"] / by_n[1000]["ms_per_step"]
        print(f"t(10 000)/t(1 000) per step = {ratio:.1f} (linear: 10; target <= 12)")
    dense = max(rows, key=lambda r: r["n"])
    print(f"contact part / smooth part at N = {dense['n']}: {dense['contact_over_smooth']:.2f} (target <= 1.5)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
