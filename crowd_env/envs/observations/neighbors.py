"""``neighbors`` (4k) and ``neighbor_mask`` (k): the k nearest other pedestrians on the floor (controlled or
background) within ``neighbor_radius_m``, nearest first: relative position x_j − x_i (m, the nearest image
in a periodic corridor) and relative velocity u_j − u_i (m/s), in the observation frame; zeros where there
are fewer than k, and 1 in the mask for a real neighbour."""
from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from ...core.periodic import minimum_image_dx
from .base import ObservationComponent, ObservationField

__all__ = ["Neighbors", "write_neighbors"]

_MASK = ObservationField("neighbor_mask", "k", "1 for a real neighbour in the slot, 0 for padding")


@dataclass(frozen=True)
class Neighbors(ObservationComponent):
    """The k nearest neighbours (one k-nearest search per step, shared: ``ctx.neighbor_rows``) and their mask;
    bounds ±``neighbor_radius_m`` for offsets, ±2 ``velocity_bound_m_s`` for relative velocities."""

    name = "neighbors"
    uses_neighbors = True
    fields = (ObservationField("neighbors", "4k", "k nearest others within neighbor_radius_m, nearest first: "
                                                  "relative position (m) and relative velocity (m/s) each; zero "
                                                  "padded"), _MASK)
    egocentric_fields = (ObservationField("neighbors", "4k", "k nearest others within neighbor_radius_m, nearest "
                                                             "first: relative position (m) and relative velocity "
                                                             "(m/s) each, body frame; zero padded"), _MASK)

    def bounds(self, spec):
        r, v, k = spec.neighbor_radius_m, spec.velocity_bound_m_s, spec.n_neighbors
        low = np.tile(np.array([-r, -r, -2 * v, -2 * v]), k)
        return np.concatenate((low, np.zeros(k))), np.concatenate((-low, np.ones(k)))

    def write(self, ctx, obs, col, size):
        st = ctx.state
        write_neighbors(st.position_m, st.velocity_m_s, ctx.index, ctx.active_index, ctx.neighbor_rows,
                         ctx.cos_heading, ctx.sin_heading, ctx.world, ctx.spec.period_m, obs, col)


@nb.njit(cache=True)
def write_neighbors(position, velocity, index, act, near, cos_t, sin_t, world, period_m, obs, col):
    """Offsets and relative velocities of the slots ``near`` (m, k) (rows into ``act``, −1: none) from
    ``col``, then the mask from ``col + 4k``. Egocentric padding is turned too (signed zeros)."""
    k = near.shape[1]
    c_mask = col + 4 * k
    for a in range(index.shape[0]):
        i = index[a]
        c = cos_t[a]
        s = sin_t[a]
        for slot in range(k):
            r = near[a, slot]
            if r < 0 and world:
                break  # the rest are missing too (zeros)
            dx = dy = du = dv = 0.0
            if r >= 0:
                g = act[r]
                dx = minimum_image_dx(position[g, 0] - position[i, 0], period_m)
                dy = position[g, 1] - position[i, 1]
                du = velocity[g, 0] - velocity[i, 0]
                dv = velocity[g, 1] - velocity[i, 1]
                obs[a, c_mask + slot] = 1.0
            base = col + 4 * slot
            if world:
                obs[a, base] = dx
                obs[a, base + 1] = dy
                obs[a, base + 2] = du
                obs[a, base + 3] = dv
            else:
                obs[a, base] = c * dx + s * dy
                obs[a, base + 1] = c * dy - s * dx
                obs[a, base + 2] = c * du + s * dv
                obs[a, base + 3] = c * dv - s * du
