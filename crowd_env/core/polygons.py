"""Polygons for compiled code: exits and measurement areas as packed rings, and their point and path tests.

Shapely answers these questions in Python; inside a compiled rollout (and in the step-by-step loop,
so that both agree to the bit) the same questions are answered here:

- :func:`path_meets_polygon`: does the straight move p0 → p1 meet the closed polygon (interior or
  boundary)? That is ``shapely.intersects(polygon, LineString([p0, p1]))``, the exit test of
  :class:`~crowd_env.core.Simulator` (a pedestrian leaves when its centre's path of the step touches
  its exit);
- :func:`point_in_interior`: is the point in the open interior? That is ``shapely.contains_xy``, the
  measurement areas' test (a point on the boundary is outside).

A :class:`PackedPolygons` holds K polygons (with holes) as one ``(V, 2)`` array of ring vertices, the
start of each ring in it and the polygon owning each ring. Tests are exact up to floating-point
rounding (crossing number with even-odd rule over every ring of the polygon; orientation tests for
the boundary): only a point within about 1e-15 m of a boundary can be classified differently from
GEOS's robust predicates (``tests/core/test_polygons.py`` compares both on random and on touching
cases).
"""
from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

from crowd_env.errors import GeometryError

__all__ = ["PackedPolygons", "pack_polygons", "path_meets_polygon", "point_in_interior", "points_in_interior",
           "polygon_boxes"]


@dataclass(frozen=True)
class PackedPolygons:
    """K polygons as flat arrays: ``vertices`` (V, 2) ring vertices (each ring closed: its first vertex
    repeated at its end), ``ring_start`` (R + 1,) start of ring r in ``vertices`` (ring r is
    ``vertices[ring_start[r]:ring_start[r + 1]]``), ``ring_owner`` (R,) the polygon of each ring,
    ``boxes`` (K, 4) bounding boxes (xmin, ymin, xmax, ymax)."""

    vertices: np.ndarray
    ring_start: np.ndarray
    ring_owner: np.ndarray
    boxes: np.ndarray

    @property
    def n_polygons(self) -> int:
        return int(self.boxes.shape[0])

    @property
    def arrays(self) -> tuple:
        """``(vertices, ring_start, ring_owner, boxes)``, the arguments of the compiled tests."""
        return self.vertices, self.ring_start, self.ring_owner, self.boxes


def pack_polygons(polygons) -> PackedPolygons:
    """Pack shapely polygons (or multipolygons: their parts share one index) for the compiled tests."""
    vertices, starts, owners, boxes = [], [0], [], []
    for k, poly in enumerate(polygons):
        if not isinstance(poly, BaseGeometry) or poly.geom_type not in ("Polygon", "MultiPolygon") or poly.is_empty:
            raise GeometryError(f"polygon {k} must be a non-empty shapely Polygon or MultiPolygon, got {poly!r}")
        parts = poly.geoms if poly.geom_type == "MultiPolygon" else [poly]
        for part in parts:
            for ring in [part.exterior, *part.interiors]:
                xy = np.asarray(ring.coords, dtype=np.float64)[:, :2]
                vertices.append(xy)
                starts.append(starts[-1] + xy.shape[0])
                owners.append(k)
        boxes.append(shapely.bounds(poly))
    if not boxes:
        return PackedPolygons(np.zeros((0, 2)), np.zeros(1, np.int64), np.zeros(0, np.int64), np.zeros((0, 4)))
    return PackedPolygons(np.ascontiguousarray(np.concatenate(vertices)), np.asarray(starts, np.int64),
                          np.asarray(owners, np.int64), np.ascontiguousarray(boxes, dtype=np.float64))


def polygon_boxes(polygons) -> np.ndarray:
    """(K, 4) bounding boxes (xmin, ymin, xmax, ymax) of shapely geometries."""
    return np.ascontiguousarray([shapely.bounds(p) for p in polygons], dtype=np.float64).reshape(-1, 4)


@nb.njit(cache=True, inline="always")
def _orientation(ax, ay, bx, by, cx, cy):
    """Twice the signed area of triangle a, b, c (> 0: counter-clockwise)."""
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)


@nb.njit(cache=True, inline="always")
def _on_segment(px, py, ax, ay, bx, by):
    """Point p lies on the closed segment a-b."""
    if _orientation(ax, ay, bx, by, px, py) != 0.0:
        return False
    return min(ax, bx) <= px <= max(ax, bx) and min(ay, by) <= py <= max(ay, by)


@nb.njit(cache=True)
def _segments_meet(px, py, qx, qy, ax, ay, bx, by):
    """The closed segments p-q and a-b share a point."""
    d1 = _orientation(ax, ay, bx, by, px, py)
    d2 = _orientation(ax, ay, bx, by, qx, qy)
    d3 = _orientation(px, py, qx, qy, ax, ay)
    d4 = _orientation(px, py, qx, qy, bx, by)
    if ((d1 > 0.0 and d2 < 0.0) or (d1 < 0.0 and d2 > 0.0)) and ((d3 > 0.0 and d4 < 0.0) or (d3 < 0.0 and d4 > 0.0)):
        return True
    return (_on_segment(px, py, ax, ay, bx, by) or _on_segment(qx, qy, ax, ay, bx, by)
            or _on_segment(ax, ay, px, py, qx, qy) or _on_segment(bx, by, px, py, qx, qy))


@nb.njit(cache=True)
def _locate(x, y, k, vertices, ring_start, ring_owner):
    """Where the point is relative to polygon k: 1 interior, 0 boundary, −1 exterior (even-odd rule over
    all the polygon's rings)."""
    inside = False
    for r in range(ring_owner.shape[0]):
        if ring_owner[r] != k:
            continue
        for v in range(ring_start[r], ring_start[r + 1] - 1):
            ax = vertices[v, 0]
            ay = vertices[v, 1]
            bx = vertices[v + 1, 0]
            by = vertices[v + 1, 1]
            if _on_segment(x, y, ax, ay, bx, by):
                return 0
            if (ay > y) != (by > y):
                if x < ax + (y - ay) * (bx - ax) / (by - ay):
                    inside = not inside
    return 1 if inside else -1


@nb.njit(cache=True)
def point_in_interior(x, y, k, vertices, ring_start, ring_owner, boxes):
    """The point lies in the open interior of polygon k (``shapely.contains_xy``: the boundary is outside)."""
    if x <= boxes[k, 0] or x >= boxes[k, 2] or y <= boxes[k, 1] or y >= boxes[k, 3]:
        return False
    return _locate(x, y, k, vertices, ring_start, ring_owner) == 1


@nb.njit(cache=True)
def points_in_interior(position, index, k, vertices, ring_start, ring_owner, boxes):
    """(n,) bool: :func:`point_in_interior` of the points ``position[index]`` in polygon k."""
    out = np.zeros(index.shape[0], np.bool_)
    for m in range(index.shape[0]):
        i = index[m]
        out[m] = point_in_interior(position[i, 0], position[i, 1], k, vertices, ring_start, ring_owner, boxes)
    return out


@nb.njit(cache=True)
def path_meets_polygon(x0, y0, x1, y1, k, vertices, ring_start, ring_owner, boxes):
    """The closed segment (x0, y0)-(x1, y1) meets the closed polygon k (interior or boundary): shapely's
    ``intersects`` of the polygon and the step's path. A zero-length path is a point test."""
    if max(x0, x1) < boxes[k, 0] or min(x0, x1) > boxes[k, 2] or max(y0, y1) < boxes[k, 1] or \
            min(y0, y1) > boxes[k, 3]:
        return False
    if _locate(x0, y0, k, vertices, ring_start, ring_owner) >= 0 or \
            _locate(x1, y1, k, vertices, ring_start, ring_owner) >= 0:
        return True
    for r in range(ring_owner.shape[0]):  # both ends outside: the path meets the polygon iff it meets a ring
        if ring_owner[r] != k:
            continue
        for v in range(ring_start[r], ring_start[r + 1] - 1):
            if _segments_meet(x0, y0, x1, y1, vertices[v, 0], vertices[v, 1], vertices[v + 1, 0], vertices[v + 1, 1]):
                return True
    return False
