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

Neighbours are every other active pedestrian, controlled or background. The builder makes one
compiled k-nearest search on a cell grid for all agents
(:func:`crowd_env.core.neighbors.grid_k_nearest`) and one call of the compiled ray kernel
(:func:`crowd_env.core.segments.ray_distances`); nothing loops over agents in Python.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from crowd_env.errors import EnvOptionError

from ..core.neighbors import grid_k_nearest
from ..core.segments import ray_distances

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
    ``frame``: one of :data:`FRAMES`.
    """

    def __init__(self, navigation, walls, *, n_neighbors: int, n_rays: int, neighbor_radius_m: float,
                 ray_range_m: float, velocity_bound_m_s: float, travel_time_bound_s: float, frame: str = "world"):
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

    def build(self, state, index: np.ndarray):
        """Observations ``(m, D)`` float32 of pedestrians ``index`` (global indices, exited ones allowed),
        and their travel times ``(m,)`` float64 (for rewards)."""
        index = np.asarray(index, dtype=np.int64)
        m = index.shape[0]
        obs = np.zeros((m, self.size), np.float32)
        if m == 0:
            return obs, np.zeros(0)
        L = self.layout
        pos = state.position_m[index]
        vel = state.velocity_m_s[index]
        theta = state.heading_rad[index]
        if getattr(self.navigation, "per_pedestrian", False):
            e_d, travel = self.navigation.sample(pos, index)
        else:
            e_d, travel = self.navigation.sample(pos)
        if self.frame == "world":
            obs[:, L["velocity"]] = vel
            obs[:, L["heading"].start] = np.cos(theta)
            obs[:, L["heading"].start + 1] = np.sin(theta)
            obs[:, L["desired_direction"]] = e_d
        else:
            c, s = np.cos(theta), np.sin(theta)
            obs[:, L["velocity"]] = to_body_frame(vel, c, s)
            obs[:, L["desired_direction"]] = to_body_frame(e_d, c, s)
        obs[:, L["travel_time"].start] = travel
        if self.n_neighbors and self.frame == "world":
            self._neighbors(state, index, obs, L["neighbors"].start, L["neighbor_mask"].start)
        elif self.n_neighbors:  # float64 first, turned into the body frame, then stored as float32 once
            k = self.n_neighbors
            near = np.zeros((m, 5 * k))
            self._neighbors(state, index, near, 0, 4 * k)
            obs[:, L["neighbors"]] = to_body_frame(near[:, :4 * k].reshape(m, 2 * k, 2), c, s).reshape(m, 4 * k)
            obs[:, L["neighbor_mask"]] = near[:, 4 * k:]
        if self.n_rays:
            if self.walls.shape[0]:
                angles = theta[:, None] + self.ray_offsets[None, :]
                obs[:, L["wall_rays"]] = ray_distances(np.ascontiguousarray(pos), angles, self.walls, self.ray_range_m)
            else:
                obs[:, L["wall_rays"]] = self.ray_range_m
        return obs, travel

    def _neighbors(self, state, index, out: np.ndarray, col_rel: int, col_mask: int) -> None:
        """Write the k nearest other active pedestrians' relative positions/velocities (world frame, from
        column ``col_rel``) and the mask (from column ``col_mask``) into the rows of ``out``."""
        active = np.flatnonzero(state.active)
        if active.size == 0:
            return
        j = grid_k_nearest(state.position_m, active, index, self.n_neighbors, self.neighbor_radius_m)
        _fill_neighbors(out, col_rel, col_mask, index, j, active, state.position_m, state.velocity_m_s)


@nb.njit(cache=True)
def _fill_neighbors(out, col_rel, col_mask, index, j, active, position, velocity):
    """For each row a: the neighbours j[a] (rows into ``active``, nearest first, −1 when missing) ->
    relative position/velocity and mask 1."""
    for a in range(index.shape[0]):
        i = index[a]
        for slot in range(j.shape[1]):
            r = j[a, slot]
            if r < 0:
                break  # the rest are missing too
            g = active[r]
            base = col_rel + 4 * slot
            out[a, base] = position[g, 0] - position[i, 0]
            out[a, base + 1] = position[g, 1] - position[i, 1]
            out[a, base + 2] = velocity[g, 0] - velocity[i, 0]
            out[a, base + 3] = velocity[g, 1] - velocity[i, 1]
            out[a, col_mask + slot] = 1.0
