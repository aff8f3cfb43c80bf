"""Time per simulation step and per agent-step in a dense room (~3 pedestrians/m²).

N pedestrians (Table 2 bodies: 83 kg, r = 0.23 m) on a square lattice of spacing 1/√3 m (3 /m²,
gaps of 0.12 m) filling a square walled room, default ModelParams (K_n = 1e5 kg, h = 0.01 s), no
social force (the core alone). Three loads:

* ``standing``: intents zero, everyone at rest: no contacts (the fixed cost of a step);
* ``random``: everyone walks at their desired speed in a fixed random direction: many small
  contact clusters all over the room;
* ``pushing``: everyone pushes at 1.5 m/s towards the centre of the room: after the warm-up a
  jammed cluster forms there, the worst case for the contact solvers.

Each run warms up (not timed, which also compiles the kernels) and then times ``--steps`` steps,
printing ms per step, agent-steps per second, the per-phase split from StepResult.timings_s and the
largest cluster, and t(N_max)/t(N_prev) between consecutive sizes. With ``--body-depth D`` every case runs twice,
with the paper's disks and with bodies of three circles of depth D (crowd_env.core.body), and prints the ratio of
their times measured in the same run.

    python benchmarks/step.py [100 1000 10000] [--modes standing random pushing] [--steps 20] [--warmup 50]
    python benchmarks/step.py 100 1000 --body-depth 0.25
"""
from __future__ import annotations

import argparse
import math
import time

import numpy as np

from crowd_env.core import CrowdState, Simulator
from crowd_env.walking import ModelParams
from crowd_env.core.step import STAGES as PHASES


def dense_room(n, seed=0):
    """n pedestrians at 3 /m² on a jittered square lattice in a square room; returns (state, walls, L)."""
    a = 1.0 / math.sqrt(3.0)
    side = int(math.ceil(math.sqrt(n)))
    L = side * a
    rng = np.random.default_rng(seed)
    ij = np.stack(np.meshgrid(np.arange(side), np.arange(side)), axis=-1).reshape(-1, 2)[:n]
    pos = (ij + 0.5) * a + rng.uniform(-0.02, 0.02, (n, 2))
    state = CrowdState.create(pos, rng=rng)
    walls = [[0, 0, L, 0], [L, 0, L, L], [L, L, 0, L], [0, L, 0, 0]]
    return state, walls, L


def intents_for(mode, state, L, rng):
    if mode == "standing":
        return lambda: np.zeros((state.n, 2))
    if mode == "random":
        ang = rng.uniform(-math.pi, math.pi, state.n)
        fixed = state.desired_speed_m_s[:, None] * np.stack([np.cos(ang), np.sin(ang)], axis=1)
        return lambda: fixed
    if mode == "pushing":
        def push():
            d = np.array([L / 2, L / 2]) - state.position_m
            return 1.5 * d / np.maximum(np.linalg.norm(d, axis=1), 1e-9)[:, None]
        return push
    raise ValueError(f"unknown mode {mode!r}")


def run(n, mode, steps, warmup, seed=0, body_depth_m=0.0):
    state, walls, L = dense_room(n, seed)
    sim = Simulator(state, walls=walls, params=ModelParams(social_forces=False, body_depth_m=body_depth_m))
    intents = intents_for(mode, state, L, np.random.default_rng(seed + 1))
    for _ in range(warmup):
        sim.step(intents())
    phases = dict.fromkeys(PHASES, 0.0)
    max_cluster = 0
    n_contacts = 0
    t0 = time.perf_counter()
    for _ in range(steps):
        res = sim.step(intents())
        for k in PHASES:
            phases[k] += res.timings_s.get(k, 0.0)
        max_cluster = max(max_cluster, res.max_cluster_size)
        n_contacts += res.contact_i.size
    wall = (time.perf_counter() - t0) / steps
    return dict(n=n, mode=mode, ms=wall * 1e3, agent_steps_per_s=n / wall,
                phases={k: v / steps * 1e3 for k, v in phases.items()}, max_cluster=max_cluster,
                contacts=n_contacts / steps, min_gap=sim.min_gap_m(), sparse=sim.n_sparse_solves,
                fallback=sim.n_fallback_solves)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sizes", type=int, nargs="*", default=[100, 1000, 10000])
    ap.add_argument("--modes", nargs="+", default=["standing", "random", "pushing"])
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--warmup", type=int, default=50)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--body-depth", type=float, default=0.0,
                    help="also run bodies of three circles of this depth (m) and print their time over the disks'")
    args = ap.parse_args(argv)
    print(f"{'mode':>9} {'N':>6} | {'ms/step':>8} {'agent-steps/s':>13} | "
          + " ".join(f"{k:>10}" for k in PHASES) + " | contacts max_cluster  min_gap_m  sparse/fallback")
    results = {}
    for mode in args.modes:
        for n in args.sizes:
            for depth in ((0.0, args.body_depth) if args.body_depth > 0 else (0.0,)):
                r = run(n, mode, args.steps, args.warmup, args.seed, depth)
                if depth == 0.0:
                    results[(mode, n)] = r
                label = mode if depth == 0.0 else f"D={depth:g}"
                print(f"{label:>9} {n:6d} | {r['ms']:8.2f} {r['agent_steps_per_s']:13,.0f} | "
                      + " ".join(f"{r['phases'][k]:10.3f}" for k in PHASES)
                      + f" | {r['contacts']:8.0f} {r['max_cluster']:11d} {r['min_gap']:10.2e}  {r['sparse']}/"
                      f"{r['fallback']}", flush=True)
                if depth > 0.0:
                    print(f"{mode:>9} {n:6d}   three circles / disks: {r['ms'] / results[(mode, n)]['ms']:.2f}")
        sizes = sorted(args.sizes)
        for a, b in zip(sizes, sizes[1:]):
            ra, rb = results[(mode, a)], results[(mode, b)]
            print(f"{mode:>9} t({b})/t({a}) = {rb['ms'] / ra['ms']:.1f}  (ideal {b / a:.0f})")
    print("phase columns: ms per step (StepResult.timings_s); wall-clock, one process, warm kernels")


if __name__ == "__main__":
    main()
