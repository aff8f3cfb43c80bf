"""Eikonal navigation (Kabalan et al. 2016, Eq. 11-13): travel time T to the exits and the desired direction.

‖∇T‖ = 1/V in the walkable area (Eq. 11), T = 0 on the exits (Eq. 12), solved once per geometry with
scikit-fmm's fast marching; e_d = -∇T / ‖∇T‖ (Eq. 13), sampled at any point by bilinear interpolation
in a compiled kernel. :class:`NavigationField` is one field (T to the nearest exit, or to chosen exits)
and states its grid conventions; :class:`DestinationNavigation` gives each pedestrian the field of its
own destination. ``clearance_m`` solves Eq. 11 on the free configuration space of a disk centre (the
walkable area eroded by the radius) instead of for points (the paper's literal field, ``clearance_m = 0``).
"""
from __future__ import annotations

from collections import OrderedDict

import numba as nb
import numpy as np
import shapely
from scipy import ndimage

from ..core.checks import check_number
from ..core.geometry import Geometry
from ..core.segments import GeometryError

__all__ = ["NavigationField", "DestinationNavigation", "RigidlyMovedNavigation", "GeometryError", "sample_bilinear"]


@nb.njit(cache=True)
def sample_bilinear(points, x0, y0, h, travel_time, direction, out_dir, out_time):
    """Bilinear interpolation of T and of the node directions; returns the first bad point or -1.

    A point is bad when it is non-finite or outside the grid. Corners with zero weight are ignored;
    if a weighted corner has T = inf (unreachable) the point gets T = inf and a NaN direction.
    """
    nx = travel_time.shape[0]
    ny = travel_time.shape[1]
    for a in range(points.shape[0]):
        fx = (points[a, 0] - x0) / h
        fy = (points[a, 1] - y0) / h
        if not (fx >= 0.0 and fx <= nx - 1 and fy >= 0.0 and fy <= ny - 1):
            return a
        i = min(int(fx), nx - 2)
        j = min(int(fy), ny - 2)
        tx = fx - i
        ty = fy - j
        t = 0.0
        gx = 0.0
        gy = 0.0
        ok = True
        wbest = -1.0
        bx = np.nan
        by = np.nan
        for c in range(4):
            di = c // 2
            dj = c % 2
            w = (tx if di else 1.0 - tx) * (ty if dj else 1.0 - ty)
            if w <= 0.0:
                continue
            v = travel_time[i + di, j + dj]
            if not np.isfinite(v):
                ok = False
                break
            dx = direction[i + di, j + dj, 0]
            dy = direction[i + di, j + dj, 1]
            t += w * v
            gx += w * dx
            gy += w * dy
            if w > wbest and dx * dx + dy * dy > 0.0:
                wbest = w
                bx = dx
                by = dy
        if not ok:
            out_time[a] = np.inf
            out_dir[a, 0] = np.nan
            out_dir[a, 1] = np.nan
            continue
        norm = np.sqrt(gx * gx + gy * gy)
        if norm > 1e-9:
            out_dir[a, 0] = gx / norm
            out_dir[a, 1] = gy / norm
        else:  # opposite corner directions cancel (a ridge): use the heaviest corner's direction
            nb_ = np.sqrt(bx * bx + by * by)
            out_dir[a, 0] = bx / nb_
            out_dir[a, 1] = by / nb_
        out_time[a] = t
    return -1


def _axis_gradient(t: np.ndarray, h: float, axis: int) -> np.ndarray:
    """dT/d(axis) at every node from walkable neighbours only (inf marks invalid nodes)."""
    pad = [(0, 0), (0, 0)]
    pad[axis] = (1, 1)
    tp = np.pad(t, pad, constant_values=np.inf)
    n = t.shape[axis]
    a = np.take(tp, np.arange(0, n), axis=axis)  # T at i - 1
    b = np.take(tp, np.arange(2, n + 2), axis=axis)  # T at i + 1
    fa = np.isfinite(a)
    fb = np.isfinite(b)
    with np.errstate(invalid="ignore"):
        back = (t - a) / h
        fwd = (b - t) / h
        cen = (b - a) / (2.0 * h)
    both = fa & fb
    g = np.where(both, cen, np.where(fa, back, np.where(fb, fwd, 0.0)))
    ridge = both & (t >= a) & (t >= b)  # local maximum along this axis: descend the steeper side
    g = np.where(ridge, np.where(a <= b, back, fwd), g)
    g[~np.isfinite(t)] = np.nan
    return g


def _block_wall_ward(direction: np.ndarray, nav: np.ndarray) -> None:
    """At nodes next to a masked axis neighbour, drop the direction component pointing into it (in place).

    A geodesic never leaves the domain through a wall, so this only removes discretisation error of the
    one-sided differences there; interpolated directions then cannot carry a pedestrian through a wall.
    """
    pad = np.pad(nav, 1, constant_values=False)
    blocked = {(0, +1): ~pad[2:, 1:-1], (0, -1): ~pad[:-2, 1:-1], (1, +1): ~pad[1:-1, 2:], (1, -1): ~pad[1:-1, :-2]}
    new = direction.copy()
    for (axis, sign), mask in blocked.items():
        comp = new[..., axis]
        comp[nav & mask & (sign * comp > 0)] = 0.0
    norm = np.hypot(new[..., 0], new[..., 1])
    ok = norm > 1e-12
    direction[ok] = new[ok] / norm[ok, None]


def _nearest_index(source: np.ndarray):
    """For every node, the distance (in cells) to and the index of the nearest ``source`` node."""
    dist, idx = ndimage.distance_transform_edt(~source, return_distances=True, return_indices=True)
    return dist, idx[0], idx[1]


class NavigationField:
    """Travel time T (s) to the nearest exit and desired directions e_d on a grid (Eq. 11-13).

    ``resolution_m``: grid spacing h. ``speed_m_s``: wavefront speed V in the walkable area (1 m/s in
    the paper, making T the geodesic distance in metres). ``wall_slowdown=(distance_m, speed_factor)``:
    V is multiplied by ``speed_factor`` in (0, 1] within ``distance_m`` of a wall (the paper's optional
    slower V near walls). ``clearance_m``: solve on the walkable area minus the band within this
    distance of a wall (configuration space of disk centres; use the pedestrians' radius; 0 = points,
    the paper's literal Eq. 11-13). ``exits``: indices into ``geometry.exits`` of the exits where T = 0
    (default None: all of them, i.e. T to the nearest exit). Built once per geometry; see :meth:`cached`.

    Grid conventions and how the field is completed outside the walkable area:

    - nodes on the boundary of the walkable area are walkable; the exit boundary is located with sub-cell
      accuracy (φ is the signed distance to the exit boundary in the nodes next to it);
    - node directions use central differences of T where both axis neighbours are walkable, one-sided
      differences next to a masked neighbour (so they never mix in wall values) and the steeper
      descending side at a ridge where T is a local maximum along an axis; at a node next to a masked
      neighbour the component pointing into it is dropped (a geodesic never crosses a wall), so that
      directions sampled within a cell of a wall run along it instead of into it;
    - inside an exit T = 0 and the direction is that of the nearest walkable node outside the exit (the
      direction the pedestrian entered with: "keep walking through");
    - masked nodes (walls, obstacles, padding) take the direction of the nearest walkable node and
      T_nearest + distance / V, so interpolation within one cell of a wall is sensible and never
      mixes in undefined values;
    - walkable nodes that no exit can reach have T = inf; points sampled there get T = inf and a NaN
      direction (:meth:`NavigationField.check_reachable` raises for them);
    - points outside the grid (the geometry's bounds plus two cells) raise :class:`GeometryError`.

    Destinations (``exits``): by default T is the travel time to the nearest of all exits (Eq. 12 with the
    union of the exits). ``exits=(k, ...)`` solves Eq. 11-13 with T = 0 on those exits only; the other
    exits are then ordinary floor. :class:`DestinationNavigation` combines such fields, one per
    destination, and answers for each pedestrian with the field of its own destination.

    Configuration space (``clearance_m``): pedestrians are disks, so their centres can only reach points
    at least their radius r from every wall. Computed for points (``clearance_m = 0``, the paper's literal
    Eq. 11-13), the geodesics hug the walls and pass through reflex corners, and near the entrance of a
    bottleneck e_d points at the corner vertex, which a disk centre can never reach: a disk beside the
    entrance is steered into the corner instead of into the opening. With ``clearance_m = r`` the field is
    solved on the walkable area eroded by r (the free configuration space of a disk centre, V = 0 within r
    of a wall, the standard treatment of finite-size agents in floor-field and eikonal navigation, e.g.
    Kretz 2009, JuPedSim's "distance to wall" floor fields): geodesics then wrap the corners at distance r
    and e_d beside an opening points into the part of it a centre can use. Exits are not eroded from
    their open sides (only wall distance counts). Nodes in the eroded band are masked and completed as
    above (nearest free node's direction), so sampling a centre touching a wall stays well defined.
    """

    per_pedestrian = False  # one field serves every pedestrian (see DestinationNavigation)

    # Fields by geometry *content* (walkable area and exits as WKB) and settings, least recently used
    # first out: a scenario rebuilt per reset on the same geometry reuses its field, and memory stays
    # bounded however many geometries a program creates.
    _cache: "OrderedDict" = OrderedDict()
    cache_size = 8

    def __init__(self, geometry: Geometry, resolution_m: float = 0.05, wall_slowdown=None, speed_m_s: float = 1.0,
                 clearance_m: float = 0.0, exits=None):
        if not isinstance(geometry, Geometry):
            raise GeometryError(f"NavigationField needs a Geometry, got {type(geometry).__name__}")
        self.speed_m_s = check_number("speed_m_s", speed_m_s, error=GeometryError, positive=True)
        self.geometry = geometry
        self.wall_slowdown = self.check_wall_slowdown(wall_slowdown)
        self.clearance_m = self._check_clearance(clearance_m)
        self.exits = self._check_exits(exits, geometry)
        raster = geometry.rasterize(resolution_m)
        self.raster = raster
        self.resolution_m = h = raster.resolution_m
        self.origin_m = raster.origin_m
        nav, ex, target = self._grid_masks(geometry, raster)
        self.walkable = nav
        pts = raster.node_points().reshape(*nav.shape, 2)
        # phi < 0 inside exits; the signed distance to the exit boundary in the nodes next to it (Eq. 12).
        band = ex ^ ndimage.binary_dilation(ex)
        band |= ex & ~ndimage.binary_erosion(ex, border_value=1)
        d = np.full(nav.shape, 10.0 * h)
        d[band] = shapely.distance(self._exit_interface(target, geometry.navigable_area), shapely.points(pts[band]))
        phi = np.where(ex, -d, d)
        speed = self._wavefront_speed(geometry, nav, pts, h)
        try:
            t = self._fmm(np.ma.MaskedArray(phi, ~nav), speed, h)
        except ValueError as exc:
            raise GeometryError(f"fast marching failed on the navigation grid ({exc})") from exc
        reachable = nav & ~np.ma.getmaskarray(t) & np.isfinite(np.ma.getdata(t))
        t_signed = np.where(reachable, np.where(ex, -1.0, 1.0) * np.ma.getdata(t), np.inf)
        direction, travel = self._node_fields(t_signed, reachable, nav, ex, h)
        travel.setflags(write=False)
        direction.setflags(write=False)
        self.travel_time_s_grid = travel
        self.direction_grid = direction
        self.reachable = reachable
        self.reachable.setflags(write=False)

    def _grid_masks(self, geometry: Geometry, raster) -> tuple:
        """(walkable nodes, exit nodes, the target exits' area): the nodes this field's exits cover, both
        masks less the nodes nearer a wall than ``clearance_m``; :class:`GeometryError` when nothing is left."""
        nav, ex = raster.walkable, raster.exit
        target = geometry.exit_area
        if self.exits is not None:  # T = 0 on these exits only; the others are floor
            target = shapely.union_all([geometry.exits[k] for k in self.exits])
            nodes = raster.node_points()
            ex = shapely.intersects_xy(target, nodes[:, 0], nodes[:, 1]).reshape(nav.shape) & nav
        if self.clearance_m > 0.0 and geometry.walls.shape[0]:
            nodes = raster.node_points().reshape(*nav.shape, 2)
            free = np.zeros(nav.shape, dtype=bool)
            free[nav] = geometry.distance_to_walls(nodes[nav]) >= self.clearance_m - 1e-9
            nav, ex = nav & free, ex & free
            if not (nav & ~ex).any():
                raise GeometryError(f"no grid node of the walkable area is {self.clearance_m} m (clearance_m) from "
                                    "the walls: the area is too narrow for a pedestrian of that radius")
        if not ex.any():
            raise GeometryError(f"no grid node lies inside an exit at resolution {raster.resolution_m} m: exits must "
                                "be at least one cell wide; use a finer resolution_m")
        if not (nav & ~ex).any():
            raise GeometryError("the walkable area lies entirely inside the exits")
        return nav, ex, target

    def _wavefront_speed(self, geometry: Geometry, nav, pts, h: float) -> np.ndarray:
        """The wavefront speed V of Eq. 11 at every node: ``speed_m_s``, times the wall slowdown's factor
        within its distance of a wall."""
        speed = np.full(nav.shape, self.speed_m_s)
        if self.wall_slowdown is not None and geometry.walls.shape[0]:
            dist_m, factor = self.wall_slowdown
            cells_to_mask = ndimage.distance_transform_edt(nav) * h
            near = nav & (cells_to_mask <= dist_m + 2.0 * h)
            slow = np.zeros(nav.shape, dtype=bool)
            slow[near] = geometry.distance_to_walls(pts[near]) < dist_m
            speed[slow] *= factor
        return speed

    def _node_fields(self, t_signed, reachable, nav, ex, h: float) -> tuple:
        """(node directions −∇T/‖∇T‖ (Eq. 13), node travel times T): inside exits the direction of the nearest
        reachable node outside them ("keep walking through"); masked nodes take the nearest walkable node's
        direction and T_nearest + distance / V."""
        gx = _axis_gradient(t_signed, h, 0)
        gy = _axis_gradient(t_signed, h, 1)
        norm = np.hypot(gx, gy)
        with np.errstate(invalid="ignore", divide="ignore"):
            direction = np.stack([np.where(norm > 0, -gx / norm, 0.0), np.where(norm > 0, -gy / norm, 0.0)], axis=-1)
        direction[~reachable] = np.nan
        _block_wall_ward(direction, nav)
        travel = np.where(reachable, np.maximum(t_signed, 0.0), np.inf)
        outside = reachable & ~ex
        if outside.any():
            _, ii, jj = _nearest_index(outside)
            direction[ex] = direction[ii[ex], jj[ex]]
        dist, ii, jj = _nearest_index(nav)
        masked = ~nav
        direction[masked] = direction[ii[masked], jj[masked]]
        travel[masked] = travel[ii[masked], jj[masked]] + dist[masked] * h / self.speed_m_s
        return direction, travel

    @staticmethod
    def _exit_interface(exit_area, navigable_area):
        """The boundary stretches of ``exit_area`` inside the navigable area (where pedestrians cross into exits).

        Exit edges lying on the outer boundary (along walls) are left out: measuring φ from them would
        put T = 0 on nodes along the wall deep inside the exit and spoil the second-order stencil.
        """
        interface = exit_area.boundary.difference(navigable_area.boundary)
        if interface.is_empty or interface.length <= 1e-12:
            return exit_area.boundary
        return interface

    @staticmethod
    def _fmm(phi, speed, h):
        import skfmm  # lazy: keeps `import crowd_env` light

        return skfmm.travel_time(phi, speed, dx=h)

    @staticmethod
    def check_wall_slowdown(wall_slowdown):
        """``wall_slowdown`` as a ``(distance_m, speed_factor)`` tuple of floats, or None; raises
        :class:`GeometryError` naming what is wrong."""
        if wall_slowdown is None:
            return None
        try:
            dist_m, factor = (float(v) for v in wall_slowdown)
        except (TypeError, ValueError) as exc:
            raise GeometryError(f"wall_slowdown must be (distance_m, speed_factor), got {wall_slowdown!r}") from exc
        if not (np.isfinite(dist_m) and dist_m > 0):
            raise GeometryError(f"wall_slowdown distance_m must be > 0, got {dist_m!r}")
        if not (0.0 < factor <= 1.0):
            raise GeometryError(f"wall_slowdown speed_factor must lie in (0, 1], got {factor!r}")
        return dist_m, factor

    @staticmethod
    def _check_clearance(clearance_m) -> float:
        try:
            value = float(clearance_m)
        except (TypeError, ValueError) as exc:
            raise GeometryError(f"clearance_m must be a number >= 0, got {clearance_m!r}") from exc
        if not (np.isfinite(value) and value >= 0.0):
            raise GeometryError(f"clearance_m must be a finite number >= 0, got {clearance_m!r}")
        return value

    @staticmethod
    def _check_exits(exits, geometry: Geometry):
        """None (all exits) or a sorted tuple of distinct valid exit indices."""
        if exits is None:
            return None
        try:
            items = [exits] if isinstance(exits, (int, np.integer)) else list(exits)
        except TypeError:
            raise GeometryError(f"exits must be None or exit indices, got {exits!r}") from None
        n = len(geometry.exits)
        bad = [k for k in items if isinstance(k, (bool, np.bool_)) or not isinstance(k, (int, np.integer))
               or not 0 <= k < n]
        if bad or not items:
            raise GeometryError(f"exits must be indices in [0, {n}) of the geometry's exits, got {exits!r}")
        return tuple(sorted({int(k) for k in items}))

    @classmethod
    def cached(cls, geometry: Geometry, resolution_m: float = 0.05, wall_slowdown=None,
               speed_m_s: float = 1.0, clearance_m: float = 0.0, exits=None) -> "NavigationField":
        """The field for ``geometry`` with these settings, computed on first use and then reused."""
        key = (float(resolution_m), cls.check_wall_slowdown(wall_slowdown), float(speed_m_s),
               cls._check_clearance(clearance_m))
        exits = cls._check_exits(exits, geometry)
        if exits is not None:
            key += (exits,)
        if not isinstance(geometry, Geometry):
            raise GeometryError(f"NavigationField needs a Geometry, got {type(geometry).__name__}")
        key += (shapely.to_wkb(geometry.walkable_area), tuple(shapely.to_wkb(e) for e in geometry.exits))
        field = cls._cache.pop(key, None)
        if field is None:
            field = cls(geometry, resolution_m, wall_slowdown, speed_m_s, clearance_m, exits)
        cls._cache[key] = field  # most recently used last
        while len(cls._cache) > cls.cache_size:
            cls._cache.popitem(last=False)
        return field

    @classmethod
    def uniform(cls, geometry: Geometry, direction, resolution_m: float = 0.05,
                speed_m_s: float = 1.0) -> "NavigationField":
        """A field without fast marching: the same e_d = ``direction`` ((2,), normalised) at every node and
        T = (max p·e_d − p·e_d)/V over the grid, which decreases along e_d. The navigation along the axis
        of a periodic corridor (no exits: T is only a potential that falls in the walking direction and
        jumps at the seam). On the grid of :meth:`Geometry.rasterize`, so compiled code samples it like any
        field (:func:`~crowd_env.walking.agent.compile_navigation`)."""
        if not isinstance(geometry, Geometry):
            raise GeometryError(f"NavigationField needs a Geometry, got {type(geometry).__name__}")
        e = np.asarray(direction, dtype=np.float64).reshape(-1)
        norm = float(np.hypot(*e)) if e.shape == (2,) and np.isfinite(e).all() else 0.0
        if norm <= 0.0:
            raise GeometryError(f"direction must be a finite non-zero (2,) vector, got {direction!r}")
        field = cls.__new__(cls)
        field.speed_m_s = check_number("speed_m_s", speed_m_s, error=GeometryError, positive=True)
        field.geometry, field.wall_slowdown, field.clearance_m, field.exits = geometry, None, 0.0, None
        raster = field.raster = geometry.rasterize(resolution_m)
        field.resolution_m, field.origin_m, field.walkable = raster.resolution_m, raster.origin_m, raster.walkable
        e = e / norm
        along = (raster.node_points() @ e).reshape(raster.shape)
        travel = (along.max() - along) / field.speed_m_s
        grid = np.broadcast_to(e, (*raster.shape, 2)).copy()
        field.reachable = np.ones(raster.shape, dtype=bool)
        for arr in (travel, grid, field.reachable):
            arr.setflags(write=False)
        field.travel_time_s_grid, field.direction_grid = travel, grid
        return field

    @property
    def max_travel_time_s(self) -> float:
        """Largest finite travel time on the grid (s)."""
        t = self.travel_time_s_grid
        return float(np.max(t[np.isfinite(t)]))

    @property
    def shape(self) -> tuple:
        return self.travel_time_s_grid.shape

    def sample(self, points):
        """Desired directions e_d (N, 2) (unit vectors, Eq. 13) and travel times T (N,) in s at ``points``.

        Raises :class:`GeometryError` for non-finite points or points outside the grid.
        """
        pts = np.ascontiguousarray(points, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 2:
            raise GeometryError(f"points must have shape (N, 2), got {pts.shape}")
        n = pts.shape[0]
        out_dir = np.empty((n, 2))
        out_time = np.empty(n)
        bad = sample_bilinear(pts, float(self.origin_m[0]), float(self.origin_m[1]), self.resolution_m,
                               self.travel_time_s_grid, self.direction_grid, out_dir, out_time)
        if bad >= 0:
            x0, y0 = self.origin_m
            x1 = x0 + (self.shape[0] - 1) * self.resolution_m
            y1 = y0 + (self.shape[1] - 1) * self.resolution_m
            raise GeometryError(f"point {bad} at {pts[bad].tolist()} is outside the navigation grid "
                                f"x in [{x0:.4g}, {x1:.4g}], y in [{y0:.4g}, {y1:.4g}] (or not finite)")
        return out_dir, out_time

    def direction(self, points) -> np.ndarray:
        """Desired directions e_d (N, 2) only."""
        return self.sample(points)[0]

    def travel_time(self, points) -> np.ndarray:
        """Travel times T (N,) in s only."""
        return self.sample(points)[1]

    def check_reachable(self, points, what: str = "point") -> None:
        """Raise :class:`GeometryError` naming the first of ``points`` from which no exit can be reached."""
        _, t = self.sample(points)
        bad = np.flatnonzero(~np.isfinite(t))
        if bad.size:
            p = np.asarray(points, dtype=np.float64)[bad[0]]
            target = "any exit" if self.exits is None else f"exit(s) {list(self.exits)}"
            raise GeometryError(f"{what} {int(bad[0])} at {p.tolist()} cannot reach {target} "
                                f"({bad.size} such point(s); the travel time is infinite there)")


class _IndexedQueries:
    """``direction`` and ``travel_time`` of a field whose queries take the pedestrians' ``index``."""

    def direction(self, points, index=None) -> np.ndarray:
        """Desired directions e_d (n, 2) only."""
        return self.sample(points, index)[0]

    def travel_time(self, points, index=None) -> np.ndarray:
        """Travel times T (n,) in s only."""
        return self.sample(points, index)[1]


class DestinationNavigation(_IndexedQueries):
    """Per-pedestrian destinations: pedestrian i follows the field of exit ``destination[i]`` (Eq. 11-13
    with T = 0 on that exit only), or of all exits where ``destination[i] = -1``.

    ``fields``: destination -> :class:`NavigationField` (key -1: the nearest-exit field).
    ``destination``: (N,) int. Queries take the pedestrians' indices ``index`` (N-indexing) besides
    their ``points``; each destination's field is sampled once for its pedestrians (vectorised).
    """

    per_pedestrian = True

    def __init__(self, fields: dict, destination):
        dest = np.array(destination, dtype=np.int64)
        if dest.ndim != 1:
            raise GeometryError(f"destination must be a 1-D array of exit indices, got shape {dest.shape}")
        missing = sorted(set(np.unique(dest).tolist()) - set(fields))
        if missing:
            raise GeometryError(f"no navigation field for destination(s) {missing}")
        dest.setflags(write=False)
        self.fields = dict(fields)
        self.destination = dest

    def _index(self, points, index):
        pts = np.ascontiguousarray(points, dtype=np.float64)
        if index is None:
            raise GeometryError("per-pedestrian navigation needs the pedestrians' indices (index=...)")
        idx = np.asarray(index, dtype=np.int64).reshape(-1)
        if pts.ndim != 2 or pts.shape[1] != 2 or pts.shape[0] != idx.shape[0]:
            raise GeometryError(f"points must have shape ({idx.shape[0]}, 2) (one per index), got {pts.shape}")
        if idx.size and (idx.min() < 0 or idx.max() >= self.destination.shape[0]):
            raise GeometryError(f"pedestrian indices outside [0, {self.destination.shape[0]})")
        return pts, idx

    def sample(self, points, index=None):
        """e_d (n, 2) and T (n,) of pedestrians ``index`` at ``points``, each from its own destination's field."""
        pts, idx = self._index(points, index)
        out_dir = np.empty((pts.shape[0], 2))
        out_time = np.empty(pts.shape[0])
        dest = self.destination[idx]
        for d in np.unique(dest):
            sel = dest == d
            out_dir[sel], out_time[sel] = self.fields[int(d)].sample(pts[sel])
        return out_dir, out_time

    @property
    def max_travel_time_s(self) -> float:
        return max(f.max_travel_time_s for f in self.fields.values())

    def check_reachable(self, points, index=None, what: str = "point") -> None:
        """Raise :class:`GeometryError` naming the first pedestrian that cannot reach its destination."""
        pts, idx = self._index(points, index)
        _, t = self.sample(pts, idx)
        bad = np.flatnonzero(~np.isfinite(t))
        if bad.size:
            i = int(idx[bad[0]])
            d = int(self.destination[i])
            target = "any exit" if d < 0 else f"its destination exit {d}"
            raise GeometryError(f"{what} {i} at {pts[bad[0]].tolist()} cannot reach {target} "
                                f"({bad.size} such point(s); the travel time is infinite there)")


class RigidlyMovedNavigation(_IndexedQueries):
    """A navigation field carried along by a rigid motion p ↦ R(φ) p + t of its geometry.

    Eq. 11-12 are invariant under rigid motions, so the moved field is the original one read at the
    moved-back point, its e_d turned by φ: e_d'(p) = R(φ) e_d(R(−φ)(p − t)), T'(p) = T(R(−φ)(p − t)).
    Unlike a field solved anew on the moved geometry, it keeps the original grid, so a moved scenario
    is the same task to rounding (:meth:`crowd_env.scenarios.Scenario.moved`). ``base``: a
    :class:`NavigationField` or :class:`DestinationNavigation`; queries take ``index`` as the base does.
    """

    def __init__(self, base, rotation_rad: float, translation_m=(0.0, 0.0)):
        t = np.asarray(translation_m, dtype=np.float64).reshape(-1)
        if t.shape != (2,) or not np.isfinite(t).all() or not np.isfinite(rotation_rad):
            raise GeometryError(f"a rigid motion needs a finite angle and a finite (2,) translation, got "
                                f"{rotation_rad!r} and {translation_m!r}")
        self.base = base
        self.rotation_rad = float(rotation_rad)
        self.translation_m = t
        self.cos, self.sin = float(np.cos(rotation_rad)), float(np.sin(rotation_rad))
        self.per_pedestrian = bool(getattr(base, "per_pedestrian", False))

    def _back(self, points) -> np.ndarray:
        p = np.asarray(points, dtype=np.float64) - self.translation_m
        return np.ascontiguousarray(np.stack((self.cos * p[:, 0] + self.sin * p[:, 1],
                                              -self.sin * p[:, 0] + self.cos * p[:, 1]), axis=1))

    def sample(self, points, index=None):
        """e_d (n, 2) and T (n,) at ``points`` of the moved geometry."""
        pts = np.asarray(points, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 2:
            raise GeometryError(f"points must have shape (N, 2), got {pts.shape}")
        q = self._back(pts)
        e, t = self.base.sample(q, index) if self.per_pedestrian else self.base.sample(q)
        return np.stack((self.cos * e[:, 0] - self.sin * e[:, 1], self.sin * e[:, 0] + self.cos * e[:, 1]), axis=1), t

    @property
    def max_travel_time_s(self) -> float:
        return self.base.max_travel_time_s

    def check_reachable(self, points, index=None, what: str = "point") -> None:
        """As the base field's, at the moved-back points."""
        q = self._back(np.asarray(points, dtype=np.float64).reshape(-1, 2))
        if self.per_pedestrian:
            self.base.check_reachable(q, index, what=what)
        else:
            self.base.check_reachable(q, what=what)
