#!/usr/bin/env python
"""Agent-steps/s of the compiled rollout for each walking model, in one run: the presets and the additions of
issue 36 (vision, time to collision) at the Seyfried bottleneck, N = 60, b = 1.0 m.

Each model runs the same seeds (compiled first, not timed); the figure is the best of ``--rounds`` rounds over
the seeds, and every ratio is to the default preset in the same run. Agent-steps are counted up to each
pedestrian's passage of the measurement line in the channel's middle (the run's crossing times; one who never
passes counts to the end), the same convention for every model: the ratios compare like with like, and the
absolute figures are close to, not equal to, ``compare_jupedsim.py``'s exact count. ::

    python benchmarks/preset_speed.py [--n 60] [--width 1.0] [--seeds 6] [--rounds 3]
"""
from __future__ import annotations

import argparse
import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import time  # noqa: E402

import numpy as np  # noqa: E402

from crowd_env.walking.presets import DEFAULT_PRESET, get_preset  # noqa: E402
from crowd_env.experiments.running.runner import run_scenario  # noqa: E402
from crowd_env.scenarios import make_scenario  # noqa: E402
from crowd_env.walking.agent import SocialForceAgent  # noqa: E402

# name -> (preset, changes): the presets and the walking additions on the default one
MODELS = {
    DEFAULT_PRESET: (DEFAULT_PRESET, {}),
    "paper": ("paper", {}),
    "vision": ("vision", {}),
    f"{DEFAULT_PRESET} + time to collision (k = 1.5)": (DEFAULT_PRESET, {"ttc_strength_m2_s2": 1.5}),
}


def _rate(params, clearance_m, n, width_m, seeds) -> tuple:
    """(agent-steps, wall s) of the compiled rollout over ``seeds``."""
    steps, wall = 0.0, 0.0
    for seed in seeds:
        sc = make_scenario("seyfried_bottleneck", width_m=width_m, n_pedestrians=n, seed=seed,
                           navigation_clearance_m=clearance_m)
        agent = SocialForceAgent(sc.navigation())
        t0 = time.perf_counter()
        r = run_scenario(sc, agent, params, max_time_s=300.0)
        wall += time.perf_counter() - t0
        present = np.concatenate([np.sort(r.crossing_times_s), np.full(n - r.crossing_times_s.size, r.simulated_time_s)])
        steps += float(np.sum(np.minimum(present, r.simulated_time_s))) / params.dt_s
    return steps, wall


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=60)
    ap.add_argument("--width", type=float, default=1.0)
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args(argv)
    seeds = range(args.seeds)
    rates = {}
    for name, (preset_name, changes) in MODELS.items():
        preset = get_preset(preset_name)
        params = preset.params(**changes)
        _rate(params, preset.navigation_clearance_m, args.n, args.width, seeds[:1])  # compile, not timed
        best = 0.0
        for _ in range(args.rounds):
            steps, wall = _rate(params, preset.navigation_clearance_m, args.n, args.width, seeds)
            best = max(best, steps / wall)
        rates[name] = best
    print(f"compiled rollout, Seyfried bottleneck b = {args.width} m, N = {args.n}, seeds 0-{args.seeds - 1}, "
          f"best of {args.rounds} rounds, one thread")
    print(f"{'model':<45} {'agent-steps/s':>14} {'ratio to ' + DEFAULT_PRESET:>22}")
    for name, rate in rates.items():
        print(f"{name:<45} {rate:>14,.0f} {rate / rates[DEFAULT_PRESET]:>21.2f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
