"""``free_distance`` (1, off by default): how far in m the own disc can move straight along the heading before
it touches the disc of one of the k observed neighbours (reach r_i + r_j) or a wall, capped at ``ray_range_m``;
the same in both frames. The gap ahead that car-following and vision models steer by (Tordeux et al. 2016;
:mod:`crowd_env.walking.vision`), here among the observed neighbours only."""
from __future__ import annotations

from dataclasses import dataclass

import numba as nb

from ...core.periodic import minimum_image_dx
from ...walking.vision import _ray_capsule_distance, ray_circle_distance
from .base import ObservationComponent, ObservationField

__all__ = ["FreeDistance", "write_free_distance"]


@dataclass(frozen=True)
class FreeDistance(ObservationComponent):
    """The free distance ahead; bounds [0, ``ray_range_m``]. Name it in ``observation_components`` to add it."""

    name = "free_distance"
    uses_neighbors = True
    fields = (ObservationField("free_distance", "1", "free walk (m) of the own disc along the heading before it "
                                                     "touches an observed neighbour or a wall, capped at "
                                                     "ray_range_m"),)

    def bounds(self, spec):
        return 0.0, spec.ray_range_m

    def write(self, ctx, obs, col, size):
        st = ctx.state
        write_free_distance(st.position_m, st.radius_m, ctx.index, ctx.active_index, ctx.neighbor_rows,
                            ctx.cos_heading, ctx.sin_heading, ctx.walls, ctx.spec.period_m, ctx.spec.ray_range_m,
                            obs, col)


@nb.njit(cache=True)
def write_free_distance(position, radius, index, act, near, cos_t, sin_t, walls, period_m, cap_m, obs, col):
    """The free distance ahead of each pedestrian ``index`` (neighbours ``near`` (m, k), rows into ``act``; walls
    (S, 4) segments), capped at ``cap_m``, into column ``col``."""
    for a in range(index.shape[0]):
        i = index[a]
        ox = position[i, 0]
        oy = position[i, 1]
        dx = cos_t[a]
        dy = sin_t[a]
        best = cap_m
        for slot in range(near.shape[1]):
            r = near[a, slot]
            if r < 0:
                break
            j = act[r]
            qx = minimum_image_dx(position[j, 0] - ox, period_m)
            best = min(best, ray_circle_distance(ox, oy, dx, dy, ox + qx, position[j, 1], radius[i] + radius[j]))
        for s in range(walls.shape[0]):
            best = min(best, _ray_capsule_distance(ox, oy, dx, dy, walls[s, 0], walls[s, 1], walls[s, 2], walls[s, 3],
                                                   radius[i]))
        obs[a, col] = best
