"""Geometry: walls from walkable boundary minus exits, queries, validation, rasterisation."""
import numpy as np
import pytest
import shapely
from shapely.geometry import LineString, MultiLineString, Polygon, box

from crowd_env.core.geometry import Geometry
from crowd_env.core.segments import GeometryError

RECT = [(0, 0), (10, 0), (10, 4), (0, 4)]


def wall_length(g):
    w = g.walls
    return float(np.hypot(w[:, 2] - w[:, 0], w[:, 3] - w[:, 1]).sum())


def test_walls_skip_exit_inside_the_area():
    g = Geometry.from_coordinates(RECT, exits=[[(9, 0), (10, 0), (10, 4), (9, 4)]])
    assert g.walls.shape[1] == 4
    # bottom 0..9, left side, top 9..0: the exit's edges are open
    assert wall_length(g) == pytest.approx(9 + 9 + 4)
    assert np.all(g.walls[:, [0, 2]] <= 9 + 1e-12)


def test_walls_skip_exit_sharing_an_edge():
    g = Geometry(box(0, 0, 10, 4), exits=[box(10, 0, 11, 4)])
    assert wall_length(g) == pytest.approx(24.0)
    assert not np.any((g.walls[:, 0] == 10) & (g.walls[:, 2] == 10))
    assert g.bounds == (0.0, 0.0, 11.0, 4.0)


def test_obstacles_holes_and_subtracted_polygons_give_walls():
    hole = [(4, 1), (5, 1), (5, 2), (4, 2)]
    g1 = Geometry(Polygon(RECT, [hole]), exits=[box(10, 0, 11, 4)])
    g2 = Geometry(RECT, exits=[box(10, 0, 11, 4)], obstacles=[hole])
    for g in (g1, g2):
        assert wall_length(g) == pytest.approx(24.0 + 4.0)
        assert not g.contains([[4.5, 1.5]])[0]
        assert g.contains([[3.0, 1.5]])[0]
        assert g.walkable_area.area == pytest.approx(39.0)


def test_contains_in_exit_vectorised():
    g = Geometry(RECT, exits=[[(9, 0), (10, 0), (10, 4), (9, 4)]])
    pts = np.array([[1, 1], [9.5, 2], [11, 2], [5, -1]])
    assert g.contains(pts).tolist() == [True, True, False, False]
    assert g.in_exit(pts).tolist() == [False, True, False, False]
    assert g.exit_index(pts).tolist() == [-1, 0, -1, -1]
    assert g.contains(np.zeros((0, 2))).shape == (0,)


def test_distance_to_walls_matches_shapely():
    g = Geometry(RECT, exits=[box(10, 0, 11, 4)], obstacles=[box(4, 1, 5, 2)])
    rng = np.random.default_rng(1)
    pts = np.column_stack([rng.uniform(0, 10, 300), rng.uniform(0, 4, 300)])
    d, n = g.distance_to_walls(pts, return_normal=True)
    lines = MultiLineString([LineString([w[:2], w[2:]]) for w in g.walls])
    ref = shapely.distance(lines, shapely.points(pts))
    np.testing.assert_allclose(d, ref, atol=1e-12)
    np.testing.assert_allclose(np.hypot(n[:, 0], n[:, 1]), 1.0)
    # the normal points from the closest wall point to the point
    assert np.all(np.isfinite(n))


def test_wkt_and_coordinates_agree_and_lines():
    lines = {"mid": [(5, 0), (5, 4)]}
    a = Geometry.from_wkt(box(0, 0, 10, 4).wkt, exits=[box(10, 0, 11, 4).wkt], measurement_lines=lines)
    b = Geometry.from_coordinates(RECT, exits=[[(10, 0), (11, 0), (11, 4), (10, 4)]], measurement_lines=lines)
    assert a.walkable_area.equals(b.walkable_area)
    assert wall_length(a) == pytest.approx(wall_length(b))
    assert a.measurement_lines["mid"].shape == (2, 2)
    with pytest.raises((TypeError, ValueError)):
        a.measurement_lines["mid"][0, 0] = 1.0
    with pytest.raises(TypeError):
        a.measurement_lines["new"] = np.zeros((2, 2))
    with pytest.raises(ValueError):
        a.walls[0, 0] = 3.0


@pytest.mark.parametrize("kwargs, match", [
    (dict(walkable_area=[(0, 0), (2, 2), (2, 0), (0, 2)], exits=[box(2, 0, 3, 2)]), "Self-intersection"),
    (dict(walkable_area=RECT, exits=[]), "no exit"),
    (dict(walkable_area=RECT, exits=[box(20, 0, 21, 4)]), "exit 0 does not touch"),
    (dict(walkable_area=[(0, 0), (1, 0), (2, 0)], exits=[box(2, 0, 3, 2)]), "empty"),
    (dict(walkable_area=Polygon(), exits=[box(2, 0, 3, 2)]), "empty"),
    (dict(walkable_area="POLYGON ((0 0, 1", exits=[box(2, 0, 3, 2)]), "WKT"),
    (dict(walkable_area=RECT, exits=[box(10, 0, 11, 4)], obstacles=[box(-1, -1, 12, 5)]), "empty"),
    (dict(walkable_area=RECT, exits=[box(10, 0, 11, 4)], measurement_lines={"x": [(20, 0), (20, 4)]}),
     "does not cross"),
    (dict(walkable_area=RECT, exits=[box(10, 0, 11, 4)], measurement_lines={"x": [(1, 1), (1, 1)]}), "zero length"),
    (dict(walkable_area=RECT, exits=[box(10, 0, 11, 4)], measurement_areas={"a": box(20, 0, 21, 1)}),
     "does not overlap"),
])
def test_validation_names_the_problem(kwargs, match):
    with pytest.raises(GeometryError, match=match):
        Geometry(**kwargs)


def test_exit_touching_at_a_single_point_is_rejected():
    with pytest.raises(GeometryError, match="does not touch"):
        Geometry(RECT, exits=[box(10, 4, 11, 5)])


def test_rasterize_covers_bounds():
    g = Geometry(RECT, exits=[box(10, 0, 11, 4)])
    r = g.rasterize(0.1)
    x, y = r.x_m, r.y_m
    assert x[0] < 0 and x[-1] > 11 and y[0] < 0 and y[-1] > 4
    np.testing.assert_allclose(np.diff(x), 0.1)
    assert np.allclose(r.origin_m / 0.1, np.round(r.origin_m / 0.1))
    # nodes on boundaries count: (110 + 1) x (40 + 1) walkable nodes, 11 x 41 of them in the exit
    assert r.walkable.sum() == 111 * 41
    assert r.exit.sum() == 11 * 41
    assert not r.walkable[0].any() and not r.walkable[:, 0].any()
    with pytest.raises(GeometryError, match="resolution_m"):
        g.rasterize(0.0)
