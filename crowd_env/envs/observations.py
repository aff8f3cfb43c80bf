"""Per-agent observation vectors of the crowd environment, built for all agents at once.

One observation is a flat ``float32`` vector in one of two frames (the environment's
``observation_frame`` option; :data:`FRAMES`). With ``k`` neighbours and ``R`` rays:

``"world"`` (default): vectors in the scenario's x, y axes; ``7 + 5 k + R`` entries, in this order
(:data:`OBSERVATION_FIELDS`; :func:`observation_layout` gives the slices):

==========================  =====  ====================================================================
field                       size   meaning (units)
==========================  =====  ====================================================================
``velocity``                2      own velocity (u_x, u_y) in m/s
``heading``                 2      (cos θ, sin θ) of the own heading θ
``desired_direction``       2      e_d = −∇T/‖∇T‖ of the (own destination's) eikonal field at the own
                                   position (unit vector)
``travel_time``             1      T at the own position: remaining travel time to the nearest exit (to
                                   the own destination exit in scenarios with destinations) in s at the
                                   field's wavefront speed (1 m/s by default, so numerically the
                                   geodesic distance in m); 0 inside an exit
``neighbors``               4 k    for each of the k nearest other pedestrians within
                                   ``neighbor_radius_m`` (nearest first): (x_j − x_i, y_j − y_i) in m and
                                   (u_j − u_i) in m/s; zeros where there are fewer than k
``neighbor_mask``           k      1 for a real neighbour in that slot, 0 for padding
``wall_rays``               R      distance in m from the own centre to the first wall along R rays at
                                   angles θ + 2π r / R (r = 0 … R−1; ray 0 points along the heading),
                                   capped at ``ray_range_m``
==========================  =====  ====================================================================

``"egocentric"``: every vector in the pedestrian's body frame: x forward along its heading θ, y to its
left (a world vector v becomes R(−θ) v). The heading itself is then the frame, so the field is left
out: ``5 + 5 k + R`` entries (:data:`EGOCENTRIC_OBSERVATION_FIELDS`): ``velocity`` (forward, left
speed), ``desired_direction`` (e_d in the body frame), ``travel_time``, ``neighbors`` (relative
positions and velocities in the body frame), ``neighbor_mask``, ``wall_rays`` (unchanged: the rays
are already relative to the heading). Nothing in it depends on the scenario's orientation or
position: a rotated and shifted copy of a scenario gives the same observations
(``tests/envs/test_frames.py``).

Neighbours are every other active pedestrian, controlled or background. The builder fills every row
in one compiled pass: the field's bilinear sampling (a plain
:class:`~crowd_env.walking.navigation.NavigationField`; other fields are sampled, vectorised, just
before), one k-nearest search on a cell grid for all agents
(:func:`crowd_env.core.neighbors.grid_k_nearest`), the wall rays (the ray–segment test of
:func:`crowd_env.core.segments.ray_distances`; ray r points along the heading turned by 2πr/R) and
the turns into the body frame; nothing loops over agents in Python.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from crowd_env.errors import EnvOptionError

from ..core.neighbors import grid_k_nearest
from ..core.periodic import minimum_image_dx
from ..walking.navigation import NavigationField, sample_bilinear

__all__ = ["FRAMES", "OBSERVATION_FIELDS", "EGOCENTRIC_OBSERVATION_FIELDS", "ObservationField", "observation_fields",
           "observation_layout", "observation_size", "check_frame", "ObservationBuilder"]

FRAMES = ("world", "egocentric")


@dataclass(frozen=True)
class ObservationField:
    """One block of the observation vector: ``size`` is an expression in k (neighbours) and R (rays)."""

    name: str
    size: str
    description: str


OBSERVATION_FIELDS: tuple = (
    ObservationField("velocity", "2", "own velocity (u_x, u_y), m/s, world frame"),
    ObservationField("heading", "2", "(cos θ, sin θ) of the own heading"),
    ObservationField("desired_direction", "2", "e_d of the eikonal field at the own position (unit vector)"),
    ObservationField("travel_time", "1", "remaining travel time T to the nearest exit (the own destination exit "
                                         "with destinations), s at the field's speed (1 m/s: the geodesic "
                                         "distance in m); 0 inside an exit"),
    ObservationField("neighbors", "4k", "k nearest others within neighbor_radius_m, nearest first: relative "
                                        "position (m) and relative velocity (m/s) each; zero padded"),
    ObservationField("neighbor_mask", "k", "1 for a real neighbour in the slot, 0 for padding"),
    ObservationField("wall_rays", "R", "distance (m) from the own centre to the first wall along R rays at "
                                       "θ + 2πr/R, capped at ray_range_m"),
)

EGOCENTRIC_OBSERVATION_FIELDS: tuple = (
    ObservationField("velocity", "2", "own velocity in the body frame (forward, left), m/s"),
    ObservationField("desired_direction", "2", "e_d of the eikonal field at the own position, body frame (unit "
                                               "vector)"),
    OBSERVATION_FIELDS[3],
    ObservationField("neighbors", "4k", "k nearest others within neighbor_radius_m, nearest first: relative "
                                        "position (m) and relative velocity (m/s) each, body frame; zero padded"),
    OBSERVATION_FIELDS[5],
    OBSERVATION_FIELDS[6],
)


def check_frame(frame) -> str:
    """``frame`` if it is one of :data:`FRAMES`, else :class:`~crowd_env.errors.EnvOptionError` naming them."""
    if not isinstance(frame, str) or frame not in FRAMES:
        raise EnvOptionError(f"observation_frame must be one of {list(FRAMES)}, got {frame!r}")
    return frame


def observation_fields(frame: str = "world") -> tuple:
    """The :class:`ObservationField` blocks of ``frame``, in order."""
    return OBSERVATION_FIELDS if check_frame(frame) == "world" else EGOCENTRIC_OBSERVATION_FIELDS


def _field_sizes(n_neighbors: int, n_rays: int, frame: str = "world") -> dict:
    k, r = int(n_neighbors), int(n_rays)
    size = {"velocity": 2, "heading": 2, "desired_direction": 2, "travel_time": 1, "neighbors": 4 * k,
            "neighbor_mask": k, "wall_rays": r}
    return {f.name: size[f.name] for f in observation_fields(frame)}


def observation_layout(n_neighbors: int, n_rays: int, frame: str = "world") -> dict:
    """Field name -> ``slice`` into the observation vector of ``frame``."""
    out, start = {}, 0
    for name, size in _field_sizes(n_neighbors, n_rays, frame).items():
        out[name] = slice(start, start + size)
        start += size
    return out


def observation_size(n_neighbors: int, n_rays: int, frame: str = "world") -> int:
    """Length of the observation vector: 7 + 5 k + R (world frame), 5 + 5 k + R (egocentric)."""
    return sum(_field_sizes(n_neighbors, n_rays, frame).values())


def to_body_frame(vectors: np.ndarray, cos_t: np.ndarray, sin_t: np.ndarray) -> np.ndarray:
    """World vectors (m, ..., 2) -> body frames of headings θ (m,): R(−θ) v = (c v_x + s v_y, −s v_x + c v_y)."""
    shape = (-1,) + (1,) * (vectors.ndim - 2)
    c, s = cos_t.reshape(shape), sin_t.reshape(shape)
    x, y = vectors[..., 0], vectors[..., 1]
    return np.stack((c * x + s * y, c * y - s * x), axis=-1)


def to_world_frame(vectors: np.ndarray, cos_t: np.ndarray, sin_t: np.ndarray) -> np.ndarray:
    """Body-frame vectors (m, 2) of headings θ -> world: R(θ) v (the inverse of :func:`to_body_frame`)."""
    x, y = vectors[:, 0], vectors[:, 1]
    return np.stack((cos_t * x - sin_t * y, sin_t * x + cos_t * y), axis=-1)


class ObservationBuilder:
    """Builds the observations of a set of pedestrians from a :class:`~crowd_env.core.state.CrowdState`.

    ``navigation``: a field with ``sample(points) -> (e_d, T)``, or ``sample(points, index)`` when its
    ``per_pedestrian`` attribute is true (per-pedestrian destinations); ``walls``: (S, 4) segments.
    ``velocity_bound_m_s`` and ``travel_time_bound_s`` only set the declared bounds of the space;
    ``frame``: one of :data:`FRAMES`; ``period_m``: the periodicity along x of the simulation
    (``Simulator.period_m``; neighbours and their offsets at the nearest image; 0: none).
    """

    def __init__(self, navigation, walls, *, n_neighbors: int, n_rays: int, neighbor_radius_m: float,
                 ray_range_m: float, velocity_bound_m_s: float, travel_time_bound_s: float, frame: str = "world",
                 period_m: float = 0.0):
        self.frame = check_frame(frame)
        self.navigation = navigation
        self.walls = np.ascontiguousarray(walls, dtype=np.float64).reshape(-1, 4)
        self.n_neighbors = int(n_neighbors)
        self.n_rays = int(n_rays)
        self.neighbor_radius_m = float(neighbor_radius_m)
        self.ray_range_m = float(ray_range_m)
        self.layout = observation_layout(self.n_neighbors, self.n_rays, self.frame)
        self.size = observation_size(self.n_neighbors, self.n_rays, self.frame)
        self.ray_offsets = 2.0 * np.pi * np.arange(self.n_rays) / max(self.n_rays, 1)
        # ray r points along R(θ) (cos φ_r, sin φ_r): the heading turned by the fixed offset φ_r = 2πr/R
        self.ray_cos, self.ray_sin = np.cos(self.ray_offsets), np.sin(self.ray_offsets)
        self._per_pedestrian = bool(getattr(navigation, "per_pedestrian", False))
        # a plain field is sampled inside the compiled pass (its grid); any other field from Python first
        self._grid = _grid_of(navigation) if type(navigation) is NavigationField else None
        self._walls_d = np.ascontiguousarray(np.column_stack(
            (self.walls[:, :2], self.walls[:, 2:] - self.walls[:, :2])))  # start (x, y) and direction (ex, ey)
        low = np.empty(self.size, np.float32)
        high = np.empty(self.size, np.float32)
        L = self.layout
        v = float(velocity_bound_m_s)
        for name, lo, hi in (("velocity", -v, v), ("heading", -1.0, 1.0), ("desired_direction", -1.0, 1.0),
                             ("travel_time", 0.0, float(travel_time_bound_s)), ("neighbor_mask", 0.0, 1.0),
                             ("wall_rays", 0.0, self.ray_range_m)):
            if name not in L:
                continue
            low[L[name]] = lo
            high[L[name]] = hi
        nb_low = np.tile(np.array([-self.neighbor_radius_m, -self.neighbor_radius_m, -2 * v, -2 * v]), self.n_neighbors)
        low[L["neighbors"]] = nb_low
        high[L["neighbors"]] = -nb_low
        self.low, self.high = low, high
        col = {name: (L[name].start if name in L else -1) for name in
               ("velocity", "heading", "desired_direction", "travel_time", "neighbors", "neighbor_mask", "wall_rays")}
        self._ints = np.array([self.n_neighbors, self.n_rays, self.frame == "world", self._grid is not None,
                               *col.values()], np.int64)
        self._floats = np.array([self.neighbor_radius_m, self.ray_range_m, float(period_m)], np.float64)

    def build(self, state, index: np.ndarray):
        """Observations ``(m, D)`` float32 of pedestrians ``index`` (global indices, exited ones allowed),
        and their travel times ``(m,)`` float64 (for rewards)."""
        obs, travel, _ = self.observe(state, index)
        return obs, travel

    def observe(self, state, index: np.ndarray):
        """:meth:`build` plus the speeds ``(m,)`` in m/s of pedestrians ``index``, in one compiled pass
        (navigation sampling, neighbours, wall rays, frame turns)."""
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
        bad = _observe(state.position_m, state.velocity_m_s, state.heading_rad, state.active, index, nav[0],
                       nav[1], nav[2], self._ints, self._floats, self._walls_d, self.ray_cos, self.ray_sin, obs,
                       e_d, travel, speed)
        if bad >= 0:  # outside the navigation grid: the field raises its own error
            self.navigation.sample(state.position_m[index[bad:bad + 1]])
        return obs, travel, speed


_NO_GRID = (np.zeros(3), np.zeros((2, 2)), np.zeros((2, 2, 2)))


def _grid_of(field: NavigationField) -> tuple:
    """``((x0, y0, h), T grid, e_d grid)`` of a plain field, for the compiled pass."""
    return (np.array([field.origin_m[0], field.origin_m[1], field.resolution_m], np.float64),
            np.ascontiguousarray(field.travel_time_s_grid, dtype=np.float64),
            np.ascontiguousarray(field.direction_grid, dtype=np.float64))


@nb.njit(cache=True)
def _observe(position, velocity, heading, active, index, grid_xyh, grid_t, grid_d, ints, floats, walls, ray_cos,
             ray_sin, obs, e_d, travel, speed):
    """Every observation row of pedestrians ``index`` in one pass (see :class:`ObservationBuilder`).

    ``ints``: k, R, world frame?, sample the grid here?, then the first column of velocity, heading,
    desired_direction, travel_time, neighbors, neighbor_mask, wall_rays (−1: absent); ``floats``: the
    neighbour radius and the ray range; ``walls`` (S, 4): start and direction of each segment. Writes
    ``obs`` (zeros on entry), ``e_d`` and ``travel`` (when sampled here; else read) and ``speed``.
    Returns −1, or the first row whose position lies outside the navigation grid.
    """
    m = index.shape[0]
    k, n_rays, world, sample = ints[0], ints[1], ints[2] != 0, ints[3] != 0
    c_vel, c_head, c_ed, c_t, c_nb, c_mask, c_ray = ints[4], ints[5], ints[6], ints[7], ints[8], ints[9], ints[10]
    if sample:
        pos = np.empty((m, 2))
        for a in range(m):
            pos[a, 0] = position[index[a], 0]
            pos[a, 1] = position[index[a], 1]
        bad = sample_bilinear(pos, grid_xyh[0], grid_xyh[1], grid_xyh[2], grid_t, grid_d, e_d, travel)
        if bad >= 0:
            return bad
    act = np.flatnonzero(active)
    near = grid_k_nearest(position, act, index, k, floats[0], floats[2])  # (m, 0) at once for k = 0
    ray_range = floats[1]
    dxs = np.empty(n_rays)
    dys = np.empty(n_rays)
    best = np.empty(n_rays)
    for a in range(m):
        i = index[a]
        th = heading[i]
        c = np.cos(th)
        s = np.sin(th)
        ux = velocity[i, 0]
        uy = velocity[i, 1]
        speed[a] = np.hypot(ux, uy)
        ex = e_d[a, 0]
        ey = e_d[a, 1]
        if world:
            obs[a, c_vel] = ux
            obs[a, c_vel + 1] = uy
            obs[a, c_head] = c
            obs[a, c_head + 1] = s
            obs[a, c_ed] = ex
            obs[a, c_ed + 1] = ey
        else:  # R(−θ) v = (c v_x + s v_y, c v_y − s v_x), as to_body_frame
            obs[a, c_vel] = c * ux + s * uy
            obs[a, c_vel + 1] = c * uy - s * ux
            obs[a, c_ed] = c * ex + s * ey
            obs[a, c_ed + 1] = c * ey - s * ex
        obs[a, c_t] = travel[a]
        for slot in range(k):
            r = near[a, slot]
            if r < 0 and world:
                break  # the rest are missing too (zeros)
            dx = dy = du = dv = 0.0
            if r >= 0:
                g = act[r]
                dx = minimum_image_dx(position[g, 0] - position[i, 0], floats[2])
                dy = position[g, 1] - position[i, 1]
                du = velocity[g, 0] - velocity[i, 0]
                dv = velocity[g, 1] - velocity[i, 1]
                obs[a, c_mask + slot] = 1.0
            base = c_nb + 4 * slot
            if world:
                obs[a, base] = dx
                obs[a, base + 1] = dy
                obs[a, base + 2] = du
                obs[a, base + 3] = dv
            else:  # padding turned too (signed zeros as before)
                obs[a, base] = c * dx + s * dy
                obs[a, base + 1] = c * dy - s * dx
                obs[a, base + 2] = c * du + s * dv
                obs[a, base + 3] = c * dv - s * du
        if n_rays > 0:
            _cast_rays(position[i, 0], position[i, 1], c, s, walls, ray_cos, ray_sin, ray_range, obs[a], c_ray, dxs,
                       dys, best)
    return -1


@nb.njit(cache=True, error_model="numpy")
def _cast_rays(ox, oy, c, s, walls, ray_cos, ray_sin, max_range, out, col, dxs, dys, best):
    """Distance from (ox, oy) to the first wall along each ray R(θ) (cos φ_r, sin φ_r), capped at
    ``max_range``, written to ``out[col + r]``: the ray–segment test of
    :func:`crowd_env.core.segments.ray_distances` (the same arithmetic), branch-free over the rays so that
    it runs in SIMD lanes; ``dxs``, ``dys``, ``best``: (R,) scratch."""
    n_rays = ray_cos.shape[0]
    for r in range(n_rays):
        dxs[r] = c * ray_cos[r] - s * ray_sin[r]
        dys[r] = s * ray_cos[r] + c * ray_sin[r]
        best[r] = max_range
    reach2 = (max_range * (1.0 + 1e-9) + 1e-9) ** 2
    for w in range(walls.shape[0]):
        ex = walls[w, 2]
        ey = walls[w, 3]
        wx = walls[w, 0] - ox
        wy = walls[w, 1] - oy
        # skip a wall farther than the range (no ray reaches it): its point nearest to the origin
        ee = ex * ex + ey * ey
        f = -(wx * ex + wy * ey) / ee if ee > 0.0 else 0.0
        f = min(max(f, 0.0), 1.0)
        qx = wx + f * ex
        qy = wy + f * ey
        if qx * qx + qy * qy > reach2:
            continue
        tn = wx * ey - wy * ex
        for r in range(n_rays):
            den = dxs[r] * ey - dys[r] * ex
            t = tn / den  # distance along the ray (inf or nan for a parallel wall, refused below)
            u = (wx * dys[r] - wy * dxs[r]) / den  # position along the segment
            hit = (abs(den) >= 1e-14) & (t >= 0.0) & (u >= 0.0) & (u <= 1.0) & (t < best[r])
            best[r] = t if hit else best[r]
    for r in range(n_rays):
        out[col + r] = best[r]
