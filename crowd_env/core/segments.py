"""Walls as line segments: one ``(S, 4)`` array of ``(x0, y0, x1, y1)`` in metres.

The compiled kernels here are the single implementation of point-to-wall queries used by contact
detection, wall repulsion and observation rays.
"""
from __future__ import annotations

import numba as nb
import numpy as np


class GeometryError(ValueError):
    """Walls, exits or walkable areas are malformed or impossible."""


def as_segments(segments) -> np.ndarray:
    """Validate and return walls as a contiguous float64 ``(S, 4)`` array."""
    seg = np.asarray(segments, dtype=np.float64)
    if seg.size == 0:
        return np.zeros((0, 4))
    if seg.ndim != 2 or seg.shape[1] != 4:
        raise GeometryError(f"wall segments must have shape (S, 4) as (x0, y0, x1, y1), got {seg.shape}")
    if not np.all(np.isfinite(seg)):
        raise GeometryError("wall segments contain non-finite coordinates")
    length = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
    bad = np.flatnonzero(length <= 1e-12)
    if bad.size:
        raise GeometryError(f"wall segment {int(bad[0])} has zero length: {seg[bad[0]].tolist()}")
    return np.ascontiguousarray(seg)


def endpoint_owners(segments: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """``(S, 2)`` bool: True where this segment is the lowest-index one sharing that endpoint.

    A point whose closest wall point is a shared corner vertex is then counted once, not once per
    segment meeting there (for contacts and for wall repulsion alike).
    """
    s = segments.shape[0]
    owner = np.ones((s, 2), dtype=np.bool_)
    if s == 0:
        return owner
    pts = segments.reshape(s * 2, 2)
    keys = np.round(pts / tol).astype(np.int64)
    seen: dict = {}
    for k in range(s * 2):
        key = (int(keys[k, 0]), int(keys[k, 1]))
        if key in seen:
            owner[k // 2, k % 2] = False
        else:
            seen[key] = k
    return owner


@nb.njit(cache=True, inline="always")
def closest_point_on_segment(px, py, x0, y0, x1, y1):
    """Closest point of segment (x0,y0)-(x1,y1) to (px,py); returns (cx, cy, t) with t in [0, 1]."""
    dx = x1 - x0
    dy = y1 - y0
    t = ((px - x0) * dx + (py - y0) * dy) / (dx * dx + dy * dy)
    if t < 0.0:
        t = 0.0
    elif t > 1.0:
        t = 1.0
    return x0 + t * dx, y0 + t * dy, t


@nb.njit(cache=True)
def wall_proximity(position, radius, index, segments, owner, margin):
    """All (pedestrian, wall) pairs whose surface gap is at most ``margin[k]`` for pedestrian ``index[k]``.

    Returns ``(ped, seg, gap, nx, ny, cx, cy)``: row into ``index``, segment, gap (m), unit normal
    from the wall into the pedestrian, and the closest wall point. Shared corner vertices are reported
    once (see :func:`endpoint_owners`).
    """
    n = index.shape[0]
    s = segments.shape[0]
    cap = max(16, 4 * n)
    ped = np.empty(cap, np.int64)
    seg = np.empty(cap, np.int64)
    out = np.empty((cap, 5))
    m = 0
    for a in range(n):
        i = index[a]
        px = position[i, 0]
        py = position[i, 1]
        r = radius[i]
        for k in range(s):
            cx, cy, t = closest_point_on_segment(px, py, segments[k, 0], segments[k, 1], segments[k, 2], segments[k, 3])
            if (t == 0.0 and not owner[k, 0]) or (t == 1.0 and not owner[k, 1]):
                continue
            dx = px - cx
            dy = py - cy
            d = np.sqrt(dx * dx + dy * dy)
            gap = d - r
            if gap > margin[a]:
                continue
            if d > 1e-12:
                nx = dx / d
                ny = dy / d
            else:  # centre exactly on the wall: use the segment's left normal
                lx = segments[k, 2] - segments[k, 0]
                ly = segments[k, 3] - segments[k, 1]
                ll = np.sqrt(lx * lx + ly * ly)
                nx = -ly / ll
                ny = lx / ll
            if m == cap:
                cap *= 2
                ped2 = np.empty(cap, np.int64)
                seg2 = np.empty(cap, np.int64)
                out2 = np.empty((cap, 5))
                ped2[:m] = ped[:m]
                seg2[:m] = seg[:m]
                out2[:m] = out[:m]
                ped, seg, out = ped2, seg2, out2
            ped[m] = a
            seg[m] = k
            out[m, 0] = gap
            out[m, 1] = nx
            out[m, 2] = ny
            out[m, 3] = cx
            out[m, 4] = cy
            m += 1
    return ped[:m], seg[:m], out[:m, 0].copy(), out[:m, 1].copy(), out[:m, 2].copy(), out[:m, 3].copy(), out[:m, 4].copy()


@nb.njit(cache=True)
def ray_distances(origin, angles, segments, max_range):
    """Distance from each origin along each ray angle to the first wall, capped at ``max_range``.

    ``origin`` (N, 2), ``angles`` (N, R) absolute angles in radians; returns (N, R).
    """
    n = origin.shape[0]
    nr = angles.shape[1]
    out = np.full((n, nr), max_range)
    for a in range(n):
        ox = origin[a, 0]
        oy = origin[a, 1]
        for r in range(nr):
            dx = np.cos(angles[a, r])
            dy = np.sin(angles[a, r])
            best = max_range
            for k in range(segments.shape[0]):
                ex = segments[k, 2] - segments[k, 0]
                ey = segments[k, 3] - segments[k, 1]
                den = dx * ey - dy * ex
                if abs(den) < 1e-14:
                    continue
                wx = segments[k, 0] - ox
                wy = segments[k, 1] - oy
                t = (wx * ey - wy * ex) / den  # distance along the ray
                u = (wx * dy - wy * dx) / den  # position along the segment
                if t >= 0.0 and 0.0 <= u <= 1.0 and t < best:
                    best = t
            out[a, r] = best
    return out
