"""The Seyfried bottleneck scenario (crowd_env.scenarios.bottleneck): geometry, valid starts filled section by
section, seeds, bad inputs, its navigation in configuration space and with wall slowdown."""
import numpy as np
import pytest
from shapely.geometry import box

from crowd_env.core.segments import GeometryError
from crowd_env.core.state import CrowdState, first_overlap, min_gap_m
from crowd_env.scenarios import ScenarioError, scenario_options, seyfried_bottleneck
from tests.scenarios.conftest import R

@pytest.fixture(scope="module")
def b60():
    return seyfried_bottleneck(width_m=1.0, n_pedestrians=60, seed=0)


def test_bottleneck_geometry_measures(b60):
    g = b60.geometry
    x0, y0, x1, y1 = g.walkable_area.bounds
    assert (y0, y1) == (-2.0, 2.0)  # 4 m corridor
    assert x0 == pytest.approx(-(2.24 + 3 * 1.515))
    walls = g.walls
    # channel side walls: y = +-b/2 from x = 0 to 2.8
    for y in (-0.5, 0.5):
        side = walls[(walls[:, 1] == y) & (walls[:, 3] == y)]
        assert side.shape[0] == 1
        assert sorted([side[0, 0], side[0, 2]]) == [0.0, 2.8]
    # entrance walls perpendicular to the flow at x = 0 from the channel to the corridor sides
    front = walls[(walls[:, 0] == 0) & (walls[:, 2] == 0)]
    assert sorted(np.abs(front[:, [1, 3]]).ravel().tolist()) == [0.5, 0.5, 2.0, 2.0]
    line = g.measurement_lines["bottleneck"]
    np.testing.assert_allclose(line, [[1.4, -0.5], [1.4, 0.5]])
    assert g.measurement_areas["inside"].equals(box(0, -0.5, 2.8, 0.5))
    fx0, fy0, fx1, fy1 = g.measurement_areas["front"].bounds
    assert fx1 <= 0.0 and (fx0 + fx1) / 2 == pytest.approx(-1.0) and fy1 - fy0 == pytest.approx(1.2)
    # the exit lies beyond the channel; walls do not close it
    assert g.in_exit([[4.5, 0.0]])[0] and not g.in_exit([[3.0, 0.0]])[0]
    assert not np.any((walls[:, 0] > 4.3 + 1e-9) | (walls[:, 2] > 4.3 + 1e-9))
    assert g.contains([[3.5, 1.8]])[0]  # open outflow area


def test_bottleneck_starts_valid(b60):
    pos = b60.position_m
    assert pos.shape == (60, 2)
    assert b60.geometry.contains(pos).all()
    assert (b60.geometry.distance_to_walls(pos) >= R - 1e-12).all()
    assert min_gap_m(pos, np.full(60, R)) >= 0.0
    assert first_overlap(pos, np.full(60, R)) is None
    # headings: the desired direction, towards the entrance
    assert np.all(np.cos(b60.heading_rad) > 0.5)
    state = b60.make_state()
    assert isinstance(state, CrowdState) and state.n == 60
    np.testing.assert_allclose(state.radius_m, R)


@pytest.mark.parametrize("n, counts", [(20, [20, 0, 0]), (40, [20, 20, 0]), (60, [20, 20, 20]), (50, [20, 20, 10])])
def test_bottleneck_sections_filled_in_order_at_3_3(n, counts):
    sc = seyfried_bottleneck(width_m=0.9, n_pedestrians=n, seed=5)
    x = sc.position_m[:, 0]
    edges = [-(2.24 + k * 1.515) for k in range(4)]
    got = [int(np.sum((x < edges[k]) & (x > edges[k + 1]))) for k in range(3)]
    assert got == counts
    assert sc.metadata["section_counts"] == counts
    assert 20 / (4.0 * 1.515) == pytest.approx(3.3, abs=0.01)
    # the nearest section spans 2.24-3.755 m upstream; disks lie inside their sections
    assert x.max() <= -2.24 - R + 1e-9
    if n == 50:  # the partial section is filled from its downstream side
        third = x[x < edges[2]]
        assert third.mean() > (edges[2] + edges[3]) / 2


def test_bottleneck_more_than_three_sections():
    sc = seyfried_bottleneck(n_pedestrians=70, seed=1)
    assert sc.metadata["section_counts"] == [20, 20, 20, 10]
    assert sc.geometry.walkable_area.bounds[0] == pytest.approx(-(2.24 + 4 * 1.515))


def test_bottleneck_seeds():
    a = seyfried_bottleneck(n_pedestrians=40, seed=7)
    b = seyfried_bottleneck(n_pedestrians=40, seed=7)
    c = seyfried_bottleneck(n_pedestrians=40, seed=8)
    np.testing.assert_array_equal(a.position_m, b.position_m)
    assert not np.allclose(a.position_m, c.position_m)
    np.testing.assert_array_equal(a.make_state().desired_speed_m_s, b.make_state().desired_speed_m_s)


@pytest.mark.parametrize("kwargs, error, match", [
    (dict(width_m=0.4), GeometryError, "not wider than a pedestrian"),
    (dict(width_m=0.46), GeometryError, "not wider than a pedestrian"),
    (dict(width_m=5.0), GeometryError, "larger than the corridor"),
    (dict(width_m=-1.0), ScenarioError, "width_m must be a positive"),
    (dict(channel_length_m=0.0), ScenarioError, "channel_length_m must be a positive"),
    (dict(initial_density_per_m2=float("nan")), ScenarioError, "initial_density_per_m2"),
    (dict(n_pedestrians=0), ScenarioError, "n_pedestrians must be an integer >= 1"),
    (dict(n_pedestrians=2.5), ScenarioError, "n_pedestrians"),
    (dict(n_pedestrians=60, n_sections=2), ScenarioError, "more pedestrians than fit"),
    (dict(initial_density_per_m2=5.0), ScenarioError, "more pedestrians than fit in the holding area"),
    (dict(exit_depth_m=3.0), GeometryError, "exit_depth_m"),
])
def test_bottleneck_bad_inputs(kwargs, error, match):
    with pytest.raises(error, match=match):
        seyfried_bottleneck(**kwargs)


def test_bottleneck_navigation_in_configuration_space():
    """navigation_clearance_m = r (the default, as in every scenario) solves the eikonal field for disk
    centres (walls inflated by the radius); 0 is the paper's literal point field. Beside the entrance the
    former steers into the usable opening, the latter straight at the wall beside it."""
    point = seyfried_bottleneck(width_m=1.0, n_pedestrians=20, seed=0, navigation_clearance_m=0.0)
    assert point.navigation_clearance_m == 0.0 and point.navigation().clearance_m == 0.0
    assert seyfried_bottleneck(width_m=1.0, n_pedestrians=20, seed=0).navigation_clearance_m == pytest.approx(R)
    sc = seyfried_bottleneck(width_m=1.0, n_pedestrians=20, seed=0, navigation_clearance_m=R)
    assert sc.metadata["navigation_clearance_m"] == pytest.approx(R)
    nav = sc.navigation()
    assert nav.clearance_m == pytest.approx(R) and sc.navigation() is nav
    beside = np.array([[-0.35, -0.4], [-0.35, 0.4]])
    d_cs, d_pt = nav.direction(beside), point.navigation().direction(beside)
    assert d_cs[0, 1] > 0.3 and d_cs[1, 1] < -0.3  # towards the axis: |y| <= b/2 - r in the channel
    assert np.all(np.abs(d_pt[:, 1]) < 0.1)  # straight at the wall beside the opening
    with pytest.raises(ScenarioError, match="navigation_clearance_m"):
        seyfried_bottleneck(width_m=1.0, n_pedestrians=20, navigation_clearance_m=-0.1)
    assert scenario_options("seyfried_bottleneck")["navigation_clearance_m"] is None  # None: the radius


def test_bottleneck_navigation_wall_slowdown():
    """navigation_wall_slowdown = (d, f) multiplies the eikonal wavefront speed by f within d of a wall
    (Eq. 11 with 0 < V < 1 there): travel times grow only where paths run near walls, by at most 1/f,
    and the option reaches the navigation field; None (the default, the paper's V = 1) changes nothing."""
    plain = seyfried_bottleneck(width_m=1.0, n_pedestrians=20, seed=0)
    slow = seyfried_bottleneck(width_m=1.0, n_pedestrians=20, seed=0, navigation_wall_slowdown=(0.5, 0.5))
    assert plain.wall_slowdown is None and plain.metadata["navigation_wall_slowdown"] is None
    assert slow.navigation().wall_slowdown == (0.5, 0.5) and slow.metadata["navigation_wall_slowdown"] == [0.5, 0.5]
    # on the channel's axis (0.5 m from both walls at b = 1.0 m) and at a wall of the holding corridor
    axis, near_wall = np.array([[0.2, 0.0]]), np.array([[-3.0, 1.9]])
    t_axis = slow.navigation().travel_time(axis)[0] / plain.navigation().travel_time(axis)[0]
    t_wall = slow.navigation().travel_time(near_wall)[0] / plain.navigation().travel_time(near_wall)[0]
    assert 1.0 <= t_axis < t_wall <= 2.0 + 1e-9
    for bad in ((0.5, 2.0), (0.0, 0.5), (0.5,), "x"):
        with pytest.raises(ScenarioError, match="navigation_wall_slowdown"):
            seyfried_bottleneck(width_m=1.0, n_pedestrians=20, navigation_wall_slowdown=bad)
