#!/usr/bin/env python
"""crowd_env against JuPedSim on the same Seyfried bottleneck, in one run: agent-steps/s and J_s.

Same geometry (the walkable area and exit of ``seyfried_bottleneck``), same seeded start positions,
same radii (0.23 m; JuPedSim's 1 µm less, see run_jupedsim) and desired speeds, h = 0.01 s, one thread. Three simulators evacuate the crowd:

* crowd_env, full model: baseline agents (eikonal field + Helbing social forces, Eq. 11-16), heading
  dynamics, Frémond impacts and the gap projection (disks never overlap);
* JuPedSim's social force model (Helbing 2000, its defaults besides radius/speed/mass);
* JuPedSim's collision-free speed model (Tordeux 2016, its defaults besides radius/speed).

Timed: only the simulation (crowd_env: policy + ``Simulator.step``; JuPedSim: ``Simulation.iterate``).
Not timed: measuring passages of the bottleneck line (the same :class:`PassageCounter` for all three)
and the per-step overlap check. Agent-steps = Σ over steps of the pedestrians present. The ratios
are crowd_env / JuPedSim from the same run. JuPedSim is a benchmark extra
(``pip install -e ".[bench]"``), never a dependency of crowd_env.

    python benchmarks/compare_jupedsim.py [--n 60] [--width 1.0] [--seeds 3]
"""
from __future__ import annotations

import argparse
import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import time  # noqa: E402

import numpy as np  # noqa: E402

from crowd_env.analysis.flow import MeasurementLine, PassageCounter, specific_flow  # noqa: E402
from crowd_env.core.state import min_gap_m  # noqa: E402
from crowd_env.scenarios import make_scenario  # noqa: E402

MAX_TIME_S = 300.0


def _counter(scenario):
    ends = np.asarray(scenario.geometry.measurement_lines["bottleneck"], dtype=float)
    return PassageCounter(MeasurementLine(ends[0], ends[1]))


def _summary(name, agent_steps, wall_s, counter, width_m, n, n_left, min_gap):
    times = np.sort(counter.times_s)
    js = specific_flow(times, width_m).specific_flow_per_m_s if times.size >= 2 else float("nan")
    return {"model": name, "agent_steps": int(agent_steps), "wall_s": wall_s, "rate": agent_steps / wall_s,
            "specific_flow": js, "evacuated": n - n_left, "n": n, "min_gap_m": min_gap}


def run_crowd_env(scenario, state):
    from baselines.social_force import SocialForceAgent
    from crowd_env.core import ModelParams, Simulator

    sim = Simulator(state, geometry=scenario.geometry, params=ModelParams())
    agent = SocialForceAgent(scenario.navigation())
    counter = _counter(scenario)
    ids = np.arange(state.n)
    agent_steps, wall, gap = 0, 0.0, np.inf
    for _ in range(int(MAX_TIME_S / sim.params.dt_s)):
        n_active = int(np.count_nonzero(state.active))
        if n_active == 0:
            break
        prev, t_prev = state.position_m.copy(), sim.time_s
        t0 = time.perf_counter()
        intents, heading = agent(sim)
        sim.step(intents, desired_heading_rad=heading)
        wall += time.perf_counter() - t0
        agent_steps += n_active
        counter.update(prev, state.position_m, t_prev, sim.time_s, ids)
        gap = min(gap, min_gap_m(state.position_m[state.active], state.radius_m[state.active]))
    return _summary("crowd_env (full model)", agent_steps, wall, counter, scenario.metadata["width_m"], state.n,
                    int(np.count_nonzero(state.active)), gap)


def run_jupedsim(scenario, state, model: str):
    import jupedsim as jps

    geometry = scenario.geometry
    # JuPedSim refuses an agent whose distance to a wall equals its radius (our placement lets disks
    # touch the walls): its agents are 1 µm thinner.
    radius = state.radius_m - 1e-6
    if model == "sfm":
        jmodel = jps.SocialForceModel()

        def params(k, journey, stage):
            return jps.SocialForceModelAgentParameters(
                position=tuple(state.position_m[k]), orientation=(1.0, 0.0), journey_id=journey, stage_id=stage,
                desired_speed=float(state.desired_speed_m_s[k]), radius=float(radius[k]),
                mass=float(state.mass_kg[k]))
        name = "JuPedSim social force"
    else:
        jmodel = jps.CollisionFreeSpeedModel()

        def params(k, journey, stage):
            return jps.CollisionFreeSpeedModelAgentParameters(
                position=tuple(state.position_m[k]), journey_id=journey, stage_id=stage,
                desired_speed=float(state.desired_speed_m_s[k]), radius=float(radius[k]))
        name = "JuPedSim collision-free speed"
    sim = jps.Simulation(model=jmodel, geometry=geometry.navigable_area, dt=0.01)
    stage = sim.add_exit_stage(geometry.exits[0])
    journey = sim.add_journey(jps.JourneyDescription([stage]))
    ids = np.array([sim.add_agent(params(k, journey, stage)) for k in range(state.n)])
    row_of = {int(a): k for k, a in enumerate(ids)}
    counter = _counter(scenario)
    pos = state.position_m.copy()
    agent_steps, wall, gap = 0, 0.0, np.inf
    for _ in range(int(MAX_TIME_S / 0.01)):
        n_active = sim.agent_count()
        if n_active == 0:
            break
        t_prev = sim.elapsed_time()
        t0 = time.perf_counter()
        sim.iterate()
        wall += time.perf_counter() - t0
        agent_steps += n_active
        new = pos.copy()
        present = []
        for a in sim.agents():
            k = row_of[a.id]
            new[k] = a.position
            present.append(k)
        counter.update(pos, new, t_prev, sim.elapsed_time(), np.arange(state.n))
        pos = new
        if present:
            present = np.asarray(present)
            gap = min(gap, min_gap_m(pos[present], radius[present]))
    return _summary(name, agent_steps, wall, counter, scenario.metadata["width_m"], state.n, sim.agent_count(), gap)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=60)
    ap.add_argument("--width", type=float, default=1.0)
    ap.add_argument("--seeds", type=int, default=3)
    args = ap.parse_args(argv)
    try:
        import jupedsim
    except ImportError:
        print("JuPedSim is not installed: pip install -e '.[bench]'")
        return 2
    # Warm-up (compiles or loads crowd_env's kernels, fills caches; loads JuPedSim) on the same case
    # (first seed), not reported.
    warm = make_scenario("seyfried_bottleneck", width_m=args.width, n_pedestrians=args.n, seed=0)
    run_crowd_env(warm, warm.make_state())
    run_jupedsim(warm, warm.make_state(), "sfm")
    rows = []
    for seed in range(args.seeds):
        sc = make_scenario("seyfried_bottleneck", width_m=args.width, n_pedestrians=args.n, seed=seed)
        rows.append(run_crowd_env(sc, sc.make_state()))
        rows.append(run_jupedsim(sc, sc.make_state(), "sfm"))
        rows.append(run_jupedsim(sc, sc.make_state(), "cfsm"))
    print(f"Seyfried bottleneck b = {args.width} m, N = {args.n}, h = 0.01 s, {args.seeds} seeds, one thread "
          f"(JuPedSim {jupedsim.__version__})")
    print(f"{'model':<30} {'agent-steps/s':>14} {'agent-steps':>12} {'wall s':>8} {'J_s 1/(m s)':>12} "
          f"{'evacuated':>10} {'min gap m':>10}")
    totals = {}
    for name in dict.fromkeys(r["model"] for r in rows):
        rs = [r for r in rows if r["model"] == name]
        steps = sum(r["agent_steps"] for r in rs)
        wall = sum(r["wall_s"] for r in rs)
        totals[name] = steps / wall
        js = np.nanmean([r["specific_flow"] for r in rs])
        ev = f"{sum(r['evacuated'] for r in rs)}/{sum(r['n'] for r in rs)}"
        print(f"{name:<30} {steps / wall:>14,.0f} {steps:>12,} {wall:>8.2f} {js:>12.3f} {ev:>10} "
              f"{min(r['min_gap_m'] for r in rs):>10.3f}")
    ours = totals["crowd_env (full model)"]
    print(f"ratio crowd_env / JuPedSim social force:         {ours / totals['JuPedSim social force']:.2f}x (target >= 1.0)")
    print(f"ratio crowd_env / JuPedSim collision-free speed: {ours / totals['JuPedSim collision-free speed']:.2f}x "
          f"(target >= 1.5)")
    print("experiment (Seyfried 2009, N = 60): J_s = 1.90 1/(m s) at b = 1.0 m")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
