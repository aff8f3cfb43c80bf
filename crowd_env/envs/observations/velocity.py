"""``velocity``: the own velocity u (2), m/s: (u_x, u_y) in the world frame, (forward, left) in the body frame."""
from __future__ import annotations

from dataclasses import dataclass

import numba as nb

from .base import ObservationComponent, ObservationField

__all__ = ["Velocity", "write_in_frame"]


@dataclass(frozen=True)
class Velocity(ObservationComponent):
    """The own velocity; bounds ±``velocity_bound_m_s``."""

    name = "velocity"
    fields = (ObservationField("velocity", "2", "own velocity (u_x, u_y), m/s, world frame"),)
    egocentric_fields = (ObservationField("velocity", "2", "own velocity in the body frame (forward, left), m/s"),)

    def bounds(self, spec):
        return -spec.velocity_bound_m_s, spec.velocity_bound_m_s

    def write(self, ctx, obs, col, size):
        write_in_frame(ctx.velocity_m_s, ctx.cos_heading, ctx.sin_heading, ctx.world, obs, col)


@nb.njit(cache=True)
def write_in_frame(vectors, cos_t, sin_t, world, obs, col):
    """Write the vectors (m, 2) into columns ``col``, ``col + 1`` of ``obs``: as they are (``world``), or
    turned into the body frames of the headings, R(−θ) v = (c v_x + s v_y, c v_y − s v_x)."""
    for a in range(vectors.shape[0]):
        x = vectors[a, 0]
        y = vectors[a, 1]
        if world:
            obs[a, col] = x
            obs[a, col + 1] = y
        else:
            c = cos_t[a]
            s = sin_t[a]
            obs[a, col] = c * x + s * y
            obs[a, col + 1] = c * y - s * x
