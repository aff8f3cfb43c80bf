#!/usr/bin/env python
"""crowd_env against JuPedSim on the same Seyfried bottleneck, in one run: agent-steps/s and J_s.

Same geometry (the walkable area and exit of ``seyfried_bottleneck``), same seeded start positions,
same radii (0.23 m; JuPedSim's 1 µm less, see run_jupedsim) and desired speeds, h = 0.01 s, one thread.
The crowd is evacuated by:

* crowd_env, full model with the default preset (``--preset``, default ``calibrated``: what every command and
  the environment run; its navigation clearance too): baseline agents (eikonal field + Helbing social forces,
  Eq. 11-16), heading dynamics, Frémond impacts and the gap projection (disks never
  overlap), run three ways on the same start (the three are the same run to the last bit):

  - *compiled rollout*: ``run_scenario`` as the reproduction and the calibration run it (agent,
    step, exits, passages, densities, stall rule in compiled chunks), timed whole, measurement included;
  - *step by step*: ``agent(sim)`` and ``Simulator.step`` from Python, timed (passages counted outside);
  - *compiled work alone*: the floor, the agent's decision, the fused step and the exit test in a
    compiled loop with nothing else (no measurement, no Python between steps);
* JuPedSim's social force model (Helbing 2000, its defaults besides radius/speed/mass);
* JuPedSim's collision-free speed model (Tordeux 2016, its defaults besides radius/speed).

JuPedSim is timed on ``Simulation.iterate`` only (its passages and the per-step overlap check are not
timed). Agent-steps = Σ over steps of the pedestrians present. The ratios are from the same run. JuPedSim is a benchmark extra
(``pip install -e ".[bench]"``), never a dependency of crowd_env.

    python benchmarks/compare_jupedsim.py [--n 60] [--width 1.0] [--seeds 3] [--preset calibrated]
"""
from __future__ import annotations

import argparse
import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import time  # noqa: E402

import numpy as np  # noqa: E402

import numba as nb  # noqa: E402

from crowd_env.analysis.flow import MeasurementLine, PassageCounter, specific_flow  # noqa: E402
from crowd_env.core.bundles import Bodies, StepInputs, World  # noqa: E402
from crowd_env.core.state import min_gap_m  # noqa: E402
from crowd_env.core.step import FUSED_OK, active_rows, advance  # noqa: E402
from crowd_env.walking.presets import DEFAULT_PRESET, PRESETS, get_preset  # noqa: E402
from crowd_env.experiments.running.runner import run_scenario  # noqa: E402
from crowd_env.scenarios import make_scenario  # noqa: E402
from crowd_env.walking.agent import AGENT_OK, compiled_agent, decide  # noqa: E402

MAX_TIME_S = 300.0


def _counter(scenario):
    ends = np.asarray(scenario.geometry.measurement_lines["bottleneck"], dtype=float)
    return PassageCounter(MeasurementLine(ends[0], ends[1], scenario.line_direction("bottleneck")))


def _summary(name, agent_steps, wall_s, counter, width_m, n, n_left, min_gap):
    times = np.sort(counter.times_s)
    js = specific_flow(times, width_m).specific_flow_per_m_s if times.size >= 2 else float("nan")
    return {"model": name, "agent_steps": int(agent_steps), "wall_s": wall_s, "rate": agent_steps / wall_s,
            "specific_flow": js, "evacuated": n - n_left, "n": n, "min_gap_m": min_gap, "crossing_times_s": times}


@nb.njit
def _floor_steps(max_steps, time_s, bodies, world, params, agent):
    """The compiled work alone: the agent's decision and the core's step (``advance``: the fused step, the exit
    test, the clock) per step, nothing else. Returns (steps done, agent-steps, clock, ok); ok False: the next step
    needs the staged path."""
    no_force = np.zeros((0, 2))
    named_bodies, named_world = Bodies(*bodies), World(*world)
    done = 0
    agent_steps = 0
    while done < max_steps:
        index = active_rows(named_bodies.active)
        if index.shape[0] == 0:
            break
        decision = decide(agent, named_bodies, named_world, index, time_s)
        if decision.status != AGENT_OK:
            return done, agent_steps, time_s, False
        inputs = StepInputs(decision.intents_m_s, decision.desired_heading_rad, True, no_force, False)[:]
        step = advance(bodies, world, params, inputs, index, decision.pairs, decision.pair_radius_m, time_s)
        if step[0] != FUSED_OK:
            return done, agent_steps, time_s, False
        time_s = step[-1]
        done += 1
        agent_steps += index.shape[0]
    return done, agent_steps, time_s, True


def run_floor(scenario, state, params):
    """The compiled work alone (``_floor_steps``), with the staged path for the steps it hands back."""
    from baselines.social_force import SocialForceAgent

    sim = scenario.make_simulator(state, params)
    agent = SocialForceAgent(scenario.navigation())
    compiled = compiled_agent(agent.compiled(state.n), sim.params)
    n_max = int(MAX_TIME_S / params.dt_s)
    agent_steps, wall = 0, 0.0
    while sim.step_count < n_max and state.active.any():
        t0 = time.perf_counter()
        k, a, clock, ok = _floor_steps(n_max - sim.step_count, sim.time_s, state.array_fields(), tuple(sim.world),
                                       tuple(sim.step_params), compiled)
        wall += time.perf_counter() - t0
        sim.advanced(k, clock)
        agent_steps += a
        if not ok:
            t0 = time.perf_counter()
            agent_steps += sim.active_index.shape[0]
            intents, heading = agent(sim)
            sim.step(intents, desired_heading_rad=heading)
            wall += time.perf_counter() - t0
    return {"model": "crowd_env compiled work alone", "agent_steps": int(agent_steps), "wall_s": wall,
            "rate": agent_steps / wall, "specific_flow": float("nan"), "evacuated": state.n - int(state.active.sum()),
            "n": state.n, "min_gap_m": float("nan")}


def run_rollout(scenario, state, params, agent_steps):
    """``run_scenario`` (compiled rollout, measurement included) timed whole; ``agent_steps`` from the
    step-by-step run of the same start (the same run to the last bit)."""
    from baselines.social_force import SocialForceAgent

    r = run_scenario(scenario, SocialForceAgent(scenario.navigation()), params, state=state, max_time_s=MAX_TIME_S)
    return {"model": "crowd_env compiled rollout", "agent_steps": agent_steps, "wall_s": r.wall_time_s,
            "rate": agent_steps / r.wall_time_s, "specific_flow": r.specific_flow_per_m_s, "evacuated": r.n_evacuated,
            "n": state.n, "min_gap_m": r.min_gap_m, "crossing_times_s": r.crossing_times_s}


def run_crowd_env(scenario, state, params):
    from baselines.social_force import SocialForceAgent
    from crowd_env.core import Simulator

    sim = Simulator(state, geometry=scenario.geometry, params=params)
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
    return _summary("crowd_env step by step", agent_steps, wall, counter, scenario.metadata["width_m"], state.n,
                    int(np.count_nonzero(state.active)), gap)


def run_jupedsim(scenario, state, model: str):
    """JuPedSim's ``model`` ("sfm" or "cfsm") on ``scenario`` with the pedestrians of ``state``, built by the
    RiMEA suite's JuPedSim backend (:func:`crowd_env.experiments.validation.rimea.jupedsim_backend.build_simulation`:
    the walkable area united with the exit, one exit stage, the same positions, radii 1 µm thinner,
    desired speeds and, for the social force model, masses; JuPedSim's defaults otherwise)."""
    from crowd_env.experiments.validation.rimea.jupedsim_backend import build_simulation

    setup = build_simulation(scenario, state, model, dt_s=0.01)
    sim, row_of, radius = setup.sim, setup.row_of, setup.radius_m
    name = "JuPedSim social force" if model == "sfm" else "JuPedSim collision-free speed"
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


def run_crowd_env_three_ways(scenario, params) -> list:
    """Step by step, compiled rollout and the compiled work alone on the same start (``params``)."""
    step = run_crowd_env(scenario, scenario.make_state(), params)
    roll = run_rollout(scenario, scenario.make_state(), params, step["agent_steps"])
    if not np.array_equal(roll.pop("crossing_times_s"), np.sort(step.pop("crossing_times_s"))):
        raise SystemExit("the compiled rollout and the step-by-step run differ: the benchmark compares unequal work")
    return [roll, step, run_floor(scenario, scenario.make_state(), params)]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=60)
    ap.add_argument("--width", type=float, default=1.0)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--preset", choices=sorted(PRESETS), default=DEFAULT_PRESET,
                    help="crowd_env's parameters and navigation clearance (default: the default preset)")
    args = ap.parse_args(argv)
    preset = get_preset(args.preset)
    params = preset.params()
    scenario_options = {"width_m": args.width, "n_pedestrians": args.n,
                        "navigation_clearance_m": preset.navigation_clearance_m}
    try:
        import jupedsim
    except ImportError:
        print("JuPedSim is not installed: pip install -e '.[bench]'")
        return 2
    # Warm-up (compiles or loads crowd_env's kernels, fills caches; loads JuPedSim) on the same case
    # (first seed), not reported.
    warm = make_scenario("seyfried_bottleneck", seed=0, **scenario_options)
    run_crowd_env_three_ways(warm, params)
    run_jupedsim(warm, warm.make_state(), "sfm")
    rows = []
    for seed in range(args.seeds):
        sc = make_scenario("seyfried_bottleneck", seed=seed, **scenario_options)
        rows.extend(run_crowd_env_three_ways(sc, params))
        rows.append(run_jupedsim(sc, sc.make_state(), "sfm"))
        rows.append(run_jupedsim(sc, sc.make_state(), "cfsm"))
    print(f"Seyfried bottleneck b = {args.width} m, N = {args.n}, h = 0.01 s, {args.seeds} seeds, one thread, "
          f"crowd_env preset {args.preset} (JuPedSim {jupedsim.__version__})")
    print(f"{'model':<30} {'agent-steps/s':>14} {'agent-steps':>12} {'wall s':>8} {'J_s 1/(m s)':>12} "
          f"{'evacuated':>10} {'min gap m':>10}")
    totals = {}
    for name in dict.fromkeys(r["model"] for r in rows):
        rs = [r for r in rows if r["model"] == name]
        steps = sum(r["agent_steps"] for r in rs)
        wall = sum(r["wall_s"] for r in rs)
        totals[name] = steps / wall
        flows = [r["specific_flow"] for r in rs if np.isfinite(r["specific_flow"])]
        gaps = [r["min_gap_m"] for r in rs if np.isfinite(r["min_gap_m"])]
        js = f"{np.mean(flows):.3f}" if flows else "(same run)"
        gap = f"{min(gaps):.1e}" if gaps else "(same run)"
        ev = f"{sum(r['evacuated'] for r in rs)}/{sum(r['n'] for r in rs)}"
        print(f"{name:<30} {steps / wall:>14,.0f} {steps:>12,} {wall:>8.2f} {js:>12} {ev:>10} {gap:>10}")
    ours = totals["crowd_env compiled rollout"]
    sfm, cfsm = totals["JuPedSim social force"], totals["JuPedSim collision-free speed"]
    print(f"ratio compiled rollout / JuPedSim social force:         {ours / sfm:.2f}x (target >= 4)")
    print(f"ratio compiled rollout / JuPedSim collision-free speed: {ours / cfsm:.2f}x (target >= 4)")
    print(f"ratio compiled work alone / compiled rollout:           "
          f"{totals['crowd_env compiled work alone'] / ours:.2f}x (target <= 1.5)")
    print(f"ratio step by step / JuPedSim social force:             {totals['crowd_env step by step'] / sfm:.2f}x")
    print("experiment (Seyfried 2009, N = 60): J_s = 1.90 1/(m s) at b = 1.0 m")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
