"""Overlaps under pressure (issue 20): the regression of the 1.53 mm overlap in the Seyfried jam.

The full high-pressure soak is ``scripts/soak.py`` (its pressure phase, ``crowd_env.reliability``).
"""
import pathlib

import numpy as np
from scipy.spatial import cKDTree

from baselines.social_force import SocialForceAgent
from crowd_env.core import ModelParams
from crowd_env.reliability import InvariantChecker
from crowd_env.scenarios import make_scenario

DATA = pathlib.Path(__file__).resolve().parent / "data"


def _all_pairs_overlap_m(position_m, radius_m):
    """Largest overlap (m) over all pairs, from a k-d tree independent of the simulator's cell grid."""
    pairs = cKDTree(position_m).query_pairs(2.0 * float(radius_m.max()), output_type="ndarray")
    if not pairs.size:
        return -np.inf
    d = np.linalg.norm(position_m[pairs[:, 0]] - position_m[pairs[:, 1]], axis=1)
    return float(np.max(radius_m[pairs[:, 0]] + radius_m[pairs[:, 1]] - d))


def test_seyfried_jam_seed2_overlap_stays_within_contact_tolerance():
    """``paper`` preset, Seyfried bottleneck b = 1.0 m, N = 180, corridor 7 m, channel 4 m, seed 2: the
    run's state after 620 steps (t = 6.20 s; 175 pedestrians left, a jam at the entrance), replayed for
    15 steps with the baseline agent. Step 627 (t = 6.27 s) overlapped two pedestrians by 1.53 mm: the
    dense projection LCP kept a polish that had drifted along the null space of a singular free set
    (tests/test_collision.py). Every step's largest overlap (all pairs and all walls) must stay within
    the contact tolerance; measured after the fix: 2.5e-11 m."""
    params = ModelParams()  # the paper preset
    scenario = make_scenario("seyfried_bottleneck", width_m=1.0, n_pedestrians=180, seed=2, corridor_width_m=7.0,
                             channel_length_m=4.0, navigation_clearance_m=0.0)
    state = scenario.make_state()
    saved = np.load(DATA / "seyfried_b1.0_n180_seed2_step620.npz")
    for name in ("position_m", "velocity_m_s", "heading_rad", "angular_velocity_rad_s", "active"):
        getattr(state, name)[...] = saved[name]
    sim = scenario.make_simulator(state, params)
    agent = SocialForceAgent(scenario.navigation())
    checker = InvariantChecker()
    worst = -np.inf
    for _ in range(15):
        intents, heading = agent(sim)
        result = sim.step(intents, desired_heading_rad=heading)
        checker.check(sim, scenario.geometry, result)
        idx = sim.active_index
        worst = max(worst, _all_pairs_overlap_m(state.position_m[idx], state.radius_m[idx]))
        wall_gap = scenario.geometry.distance_to_walls(state.position_m[idx]) - state.radius_m[idx]
        worst = max(worst, -float(wall_gap.min()))
    assert sim.step_count == 15 and checker.n_checked_steps == 15
    assert worst <= params.contact_tolerance_m, f"overlap {worst:.3g} m"
    assert worst < 1e-9  # round-off level: the projection holds every gap it knows
    assert checker.n_violations == 0, checker.examples
