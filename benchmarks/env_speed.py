#!/usr/bin/env python
"""Speed of the PettingZoo parallel environment: env steps/s and agent-steps/s on one core.

Every pedestrian is controlled (observations, rewards and dicts for all of them), ``frame_skip=1``
(one simulator step of 0.01 s per environment step). Actions (their computation is not timed):

- ``--policy baseline`` (default): the calibrated social-force agent's intents, fed as actions (the
  paper's crowd: it moves, queues at the bottleneck, few contacts);
- ``--policy walk``: everyone walks along its observed desired direction at 1.3 m/s with no social
  repulsion: the crowd pushes into a dense jam at the bottleneck with many simultaneous contacts,
  the simulator's worst case (its impact solver then dominates).

Each case
reports the mean over ``--steps`` steps after ``--warmup`` steps (numba loads its cached kernels
lazily, on first contact) and splits the time into the simulator step and the rest, the environment's
own work (observations, validation, rewards, infos, dicts), with its ratio to the simulator's time
(target: <= 0.5 at N = 100).

Scenarios: the Seyfried bottleneck (b = 1 m) with N pedestrians (N > 60 fills holding sections further
upstream, so N = 1000 is a 4 m x 78 m corridor in front of the bottleneck).

    python benchmarks/env_speed.py                    # N = 10, 60, 100, 1000
    python benchmarks/env_speed.py --n 100 --steps 2000
"""
from __future__ import annotations

import argparse
import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from timing import time_calls  # noqa: E402

TARGET_ENV_OVER_SIM = 0.5  # the environment's own work per step over the simulator's, at N = 100


def bench(n: int, steps: int, warmup: int, n_neighbors: int, n_rays: int, policy: str = "baseline") -> dict:
    from crowd_env.envs import crowd_v0

    env = crowd_v0.parallel_env(scenario="seyfried_bottleneck", scenario_options={"n_pedestrians": n, "width_m": 1.0},
                                controlled="all", frame_skip=1, max_steps=10**9, n_neighbors=n_neighbors,
                                n_rays=n_rays, action_max_m_s=50.0)
    obs, _ = env.reset(seed=0)
    ed = env.observation_layout["desired_direction"]
    agent = None
    if policy == "baseline":
        from baselines.social_force import SocialForceAgent

        agent = SocialForceAgent(env.navigation)
    sim_time, obs_time = [0.0], [0.0]
    time_calls(env.sim, "step", sim_time)  # the simulator's share
    time_calls(env._observer, "observe", obs_time)  # the compiled observation pass's (part of the env's own work)
    total = 0.0
    agent_steps = 0
    done = 0
    for k in range(warmup + steps):
        if not env.agents:
            break
        if agent is None:
            acts = np.stack([obs[a][ed] for a in env.agents]) * np.float32(1.3)
        else:
            acts = agent(env.sim)[0][[int(a[4:]) for a in env.agents]]
        actions = dict(zip(env.agents, acts))
        if k == warmup:
            sim_time[0] = obs_time[0] = 0.0
        t = time.perf_counter()
        obs, *_ = env.step(actions)
        dt = time.perf_counter() - t
        if k >= warmup:
            total += dt
            agent_steps += len(actions)
            done += 1
    return {"n": n, "env_steps": done, "env_steps_per_s": done / total, "agent_steps_per_s": agent_steps / total,
            "ms_per_step": 1e3 * total / done, "sim_ms_per_step": 1e3 * sim_time[0] / done,
            "obs_ms_per_step": 1e3 * obs_time[0] / done,
            "mean_live_agents": agent_steps / done, "obs_dim": env.observation_space(env.possible_agents[0]).shape[0]}


def dict_floor_ms(m: int, dim: int, repeats: int = 2000) -> float:
    """The PettingZoo API's share that no compiled pass removes: building the five per-agent dicts of a
    step (observation rows, rewards, terminations, truncations, infos of four measures, as the environment
    gives them by default) and stacking an action dict, for ``m`` agents from ready arrays, in ms (the mean
    of ``repeats``)."""
    rng = np.random.default_rng(0)
    agents = [f"ped_{i}" for i in range(m)]
    obs = rng.random((m, dim)).astype(np.float32)
    rew, perc, speed, travel = rng.random((4, m))
    count = rng.integers(0, 3, m)
    actions = dict(zip(agents, rng.random((m, 2)).astype(np.float32)))
    t = time.perf_counter()
    for _ in range(repeats):
        np.array(list(actions.values()), dtype=np.float64)
        dict(zip(agents, obs))
        dict(zip(agents, rew.tolist()))
        term = dict.fromkeys(agents, False)
        term.copy()
        {a: {"contact_percussion_kg_m_s": p, "n_contacts": c, "travel_time_s": tt, "speed_m_s": v}
         for a, p, c, tt, v in zip(agents, perc.tolist(), count.tolist(), travel.tolist(), speed.tolist())}
    return 1e3 * (time.perf_counter() - t) / repeats


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, nargs="+", default=[10, 60, 100, 1000], help="numbers of pedestrians")
    ap.add_argument("--steps", type=int, default=1000, help="timed environment steps per case")
    ap.add_argument("--warmup", type=int, default=800, help="untimed steps first (numba's lazy kernel loading)")
    ap.add_argument("--n-neighbors", type=int, default=6)
    ap.add_argument("--n-rays", type=int, default=8)
    ap.add_argument("--policy", choices=["baseline", "walk"], default="baseline", help="how actions are chosen")
    args = ap.parse_args(argv)
    try:
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})  # one core
    except (AttributeError, OSError):
        pass
    print(f"policy: {args.policy}; k = {args.n_neighbors} neighbours, R = {args.n_rays} rays; one core")
    print(f"{'N':>6} {'steps':>6} {'env steps/s':>12} {'agent-steps/s':>14} {'ms/step':>8} {'sim ms':>7} "
          f"{'env ms':>7} {'env/sim':>7} {'target':>7} {'live':>6} {'obs ms':>7} {'dicts ms':>8} {'floor/sim':>9}")
    for n in args.n:
        r = bench(n, args.steps, args.warmup, args.n_neighbors, args.n_rays, args.policy)
        own = r["ms_per_step"] - r["sim_ms_per_step"]
        target = f"<= {TARGET_ENV_OVER_SIM:g}" if n == 100 else ""
        floor = dict_floor_ms(int(round(r["mean_live_agents"])), r["obs_dim"])
        print(f"{r['n']:>6} {r['env_steps']:>6} {r['env_steps_per_s']:>12.0f} {r['agent_steps_per_s']:>14.0f} "
              f"{r['ms_per_step']:>8.3f} {r['sim_ms_per_step']:>7.3f} {own:>7.3f} {own / r['sim_ms_per_step']:>7.2f} "
              f"{target:>7} {r['mean_live_agents']:>6.0f} {r['obs_ms_per_step']:>7.3f} {floor:>8.3f} "
              f"{(floor + r['obs_ms_per_step']) / r['sim_ms_per_step']:>9.2f}", flush=True)
    print("env ms: everything in env.step but sim.step (observations, validation, rewards, infos, dicts); env/sim: "
          "its ratio to the simulator's time (target at N = 100); dicts ms: the part of it\nthat is the PettingZoo dict API "
          "itself (five per-agent dicts built from ready arrays and one action dict "
          "stacked, for the mean live agents);\n"
          "obs ms: the compiled observation pass (neighbours, wall rays, navigation sampling) within env ms; floor/sim: "
          "(obs ms + dicts ms) / sim ms, the environment's own work without its Python glue")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
