#!/usr/bin/env python
"""Speed of the native vector environment against the PettingZoo environment and the bare simulator.

For N pedestrians (all controlled) and K copies, one "step" advances all K crowds by one environment
step (``frame_skip=1``: one simulator step of 0.01 s):

- ``bare``: K :class:`~crowd_env.core.simulator.Simulator` objects stepped with the intents (no
  observations, no rewards): the floor any interface sits on;
- ``pettingzoo``: K ``crowd_v0.parallel_env`` copies stepped one after another with dict actions
  (observations, rewards and the dicts included);
- ``vector``: one ``CrowdVectorEnv`` of the K copies stepped with one (K N, 2) action array.

All three walk the same crowds (the Seyfried bottleneck at b = 1 m, seeds 0 … K−1) with the same rule,
1.3 m/s along each pedestrian's e_d; computing the actions is not timed. Figures: steps/s of the K
crowds, agent-steps/s, and the ratios vector / pettingzoo and vector / bare, measured in one run.

    python benchmarks/vector_speed.py                      # N = 10, 100, 1000 x K = 1, 8, 32
    python benchmarks/vector_speed.py --n 100 --k 8 --steps 50
"""
from __future__ import annotations

import argparse
import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import time  # noqa: E402

import numpy as np  # noqa: E402

SPEED_M_S = 1.3


def _options(n: int) -> dict:
    return {"scenario": "seyfried_bottleneck", "scenario_options": {"n_pedestrians": n, "width_m": 1.0},
            "controlled": "all", "frame_skip": 1, "max_steps": 10**9, "action_max_m_s": 5.0}


def bench_bare(n: int, k: int, steps: int, warmup: int) -> float:
    from crowd_env.envs import crowd_v0

    envs = [crowd_v0.parallel_env(**_options(n)) for _ in range(k)]
    for c, e in enumerate(envs):
        e.reset(seed=c)
    sims = [e.sim for e in envs]
    navs = [e.navigation for e in envs]
    total = 0.0
    for s in range(warmup + steps):
        intents = [SPEED_M_S * nav.direction(sim.state.position_m) for sim, nav in zip(sims, navs)]
        t = time.perf_counter()
        for sim, u in zip(sims, intents):
            sim.step(u, desired_heading_rad=np.arctan2(u[:, 1], u[:, 0]))
        if s >= warmup:
            total += time.perf_counter() - t
    return total / steps


def bench_pettingzoo(n: int, k: int, steps: int, warmup: int) -> float:
    from crowd_env.envs import crowd_v0

    envs = [crowd_v0.parallel_env(**_options(n)) for _ in range(k)]
    obs = [e.reset(seed=c)[0] for c, e in enumerate(envs)]
    ed = envs[0].observation_layout["desired_direction"]
    total = 0.0
    for s in range(warmup + steps):
        actions = [{a: SPEED_M_S * o[a][ed].astype(np.float64) for a in e.agents} for e, o in zip(envs, obs)]
        t = time.perf_counter()
        obs = [e.step(act)[0] for e, act in zip(envs, actions)]
        if s >= warmup:
            total += time.perf_counter() - t
    return total / steps


def bench_vector(n: int, k: int, steps: int, warmup: int) -> float:
    from crowd_env.envs.vector import vector_env

    vec = vector_env(k, **_options(n))
    obs, _ = vec.reset(seed=0)
    ed = vec.envs[0].observation_layout["desired_direction"]
    total = 0.0
    for s in range(warmup + steps):
        actions = SPEED_M_S * obs[:, ed].astype(np.float64)
        t = time.perf_counter()
        obs = vec.step(actions)[0]
        if s >= warmup:
            total += time.perf_counter() - t
    return total / steps


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, nargs="+", default=[10, 100, 1000], help="pedestrians per copy")
    ap.add_argument("--k", type=int, nargs="+", default=[1, 8, 32], help="copies")
    ap.add_argument("--steps", type=int, default=None, help="timed steps (default: 2000 / (N K / 10), 5..200)")
    ap.add_argument("--warmup", type=int, default=3)
    args = ap.parse_args(argv)
    # Load every compiled kernel before timing anything: 8 s of a crowd of 20 (contacts, exits, resets).
    bench_vector(20, 2, 5, 800)
    print(f"{'N':>5} {'K':>3} {'steps':>5} {'bare st/s':>10} {'PZ st/s':>9} {'vec st/s':>9} {'vec agent-st/s':>14} "
          f"{'vec/PZ':>7} {'vec/bare':>8}")
    for n in args.n:
        for k in args.k:
            steps = args.steps or int(np.clip(2000 * 10 / (n * k), 5, 200))
            bare = bench_bare(n, k, steps, args.warmup)
            pz = bench_pettingzoo(n, k, steps, args.warmup)
            vec = bench_vector(n, k, steps, args.warmup)
            print(f"{n:>5} {k:>3} {steps:>5} {1 / bare:>10.1f} {1 / pz:>9.1f} {1 / vec:>9.1f} {n * k / vec:>14.0f} "
                  f"{pz / vec:>7.2f} {bare / vec:>8.2f}", flush=True)
    print("vec/PZ: speed of the vector env over the PettingZoo env on the same crowds; vec/bare: its share of the "
          "bare simulator's speed (1 = no interface cost)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
