"""``wall_rays`` (R): the distance in m from the own centre to the first wall along R rays at angles
θ + 2πr/R (r = 0 … R−1; ray 0 along the heading), capped at ``ray_range_m``; the same in both frames (the rays
turn with the heading)."""
from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from .base import ObservationComponent, ObservationField

__all__ = ["WallRays", "cast_rays", "write_rays", "ray_table", "wall_inverse_lengths2"]


@dataclass(frozen=True)
class WallRays(ObservationComponent):
    """Wall distances along the rays (the ray–segment test of :func:`crowd_env.core.segments.ray_distances`);
    bounds [0, ``ray_range_m``]."""

    name = "wall_rays"
    fields = (ObservationField("wall_rays", "R", "distance (m) from the own centre to the first wall along R rays "
                                                 "at θ + 2πr/R, capped at ray_range_m"),)

    def bounds(self, spec):
        return 0.0, spec.ray_range_m

    def write(self, ctx, obs, col, size):
        n_rays = ctx.spec.n_rays
        if n_rays == 0:
            return
        cos_r, sin_r = ray_table(n_rays)
        write_rays(ctx.state.position_m, ctx.index, ctx.cos_heading, ctx.sin_heading, ctx.wall_directions, cos_r,
                    sin_r, ctx.spec.ray_range_m, obs, col)


_TABLES = {}


def ray_table(n_rays: int) -> tuple:
    """(cos φ_r, sin φ_r) of the fixed offsets φ_r = 2πr/R (ray r: the heading turned by φ_r), once per R."""
    table = _TABLES.get(n_rays)
    if table is None:
        offsets = 2.0 * np.pi * np.arange(n_rays) / max(n_rays, 1)
        table = _TABLES[n_rays] = (np.cos(offsets), np.sin(offsets))
    return table


@nb.njit(cache=True)
def write_rays(position, index, cos_t, sin_t, walls, ray_cos, ray_sin, ray_range, obs, col):
    n_rays = ray_cos.shape[0]
    dxs = np.empty(n_rays)
    dys = np.empty(n_rays)
    best = np.empty(n_rays)
    inv_length2 = wall_inverse_lengths2(walls)
    rays, scratch = (ray_cos, ray_sin, ray_range), (dxs, dys, best)
    for a in range(index.shape[0]):
        i = index[a]
        cast_rays(position[i, 0], position[i, 1], cos_t[a], sin_t[a], walls, inv_length2, rays, obs[a], col, scratch)


@nb.njit(cache=True)
def wall_inverse_lengths2(walls):
    """1 / ‖e‖² of each segment of ``walls`` (S, 4: start and direction e), 0 for a point (:func:`cast_rays`)."""
    out = np.zeros(walls.shape[0])
    for w in range(walls.shape[0]):
        ee = walls[w, 2] * walls[w, 2] + walls[w, 3] * walls[w, 3]
        if ee > 0.0:
            out[w] = 1.0 / ee
    return out


@nb.njit(cache=True, error_model="numpy")
def cast_rays(ox, oy, c, s, walls, inv_length2, rays, out, col, scratch):
    """Distance from (ox, oy) to the first wall along each ray R(θ) (cos φ_r, sin φ_r), capped at
    ``max_range``, written to ``out[col + r]`` (``rays`` = ``(cos φ_r, sin φ_r, max_range)``): the ray–segment test
    of :func:`crowd_env.core.segments.ray_distances` (the same arithmetic), branch-free over the rays so that
    it runs in SIMD lanes; ``walls`` (S, 4): start and direction of each segment, ``inv_length2`` their
    :func:`wall_inverse_lengths2`; ``scratch`` = ``(dxs, dys, best)``: (R,) each."""
    ray_cos, ray_sin, max_range = rays
    dxs, dys, best = scratch
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
        # skip a wall farther than the range (no ray reaches it): its point nearest to the origin (with a product
        # for the quotient: a wall within the range's 1e-9 margin is cast either way, and none of them can hit)
        f = min(max(-(wx * ex + wy * ey) * inv_length2[w], 0.0), 1.0)
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
