"""Per-pedestrian destinations (crowd_env.scenarios.corridor, the bidirectional corridor): each group leaves
through its own exit only, the other exit is floor, destination fields and observations, a single
destination runs as none, bad destinations. (The other scenario families: tests/scenarios/test_room.py,
test_corner.py, test_groups.py, test_polygon.py.)"""
import dataclasses

import numpy as np
import pytest
from shapely.geometry import box

from crowd_env.core import Simulator
from crowd_env.core.geometry import Geometry, GeometryError
from crowd_env.core.params import ParameterError
from crowd_env.envs import crowd_v0
from crowd_env.scenarios import Scenario, ScenarioError, make_scenario
from tests.scenarios.conftest import R, exit_of, run_baseline


# ---------------------------------------------------------------- bidirectional corridor, destinations
def test_corridor_groups_leave_through_their_own_exit_only():
    sc = make_scenario("corridor_bidirectional", n_per_direction=8, seed=1)
    assert sc.exit_names == ("west", "east") and sc.n_pedestrians == 16
    np.testing.assert_array_equal(sc.destination, [1] * 8 + [0] * 8)
    # eastbound start in the west (next to the west exit), westbound in the east
    assert sc.position_m[:8, 0].max() < 5.0 < sc.position_m[8:, 0].min()
    gaps = []
    sim = run_baseline(sc, 40.0, on_step=lambda s: gaps.append(s.min_gap_m()))
    assert not sim.state.active.any(), "everybody leaves"
    left_by = exit_of(sc, sim)
    np.testing.assert_array_equal(left_by, sc.destination)  # nobody took the other exit
    assert np.bincount(left_by, minlength=2).tolist() == [8, 8]
    assert min(gaps) > -1e-3
    # Contrast: without destinations the eastbound group, starting beside the west exit, leaves there.
    nearest = dataclasses.replace(sc, destination=None, heading_rad=None)
    sim = run_baseline(nearest, 5.0)
    assert np.count_nonzero(exit_of(nearest, sim)[:8] == 0) >= 4


def test_wrong_exit_is_floor_and_the_corridor_stays_closed():
    """A pedestrian bound east, pushed west into the west exit, does not leave and stays inside."""
    sc = make_scenario("corridor_bidirectional", n_per_direction=1, seed=0)
    sim = sc.make_simulator()
    intents = np.zeros((2, 2))
    intents[0] = (-2.0, 0.0)  # ped 0 (bound east) walks into the west exit and against the end wall
    for _ in range(400):
        sim.step(intents)
        assert sim.min_gap_m() > -1e-3
    x = sim.state.position_m[0, 0]
    assert sim.state.active[0] and sc.geometry.exit_index(sim.state.position_m[:1])[0] == 0
    assert R - 1e-3 <= x < 0.5  # inside the west exit strip, held by the end wall
    assert sim.state.active[1]


def test_destination_fields_and_observations():
    sc = make_scenario("corridor_bidirectional", n_per_direction=4, seed=0)
    nav = sc.navigation()
    assert nav.per_pedestrian and set(nav.fields) == {0, 1}
    assert nav.fields[1].exits == (1,) and nav.fields[0].exits == (0,)
    p = np.array([[2.0, 0.0], [2.0, 0.0]])
    e_d, t = nav.sample(p, [0, 4])  # ped 0 goes east, ped 4 west
    np.testing.assert_allclose(e_d, [[1.0, 0.0], [-1.0, 0.0]], atol=1e-6)
    assert t[0] == pytest.approx(7.5, abs=0.05) and t[1] == pytest.approx(1.5, abs=0.05)
    with pytest.raises(GeometryError, match="index"):
        nav.sample(p)
    env = crowd_v0.parallel_env(scenario="corridor_bidirectional", scenario_options={"n_per_direction": 4},
                                frame_skip=5, max_steps=20)
    obs, _ = env.reset(seed=0)
    ed = env.observation_layout["desired_direction"]
    assert obs["ped_0"][ed][0] > 0.9 and obs["ped_7"][ed][0] < -0.9
    assert env.destinations["ped_0"] == "east" and env.destinations["ped_7"] == "west"


def test_single_destination_is_bitwise_the_default():
    """destination = the only exit, or -1 (any exit), run exactly like no destination at all."""
    sc = make_scenario("room_pillar", n_pedestrians=12, seed=2)
    runs = []
    for dest in (None, np.zeros(12, int), np.full(12, -1)):
        variant = dataclasses.replace(sc, destination=dest, heading_rad=None)
        sim = run_baseline(variant, 3.0)
        runs.append((sim.state.position_m.copy(), sim.state.velocity_m_s.copy(), sim.state.active.copy()))
    for other in runs[1:]:
        for a, b in zip(runs[0], other):
            np.testing.assert_array_equal(a, b)


def test_bad_destinations_raise():
    sc = make_scenario("corridor_bidirectional", n_per_direction=2, seed=0)
    with pytest.raises(ScenarioError, match="unknown exit 'north'"):
        dataclasses.replace(sc, destination=["north"] * 4)
    with pytest.raises(ScenarioError, match=r"one entry per pedestrian \(4,\)"):
        dataclasses.replace(sc, destination=[0, 1])
    with pytest.raises(ScenarioError, match="index in"):
        dataclasses.replace(sc, destination=[0, 1, 2, 0])
    with pytest.raises(ScenarioError, match="exit_names must be distinct"):
        dataclasses.replace(sc, exit_names=("a", "a"))
    # exits open to the outside cannot be somebody's "other" exit
    geom = Geometry(box(0, 0, 10, 3), exits=[box(-0.5, 0, 0.0, 3), box(10, 0, 10.5, 3)])
    with pytest.raises(ScenarioError, match="exit 0 .* is open to the outside"):
        Scenario(geometry=geom, position_m=[[3.0, 1.5], [7.0, 1.5]], destination=[1, 0])
    ok = Scenario(geometry=geom, position_m=[[3.0, 1.5], [7.0, 1.5]], destination=[-1, -1])  # any exit: fine
    assert ok.navigation().per_pedestrian
    with pytest.raises(ParameterError, match="destination 5"):
        Simulator(sc.make_state(), geometry=sc.geometry, destination=[0, 1, 5, 0])
    with pytest.raises(ParameterError, match="need a geometry"):
        Simulator(sc.make_state(), walls=sc.geometry.walls, destination=[0, 1, 1, 0])
