"""The scenario families beyond the bottleneck: per-pedestrian destinations (bidirectional corridor), the
pillar room, the 90° corner, hand-holding groups, user polygons; their Gymnasium/PettingZoo/evaluation use."""
import dataclasses
import warnings

import gymnasium
import numpy as np
import pytest
import shapely
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import parallel_api_test
from shapely.geometry import box

import crowd_env  # noqa: F401  (registers the gymnasium ids)
from baselines import SocialForceAgent
from baselines.reference_policies import as_policy
from crowd_env.experiments.evaluation import ScenarioSpec, evaluate, run_episode
from crowd_env.core import ModelParams, Simulator
from crowd_env.core.contacts import link_geometry
from crowd_env.core.geometry import Geometry, GeometryError
from crowd_env.core.params import ParameterError
from crowd_env.envs import crowd_v0
from crowd_env.scenarios import (Scenario, ScenarioError, list_scenarios, make_scenario, scenario_from_polygon,
                                 scenario_options)

R = 0.23


def run_baseline(scenario, max_time_s, params=None, on_step=None):
    """Everyone on the calibrated agent until all left or ``max_time_s``; returns the simulator."""
    sim = scenario.make_simulator(params=ModelParams() if params is None else params)
    agent = SocialForceAgent(scenario.navigation())
    while sim.state.active.any() and sim.time_s < max_time_s:
        intents, heading = agent(sim)
        sim.step(intents, desired_heading_rad=heading)
        if on_step is not None:
            on_step(sim)
    return sim


def exit_of(scenario, sim):
    """Index of the exit each pedestrian left through (positions freeze where they left), -1 if still in."""
    k = scenario.geometry.exit_index(sim.state.position_m)
    return np.where(sim.state.active, -1, k)


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


# ---------------------------------------------------------------- room with a pillar
@pytest.mark.parametrize("shape", ["circle", "square"])
def test_room_pillar_evacuates_around_the_pillar(shape):
    sc = make_scenario("room_pillar", n_pedestrians=20, seed=0, pillar_shape=shape)
    pillar = shapely.from_wkt(sc.metadata["pillar"])
    assert len(sc.geometry.walkable_area.interiors) == 1  # the pillar is a hole
    assert sc.geometry.walkable_area.intersection(pillar).area == pytest.approx(0.0, abs=1e-9)
    # in front of the door, on its axis
    assert pillar.centroid.x == pytest.approx(8.0 - 1.2) and pillar.centroid.y == pytest.approx(0.0)
    worst = [np.inf]

    def clearance(sim):
        pos = sim.state.position_m[sim.state.active]
        if pos.size:
            worst[0] = min(worst[0], float(shapely.distance(pillar, shapely.points(pos)).min()))

    sim = run_baseline(sc, 45.0, on_step=clearance)
    assert not sim.state.active.any()
    assert worst[0] >= R - 1e-3  # nobody overlaps the pillar
    assert worst[0] < R + 0.3  # and people did pass close to it


def test_room_pillar_bad_inputs():
    with pytest.raises(GeometryError, match="pillar .* must lie inside the room"):
        make_scenario("room_pillar", pillar_distance_m=0.1)
    with pytest.raises(ScenarioError, match="pillar_shape"):
        make_scenario("room_pillar", pillar_shape="hexagon")
    with pytest.raises(ScenarioError, match="spawn_depth_m .* reaches the pillar"):
        make_scenario("room_pillar", spawn_depth_m=6.8)
    with pytest.raises(GeometryError, match="door width"):
        make_scenario("room_pillar", door_width_m=0.4)


# ---------------------------------------------------------------- 90° corner
def test_corner_pedestrians_turn_the_corner():
    sc = make_scenario("corner_90", n_pedestrians=20, seed=0)
    assert sc.position_m[:, 0].max() < 3.0 and sc.position_m[:, 1].max() < 2.0  # start in the first leg
    gaps = []
    sim = run_baseline(sc, 40.0, on_step=lambda s: gaps.append(s.min_gap_m()))
    assert not sim.state.active.any()
    assert min(gaps) > -1e-3  # nobody overlaps a wall (or another) on the way
    end = sim.state.position_m
    assert np.all(end[:, 1] >= 6.0) and np.all((end[:, 0] > 6.0) & (end[:, 0] < 8.0))  # left at the second leg's end
    with pytest.raises(ScenarioError, match="leg2_length_m"):
        make_scenario("corner_90", leg2_length_m=1.5)


# ---------------------------------------------------------------- hand-holding groups
def shoulder_distance(st):
    d, _, _ = link_geometry(st.position_m, st.heading_rad, st.links, st.link_offsets_m)
    return np.hypot(d[:, 0], d[:, 1])


def test_groups_are_placed_side_by_side():
    # the point field (the placement's tolerance below is stated for it)
    sc = make_scenario("bottleneck_groups", n_pedestrians=30, n_pairs=3, n_triples=2, seed=4, hand_gap_m=0.05,
                       navigation_clearance_m=0.0)
    groups = sc.metadata["groups"]
    assert sorted(len(g) for g in groups) == [2, 2, 2, 3, 3]
    assert sc.links.shape == (3 * 1 + 2 * 2, 2)
    e_d = sc.navigation().direction(sc.position_m)
    for g in groups:
        p = sc.position_m[g]
        step = np.diff(p, axis=0)
        np.testing.assert_allclose(np.hypot(step[:, 0], step[:, 1]), 2 * R + 0.05, atol=1e-9)  # adjacent
        across = np.abs(step @ e_d[g[0]]) / np.hypot(step[:, 0], step[:, 1])
        assert np.all(across < np.sin(np.deg2rad(20.0)) + 1e-9)  # side by side across the walking direction
    assert len({i for g in groups for i in g}) == 12  # disjoint
    sc.validate()  # no overlap, inside, reachable


def test_groups_stay_linked_and_everyone_exits():
    sc = make_scenario("bottleneck_groups", n_pedestrians=30, n_pairs=3, n_triples=2, seed=4)

    def run(params):
        worst = np.zeros(sc.links.shape[0])

        def track(sim):
            st = sim.state
            both = st.active[st.links[:, 0]] & st.active[st.links[:, 1]]
            np.maximum(worst, np.where(both, shoulder_distance(st), 0.0), out=worst)

        sim = run_baseline(sc, 40.0, params=params, on_step=track)
        return sim, worst

    start = shoulder_distance(sc.make_state())
    sim, worst = run(ModelParams())
    assert not sim.state.active.any()
    # Hands held (K_v, Eq. 2): shoulders stay within 0.3 m of their start distance, even where a triple
    # (1.5 m abreast) squeezes through the 1.2 m bottleneck; without the link they drift metres apart.
    assert np.all(worst <= start + 0.3)
    _, free_worst = run(ModelParams(link_dissipation_kg_per_m2=0.0))
    assert np.count_nonzero(free_worst > start + 0.5) >= 3


def test_group_bad_inputs():
    with pytest.raises(ScenarioError, match="0 pairs and 7 triples need 21 pedestrians, but the crowd has 20"):
        make_scenario("bottleneck_groups", n_pedestrians=20, n_pairs=0, n_triples=7)
    with pytest.raises(ScenarioError, match="no room to form group"):
        make_scenario("bottleneck_groups", n_pedestrians=20, n_pairs=0, n_triples=6, hand_gap_m=0.3)
    with pytest.raises(ScenarioError, match="unknown option"):
        make_scenario("bottleneck_groups", n_quads=1)
    with pytest.raises(ScenarioError, match="n_pairs"):
        make_scenario("bottleneck_groups", n_pairs=-1)


# ---------------------------------------------------------------- user polygons
ROOM = [(0, 0), (8, 0), (8, 6), (0, 6)]
HOLE = [(4, 2.5), (5, 2.5), (5, 3.5), (4, 3.5)]
SPAWN = [(0, 0), (3, 0), (3, 6), (0, 6)]
ROOM_WKT = "POLYGON ((0 0, 8 0, 8 6, 0 6, 0 0), (4 2.5, 5 2.5, 5 3.5, 4 3.5, 4 2.5))"


def polygon(**kw):
    opts = {"walkable_area": ROOM, "holes": [HOLE], "exits": [[(8, 2.5), (8, 3.5)]], "spawn_area": SPAWN,
            "n_pedestrians": 12, "seed": 3}
    return make_scenario("polygon", **{**opts, **kw})


def test_polygon_from_coordinates_and_wkt_are_identical():
    a = polygon()
    b = make_scenario("polygon", walkable_area=ROOM_WKT, exits=["LINESTRING (8 2.5, 8 3.5)"],
                      spawn_area="POLYGON ((0 0, 3 0, 3 6, 0 6, 0 0))", n_pedestrians=12, seed=3)
    c = polygon(walkable_area=ROOM[::-1], holes=[HOLE[::-1]], exits=[[(8, 3.5), (8, 2.5)]])  # other orientation
    for other in (b, c):
        assert a.geometry.walkable_area.equals_exact(other.geometry.walkable_area, 0.0)
        np.testing.assert_array_equal(a.geometry.walls, other.geometry.walls)
        assert all(x.equals_exact(y, 0.0) for x, y in zip(a.geometry.exits, other.geometry.exits))
        np.testing.assert_array_equal(a.position_m, other.position_m)
    assert a.geometry.exits[0].equals(box(8, 2.5, 8.5, 3.5))  # the door's exit strip lies behind the door
    sim = run_baseline(a, 30.0)
    assert not sim.state.active.any()


@pytest.mark.parametrize("kw, error, match", [
    ({"walkable_area": [(0, 0), (8, 6), (8, 0), (0, 6)]}, GeometryError, "not a valid polygon: Self-intersection"),
    ({"walkable_area": "POLYGON ((0 0, 8 6, 8 0, 0 6, 0 0))", "holes": []}, GeometryError, "Self-intersection"),
    ({"holes": [[(4, 2), (5, 3), (5, 2), (4, 3)]]}, GeometryError, "Self-intersection"),
    ({"walkable_area": "POLYGON ((0 0, 8 6"}, GeometryError, "cannot parse WKT"),
    ({"exits": []}, GeometryError, "no exit"),
    ({"exits": None}, GeometryError, "no exit"),
    ({"exits": [[(20, 0), (21, 0), (21, 1), (20, 1)]]}, GeometryError, "exit 0 does not touch the walkable area"),
    ({"exits": [[(7, 2.5), (7, 3.5)]]}, ScenarioError, "does not lie on the boundary"),
    ({"walkable_area": [(0, 0), (8, 0), (8, 6), (4.2, 6), (4.2, 0.3), (3.8, 0.3), (3.8, 6), (0, 6)], "holes": []},
     ScenarioError, "exit 0 is unreachable from the spawn area"),
    ({"spawn_area": [(-1, 0), (3, 0), (3, 6), (-1, 6)]}, ScenarioError, "spawn area must lie inside the walkable area"),
    ({"spawn_area": [(3.5, 2), (5.5, 2), (5.5, 4), (3.5, 4)]}, ScenarioError, "spawn area must lie inside"),
    ({"n_pedestrians": 200}, ScenarioError, "more pedestrians than fit .* at most 78"),
    ({"walkable_area": [(0, 0), (1, 1)]}, GeometryError, "at least 3 vertices"),
])
def test_polygon_bad_inputs_name_the_problem(kw, error, match):
    with pytest.raises(error, match=match):
        polygon(**kw)


def test_polygon_named_exits_and_destinations():
    """Two closed exits named by a dict, one group bound for each."""
    exits = {"left": [(0.01, 0.01), (0.5, 0.01), (0.5, 2.99), (0.01, 2.99)],
             "right": [(9.5, 0.01), (9.99, 0.01), (9.99, 2.99), (9.5, 2.99)]}
    sc = scenario_from_polygon([(0, 0), (10, 0), (10, 3), (0, 3)], exits, [(4, 0), (6, 0), (6, 3), (4, 3)], 6,
                               destination=["left", "right"] * 3, seed=0)
    assert sc.exit_names == ("left", "right")
    sim = run_baseline(sc, 20.0)
    np.testing.assert_array_equal(exit_of(sc, sim), [0, 1] * 3)


# ---------------------------------------------------------------- registry, Gymnasium, PettingZoo, evaluation
def test_new_scenarios_are_registered_with_seeds():
    for name in ("corridor_bidirectional", "room_pillar", "corner_90", "bottleneck_groups", "polygon"):
        assert name in list_scenarios()
        assert "seed" in scenario_options(name)


SMALL_OPTIONS = {"crowd_env/CorridorBidirectional-v0": {"n_per_direction": 3},
                 "crowd_env/RoomPillar-v0": {"n_pedestrians": 6},
                 "crowd_env/Corner90-v0": {"n_pedestrians": 6},
                 "crowd_env/BottleneckGroups-v0": {"n_pedestrians": 12, "n_pairs": 2, "n_triples": 1},
                 "crowd_env/Custom-v0": None}


@pytest.mark.parametrize("env_id", sorted(SMALL_OPTIONS))
def test_gymnasium_make_and_check_env_new_ids(env_id):
    assert env_id in gymnasium.registry
    kwargs = {"max_steps": 5}
    if SMALL_OPTIONS[env_id] is not None:
        kwargs["scenario_options"] = SMALL_OPTIONS[env_id]
    env = gymnasium.make(env_id, **kwargs)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # gymnasium's advice on non-normalised Boxes
        check_env(env.unwrapped, skip_render_check=True)
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    obs, r, term, trunc, _ = env.step(env.action_space.sample())
    assert env.observation_space.contains(obs) and np.isfinite(r)
    env.close()


def test_parallel_api_on_the_bidirectional_corridor():
    env = crowd_v0.parallel_env(scenario="corridor_bidirectional", scenario_options={"n_per_direction": 4},
                                frame_skip=5, max_steps=40)
    parallel_api_test(env, num_cycles=60)
    env = crowd_v0.parallel_env(scenario="bottleneck_groups", controlled=3, frame_skip=5, max_steps=10,
                                scenario_options={"n_pedestrians": 12, "n_pairs": 2, "n_triples": 1})
    parallel_api_test(env, num_cycles=10)


def test_evaluation_harness_takes_scenario_name_and_options():
    res = run_episode(as_policy("baseline"), ScenarioSpec("corridor_bidirectional", {"n_per_direction": 3}), seed=0,
                      max_time_s=30.0)
    assert res.scenario == "corridor_bidirectional(n_per_direction=3)"
    assert res.n_evacuated == res.n_pedestrians == 6 and np.isfinite(res.evacuation_time_s)
    assert res.min_gap_m > -1e-3
    assert np.isfinite(res.flow_per_s) and np.isnan(res.specific_flow_per_m_s)  # "middle" line, no width
    (room,) = evaluate(["baseline"], [("room_pillar", {"n_pedestrians": 8})], seeds=[1], max_time_s=30.0,
                       progress=None, resolve=as_policy)
    assert room.n_evacuated == 8 and room.specific_flow_per_m_s > 0  # J_s at the "door" line, b = door width
