#!/usr/bin/env python
"""The calibrated agent and the simulator driven from Python: µs per ``agent(sim)`` and per ``Simulator.step``.

What a user's own loop, the PettingZoo environment's background pedestrians and ``compare_jupedsim.py``'s
"step by step" pay per step: Seyfried's bottleneck (b = 1 m, N = 60, seed 0, the default preset), the first
``--steps`` steps decided by :class:`~crowd_env.walking.agent.SocialForceAgent` (one compiled call per decision,
``python_decide``) and stepped by :meth:`~crowd_env.core.Simulator.step` (one compiled call, ``advance``), each
timed on its own; the best of ``--repeats`` runs from the same start. To compare two checkouts, run it on each,
alternately, in one sitting (it runs on checkouts from before the walking layer too, whose presets lived in
``crowd_env.core.presets``)::

    python benchmarks/agent_call_speed.py [--steps 1000] [--repeats 12]
"""
from __future__ import annotations

import argparse
import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import time  # noqa: E402

from crowd_env.core import Simulator  # noqa: E402
from crowd_env.scenarios import make_scenario  # noqa: E402
from crowd_env.walking.agent import SocialForceAgent  # noqa: E402

try:
    from crowd_env.walking.presets import DEFAULT_PRESET, get_preset  # noqa: E402
except ImportError:  # a checkout from before the walking layer (A/B runs)
    from crowd_env.core.presets import DEFAULT_PRESET, get_preset  # noqa: E402


def one_run(scenario, params, steps: int) -> tuple[float, float, int, int]:
    """(s in ``agent(sim)``, s in ``sim.step``, agent-steps, steps) over the first ``steps`` steps of ``scenario``
    (fewer when everybody left before)."""
    state = scenario.make_state()
    sim = Simulator(state, geometry=scenario.geometry, params=params)
    agent = SocialForceAgent(scenario.navigation())
    in_agent = in_step = 0.0
    agent_steps = done = 0
    for _ in range(steps):
        if not state.active.any():
            break
        agent_steps += int(sim.active_index.shape[0])
        t0 = time.perf_counter()
        intents, heading = agent(sim)
        t1 = time.perf_counter()
        sim.step(intents, desired_heading_rad=heading)
        t2 = time.perf_counter()
        in_agent += t1 - t0
        in_step += t2 - t1
        done += 1
    return in_agent, in_step, agent_steps, done


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=1000, help="steps per run (from the start)")
    ap.add_argument("--repeats", type=int, default=12, help="runs; the best is reported")
    args = ap.parse_args(argv)
    preset = get_preset(DEFAULT_PRESET)
    scenario = make_scenario("seyfried_bottleneck", seed=0, width_m=1.0, n_pedestrians=60,
                             navigation_clearance_m=preset.navigation_clearance_m)
    params = preset.params()
    one_run(scenario, params, 50)  # loads the compiled kernels
    runs = [one_run(scenario, params, args.steps) for _ in range(args.repeats)]
    best_agent = min(r[0] for r in runs)
    best_step = min(r[1] for r in runs)
    agent_steps, n_steps = runs[0][2], runs[0][3]
    print(f"Seyfried bottleneck b = 1.0 m, N = 60, preset {DEFAULT_PRESET}, first {n_steps} steps "
          f"({agent_steps:,} agent-steps), best of {args.repeats}, one thread")
    print(f"agent(sim)      {1e3 * best_agent:8.2f} ms   {1e6 * best_agent / n_steps:6.2f} µs per decision")
    print(f"Simulator.step  {1e3 * best_step:8.2f} ms   {1e6 * best_step / n_steps:6.2f} µs per step")
    print(f"both            {1e3 * (best_agent + best_step):8.2f} ms   "
          f"{agent_steps / (best_agent + best_step):,.0f} agent-steps/s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
