"""Scenarios in general (crowd_env.scenarios.scenario, .placement, .registry): pedestrian placement, validation that names the
pedestrian, hand links, and the registry."""
import numpy as np
import pytest
from shapely.geometry import Point, box

from crowd_env.core.geometry import Geometry
from crowd_env.core.segments import GeometryError
from crowd_env.core.state import first_overlap, min_gap_m
from crowd_env.scenarios import (Scenario, ScenarioError, list_scenarios, make_scenario, place_pedestrians,
                                 register_scenario, scenario_options)
from tests.scenarios.conftest import R


def test_place_pedestrians_dense_section():
    sec = box(-3.755, -2, -2.24, 2)
    rng = np.random.default_rng(0)
    pos = place_pedestrians(sec, 20, R, rng, density_per_m2=3.3)
    assert pos.shape == (20, 2)
    assert first_overlap(pos, np.full(20, R)) is None
    inner = sec.buffer(-R + 1e-9)
    assert all(inner.covers(Point(p)) for p in pos)
    again = place_pedestrians(sec, 20, R, np.random.default_rng(0), density_per_m2=3.3)
    np.testing.assert_array_equal(pos, again)
    by_density = place_pedestrians(sec, radius_m=R, rng=rng, density_per_m2=3.3)
    assert by_density.shape == (20, 2)


def test_place_pedestrians_other_shapes_and_limits():
    disk = Point(0, 0).buffer(2.0)
    pos = place_pedestrians(disk, 30, R, np.random.default_rng(1), min_gap_m=0.02)
    assert pos.shape == (30, 2)
    assert min_gap_m(pos, np.full(30, R)) >= 0.02 - 1e-12
    assert np.all(np.hypot(pos[:, 0], pos[:, 1]) <= 2.0 - R + 1e-9)
    with pytest.raises(ScenarioError, match=r"more pedestrians than fit in the holding area: 40 requested.*at most \d+"):
        place_pedestrians(box(0, 0, 2, 2), 40, R, np.random.default_rng(0))
    with pytest.raises(ScenarioError, match="too small"):
        place_pedestrians(box(0, 0, 0.3, 0.3), 1, R, np.random.default_rng(0))
    with pytest.raises(ScenarioError, match="exceed the requested density"):
        place_pedestrians(box(0, 0, 2, 2), 10, R, np.random.default_rng(0), density_per_m2=1.0)
    assert place_pedestrians(box(0, 0, 2, 2), 0, R).shape == (0, 2)


def simple_geometry():
    return Geometry(box(0, 0, 10, 4), exits=[box(10, 0, 11, 4)])


def test_scenario_validation_names_the_pedestrian():
    g = simple_geometry()
    ok = Scenario(g, [[1, 1], [2, 2]])
    np.testing.assert_allclose(ok.heading_rad, 0.0, atol=1e-6)  # towards the exit on the right
    with pytest.raises(ScenarioError, match="pedestrian 1 starts at \\[12.0, 2.0\\], outside the walkable area"):
        Scenario(g, [[1, 1], [12, 2]])
    with pytest.raises(ScenarioError, match="pedestrians 0 and 1 overlap"):
        Scenario(g, [[1, 1], [1.3, 1]])
    with pytest.raises(ScenarioError, match="pedestrian 0 .* overlaps a wall"):
        Scenario(g, [[0.1, 1]])
    with pytest.raises(ScenarioError, match="unknown pedestrian parameter"):
        Scenario(g, [[1, 1]], pedestrian_params={"speed": 1.0})
    with pytest.raises(ScenarioError, match="shape"):
        Scenario(g, [1, 1, 1])
    walled = Geometry(box(0, 0, 10, 4), exits=[box(10, 0, 11, 4)], obstacles=[box(4, -1, 4.5, 5)])
    with pytest.raises(GeometryError, match="pedestrian 1 .* cannot reach any exit"):
        Scenario(walled, [[8, 2], [2, 2]])
    inexit = Geometry(box(0, 0, 10, 4), exits=[box(9, 0, 10, 4)])
    with pytest.raises(ScenarioError, match="inside an exit"):
        Scenario(inexit, [[9.5, 2]])


def test_scenario_links_and_state():
    g = simple_geometry()
    sc = Scenario(g, [[1, 1], [1, 1.5]], links=[[0, 1]], pedestrian_params={"radius_m": [0.2, 0.22]})
    # heading +x: pedestrian 1 is on 0's left, so 0's left shoulder (0, +r0) and 1's right one (0, -r1)
    np.testing.assert_allclose(sc.link_offsets_m, [[0, 0.2, 0, -0.22]], atol=1e-9)
    state = sc.make_state(np.random.default_rng(0))
    assert state.links.tolist() == [[0, 1]]
    with pytest.raises(ScenarioError, match="joins pedestrian 0 to itself"):
        Scenario(g, [[1, 1], [1, 1.5]], links=[[0, 0]])


@pytest.fixture
def scratch_registry(monkeypatch):
    """The scenario registry as it is, restored after the test: a scenario a test registers does not leak
    into later tests (the soak covers every registered scenario, and would soak it too)."""
    from crowd_env.scenarios import registry

    monkeypatch.setattr(registry, "_REGISTRY", dict(registry._REGISTRY))
    monkeypatch.setattr(registry, "_ALIASES", dict(registry._ALIASES))


def test_registry(scratch_registry):
    assert {"seyfried_bottleneck", "bottleneck"} <= set(list_scenarios())
    sc = make_scenario("bottleneck", width_m=0.8, n_pedestrians=20, seed=3)
    assert sc.n_pedestrians == 20 and sc.metadata["width_m"] == 0.8
    assert scenario_options("seyfried_bottleneck")["width_m"] == 1.0
    with pytest.raises(ScenarioError, match="unknown scenario 'nope'; known: .*seyfried_bottleneck"):
        make_scenario("nope")
    with pytest.raises(ScenarioError, match=r"unknown option\(s\) \['widht_m'\].*known: .*width_m"):
        make_scenario("bottleneck", widht_m=1.0)
    with pytest.raises(ScenarioError, match="already registered"):
        register_scenario("bottleneck", lambda: None)

    def tiny(seed=0):
        return Scenario(simple_geometry(), [[1.0, 1.0]], seed=seed)

    register_scenario("test_tiny", tiny, overwrite=True)
    assert make_scenario("test_tiny").n_pedestrians == 1


def test_a_scenario_registered_by_a_test_is_gone_after_it():
    """Runs after test_registry in this module's order: its scenario did not stay registered."""
    assert "test_tiny" not in list_scenarios()


def test_new_scenarios_are_registered_with_seeds():
    for name in ("corridor_bidirectional", "room_pillar", "corner_90", "bottleneck_groups", "polygon"):
        assert name in list_scenarios()
        assert "seed" in scenario_options(name)


@pytest.mark.parametrize("seed", ["abc", 1.5, -1, True])
def test_make_scenario_refuses_a_bad_seed_naming_it(seed):
    """Issue 37, item 8: these raised numpy's messages, which do not name the seed (True was taken as 1)."""
    with pytest.raises(ScenarioError, match=r"^seed must be None or an integer >= 0, got "):
        make_scenario("seyfried_bottleneck", n_pedestrians=10, seed=seed)
    with pytest.raises(ScenarioError, match=r"^seed must be None or an integer >= 0"):
        make_scenario("polygon", walkable_area=[(0, 0), (8, 0), (8, 6), (0, 6)], exits=[[(8, 2.5), (8, 3.5)]],
                      spawn_area=[(0, 0), (3, 0), (3, 6), (0, 6)], n_pedestrians=5, seed=seed)


def test_make_scenario_seed_as_numpy_integer_is_the_same_scenario():
    a = make_scenario("seyfried_bottleneck", n_pedestrians=10, seed=np.int64(4))
    b = make_scenario("seyfried_bottleneck", n_pedestrians=10, seed=4)
    np.testing.assert_array_equal(a.position_m, b.position_m)
    assert type(a.seed) is int
