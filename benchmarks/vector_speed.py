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

All walk the same crowds (the Seyfried bottleneck at b = 1 m, seeds 0 … K−1) with the same rule from the
observations (computing the actions is not timed), ``--policy``:

- ``speed`` (default): the collision-free speed rule of Tordeux et al. (2016) on each pedestrian's e_d:
  speed min(1.3, max(0, (s − 0.4 m) / 1 s)), s the distance to the nearest observed neighbour ahead
  (within 0.4 m of the walking line): a queue that flows through the bottleneck with few contacts, the
  regime of the PettingZoo figure of ``env_speed.py`` (the calibrated agent's intents);
- ``walk``: 1.3 m/s along e_d, no regard for others: a dense jam with many simultaneous contacts, where
  the simulator's impact solver dominates every interface's time.
 Every case first runs ``--warmup``
untimed steps (numba loads its cached kernels lazily, in each worker too). Figures: agent-steps/s (live
agents only), and, in the same run, vector (2 workers) / PZ (target >= 3 at N = 100) and 2 workers /
1 worker (target >= 1.6).

    python benchmarks/vector_speed.py                      # N = 100, K = 8, both rules
    python benchmarks/vector_speed.py --n 10 100 --k 2 8 --steps 200
"""
from __future__ import annotations

import argparse
import itertools
import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from timing import time_calls  # noqa: E402

SPEED_M_S = 1.3
DIAMETER_M = 0.4  # l of the speed rule: the gap below which a pedestrian stops
TIME_GAP_S = 1.0  # T of the speed rule
POLICIES = ("speed", "walk")


def act(obs: np.ndarray, layout: dict, policy: str) -> np.ndarray:
    """Velocity intents (M, 2) float64 from observation rows (M, D) (world frame) under ``policy``."""
    e = obs[:, layout["desired_direction"]].astype(np.float64)
    if policy == "walk":
        return SPEED_M_S * e
    rel = obs[:, layout["neighbors"]].astype(np.float64).reshape(len(obs), -1, 4)[:, :, :2]
    mask = obs[:, layout["neighbor_mask"]] > 0
    ahead = rel[:, :, 0] * e[:, None, 0] + rel[:, :, 1] * e[:, None, 1]
    side = np.abs(rel[:, :, 1] * e[:, None, 0] - rel[:, :, 0] * e[:, None, 1])
    blocking = mask & (ahead > 0.0) & (side < DIAMETER_M)
    gap = np.where(blocking, np.hypot(rel[:, :, 0], rel[:, :, 1]), np.inf).min(axis=1, initial=np.inf)
    speed = np.clip((gap - DIAMETER_M) / TIME_GAP_S, 0.0, SPEED_M_S)
    return speed[:, None] * e


TARGET_VEC_OVER_PZ = 3.0
TARGET_TWO_OVER_ONE = 1.6


def _options(n: int) -> dict:
    return {"scenario": "seyfried_bottleneck", "scenario_options": {"n_pedestrians": n, "width_m": 1.0},
            "controlled": "all", "frame_skip": 1, "max_steps": 10**9, "action_max_m_s": 5.0}


def bench_bare(n: int, k: int, steps: int, warmup: int, policy: str) -> float:
    """Agent-steps/s of K bare simulators (a copy whose crowd has left is reset, untimed)."""
    from crowd_env.envs import crowd_v0

    envs = [crowd_v0.parallel_env(**_options(n)) for _ in range(k)]
    for c, e in enumerate(envs):
        e.reset(seed=c)
    layout = envs[0].observation_layout
    total, agent_steps = 0.0, 0
    for s in range(warmup + steps):
        for e in envs:
            if not e.sim.state.active.any():
                e.reset()
        sims = [e.sim for e in envs]
        intents = []
        for e, sim in zip(envs, sims):
            obs, _ = e._observer.build(sim.state, np.arange(sim.state.n))
            u = act(obs, layout, policy)
            intents.append((u, np.where(np.hypot(u[:, 0], u[:, 1]) > 1e-12, np.arctan2(u[:, 1], u[:, 0]),
                                        sim.state.heading_rad)))
        live = sum(int(sim.state.active.sum()) for sim in sims)
        t = time.perf_counter()
        for sim, (u, heading) in zip(sims, intents):
            sim.step(u, desired_heading_rad=heading)
        if s >= warmup:
            total += time.perf_counter() - t
            agent_steps += live
    return agent_steps / total


def bench_pettingzoo(n: int, k: int, steps: int, warmup: int, policy: str) -> float:
    """Agent-steps/s of K PettingZoo environments stepped one after another."""
    from crowd_env.envs import crowd_v0

    envs = [crowd_v0.parallel_env(**_options(n)) for _ in range(k)]
    obs = [e.reset(seed=c)[0] for c, e in enumerate(envs)]
    layout = envs[0].observation_layout
    total, agent_steps = 0.0, 0
    for s in range(warmup + steps):
        for c, e in enumerate(envs):
            if not e.agents:
                obs[c] = e.reset()[0]
        actions = [dict(zip(e.agents, act(np.stack([o[a] for a in e.agents]), layout, policy)))
                   for e, o in zip(envs, obs)]
        t = time.perf_counter()
        obs = [e.step(a)[0] for e, a in zip(envs, actions)]
        if s >= warmup:
            total += time.perf_counter() - t
            agent_steps += sum(len(a) for a in actions)
    return agent_steps / total


def bench_vector(n: int, k: int, steps: int, warmup: int, policy: str, workers: int = 1) -> tuple:
    """Agent-steps/s of one vector environment of the K copies, and (with one worker: the copies live
    in this process) the seconds per agent-step of its simulator steps and of its observation passes
    (NaN with more workers)."""
    from crowd_env.envs.vector import vector_env

    vec = vector_env(k, workers=workers, **_options(n))
    sim_clock, obs_clock = [0.0], [0.0]
    try:
        obs, _ = vec.reset(seed=0)
        layout = vec.envs[0].observation_layout
        if workers == 1:
            for e in vec.envs:
                time_calls(e.sim, "step", sim_clock)  # reset() makes a new simulator: a copy that resets is untimed
                time_calls(e._observer, "observe", obs_clock)
        total, agent_steps = 0.0, 0
        for s in range(warmup + steps):
            actions = act(obs, layout, policy)
            if s == warmup:
                sim_clock[0] = obs_clock[0] = 0.0
            t = time.perf_counter()
            obs, _, _, _, infos = vec.step(actions)
            if s >= warmup:
                total += time.perf_counter() - t
                agent_steps += int(infos["acted"].sum())
    finally:
        vec.close()
    if workers != 1:
        return agent_steps / total, float("nan"), float("nan")
    return agent_steps / total, sim_clock[0] / agent_steps, obs_clock[0] / agent_steps


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, nargs="+", default=[100], help="pedestrians per copy")
    ap.add_argument("--k", type=int, nargs="+", default=[8], help="copies (>= 2 for two workers)")
    ap.add_argument("--steps", type=int, default=400, help="timed steps per case")
    ap.add_argument("--warmup", type=int, default=800, help="untimed steps first (numba's lazy kernel loading)")
    ap.add_argument("--policy", choices=POLICIES, nargs="+", default=list(POLICIES), help="action rules (see above)")
    args = ap.parse_args(argv)
    print(f"cores available: {len(os.sched_getaffinity(0))}; agent-steps/s (live agents), warm-up {args.warmup} steps")
    print(f"{'policy':>6} {'N':>5} {'K':>3} {'steps':>5} {'bare':>10} {'PZ':>10} {'vec w=1':>10} {'vec w=2':>10} {'w=1/PZ':>7} "
          f"{'w=2/PZ':>7} {'target':>6} {'w=2/w=1':>7} {'target':>6} {'sim %':>6} {'obs %':>6} {'ceil/PZ':>7}")
    for policy, n, k in itertools.product(args.policy, args.n, args.k):
        bare = bench_bare(n, k, args.steps, args.warmup, policy)
        pz = bench_pettingzoo(n, k, args.steps, args.warmup, policy)
        one, sim_s, obs_s = bench_vector(n, k, args.steps, args.warmup, policy, workers=1)
        two = bench_vector(n, k, args.steps, args.warmup, policy, workers=2)[0] if k >= 2 else float("nan")
        ceiling = 2.0 / (sim_s + obs_s)  # two cores doing nothing but the simulator steps and observation passes
        print(f"{policy:>6} {n:>5} {k:>3} {args.steps:>5} {bare:>10.0f} {pz:>10.0f} {one:>10.0f} {two:>10.0f} {one / pz:>7.2f} "
              f"{two / pz:>7.2f} {'>= ' + format(TARGET_VEC_OVER_PZ, 'g'):>6} {two / one:>7.2f} "
              f"{'>= ' + format(TARGET_TWO_OVER_ONE, 'g'):>6} {100 * sim_s * one:>6.1f} {100 * obs_s * one:>6.1f} "
              f"{ceiling / pz:>7.2f}", flush=True)
    print("w=2/PZ: the vector env on two worker processes over the PettingZoo env on the same crowds (target at "
          "N = 100); w=2/w=1: its speed-up from the second core;\nsim %, obs %: the shares of the vector env's time "
          "(one worker) in its simulator steps and in its compiled observation passes; ceil/PZ: what two cores doing\n"
          "nothing but those two would reach over the PettingZoo env (the most any two-process interface with these "
          "observations can reach; the rest is per-copy bookkeeping)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
