"""Scenarios from user polygons (crowd_env.scenarios.polygon): coordinates and WKT, bad inputs named, named
exits and destinations."""
import numpy as np
import pytest
from shapely.geometry import box

from crowd_env.core.geometry import GeometryError
from crowd_env.scenarios import ScenarioError, make_scenario, scenario_from_polygon
from tests.scenarios.conftest import exit_of, run_baseline


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


def test_polygon_door_narrower_than_a_pedestrian_names_the_exit_its_width_and_the_clearance():
    """Issue 37, item 7: a 0.3 m door raised fast marching's "phi contains no zero contour"."""
    room = [(0, 0), (10, 0), (10, 6), (0, 6)]
    left = [(0, 0), (4, 0), (4, 6), (0, 6)]
    with pytest.raises(GeometryError, match=r"exit 0, the door from \(10, 2\.9\) to \(10, 3\.2\), is 0\.3 m wide: a "
                                            r"pedestrian of radius 0\.23 m needs a door wider than 0\.46 m "
                                            r"\(2 x max\(radius_m, navigation_clearance_m\)"):
        make_scenario("polygon", walkable_area=room, exits=[[(10, 2.9), (10, 3.2)]], spawn_area=left, n_pedestrians=10)
    # a named exit is named; every narrow door is listed, a wide one is not
    with pytest.raises(GeometryError, match=r"exit 1 \('west'\), the door from .* is 0\.4 m wide: .* nobody can "
                                            r"reach it") as info:
        make_scenario("polygon", walkable_area=room, exits={"east": [(10, 2.5), (10, 3.5)], "west": [(0, 1), (0, 1.4)]},
                      spawn_area=left, n_pedestrians=10)
    assert "exit 0" not in str(info.value)
    # the clearance counts when it is larger than the radius
    with pytest.raises(GeometryError, match=r"0\.6 m wide: .* wider than 0\.8 m .* max\(0\.23, 0\.4\)"):
        make_scenario("polygon", walkable_area=room, exits=[[(10, 2.9), (10, 3.5)]], spawn_area=left,
                      n_pedestrians=10, navigation_clearance_m=0.4)
    # wider than a pedestrian but with no grid node between the jambs: the grid and its resolution are named
    with pytest.raises(GeometryError, match=r"navigation_resolution_m = 0\.05 m.*exit 0 0\.47 m wide.*finer "
                                            r"navigation_resolution_m"):
        make_scenario("polygon", walkable_area=room, exits=[[(10, 2.9), (10, 3.37)]], spawn_area=left, n_pedestrians=10)
    sc = make_scenario("polygon", walkable_area=room, exits=[[(10, 2.9), (10, 3.37)]], spawn_area=left,
                       n_pedestrians=10, navigation_resolution_m=0.01)
    assert sc.geometry.exits[0].bounds[1] == pytest.approx(2.9)
