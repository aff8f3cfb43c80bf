"""Walkable area, walls, exits and measurement lines/areas of a scenario (shapely 2 based).

The walkable area is the domain Υ of the paper's Section 2.3 with the obstacles Γ removed; exits are
the areas ∂Υ where the travel time vanishes (Eq. 12) and where pedestrians leave the simulation when
their centre enters. Walls are the boundary of the walkable area minus the parts lying in or on an
exit, as ``(S, 4)`` segments (see :mod:`crowd_env.core.segments`), so pedestrians can walk into exits.

A *periodic* geometry (``period_x_m`` L > 0, the periodic corridor) identifies x = 0 with x = L: its walkable
area spans x ∈ [0, L] with the same cross-section at both ends, it has no exits, and its walls are the
boundary minus the two seam lines, each wall that reaches the seam prolonged by
:data:`PERIODIC_WALL_EXTENSION_M` beyond it (so that the side walls of a corridor run from x = −1 m to
L + 1 m and cover every wrapped position; walls themselves are not periodic).
"""
from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType

import numba as nb
import numpy as np
import shapely
import shapely.affinity
from shapely import wkt as shapely_wkt
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.base import BaseGeometry
from shapely.validation import explain_validity

from .checks import check_number
from .segments import GeometryError, as_segments, closest_point_on_segment

__all__ = ["Geometry", "Raster", "GeometryError", "as_polygon", "PERIODIC_WALL_EXTENSION_M"]

PERIODIC_WALL_EXTENSION_M = 1.0  # how far a wall reaching the seam of a periodic geometry runs on beyond it


def ring_coordinates(coords, what: str) -> np.ndarray:
    """(K, 2) finite float coordinates of a polygon ring, K ≥ 3; errors name ``what``."""
    ring = np.asarray(coords, dtype=np.float64)
    if ring.ndim != 2 or ring.shape[1] != 2:
        raise GeometryError(f"{what}: coordinates must have shape (K, 2), got {ring.shape}")
    if ring.shape[0] < 3:
        raise GeometryError(f"{what}: a polygon needs at least 3 vertices, got {ring.shape[0]}")
    if not np.all(np.isfinite(ring)):
        raise GeometryError(f"{what}: coordinates contain non-finite values")
    return ring


def as_polygon(obj, what: str):
    """A valid, non-empty shapely (Multi)Polygon from a shapely geometry, WKT string or (K, 2) coordinates."""
    if isinstance(obj, BaseGeometry):
        geom = obj
    elif isinstance(obj, str):
        try:
            geom = shapely_wkt.loads(obj)
        except Exception as exc:  # shapely raises its own error types
            raise GeometryError(f"{what}: cannot parse WKT ({exc})") from exc
    else:
        geom = Polygon(ring_coordinates(obj, what))
    if not isinstance(geom, (Polygon, MultiPolygon)):
        raise GeometryError(f"{what}: expected a Polygon or MultiPolygon, got {geom.geom_type}")
    if geom.is_empty:
        raise GeometryError(f"{what} is empty")
    if not geom.is_valid:
        zero = " and is empty (zero area)" if geom.area <= 0.0 else ""
        raise GeometryError(f"{what} is not a valid polygon: {explain_validity(geom)}{zero}")
    if geom.area <= 0.0:
        raise GeometryError(f"{what} is empty (zero area)")
    return geom


_LINE_KEYS = ("ends", "direction", "against_walkers")


def _line_spec(name: str, value) -> tuple:
    """``(ends, direction or None, against_walkers)`` of a measurement line given as its two end points or as a
    dict of :data:`_LINE_KEYS` (``ends`` required); ``direction`` becomes a read-only unit (2,) vector."""
    if not isinstance(value, dict):
        return _as_line(name, value), None, False
    unknown = sorted(set(value) - set(_LINE_KEYS))
    if unknown or "ends" not in value:
        raise GeometryError(f"measurement line {name!r}: a dict takes the keys {list(_LINE_KEYS)} ('ends' required), "
                            f"got {sorted(value)}")
    ends = _as_line(name, value["ends"])
    against = value.get("against_walkers", False)
    if not isinstance(against, (bool, np.bool_)):
        raise GeometryError(f"measurement line {name!r}: against_walkers must be True or False, got {against!r}")
    direction = value.get("direction")
    if direction is None:
        if against:
            raise GeometryError(f"measurement line {name!r}: against_walkers needs a direction (without one the line "
                                "counts towards the walkers' destination)")
        return ends, None, False
    d = np.array(direction, dtype=np.float64).reshape(-1) if np.size(direction) == 2 else np.full(3, np.nan)
    t = ends[1] - ends[0]
    norm = float(np.hypot(*d)) if d.shape == (2,) and np.isfinite(d).all() else 0.0
    if norm <= 0.0 or abs(d[0] * t[1] - d[1] * t[0]) <= 1e-9 * norm * float(np.hypot(*t)):
        raise GeometryError(f"measurement line {name!r}: direction must be a finite (x, y) vector across the line "
                            f"(not along it), got {direction!r}")
    d = d / norm
    d.setflags(write=False)
    return ends, d, bool(against)


def _as_line(name: str, value) -> np.ndarray:
    line = np.array(value, dtype=np.float64)
    if line.shape != (2, 2):
        raise GeometryError(f"measurement line {name!r} must be two end points of shape (2, 2), got {line.shape}")
    if not np.all(np.isfinite(line)):
        raise GeometryError(f"measurement line {name!r} has non-finite coordinates")
    if np.hypot(*(line[1] - line[0])) <= 1e-12:
        raise GeometryError(f"measurement line {name!r} has zero length")
    line.setflags(write=False)
    return line


def _lines_to_segments(lines) -> np.ndarray:
    """(S, 4) segments of every consecutive vertex pair of the line parts of ``lines``."""
    parts = [p for p in shapely.get_parts(lines) if p.geom_type in ("LineString", "LinearRing") and not p.is_empty]
    if not parts:
        return np.zeros((0, 4))
    coords, index = shapely.get_coordinates(parts, return_index=True)
    same = index[1:] == index[:-1]
    seg = np.hstack([coords[:-1][same], coords[1:][same]])
    length = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
    return np.ascontiguousarray(seg[length > 1e-9])


def _periodic_walls(area, period_m: float) -> np.ndarray:
    """The walls of a walkable area periodic along x with period ``period_m`` (module docstring): its boundary
    minus the seam lines x = 0 and x = L, the walls ending on the seam prolonged beyond it. Raises
    :class:`GeometryError` unless the area spans [0, L] with the same cross-section at both ends."""
    x0, y0, x1, y1 = area.bounds
    tol = 1e-9 * max(1.0, period_m)
    if abs(x0) > tol or abs(x1 - period_m) > tol:
        raise GeometryError(f"a periodic walkable area must span x from 0 to period_x_m = {period_m:g} m, got "
                            f"x from {x0:.6g} to {x1:.6g} m")
    seam = [shapely.LineString([(x, y0 - 1.0), (x, y1 + 1.0)]) for x in (0.0, period_m)]
    left, right = (area.intersection(line) for line in seam)
    mismatch = shapely.symmetric_difference(left, shapely.affinity.translate(right, -period_m)).length
    if mismatch > tol:
        raise GeometryError(f"the walkable area's cross-sections at x = 0 and x = period_x_m = {period_m:g} m differ "
                            f"({mismatch:.4g} m of them do not match): it is not periodic along x")
    seg = _lines_to_segments(area.boundary.difference(shapely.MultiLineString(seam)))
    for k in range(seg.shape[0]):
        d = seg[k, 2:] - seg[k, :2]
        d /= np.hypot(d[0], d[1])
        for end, sign in ((slice(0, 2), -1.0), (slice(2, 4), 1.0)):
            x = seg[k, end][0]
            if min(abs(x), abs(x - period_m)) <= tol and d[0] != 0.0:
                seg[k, end] += sign * PERIODIC_WALL_EXTENSION_M / abs(d[0]) * d
    return seg


@nb.njit(cache=True)
def _nearest_wall(points, segments):
    """Distance from each point to the closest segment and the unit normal from that wall point to the point."""
    n = points.shape[0]
    dist = np.full(n, np.inf)
    normal = np.zeros((n, 2))
    for a in range(n):
        px = points[a, 0]
        py = points[a, 1]
        best = np.inf
        bx = 0.0
        by = 0.0
        bk = -1
        for k in range(segments.shape[0]):
            cx, cy, _ = closest_point_on_segment(px, py, segments[k, 0], segments[k, 1], segments[k, 2], segments[k, 3])
            d = np.sqrt((px - cx) ** 2 + (py - cy) ** 2)
            if d < best:
                best = d
                bx = cx
                by = cy
                bk = k
        dist[a] = best
        if bk >= 0:
            if best > 1e-12:
                normal[a, 0] = (px - bx) / best
                normal[a, 1] = (py - by) / best
            else:  # on the wall: the segment's left normal
                lx = segments[bk, 2] - segments[bk, 0]
                ly = segments[bk, 3] - segments[bk, 1]
                ll = np.sqrt(lx * lx + ly * ly)
                normal[a, 0] = -ly / ll
                normal[a, 1] = lx / ll
    return dist, normal


def _as_points(points) -> np.ndarray:
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim == 1 and pts.shape == (2,):
        pts = pts[None, :]
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise GeometryError(f"points must have shape (N, 2), got {pts.shape}")
    return np.ascontiguousarray(pts)


@dataclass(frozen=True)
class Raster:
    """Nodes of a regular grid covering a geometry: node (i, j) is at ``origin_m + (i, j) * resolution_m``.

    Arrays are indexed ``[i, j]`` = ``[x index, y index]``. ``walkable`` marks nodes in the walkable area
    or in an exit (boundary included), ``exit`` nodes in an exit.
    """

    origin_m: np.ndarray
    resolution_m: float
    walkable: np.ndarray
    exit: np.ndarray

    @property
    def shape(self) -> tuple:
        return self.walkable.shape

    @property
    def x_m(self) -> np.ndarray:
        return self.origin_m[0] + np.arange(self.shape[0]) * self.resolution_m

    @property
    def y_m(self) -> np.ndarray:
        return self.origin_m[1] + np.arange(self.shape[1]) * self.resolution_m

    def node_points(self) -> np.ndarray:
        """(nx * ny, 2) coordinates of every node in C order (x index major)."""
        xx, yy = np.meshgrid(self.x_m, self.y_m, indexing="ij")
        return np.column_stack([xx.ravel(), yy.ravel()])


class Geometry:
    """Walkable area with obstacles, exits, walls and named measurement lines and areas (immutable).

    ``walkable_area``: shapely (Multi)Polygon, WKT string or (K, 2) outer-ring coordinates; holes of a
    polygon are obstacles. ``obstacles``: polygons subtracted from it. ``exits``: one or more polygons
    where pedestrians leave (each must overlap the walkable area or share a boundary stretch with it).
    ``measurement_lines``: name -> two end points, or a dict ``{"ends": two end points, "direction": (x, y),
    "against_walkers": False}``: the side a line counts passages towards (:attr:`measurement_line_directions`;
    without one, a scenario counts them towards its walkers' destination,
    :meth:`~crowd_env.scenarios.Scenario.line_direction`), and whether it counts against its walkers on purpose.
    ``measurement_areas``: name -> polygon (density).
    ``period_x_m``: L > 0 makes the geometry periodic along x (module docstring; no exits then, ``exits``
    empty); 0 (the default) for none. Raises :class:`GeometryError` naming the problem.
    """

    def __init__(self, walkable_area, exits, obstacles=(), measurement_lines=None, measurement_areas=None,
                 name: str = "geometry", period_x_m: float = 0.0):
        period = check_number("period_x_m", period_x_m, error=GeometryError, minimum=0.0)
        area = as_polygon(walkable_area, "walkable area")
        if obstacles is not None and not isinstance(obstacles, (list, tuple)):
            obstacles = [obstacles]
        obs = [as_polygon(o, f"obstacle {k}") for k, o in enumerate(obstacles or ())]
        if obs:
            area = area.difference(shapely.union_all(obs))
            area = shapely.normalize(area)
            if area.is_empty or area.area <= 0.0:
                raise GeometryError("walkable area is empty once the obstacles are removed")
            if not area.is_valid:
                raise GeometryError(f"walkable area minus obstacles is not valid: {explain_validity(area)}")
        if isinstance(exits, (BaseGeometry, str)):
            exits = [exits]
        exits = list(exits) if exits is not None else []
        if not exits and period == 0.0:
            raise GeometryError("the geometry has no exit: give at least one exit polygon")
        if exits and period > 0.0:
            raise GeometryError(f"a periodic geometry (period_x_m = {period:g} m) has no exits: nobody leaves a "
                                f"periodic corridor; got {len(exits)} exit(s)")
        exit_polys = []
        for k, e in enumerate(exits):
            poly = as_polygon(e, f"exit {k}")
            overlap = poly.intersection(area).area
            shared = poly.intersection(area.boundary).length
            if overlap <= 1e-12 and shared <= 1e-9:
                raise GeometryError(f"exit {k} does not touch the walkable area (distance "
                                    f"{poly.distance(area):.4g} m; it must overlap it or share a boundary stretch)")
            exit_polys.append(poly)
        exit_union = shapely.union_all(exit_polys)
        walls = _periodic_walls(area, period) if period > 0.0 else \
            _lines_to_segments(area.boundary.difference(exit_union))
        self._period_x_m = period
        self._walls = as_segments(walls) if walls.shape[0] else np.zeros((0, 4))
        self._walls.setflags(write=False)
        self._area = area
        self._exits = tuple(exit_polys)
        self._exit_union = exit_union
        self._navigable = shapely.union_all([area, exit_union])
        for g in (self._area, self._exit_union, self._navigable):
            shapely.prepare(g)
        specs = {str(k): _line_spec(str(k), v) for k, v in dict(measurement_lines or {}).items()}
        lines = {k: spec[0] for k, spec in specs.items()}
        self._line_directions = MappingProxyType({k: spec[1] for k, spec in specs.items() if spec[1] is not None})
        self._against_walkers = frozenset(k for k, spec in specs.items() if spec[2])
        for k, line in lines.items():
            if not shapely.LineString(line).intersects(self._navigable):
                raise GeometryError(f"measurement line {k!r} {line.tolist()} does not cross the walkable area")
        areas = {}
        for k, v in dict(measurement_areas or {}).items():
            poly = as_polygon(v, f"measurement area {k!r}")
            if poly.intersection(self._navigable).area <= 1e-12:
                raise GeometryError(f"measurement area {k!r} does not overlap the walkable area")
            areas[str(k)] = poly
        self._lines = MappingProxyType(lines)
        self._areas = MappingProxyType(areas)
        self.name = str(name)

    # -- constructors -------------------------------------------------------------------------------
    @classmethod
    def from_wkt(cls, walkable_area: str, exits, obstacles=(), measurement_lines=None, measurement_areas=None,
                 name: str = "geometry", period_x_m: float = 0.0) -> "Geometry":
        """Build from WKT strings (``exits``/``obstacles``: one string or a list of them)."""
        for what, value in (("walkable_area", walkable_area),):
            if not isinstance(value, str):
                raise GeometryError(f"{what} must be a WKT string, got {type(value).__name__}")
        return cls(walkable_area, exits, obstacles, measurement_lines, measurement_areas, name, period_x_m)

    @classmethod
    def from_coordinates(cls, walkable_area, exits, obstacles=(), measurement_lines=None, measurement_areas=None,
                         name: str = "geometry", period_x_m: float = 0.0) -> "Geometry":
        """Build from (K, 2) vertex lists: the walkable outer ring, a list of exit rings, obstacle rings."""
        return cls(np.asarray(walkable_area, dtype=np.float64), [np.asarray(e, dtype=np.float64) for e in exits],
                   [np.asarray(o, dtype=np.float64) for o in obstacles], measurement_lines, measurement_areas, name,
                   period_x_m)

    # -- properties ---------------------------------------------------------------------------------
    @property
    def walkable_area(self):
        """Walkable area (obstacles removed), a shapely (Multi)Polygon."""
        return self._area

    @property
    def navigable_area(self):
        """Walkable area united with the exits: where the travel time is computed."""
        return self._navigable

    @property
    def walls(self) -> np.ndarray:
        """(S, 4) read-only wall segments: the walkable boundary minus the stretches in or on an exit."""
        return self._walls

    @property
    def exits(self) -> tuple:
        return self._exits

    @property
    def period_x_m(self) -> float:
        """The periodicity L along x in metres (0: not periodic; module docstring)."""
        return self.__dict__.get("_period_x_m", 0.0)  # geometries pickled before periodicity existed have none

    @property
    def exit_area(self):
        """Union of all exits (shapely)."""
        return self._exit_union

    @property
    def measurement_lines(self):
        """Read-only mapping name -> (2, 2) end points."""
        return self._lines

    @property
    def measurement_line_directions(self):
        """Read-only mapping name -> unit (2,) vector: the side each line given a direction counts passages
        towards (lines without one are not in it: a scenario counts them towards its walkers' destination)."""
        return self.__dict__.get("_line_directions", MappingProxyType({}))  # none in geometries pickled before

    @property
    def lines_against_walkers(self) -> frozenset:
        """The names of the lines whose direction points against their walkers on purpose (a scenario refuses
        any other such line)."""
        return self.__dict__.get("_against_walkers", frozenset())

    def measurement_line_spec(self, name: str):
        """Line ``name`` as the constructor takes it: its end points, or a dict with its direction (the inverse
        of the ``measurement_lines`` argument; a moved copy of a geometry passes them on)."""
        direction = self.measurement_line_directions.get(name)
        if direction is None:
            return self._lines[name]
        return {"ends": self._lines[name], "direction": direction, "against_walkers": name in self.lines_against_walkers}

    @property
    def measurement_areas(self):
        """Read-only mapping name -> shapely polygon."""
        return self._areas

    @property
    def bounds(self) -> tuple:
        """(min_x, min_y, max_x, max_y) in metres of the walkable area and exits together."""
        return tuple(float(v) for v in self._navigable.bounds)

    def __getstate__(self) -> dict:
        """A geometry pickles (a simulator does, for checkpoints and worker processes): its read-only
        mappings travel as plain dicts and come back read-only."""
        state = self.__dict__.copy()
        state["_lines"], state["_areas"] = dict(self._lines), dict(self._areas)
        state["_line_directions"] = dict(self.measurement_line_directions)
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._lines, self._areas = MappingProxyType(self._lines), MappingProxyType(self._areas)
        self._line_directions = MappingProxyType(state.get("_line_directions", {}))

    def __repr__(self) -> str:
        b = ", ".join(f"{v:.3g}" for v in self.bounds)
        period = f", period_x_m={self.period_x_m:g}" if self.period_x_m else ""
        return (f"Geometry({self.name!r}, area={self._area.area:.4g} m², bounds=({b}), walls={self._walls.shape[0]}, "
                f"exits={len(self._exits)}, lines={list(self._lines)}, areas={list(self._areas)}{period})")

    # -- queries ------------------------------------------------------------------------------------
    def contains(self, points) -> np.ndarray:
        """(N,) bool: point strictly inside the walkable area (shapely.contains_xy)."""
        pts = _as_points(points)
        return shapely.contains_xy(self._area, pts[:, 0], pts[:, 1])

    def in_exit(self, points) -> np.ndarray:
        """(N,) bool: point inside an exit (a pedestrian whose centre is there leaves)."""
        pts = _as_points(points)
        return shapely.contains_xy(self._exit_union, pts[:, 0], pts[:, 1])

    def exit_index(self, points) -> np.ndarray:
        """(N,) int: index of the exit containing each point, -1 for none."""
        pts = _as_points(points)
        out = np.full(pts.shape[0], -1, dtype=np.int64)
        for k in range(len(self._exits) - 1, -1, -1):
            out[shapely.contains_xy(self._exits[k], pts[:, 0], pts[:, 1])] = k
        return out

    def distance_to_walls(self, points, return_normal: bool = False):
        """(N,) distance (m) from each point to the closest wall; with ``return_normal`` also the (N, 2)
        unit normal from that wall point towards the point. ``inf`` (and zero normals) without walls."""
        pts = _as_points(points)
        dist, normal = _nearest_wall(pts, self._walls)
        return (dist, normal) if return_normal else dist

    def rasterize(self, resolution_m: float, padding_cells: int = 2) -> Raster:
        """Grid of nodes every ``resolution_m`` covering :attr:`bounds` plus ``padding_cells`` on each side.

        Node coordinates are integer multiples of ``resolution_m`` so that walls on such multiples fall
        exactly on nodes. Nodes on a boundary count as walkable (shapely.intersects_xy).
        """
        check_number("resolution_m", resolution_m, error=GeometryError, positive=True)
        if int(padding_cells) < 1:
            raise GeometryError(f"padding_cells must be >= 1, got {padding_cells!r}")
        h = float(resolution_m)
        x0, y0, x1, y1 = self.bounds
        i0 = int(np.floor(x0 / h)) - int(padding_cells)
        j0 = int(np.floor(y0 / h)) - int(padding_cells)
        i1 = int(np.ceil(x1 / h)) + int(padding_cells)
        j1 = int(np.ceil(y1 / h)) + int(padding_cells)
        nx, ny = i1 - i0 + 1, j1 - j0 + 1
        if nx * ny > 50_000_000:
            raise GeometryError(f"navigation grid of {nx} x {ny} nodes at {h} m is too large; use a coarser resolution")
        x = np.arange(i0, i1 + 1) * h
        y = np.arange(j0, j1 + 1) * h
        xx, yy = np.meshgrid(x, y, indexing="ij")
        walkable = shapely.intersects_xy(self._navigable, xx, yy)
        exit_mask = shapely.intersects_xy(self._exit_union, xx, yy) & walkable
        return Raster(origin_m=np.array([i0 * h, j0 * h]), resolution_m=h, walkable=walkable, exit=exit_mask)
