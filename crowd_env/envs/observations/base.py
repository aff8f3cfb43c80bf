"""What an observation component is: its blocks of the vector, their sizes and bounds, and what it reads.

A component (:class:`ObservationComponent`) owns one or more consecutive blocks (:class:`ObservationField`)
of the observation vector. The assembler (:class:`~crowd_env.envs.observations.assembler.ObservationBuilder`)
lays the components out in the order given, prepares the per-step work they share once
(:class:`ObservationContext`: the navigation sampling, the k-nearest search, the headings' cos and sin)
and lets each fill its own columns of the ``(m, D)`` float32 output for all agents at once.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from crowd_env.errors import EnvOptionError

__all__ = ["FRAMES", "check_frame", "ObservationField", "ObservationSpec", "ObservationContext",
           "ObservationComponent", "to_body_frame", "to_world_frame"]

FRAMES = ("world", "egocentric")
_SIZE_TERM = re.compile(r"^(\d*)([kR]?)$")


def check_frame(frame) -> str:
    """``frame`` if it is one of :data:`FRAMES`, else :class:`~crowd_env.errors.EnvOptionError` naming them."""
    if not isinstance(frame, str) or frame not in FRAMES:
        raise EnvOptionError(f"observation_frame must be one of {list(FRAMES)}, got {frame!r}")
    return frame


@dataclass(frozen=True)
class ObservationField:
    """One block of the observation vector: ``size`` is a sum of terms ``a``, ``ak`` or ``aR`` in k
    (neighbours) and R (rays), e.g. ``"4k"`` or ``"2+R"``."""

    name: str
    size: str
    description: str

    def size_of(self, n_neighbors: int, n_rays: int) -> int:
        """The block's length for k = ``n_neighbors`` and R = ``n_rays``."""
        total = 0
        for term in self.size.replace(" ", "").split("+"):
            match = _SIZE_TERM.match(term)
            if match is None or term == "":
                raise EnvOptionError(f"observation field {self.name!r}: size {self.size!r} is not a sum of a, ak, aR")
            coef, symbol = match.groups()
            a = int(coef) if coef else 1
            total += a * {"": 1, "k": int(n_neighbors), "R": int(n_rays)}[symbol]
        return total


@dataclass(frozen=True)
class ObservationSpec:
    """The environment's observation settings every component may read (sizes, bounds, ranges).

    ``velocity_bound_m_s`` and ``travel_time_bound_s`` only set declared bounds; ``period_m``: the
    periodicity along x (0: none)."""

    n_neighbors: int
    n_rays: int
    neighbor_radius_m: float
    ray_range_m: float
    velocity_bound_m_s: float
    travel_time_bound_s: float
    frame: str = "world"
    period_m: float = 0.0


class ObservationContext:
    """The per-step work the components of one observation pass share, computed once.

    Rows ``a`` = 0 … m−1 are the observed pedestrians ``index`` (global rows of ``state``, a
    :class:`~crowd_env.core.state.CrowdState`); ``walls`` (S, 4): the wall segments (x0, y0, x1, y1) in m,
    ``wall_directions`` (S, 4) the same as start and direction (x0, y0, x1 − x0, y1 − y0). Arrays:
    ``velocity_m_s`` (m, 2), ``cos_heading``, ``sin_heading`` (m,), ``desired_direction`` e_d (m, 2, unit
    vectors, Eq. 13), ``travel_time_s`` T (m,), ``speed_m_s`` (m,); ``active_index``: the global rows of
    the pedestrians on the floor, and ``neighbor_rows`` (m, k): rows into it of the k nearest others
    within ``spec.neighbor_radius_m``, nearest first, −1 for none (only when a component asks for
    neighbours, else (m, 0)); ``navigation``: the field e_d and T come from (``sample(points)``, or
    ``sample(points, index)`` when its ``per_pedestrian`` is true), for a component that reads it elsewhere.
    """

    __slots__ = ("state", "index", "spec", "world", "walls", "wall_directions", "velocity_m_s", "cos_heading",
                 "sin_heading", "desired_direction", "travel_time_s", "speed_m_s", "active_index", "neighbor_rows",
                 "navigation")

    def __init__(self, state, index, spec, walls, wall_directions, velocity_m_s, cos_heading, sin_heading,
                 desired_direction, travel_time_s, speed_m_s, active_index, neighbor_rows, navigation=None):
        self.state = state
        self.index = index
        self.spec = spec
        self.world = spec.frame == "world"
        self.walls = walls
        self.wall_directions = wall_directions
        self.velocity_m_s = velocity_m_s
        self.cos_heading = cos_heading
        self.sin_heading = sin_heading
        self.desired_direction = desired_direction
        self.travel_time_s = travel_time_s
        self.speed_m_s = speed_m_s
        self.active_index = active_index
        self.neighbor_rows = neighbor_rows
        self.navigation = navigation

    @property
    def frame(self) -> str:
        """The observation frame, one of :data:`FRAMES`."""
        return self.spec.frame

    def in_frame(self, vectors: np.ndarray) -> np.ndarray:
        """World vectors (m, ..., 2) of the rows in the observation frame (the body frame R(−θ) v when
        egocentric)."""
        return vectors if self.world else to_body_frame(vectors, self.cos_heading, self.sin_heading)


class ObservationComponent:
    """One named part of the observation. Subclass it (a frozen dataclass is convenient) and set:

    - ``name``: how the environment's ``observation_components`` option names it;
    - ``fields``: its :class:`ObservationField` blocks in the world frame, in order;
      ``egocentric_fields``: the blocks in the egocentric frame (None: the same; ``()``: the component is
      left out there, as the heading is);
    - ``uses_neighbors``: True when :meth:`compute` reads ``ctx.neighbor_rows``;
    - :meth:`bounds`: the declared low and high of its entries;
    - :meth:`compute`: fill ``out``, the component's (m, size) float32 columns (zeros on entry), for
      every row of the :class:`ObservationContext`.
    """

    name: str = ""
    fields: tuple = ()
    egocentric_fields = None
    uses_neighbors: bool = False

    def fields_in(self, frame: str) -> tuple:
        """The blocks of the component in ``frame``."""
        if frame == "egocentric" and self.egocentric_fields is not None:
            return tuple(self.egocentric_fields)
        return tuple(self.fields)

    def size(self, spec: ObservationSpec) -> int:
        """Its number of entries under ``spec``."""
        return sum(f.size_of(spec.n_neighbors, spec.n_rays) for f in self.fields_in(spec.frame))

    def bounds(self, spec: ObservationSpec) -> tuple:
        """``(low, high)``, each (size,) or a scalar; default: unbounded."""
        return -np.inf, np.inf

    def compute(self, ctx: ObservationContext, out: np.ndarray) -> None:
        """Write the component's entries of every row into ``out`` (m, size) float32."""
        raise NotImplementedError(f"{type(self).__name__}.compute")

    def write(self, ctx: ObservationContext, obs: np.ndarray, col: int, size: int) -> None:
        """Fill columns ``col:col + size`` of ``obs`` (m, D); built-in components write in place."""
        self.compute(ctx, obs[:, col:col + size])


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
