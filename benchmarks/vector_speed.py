#!/usr/bin/env python
"""Speed of the native vector environment (1 and 2 worker processes) against the PettingZoo environment.

For N pedestrians (all controlled) and K copies, one "step" advances all K crowds by one environment
step (``frame_skip=1``: one simulator step of 0.01 s):

- ``bare``: K :class:`~crowd_env.core.simulator.Simulator` objects stepped with the intents (no
  observations, no rewards): the floor any interface sits on;
- ``PZ``: K ``crowd_v0.parallel_env`` copies stepped one after another with dict actions
  (observations, rewards and the dicts included);
- ``vec w=1``: one ``CrowdVectorEnv`` of the K copies stepped with one (K N, 2) action array in this process;
- ``vec w=2``: the same with ``workers=2`` (two processes, shared-memory buffers).

All walk the same crowds (the Seyfried bottleneck at b = 1 m, seeds 0 … K−1) with the same rule, 1.3 m/s
along each pedestrian's e_d; computing the actions is not timed. Every case first runs ``--warmup``
untimed steps (numba loads its cached kernels lazily, in each worker too). Figures: agent-steps/s (live
agents only), and, in the same run, vector (2 workers) / PZ (target >= 3 at N = 100) and 2 workers /
1 worker (target >= 1.6).

    python benchmarks/vector_speed.py                      # N = 100, K = 8
    python benchmarks/vector_speed.py --n 10 100 --k 2 8 --steps 200
"""
from __future__ import annotations

import argparse
import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import time  # noqa: E402

import numpy as np  # noqa: E402

SPEED_M_S = 1.3
TARGET_VEC_OVER_PZ = 3.0
TARGET_TWO_OVER_ONE = 1.6


def _options(n: int) -> dict:
    return {"scenario": "seyfried_bottleneck", "scenario_options": {"n_pedestrians": n, "width_m": 1.0},
            "controlled": "all", "frame_skip": 1, "max_steps": 10**9, "action_max_m_s": 5.0}


def bench_bare(n: int, k: int, steps: int, warmup: int) -> float:
    """Agent-steps/s of K bare simulators."""
    from crowd_env.envs import crowd_v0

    envs = [crowd_v0.parallel_env(**_options(n)) for _ in range(k)]
    for c, e in enumerate(envs):
        e.reset(seed=c)
    sims = [e.sim for e in envs]
    navs = [e.navigation for e in envs]
    total, agent_steps = 0.0, 0
    for s in range(warmup + steps):
        intents = [SPEED_M_S * nav.direction(sim.state.position_m) for sim, nav in zip(sims, navs)]
        live = sum(int(sim.state.active.sum()) for sim in sims)
        t = time.perf_counter()
        for sim, u in zip(sims, intents):
            sim.step(u, desired_heading_rad=np.arctan2(u[:, 1], u[:, 0]))
        if s >= warmup:
            total += time.perf_counter() - t
            agent_steps += live
    return agent_steps / total


def bench_pettingzoo(n: int, k: int, steps: int, warmup: int) -> float:
    """Agent-steps/s of K PettingZoo environments stepped one after another."""
    from crowd_env.envs import crowd_v0

    envs = [crowd_v0.parallel_env(**_options(n)) for _ in range(k)]
    obs = [e.reset(seed=c)[0] for c, e in enumerate(envs)]
    ed = envs[0].observation_layout["desired_direction"]
    total, agent_steps = 0.0, 0
    for s in range(warmup + steps):
        for c, e in enumerate(envs):
            if not e.agents:
                obs[c] = e.reset()[0]
        actions = [{a: SPEED_M_S * o[a][ed].astype(np.float64) for a in e.agents} for e, o in zip(envs, obs)]
        t = time.perf_counter()
        obs = [e.step(act)[0] for e, act in zip(envs, actions)]
        if s >= warmup:
            total += time.perf_counter() - t
            agent_steps += sum(len(act) for act in actions)
    return agent_steps / total


def bench_vector(n: int, k: int, steps: int, warmup: int, workers: int = 1) -> float:
    """Agent-steps/s of one vector environment of the K copies."""
    from crowd_env.envs.vector import vector_env

    vec = vector_env(k, workers=workers, **_options(n))
    try:
        obs, _ = vec.reset(seed=0)
        ed = vec.envs[0].observation_layout["desired_direction"]
        total, agent_steps = 0.0, 0
        for s in range(warmup + steps):
            actions = SPEED_M_S * obs[:, ed].astype(np.float64)
            t = time.perf_counter()
            obs, _, _, _, infos = vec.step(actions)
            if s >= warmup:
                total += time.perf_counter() - t
                agent_steps += int(infos["acted"].sum())
    finally:
        vec.close()
    return agent_steps / total


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, nargs="+", default=[100], help="pedestrians per copy")
    ap.add_argument("--k", type=int, nargs="+", default=[8], help="copies (>= 2 for two workers)")
    ap.add_argument("--steps", type=int, default=400, help="timed steps per case")
    ap.add_argument("--warmup", type=int, default=800, help="untimed steps first (numba's lazy kernel loading)")
    args = ap.parse_args(argv)
    print(f"cores available: {len(os.sched_getaffinity(0))}; agent-steps/s (live agents), warm-up {args.warmup} steps")
    print(f"{'N':>5} {'K':>3} {'steps':>5} {'bare':>10} {'PZ':>10} {'vec w=1':>10} {'vec w=2':>10} {'w=1/PZ':>7} "
          f"{'w=2/PZ':>7} {'target':>6} {'w=2/w=1':>7} {'target':>6}")
    for n in args.n:
        for k in args.k:
            bare = bench_bare(n, k, args.steps, args.warmup)
            pz = bench_pettingzoo(n, k, args.steps, args.warmup)
            one = bench_vector(n, k, args.steps, args.warmup, workers=1)
            two = bench_vector(n, k, args.steps, args.warmup, workers=2) if k >= 2 else float("nan")
            print(f"{n:>5} {k:>3} {args.steps:>5} {bare:>10.0f} {pz:>10.0f} {one:>10.0f} {two:>10.0f} {one / pz:>7.2f} "
                  f"{two / pz:>7.2f} {'>= ' + format(TARGET_VEC_OVER_PZ, 'g'):>6} {two / one:>7.2f} "
                  f"{'>= ' + format(TARGET_TWO_OVER_ONE, 'g'):>6}", flush=True)
    print("w=2/PZ: the vector env on two worker processes over the PettingZoo env on the same crowds (target at "
          "N = 100); w=2/w=1: its speed-up from the second core")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
