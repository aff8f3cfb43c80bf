"""Overlaps under pressure (issue 20): the regression of the 1.53 mm overlap in the Seyfried jam, and the
soak's high-pressure phase reduced to a few seconds (the full one: ``crowd-soak``, its pressure
phase, ``crowd_env.experiments.validation.soak.pressure_soak``).
"""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from baselines.social_force import SocialForceAgent
from crowd_env.core import Simulator
from crowd_env.walking import ModelParams
from crowd_env.experiments.validation.soak import OVERLAP_TOLERANCE_M, PRESSURE_CASES, InvariantChecker, pressure_soak
from crowd_env.scenarios import make_scenario
from tests.conftest import DATA, load_script


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
    (tests/core/test_collision.py). Every step's largest overlap (all pairs and all walls) must stay within
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


# ---------------------------------------------------------------------------------------------- pressure soak
def test_reduced_pressure_soak():
    """The soak's high-pressure phase, reduced: 180k agent-steps in each case of PRESSURE_CASES (the jams
    of 220-400 pedestrians form within the 4-8 s this covers). No invariant is violated, every overlap
    stays at round-off (measured ≤ 3e-10 m; before the LCP fix room_paper reached 1.0e-4 m at t = 5.96 s
    and longer runs 1.26 mm), and it is high pressure: contacts carrying force join more than 100
    pedestrians (17 was the environment soak's largest cluster), and the pushing cases need the large
    (sparse / interior point) solvers."""
    r = pressure_soak(720_000)
    assert r["cases"] == [c.name for c in PRESSURE_CASES] and r["agent_steps"] >= 720_000
    assert r["violations"] == {} and r["n_violations"] == 0, "\n".join(r["examples"])
    assert r["max_overlap_m"] <= OVERLAP_TOLERANCE_M
    assert r["max_overlap_m"] < 1e-6
    assert r["max_contact_group"] > 200 and r["max_cluster_size"] > 100
    for name, case in r["per_case"].items():
        assert case["max_contact_group"] >= 80, name
        assert case["fallback_solves"] == 0, name
    assert r["per_case"]["room_push"]["large_solves"] > 0 and r["per_case"]["bottleneck_push"]["large_solves"] > 0
    assert r["max_impact_energy_increase_j"] <= 1e-9 and r["max_projection_energy_increase_j"] <= 1e-9


def _closest_pair(state):
    idx = np.flatnonzero(state.active)
    dist, near = cKDTree(state.position_m[idx]).query(state.position_m[idx], k=2)
    a = int(np.argmin(dist[:, 1]))
    return idx[a], idx[near[a, 1]]


def test_pressure_soak_fails_on_an_overlap(monkeypatch):
    """The pressure phase can fail: a simulator that lets two pedestrians overlap by 1.5 mm once (what the
    seed-2 jam did before the fix) is reported as a pedestrian overlap, by name, and the soak command
    exits 1; so does a negative tolerance (every step flagged). Unknown case names are refused."""
    real_step = Simulator.step

    def leaky_step(self, *args, **kwargs):
        result = real_step(self, *args, **kwargs)
        if self.step_count == 40:
            st = self.state
            i, j = _closest_pair(st)
            d = st.position_m[j] - st.position_m[i]
            st.position_m[j] = st.position_m[i] + d / np.linalg.norm(d) * (st.radius_m[i] + st.radius_m[j] - 1.5e-3)
        return result

    monkeypatch.setattr(Simulator, "step", leaky_step)
    r = pressure_soak(30_000, cases=["room_paper"])
    assert r["violations"].get("pedestrian_overlap", 0) >= 1, r
    assert r["max_overlap_m"] == pytest.approx(1.5e-3, rel=1e-3)
    assert any("pedestrian_overlap" in e and "pressure/room_paper" in e for e in r["examples"])
    soak = load_script("soak")
    assert soak.main(["--agent-steps", "0", "--pressure-agent-steps", "30000", "--pressure-cases", "room_paper"]) == 1
    monkeypatch.setattr(Simulator, "step", real_step)
    assert soak.main(["--agent-steps", "0", "--pressure-agent-steps", "2000", "--pressure-cases", "room_paper"]) == 0
    assert soak.main(["--agent-steps", "0", "--pressure-agent-steps", "2000", "--pressure-cases", "room_paper",
                      "--overlap-tolerance-m", "-1"]) == 1
    with pytest.raises(SystemExit, match="unknown pressure case"):
        soak.main(["--agent-steps", "0", "--pressure-agent-steps", "10", "--pressure-cases", "door_jam"])
    with pytest.raises(ValueError, match="unknown pressure case"):
        pressure_soak(10, cases=["door_jam"])
