"""The observation assembler: components by name, their layout and bounds, and one pass per step.

:class:`ObservationBuilder` resolves the ``observation_components`` option (:func:`resolve_components`:
built-in names of :data:`COMPONENTS`, ``"module:attribute"`` import paths or component objects), lays
their blocks out in that order, computes the work they share once per step in one compiled call
(:func:`_prepare`: the navigation sampling, the k-nearest search on a cell grid,
:func:`crowd_env.core.neighbors.grid_k_nearest`, and the headings' cos and sin) and lets each component
fill its own columns for all agents at once; nothing loops over agents in Python. The built-in components
(:data:`_KINDS`) are written by one compiled function, :func:`_write_builtins`, in the same call as the shared work
when every component is built in (:func:`_observe`); a component of another module then fills its columns from
Python.
"""
from __future__ import annotations

import importlib

import numba as nb
import numpy as np

from crowd_env.errors import EnvOptionError

from ...core.neighbors import grid_k_nearest
from ...walking.navigation import NavigationField, sample_bilinear
from .base import ObservationComponent, ObservationContext, ObservationSpec, check_frame
from .desired_direction import DesiredDirection
from .free_distance import FreeDistance, write_free_distance
from .heading import Heading, write_heading
from .local_density import LocalDensity, write_density
from .neighbors import Neighbors, write_neighbors
from .travel_time import TravelTime, write_column
from .velocity import Velocity, write_in_frame
from .wall_rays import WallRays, ray_table, write_rays

__all__ = ["COMPONENTS", "DEFAULT_COMPONENTS", "resolve_components", "observation_fields", "observation_layout",
           "observation_size", "ObservationBuilder"]

# The built-in components by name (each in its own module of this package).
COMPONENTS = {c.name: c for c in (Velocity, Heading, DesiredDirection, TravelTime, Neighbors, WallRays, FreeDistance,
                                  LocalDensity)}
# The default observation, in order (the heading drops out of the egocentric frame by itself).
DEFAULT_COMPONENTS = ("velocity", "heading", "desired_direction", "travel_time", "neighbors", "wall_rays")
OPTION = "observation_components"


def _component(item):
    """One entry of the option as a component object (None when it names none)."""
    if isinstance(item, str):
        if item in COMPONENTS:
            return COMPONENTS[item]()
        if ":" not in item:
            return None
        module, _, attr = item.partition(":")
        try:
            item = getattr(importlib.import_module(module), attr)
        except (ImportError, AttributeError) as exc:
            raise EnvOptionError(f"{OPTION}: cannot import {module!r}:{attr!r} ({exc})") from None
    if isinstance(item, type) and issubclass(item, ObservationComponent):
        item = item()
    return item if isinstance(item, ObservationComponent) else None


def resolve_components(components=None) -> tuple:
    """The component objects of the ``observation_components`` option: None for :data:`DEFAULT_COMPONENTS`,
    else a sequence of names of :data:`COMPONENTS`, ``"module:Class"`` paths or ObservationComponent objects
    (or classes). Raises :class:`~crowd_env.errors.EnvOptionError` naming the option for anything else and for
    two blocks of one name."""
    if components is None:
        components = DEFAULT_COMPONENTS
    if isinstance(components, (str, ObservationComponent)) or not hasattr(components, "__iter__"):
        raise EnvOptionError(f"{OPTION} must be a sequence of component names or objects, got {components!r}")
    out = []
    for item in components:
        comp = _component(item)
        if comp is None:
            raise EnvOptionError(f"{OPTION}: unknown component {item!r}; known: {sorted(COMPONENTS)}, a "
                                 "'module:Class' import path or an ObservationComponent object")
        if not comp.fields:
            raise EnvOptionError(f"{OPTION}: component {type(comp).__name__} declares no fields")
        out.append(comp)
    seen = set()
    for c in out:
        own = {f.name for frame in ("world", "egocentric") for f in c.fields_in(frame)}
        twice = own & seen
        if twice:
            raise EnvOptionError(f"{OPTION}: the field(s) {sorted(twice)} appear twice (components "
                                 f"{[type(x).__name__ for x in out]})")
        seen |= own
    return tuple(out)


def observation_fields(frame: str = "world", components=None) -> tuple:
    """The :class:`~.base.ObservationField` blocks of ``frame``, in order."""
    frame = check_frame(frame)
    return tuple(f for c in resolve_components(components) for f in c.fields_in(frame))


def observation_layout(n_neighbors: int, n_rays: int, frame: str = "world", components=None) -> dict:
    """Field name -> ``slice`` into the observation vector of ``frame``."""
    out, start = {}, 0
    for f in observation_fields(frame, components):
        size = f.size_of(n_neighbors, n_rays)
        out[f.name] = slice(start, start + size)
        start += size
    return out


def observation_size(n_neighbors: int, n_rays: int, frame: str = "world", components=None) -> int:
    """Length of the observation vector: 7 + 5 k + R (world frame), 5 + 5 k + R (egocentric) by default."""
    return sum(f.size_of(n_neighbors, n_rays) for f in observation_fields(frame, components))


class ObservationBuilder:
    """Builds the observations of a set of pedestrians from a :class:`~crowd_env.core.state.CrowdState`.

    ``navigation``: a field with ``sample(points) -> (e_d, T)``, or ``sample(points, index)`` when its
    ``per_pedestrian`` attribute is true (per-pedestrian destinations); ``walls``: (S, 4) segments.
    ``velocity_bound_m_s`` and ``travel_time_bound_s`` only set the declared bounds of the space;
    ``frame``: one of :data:`~.base.FRAMES`; ``period_m``: the periodicity along x of the simulation
    (``Simulator.period_m``; neighbours and their offsets at the nearest image; 0: none);
    ``components``: the ``observation_components`` option (:func:`resolve_components`).
    """

    def __init__(self, navigation, walls, *, n_neighbors: int, n_rays: int, neighbor_radius_m: float,
                 ray_range_m: float, velocity_bound_m_s: float, travel_time_bound_s: float, frame: str = "world",
                 period_m: float = 0.0, components=None):
        self.frame = check_frame(frame)
        self.navigation = navigation
        self.walls = np.ascontiguousarray(walls, dtype=np.float64).reshape(-1, 4)
        self.n_neighbors = int(n_neighbors)
        self.n_rays = int(n_rays)
        self.neighbor_radius_m = float(neighbor_radius_m)
        self.ray_range_m = float(ray_range_m)
        self.spec = ObservationSpec(self.n_neighbors, self.n_rays, self.neighbor_radius_m, self.ray_range_m,
                                    float(velocity_bound_m_s), float(travel_time_bound_s), self.frame, float(period_m))
        self.components = resolve_components(components)
        self.layout = observation_layout(self.n_neighbors, self.n_rays, self.frame, self.components)
        self.size = sum(s.stop - s.start for s in self.layout.values())
        self._per_pedestrian = bool(getattr(navigation, "per_pedestrian", False))
        # a plain field is sampled inside the compiled pass (its grid); any other field from Python first
        self._grid = _grid_of(navigation) if type(navigation) is NavigationField else None
        self._walls_d = np.ascontiguousarray(np.column_stack(
            (self.walls[:, :2], self.walls[:, 2:] - self.walls[:, :2])))  # start (x, y) and direction (ex, ey)
        self._parts, self.low, self.high = self._lay_out()
        self._search_k = self.n_neighbors if any(c.uses_neighbors for c, _, _ in self._parts) else 0
        self._search = (self._search_k, self.spec.neighbor_radius_m, self.spec.period_m)  # _prepare's search
        self._fused = self._compiled_table()
        compiled = () if self._fused is None else self._fused[-1]
        self._writers = tuple((c.write, col, size) for c, col, size in self._parts if type(c) not in _KINDS
                              or not len(compiled))  # written from Python: components of other modules

    def _compiled_table(self):
        """What :func:`_write_builtins` reads that stays the same at every step (its ``tables``: the frame, the walls
        twice, the rays and their range), its table last: a row per built-in component (:data:`_KINDS`: every one of
        :data:`COMPONENTS`) with entries, in their order (its kind, its first column and its constants); None when
        there is none. The builder writes them all in one compiled call (with the shared work, :func:`_observe`,
        when no other component needs the context)."""
        rows = [_table_row(c, col) for c, col, _ in self._parts if type(c) in _KINDS]
        if not rows:
            return None
        ray_cos, ray_sin = ray_table(self.n_rays)
        spec = self.spec
        return (self.frame == "world", self.walls, self._walls_d, ray_cos, ray_sin, spec.ray_range_m,
                np.array(rows, np.float64))

    def _lay_out(self) -> tuple:
        """The (component, first column, size) of every component with entries, and the bounds."""
        low = np.empty(self.size, np.float32)
        high = np.empty(self.size, np.float32)
        parts, col = [], 0
        for comp in self.components:
            size = comp.size(self.spec)
            if not comp.fields_in(self.frame):
                continue
            lo, hi = comp.bounds(self.spec)
            try:
                low[col:col + size] = lo
                high[col:col + size] = hi
            except ValueError:
                raise EnvOptionError(f"{OPTION}: {type(comp).__name__}.bounds() gives bounds that do not fit its "
                                     f"{size} entries") from None
            if size:
                parts.append((comp, col, size))
            col += size
        return parts, low, high

    def build(self, state, index: np.ndarray):
        """Observations ``(m, D)`` float32 of pedestrians ``index`` (global indices, exited ones allowed),
        and their travel times ``(m,)`` float64 (for rewards)."""
        obs, travel, _ = self.observe(state, index)
        return obs, travel

    def observe(self, state, index: np.ndarray):
        """:meth:`build` plus the speeds ``(m,)`` in m/s of pedestrians ``index``: the shared work in one
        compiled call, then each component's columns."""
        index = np.asarray(index, dtype=np.int64)
        m = index.shape[0]
        obs = np.zeros((m, self.size), np.float32)
        travel = np.empty(m)
        speed = np.empty(m)
        if m == 0:
            return obs, travel, speed
        e_d = np.empty((m, 2))
        nav = self._grid
        if nav is None:  # a field the kernel cannot read: sample it first (vectorised), pass e_d and T in
            pos = state.position_m[index]
            if self._per_pedestrian:
                e_d, travel = self.navigation.sample(pos, index)
            else:
                e_d, travel = self.navigation.sample(pos)
            nav = _NO_GRID
        fused = self._fused
        crowd = (state.position_m, state.velocity_m_s, state.heading_rad, state.active, state.radius_m)
        grid = (nav[0], nav[1], nav[2], nav is not _NO_GRID)
        if fused is not None and not self._writers:  # built-in components only: one compiled call
            bad = _observe(crowd, index, grid, self._search, (e_d, travel, speed), fused, obs)
            if bad >= 0:  # outside the navigation grid: the field raises its own error
                self.navigation.sample(state.position_m[index[bad:bad + 1]])
            return obs, travel, speed
        spec = self.spec
        velocity = np.empty((m, 2))
        cos_t = np.empty(m)
        sin_t = np.empty(m)
        bad, act, near = _prepare(crowd, index, grid, self._search, (e_d, travel, speed, velocity, cos_t, sin_t))
        if bad >= 0:  # outside the navigation grid: the field raises its own error
            self.navigation.sample(state.position_m[index[bad:bad + 1]])
            return obs, travel, speed
        if fused is not None:
            _write_builtins(crowd, index, (act, near, velocity, cos_t, sin_t, e_d, travel), spec.period_m, fused, obs)
        ctx = ObservationContext(state, index, spec, self.walls, self._walls_d, velocity, cos_t, sin_t, e_d, travel,
                                 speed, act, near, self.navigation)
        for write, col, size in self._writers:
            write(ctx, obs, col, size)
        return obs, travel, speed


_NO_GRID = (np.zeros(3), np.zeros((2, 2)), np.zeros((2, 2, 2)))
# The built-in components that _write_builtins writes, by class (a subclass, which may write otherwise, is not one):
# every one of COMPONENTS (tests/envs/test_components.py), so that none is left to a call of its own from Python.
VELOCITY, HEADING, DESIRED_DIRECTION, TRAVEL_TIME, NEIGHBORS, WALL_RAYS, FREE_DISTANCE, LOCAL_DENSITY = range(8)
_KINDS = {Velocity: VELOCITY, Heading: HEADING, DesiredDirection: DESIRED_DIRECTION, TravelTime: TRAVEL_TIME,
          Neighbors: NEIGHBORS, WallRays: WALL_RAYS, FreeDistance: FREE_DISTANCE, LocalDensity: LOCAL_DENSITY}


def _table_row(component, col: int) -> tuple:
    """A row of :func:`_write_builtins`' table: the component's kind, its first column and its constants (the
    local density's count limit, radius ρ and 1/(π ρ²))."""
    if type(component) is LocalDensity:
        return LOCAL_DENSITY, col, component.max_count, component.radius_m, component.per_area
    return _KINDS[type(component)], col, 0.0, 0.0, 0.0


def _grid_of(field: NavigationField) -> tuple:
    """``((x0, y0, h), T grid, e_d grid)`` of a plain field, for the compiled pass."""
    return (np.array([field.origin_m[0], field.origin_m[1], field.resolution_m], np.float64),
            np.ascontiguousarray(field.travel_time_s_grid, dtype=np.float64),
            np.ascontiguousarray(field.direction_grid, dtype=np.float64))


@nb.njit(cache=True)
def _prepare(crowd, index, grid, search, out):
    """The per-step work the components share (:class:`~.base.ObservationContext`), for pedestrians ``index`` of
    ``crowd`` = ``(position, velocity, heading, active, radius)`` (the state's arrays), into ``out`` = ``(e_d, T,
    speeds, velocities, cos θ, sin θ)``: e_d and T by bilinear sampling of ``grid`` = ``((x0, y0, h), T grid, e_d
    grid, sample)`` when ``sample`` (else given), and the k nearest others on the floor within ``radius_m``, with
    ``search`` = ``(k, radius_m, period_m)`` (k = 0: none searched). Returns ``(bad, active rows, nearest (m,
    k))``: ``bad`` is −1, or the first row outside the grid."""
    position, velocity, heading, active, _ = crowd
    grid_xyh, grid_t, grid_d, sample = grid
    k, radius_m, period_m = search
    e_d, travel, speed, vel, cos_t, sin_t = out
    m = index.shape[0]
    act = np.flatnonzero(active)
    if sample:
        pos = np.empty((m, 2))
        for a in range(m):
            pos[a, 0] = position[index[a], 0]
            pos[a, 1] = position[index[a], 1]
        bad = sample_bilinear(pos, grid_xyh[0], grid_xyh[1], grid_xyh[2], grid_t, grid_d, e_d, travel)
        if bad >= 0:
            return bad, act, np.empty((0, 0), np.int64)
    near = grid_k_nearest(position, act, index, k, radius_m, period_m)  # (m, 0) at once for k = 0
    for a in range(m):
        i = index[a]
        th = heading[i]
        cos_t[a] = np.cos(th)
        sin_t[a] = np.sin(th)
        ux = velocity[i, 0]
        uy = velocity[i, 1]
        vel[a, 0] = ux
        vel[a, 1] = uy
        speed[a] = np.hypot(ux, uy)
    return -1, act, near


@nb.njit(cache=True)
def _write_builtins(crowd, index, shared, period_m, tables, obs):
    """The built-in components' columns of the pedestrians ``index`` of ``crowd`` (:func:`_prepare`), each by the
    kernel its own ``write`` calls, from the shared work ``shared`` = ``(act, near, vel, cos_t, sin_t, e_d, travel)``
    of :func:`_prepare`; ``tables`` = ``(world frame, walls (S, 4), walls as start and direction, ray cos, ray sin,
    ray range, table)`` (:meth:`ObservationBuilder._compiled_table`; ``table``: a row per component,
    :func:`_table_row`)."""
    position, velocity, _, _, radius = crowd
    act, near, vel, cos_t, sin_t, e_d, travel = shared
    world, walls, walls_d, ray_cos, ray_sin, ray_range_m, table = tables
    for row in range(table.shape[0]):
        kind = int(table[row, 0])
        col = int(table[row, 1])
        if kind == VELOCITY:
            write_in_frame(vel, cos_t, sin_t, world, obs, col)
        elif kind == HEADING:
            write_heading(cos_t, sin_t, obs, col)
        elif kind == DESIRED_DIRECTION:
            write_in_frame(e_d, cos_t, sin_t, world, obs, col)
        elif kind == TRAVEL_TIME:
            write_column(travel, obs, col)
        elif kind == NEIGHBORS:
            write_neighbors(position, velocity, index, act, near, cos_t, sin_t, world, period_m, obs, col)
        elif kind == WALL_RAYS:
            write_rays(position, index, cos_t, sin_t, walls_d, ray_cos, ray_sin, ray_range_m, obs, col)
        elif kind == FREE_DISTANCE:
            write_free_distance(position, radius, index, act, near, cos_t, sin_t, walls, period_m, ray_range_m, obs,
                                col)
        elif kind == LOCAL_DENSITY:
            found = grid_k_nearest(position, act, index, int(table[row, 2]), table[row, 3], period_m)
            write_density(found, table[row, 4], obs, col)


@nb.njit(cache=True)
def _observe(crowd, index, grid, search, given, tables, obs):
    """An observation of built-in components only, in one compiled call: :func:`_prepare` (``given`` = ``(e_d, T,
    speeds)``, its first outputs), then :func:`_write_builtins`. Returns −1, or the first row outside the navigation
    grid."""
    e_d, travel, speed = given
    m = index.shape[0]
    vel = np.empty((m, 2))
    cos_t = np.empty(m)
    sin_t = np.empty(m)
    bad, act, near = _prepare(crowd, index, grid, search, (e_d, travel, speed, vel, cos_t, sin_t))
    if bad >= 0:
        return bad
    _write_builtins(crowd, index, (act, near, vel, cos_t, sin_t, e_d, travel), search[2], tables, obs)
    return -1
