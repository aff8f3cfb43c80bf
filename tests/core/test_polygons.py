"""The compiled polygon tests (crowd_env.core.polygons) against shapely's, an independent implementation:
random paths and points around polygons with holes and concave corners, and exact touching cases."""
import numpy as np
import pytest
import shapely
from shapely.geometry import LineString, MultiPolygon, Polygon

from crowd_env.core.polygons import pack_polygons, path_meets_polygon, point_in_interior
from crowd_env.errors import GeometryError

POLYGONS = [
    Polygon([(0, 0), (2, 0), (2, 1), (0, 1)]),  # an exit-like rectangle
    Polygon([(0, 0), (4, 0), (4, 4), (2, 1.5), (0, 4)]),  # concave
    Polygon([(0, 0), (5, 0), (5, 5), (0, 5)], holes=[[(1, 1), (4, 1), (4, 4), (1, 4)]]),  # with a hole
    MultiPolygon([Polygon([(0, 0), (1, 0), (1, 1)]), Polygon([(3, 3), (4, 3), (4, 4), (3, 4)])]),
]


@pytest.mark.parametrize("k", range(len(POLYGONS)))
def test_random_paths_and_points_agree_with_shapely(k):
    packed = pack_polygons(POLYGONS)
    rng = np.random.default_rng(k)
    p0 = rng.uniform(-1.0, 6.0, (3000, 2))
    p1 = p0 + rng.normal(0.0, 0.6, (3000, 2))
    p1[:200] = p0[:200]  # zero-length paths: point tests
    ours = np.array([path_meets_polygon(a[0], a[1], b[0], b[1], k, *packed.arrays) for a, b in zip(p0, p1)])
    theirs = shapely.intersects(POLYGONS[k], shapely.linestrings(np.stack([p0, p1], axis=1)))
    np.testing.assert_array_equal(ours, theirs)
    assert 100 < ours.sum() < 2900  # both outcomes are exercised
    inside = np.array([point_in_interior(x, y, k, *packed.arrays) for x, y in p0])
    np.testing.assert_array_equal(inside, shapely.contains_xy(POLYGONS[k], p0[:, 0], p0[:, 1]))


def test_touching_cases():
    """Closed polygon for paths (the boundary counts: a centre that reaches an exit's edge leaves), open
    interior for points (shapely.contains_xy: a point on the edge of a measurement area is outside)."""
    packed = pack_polygons(POLYGONS[:1])
    cases = [((-1.0, 0.5), (0.0, 0.5)), ((-1.0, 1.0), (3.0, 1.0)), ((-1.0, 2.0), (0.0, 1.0)), ((2.0, 1.0), (2.0, 1.0)),
             ((-1.0, 1.5), (3.0, 1.5)), ((0.5, 0.5), (0.6, 0.6)), ((-1.0, -1e-12), (3.0, -1e-12))]
    for a, b in cases:
        assert path_meets_polygon(*a, *b, 0, *packed.arrays) == POLYGONS[0].intersects(LineString([a, b])), (a, b)
    for x, y in [(0.0, 0.5), (2.0, 1.0), (1.0, 0.5), (1.0, 1.0), (2.5, 0.5)]:
        assert point_in_interior(x, y, 0, *packed.arrays) == shapely.contains_xy(POLYGONS[0], x, y), (x, y)


def test_bad_polygons_are_refused():
    with pytest.raises(GeometryError, match="polygon 1"):
        pack_polygons([POLYGONS[0], LineString([(0, 0), (1, 1)])])
    with pytest.raises(GeometryError, match="polygon 0"):
        pack_polygons([Polygon()])
