"""Eikonal navigation field (Kabalan Eq. 11-13): accuracy, walls, exits, reachability."""
import numpy as np
import pytest
from shapely.geometry import box

from crowd_env.core.geometry import Geometry
from crowd_env.walking.navigation import NavigationField
from crowd_env.core.segments import GeometryError

H = 0.05
# L-shaped corridor: a horizontal leg [0, 6] x [0, 2] and a vertical leg [4, 6] x [2, 8], exit at the top.
L_SHAPE = [(0, 0), (6, 0), (6, 8), (4, 8), (4, 2), (0, 2)]
CORNER = np.array([4.0, 2.0])


@pytest.fixture(scope="module")
def rect():
    return Geometry(box(0, 0, 10, 4), exits=[box(10, 0, 11, 4)])


@pytest.fixture(scope="module")
def ell():
    return Geometry(L_SHAPE, exits=[box(4, 8, 6, 9)])


def far_leg_points(rng, n=3000):
    """Points of the horizontal leg with x < 3.9: they cannot see the exit, the geodesic goes via CORNER."""
    return np.column_stack([rng.uniform(0.01, 3.9, n), rng.uniform(0.01, 1.99, n)])


def angle_deg(a, b):
    return np.degrees(np.arccos(np.clip(np.sum(a * b, axis=1), -1.0, 1.0)))


def test_rectangle_direction_and_travel_time(rect):
    nf = NavigationField(rect, H)
    rng = np.random.default_rng(0)
    p = np.column_stack([rng.uniform(0.0, 10.0, 2000), rng.uniform(0.0, 4.0, 2000)])
    d, t = nf.sample(p)
    np.testing.assert_allclose(np.hypot(d[:, 0], d[:, 1]), 1.0)
    away = (p[:, 1] > 0.2) & (p[:, 1] < 3.8)
    assert angle_deg(d[away], np.array([[1.0, 0.0]])).max() < 1.0
    assert np.abs(t - (10.0 - p[:, 0])).max() < 1.5 * H


def test_l_shape_follows_the_shortest_path(ell):
    nf = NavigationField(ell, H)
    p = far_leg_points(np.random.default_rng(1))
    d, t = nf.sample(p)
    to_corner = CORNER - p
    dist = np.linalg.norm(to_corner, axis=1)
    geodesic = dist + 6.0  # to the corner, then straight up to y = 8
    assert np.abs(t - geodesic).max() < 1.5 * H
    ok = (dist > 0.5) & (p[:, 1] > 0.2) & (p[:, 1] < 1.8)
    err = angle_deg(d[ok], to_corner[ok] / dist[ok, None])
    assert err.max() < 3.0 and err.mean() < 1.0
    # in the vertical leg the exit is straight ahead
    q = np.column_stack([np.full(50, 5.0), np.linspace(2.5, 7.5, 50)])
    dq, tq = nf.sample(q)
    assert angle_deg(dq, np.array([[0.0, 1.0]])).max() < 1.0
    np.testing.assert_allclose(tq, 8.0 - q[:, 1], atol=1.5 * H)


def test_refining_the_grid_converges(ell):
    p = far_leg_points(np.random.default_rng(2), 2000)
    to_corner = CORNER - p
    dist = np.linalg.norm(to_corner, axis=1)
    t_err, a_err = [], []
    for h in (0.2, 0.1, 0.05):
        d, t = NavigationField(ell, h).sample(p)
        t_err.append(np.abs(t - dist - 6.0).max())
        a_err.append(angle_deg(d, to_corner / dist[:, None]).mean())
    assert t_err[0] > t_err[1] > t_err[2]
    assert a_err[0] > a_err[1] > a_err[2]


def funnel():
    """Corridor ending in a 0.8 m channel (reflex corners at x = 0, y = +-0.4), exit beyond it."""
    area = [(-4, -2), (0, -2), (0, -0.4), (2.8, -0.4), (2.8, -2), (4.8, -2), (4.8, 2), (2.8, 2), (2.8, 0.4),
            (0, 0.4), (0, 2), (-4, 2)]
    return Geometry(area, exits=[box(4.3, -2, 4.8, 2)])


def test_directions_near_walls_are_finite_and_do_not_enter_walls():
    g = funnel()
    nf = NavigationField(g, H)
    rng = np.random.default_rng(3)
    p = np.column_stack([rng.uniform(-4, 4.8, 200_000), rng.uniform(-2, 2, 200_000)])
    p = p[g.contains(p) & ~g.in_exit(p)]
    dist, normal = g.distance_to_walls(p, return_normal=True)
    near = dist < H  # within one grid cell of a wall
    p, normal = p[near], normal[near]
    d, t = nf.sample(p)
    assert np.all(np.isfinite(d)) and np.all(np.isfinite(t))
    np.testing.assert_allclose(np.hypot(d[:, 0], d[:, 1]), 1.0)
    corners = np.array([[0, 0.4], [0, -0.4], [2.8, 0.4], [2.8, -0.4]])
    from_corner = np.min(np.linalg.norm(p[:, None] - corners[None], axis=2), axis=1)
    away = from_corner > 3 * H
    # half a cell along e_d stays in the walkable area
    assert g.contains(p[away] + 0.5 * H * d[away]).all()
    # along walls parallel to the flow (channel sides) the direction is tangent
    channel = (p[:, 0] > 0.3) & (p[:, 0] < 2.5)
    assert np.abs(np.sum(d[channel] * normal[channel], axis=1)).max() < np.sin(np.radians(2.0))


def test_exit_interior_keeps_walking_through(rect):
    nf = NavigationField(rect, H)
    p = np.column_stack([np.linspace(10.02, 10.98, 20), np.full(20, 2.0)])
    d, t = nf.sample(p)
    np.testing.assert_allclose(t, 0.0, atol=1e-12)
    assert angle_deg(d, np.array([[1.0, 0.0]])).max() < 1.0


def test_points_outside_grid_or_not_finite_raise(rect):
    nf = NavigationField.cached(rect, H)
    with pytest.raises(GeometryError, match="point 1 .* outside the navigation grid"):
        nf.sample(np.array([[1.0, 1.0], [50.0, 1.0]]))
    with pytest.raises(GeometryError, match="outside the navigation grid"):
        nf.sample(np.array([[np.nan, 1.0]]))
    with pytest.raises(GeometryError, match="shape"):
        nf.sample(np.zeros((3, 3)))
    d, t = nf.sample(np.zeros((0, 2)))
    assert d.shape == (0, 2) and t.shape == (0,)


def test_unreachable_points_raise():
    # A wall across the room: the left part cannot reach the exit on the right.
    g = Geometry(box(0, 0, 10, 4), exits=[box(10, 0, 11, 4)], obstacles=[box(4, -1, 4.5, 5)])
    nf = NavigationField(g, H)
    pts = np.array([[8.0, 2.0], [2.0, 2.0]])
    d, t = nf.sample(pts)
    assert np.isfinite(t[0]) and np.isinf(t[1]) and np.isnan(d[1]).all()
    nf.check_reachable(pts[:1])
    with pytest.raises(GeometryError, match="pedestrian 1 at \\[2.0, 2.0\\] cannot reach any exit"):
        nf.check_reachable(pts, what="pedestrian")


def test_wall_slowdown_makes_walls_slower(rect):
    slow = NavigationField(rect, H, wall_slowdown=(0.5, 0.5))
    fast = NavigationField(rect, H)
    p = np.array([[2.0, 0.2], [2.0, 2.0]])
    t_slow = slow.travel_time(p)
    t_fast = fast.travel_time(p)
    assert t_slow[0] > t_slow[1] + 0.2  # close to the wall it pays to move away from it first
    assert t_slow[1] == pytest.approx(t_fast[1], abs=1.5 * H)
    with pytest.raises(GeometryError, match="speed_factor"):
        NavigationField(rect, H, wall_slowdown=(0.5, 0.0))
    with pytest.raises(GeometryError, match="distance_m"):
        NavigationField(rect, H, wall_slowdown=(-1.0, 0.5))


def test_exit_thinner_than_a_cell_raises():
    g = Geometry(box(0, 0, 10, 4), exits=[box(9.92, 0, 9.97, 4)])  # between two node columns
    with pytest.raises(GeometryError, match="exit"):
        NavigationField(g, 0.1)


def test_cache_by_content_and_bounded(rect):
    """Equal geometries (e.g. a scenario rebuilt per reset) share one field; other settings or another
    geometry get their own; the cache never holds more than ``cache_size`` fields."""
    a = NavigationField.cached(rect, H)
    assert NavigationField.cached(rect, H) is a
    assert NavigationField.cached(Geometry(box(0, 0, 10, 4), exits=[box(10, 0, 11, 4)]), H) is a
    assert NavigationField.cached(rect, 0.1) is not a
    assert NavigationField.cached(Geometry(box(0, 0, 10, 4.5), exits=[box(10, 0, 11, 4.5)]), H) is not a
    for k in range(NavigationField.cache_size + 3):
        NavigationField.cached(Geometry(box(0, 0, 5 + k, 4), exits=[box(5 + k, 0, 6 + k, 4)]), 0.2)
    assert len(NavigationField._cache) == NavigationField.cache_size
    p = np.random.default_rng(4).uniform([0, 0], [10, 4], (1000, 2))
    np.testing.assert_array_equal(NavigationField.cached(rect, H).sample(p)[0], a.sample(p)[0])


# -- configuration space (clearance_m): disk centres keep their radius from the walls ---------------
R = 0.23


def test_clearance_wraps_reflex_corners_at_the_radius():
    """With clearance r the geodesic from beside the entrance wraps the corner at distance r: e_d points
    into the part of the opening a disk centre can use (|y| <= 0.4 - r), not at the corner vertex."""
    g = funnel()
    point = NavigationField(g, H)
    disk = NavigationField(g, H, clearance_m=R)
    assert disk.clearance_m == R and point.clearance_m == 0.0
    # beside the entrance, in line with the corner: the point field aims straight at the wall beside
    # the opening, the configuration-space field turns towards the axis
    p = np.array([[-0.35, -0.35], [-0.35, 0.35], [-0.5, -0.3]])
    dp = point.direction(p)
    dd = disk.direction(p)
    assert np.all(np.abs(dp[:, 1]) < 0.2)
    assert dd[0, 1] > 0.3 and dd[1, 1] < -0.3 and dd[2, 1] > 0.2
    # following e_d from there, a disk centre enters the channel within |y| <= 0.4 - r
    for start in p:
        q = start.copy()
        for _ in range(400):
            q = q + 0.01 * disk.direction(q[None])[0]
            if q[0] >= 0.0:
                break
        assert q[0] >= 0.0 and abs(q[1]) <= 0.4 - R + 0.03
    # inside the channel's free band and far from walls the fields agree
    c = np.column_stack([np.linspace(0.5, 2.5, 20), np.zeros(20)])
    assert angle_deg(point.direction(c), disk.direction(c)).max() < 1.0


def test_clearance_travel_time_is_the_disk_geodesic(ell):
    """T with clearance c around the L-corner: tangent to the circle of radius c around CORNER, the arc,
    then straight to the exit, measured for a centre that keeps c from the walls."""
    c = 0.3
    nf = NavigationField(ell, H, clearance_m=c)
    p = np.array([[1.0, 1.0], [2.0, 0.6], [0.5, 1.5]])
    t = nf.travel_time(p)
    expected = []
    for x, y in p:
        v = CORNER - np.array([x, y])
        dist = np.linalg.norm(v)
        tangent = np.sqrt(dist ** 2 - c ** 2)
        # polar angle (about CORNER) of the tangent point below the corner, then the arc to angle 0, the
        # point (4 + c, 2) where the path turns straight up along x = 4 + c
        phi_p = np.arctan2(y - 2.0, x - 4.0) + np.arccos(c / dist)
        arc = c * abs(np.angle(np.exp(-1j * phi_p)))
        expected.append(tangent + arc + 6.0)
    np.testing.assert_allclose(t, expected, atol=2.0 * H)


def test_clearance_validation_and_cache(rect):
    with pytest.raises(GeometryError, match="clearance_m"):
        NavigationField(rect, H, clearance_m=-0.1)
    with pytest.raises(GeometryError, match="clearance_m"):
        NavigationField(rect, H, clearance_m=float("nan"))
    with pytest.raises(GeometryError, match="too narrow"):
        NavigationField(rect, H, clearance_m=2.5)  # the 4 m room has no point 2.5 m from both long walls
    a = NavigationField.cached(rect, H)
    b = NavigationField.cached(rect, H, clearance_m=R)
    assert b is not a and NavigationField.cached(rect, H, clearance_m=R) is b
    # centres touching a wall (inside the eroded band) still get finite directions along the wall
    d, t = b.sample(np.array([[5.0, R], [5.0, R - 1e-3], [5.0, 2.0]]))
    assert np.all(np.isfinite(d)) and np.all(np.isfinite(t))
    assert angle_deg(d, np.array([[1.0, 0.0]])).max() < 1.0


def test_clearance_blocks_openings_narrower_than_a_pedestrian():
    """A 0.4 m gap lets points through but not a disk of radius 0.23 m: its far side becomes unreachable."""
    g = Geometry(box(0, 0, 10, 4), exits=[box(10, 0, 11, 4)],
                 obstacles=[box(4, -1, 4.5, 1.8), box(4, 2.2, 4.5, 5)])
    assert np.isfinite(NavigationField(g, H).travel_time(np.array([[2.0, 2.0]])))[0]
    nf = NavigationField(g, H, clearance_m=R)
    with pytest.raises(GeometryError, match="cannot reach any exit"):
        nf.check_reachable(np.array([[2.0, 2.0]]), what="pedestrian")
