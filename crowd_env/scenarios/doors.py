"""Doors: the exit polygon behind a door segment on the walkable area's boundary, and the width of each exit's door."""
from __future__ import annotations

from crowd_env.errors import ScenarioError

import math

import numpy as np
import shapely
import shapely.affinity

from .checks import check_positive

__all__ = ["door_exit", "door_widths_m"]


def door_exit(segment, walkable_area, depth_m: float = 0.5, what: str = "exit"):
    """An exit polygon behind a door: the rectangle of depth ``depth_m`` on the outer side of ``segment``
    ((2, 2) end points or a shapely LineString), which must lie on the boundary of ``walkable_area``.
    Pedestrians leave when their centre crosses the door line."""
    line = segment if isinstance(segment, shapely.LineString) else None
    pts = np.asarray(line.coords if line is not None else segment, dtype=np.float64)
    if pts.shape != (2, 2) or not np.all(np.isfinite(pts)):
        raise ScenarioError(f"{what}: a door segment must be two finite end points of shape (2, 2), got {pts.shape}")
    d = pts[1] - pts[0]
    length = math.hypot(*d)
    if length <= 1e-9:
        raise ScenarioError(f"{what}: the door segment has zero length")
    check_positive(exit_depth_m=depth_m)
    line = shapely.LineString(pts)
    on_boundary = line.difference(walkable_area.boundary.buffer(1e-9)).length
    if on_boundary > 1e-6:
        raise ScenarioError(f"{what}: the door segment {pts.tolist()} does not lie on the boundary of the walkable "
                            f"area ({on_boundary:.4g} m of it lie off the boundary)")
    normal = np.array([-d[1], d[0]]) / length
    mid = 0.5 * (pts[0] + pts[1])
    probe = 1e-4 * max(1.0, length)
    if walkable_area.contains(shapely.Point(*(mid + probe * normal))):
        normal = -normal
    if walkable_area.contains(shapely.Point(*(mid + probe * normal))):
        raise ScenarioError(f"{what}: the door segment {pts.tolist()} has walkable area on both sides")
    return shapely.Polygon([pts[0], pts[1], pts[1] + depth_m * normal, pts[0] + depth_m * normal])


def door_widths_m(geometry) -> np.ndarray:
    """(E,) the width of each exit's door: the length of the exit polygon's edge on the walkable area's
    boundary, or, for an exit inside the walkable area, the shorter side of its minimum rectangle."""
    area = geometry.walkable_area
    out = []
    for poly in geometry.exits:
        opening = poly.intersection(area.boundary).length
        if opening <= 1e-9:
            x, y = np.asarray(poly.minimum_rotated_rectangle.exterior.coords).T
            sides = np.hypot(np.diff(x), np.diff(y))
            opening = float(sides[sides > 1e-9].min())
        out.append(float(opening))
    return np.array(out)
