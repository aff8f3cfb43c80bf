"""Walls as line segments: one ``(S, 4)`` array of ``(x0, y0, x1, y1)`` in metres.

The compiled kernels here are the single implementation of point-to-wall queries used by contact
detection, wall repulsion and observation rays.
"""
from __future__ import annotations

from crowd_env.errors import GeometryError

import numba as nb
import numpy as np


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
    """Shared corner vertices: ``(S, 2, D)`` int64, for each (segment, endpoint) the other endpoints
    at the same vertex, each encoded as ``2 * segment + endpoint``, padded with −1 (D ≥ 1).

    :func:`wall_proximity` uses it so that a point whose closest point on segment k is a shared
    vertex V counts V only when *every* segment meeting at V also has V as its closest point, and
    then once (for the lowest segment index). When a neighbour's closest point is elsewhere, that
    neighbour is at least as close as V (V belongs to it), so its own contact covers V. The result
    is independent of the order of the segments (for contacts and for wall repulsion alike).
    Vertices are matched to within ``tol`` metres.
    """
    s = segments.shape[0]
    if s == 0:
        return np.full((0, 2, 1), -1, dtype=np.int64)
    pts = segments.reshape(s * 2, 2)
    keys = np.round(pts / tol).astype(np.int64)
    groups: dict = {}
    for k in range(s * 2):
        groups.setdefault((int(keys[k, 0]), int(keys[k, 1])), []).append(k)
    depth = max(1, max(len(g) for g in groups.values()) - 1)
    out = np.full((s, 2, depth), -1, dtype=np.int64)
    for members in groups.values():
        for k in members:
            others = [o for o in members if o // 2 != k // 2]  # a segment never neighbours itself
            out[k // 2, k % 2, :len(others)] = others
    return out


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
def _segment_boxes(segments):
    """Bounding boxes (S, 4: x_min, x_max, y_min, y_max) of the segments (S, 4: x0, y0, x1, y1)."""
    boxes = np.empty((segments.shape[0], 4))
    for k in range(segments.shape[0]):
        boxes[k, 0] = min(segments[k, 0], segments[k, 2])
        boxes[k, 1] = max(segments[k, 0], segments[k, 2])
        boxes[k, 2] = min(segments[k, 1], segments[k, 3])
        boxes[k, 3] = max(segments[k, 1], segments[k, 3])
    return boxes


@nb.njit(cache=True, inline="always")
def _box_distances2(px, py, boxes, out):
    """Squared distance from (px, py) to each box of :func:`_segment_boxes` (at most the squared distance to its
    segment), written to ``out``."""
    for k in range(boxes.shape[0]):
        dx = max(max(boxes[k, 0] - px, px - boxes[k, 1]), 0.0)
        dy = max(max(boxes[k, 2] - py, py - boxes[k, 3]), 0.0)
        out[k] = dx * dx + dy * dy


@nb.njit(cache=True, inline="always")
def _counts_vertex(px, py, k, end, segments, owner):
    """Whether segment k's clamped endpoint ``end`` (its closest point to (px, py)) is reported:
    only if every other segment sharing that vertex also has it as closest point and k is the
    lowest index among them."""
    for q in range(owner.shape[2]):
        code = owner[k, end, q]
        if code < 0:
            break
        k2 = code // 2
        _, _, t2 = closest_point_on_segment(px, py, segments[k2, 0], segments[k2, 1], segments[k2, 2], segments[k2, 3])
        if t2 != (1.0 if code % 2 == 1 else 0.0):
            return False  # k2 is closer elsewhere (V belongs to k2): its own contact covers V
        if k2 < k:
            return False  # counted once, by the lowest index
    return True


@nb.njit(cache=True)
def wall_proximity(position, radius, index, segments, owner, margin):
    """All (pedestrian, wall) pairs whose surface gap is at most ``margin[k]`` for pedestrian ``index[k]``.

    Returns ``(ped, seg, gap, nx, ny, cx, cy)``: row into ``index``, segment, gap (m), unit normal
    from the wall into the pedestrian, and the closest wall point. ``owner`` comes from
    :func:`endpoint_owners`: a shared corner vertex is reported only when it is the closest point of
    every segment meeting there, and then once, so results do not depend on segment order.
    """
    ped, seg, out, m = wall_rows(position, radius, index, segments, owner, margin)
    return (ped[:m], seg[:m], out[:m, 0].copy(), out[:m, 1].copy(), out[:m, 2].copy(), out[:m, 3].copy(),
            out[:m, 4].copy())


@nb.njit(cache=True)
def wall_rows(position, radius, index, segments, owner, margin):
    """:func:`wall_proximity` in buffers: ``(ped, seg, out, m)``, the first m rows holding the pairs (out: gap,
    nx, ny, cx, cy); :func:`~crowd_env.core.contacts.contact_candidates` reads them without copies."""
    cap = max(16, 4 * index.shape[0])
    while True:  # more than ~4 walls within the margin of each pedestrian needs a larger buffer
        ped = np.empty(cap, np.int64)
        seg = np.empty(cap, np.int64)
        out = np.empty((cap, 5))
        m = _fill_wall_proximity(position, radius, index, segments, owner, margin, ped, seg, out)
        if m >= 0:
            return ped, seg, out, m
        cap *= 4


@nb.njit(cache=True)
def _fill_wall_proximity(position, radius, index, segments, owner, margin, ped, seg, out):
    """Write the pairs of :func:`wall_proximity` into the buffers; their number, or −1 when too small."""
    cap = ped.shape[0]
    m = 0
    boxes = _segment_boxes(segments)
    box_d2 = np.empty(segments.shape[0])
    for a in range(index.shape[0]):
        i = index[a]
        px = position[i, 0]
        py = position[i, 1]
        r = radius[i]
        # a wall whose bounding box lies beyond r + margin (+1e-9 m, far above the rounding of the test below) is
        # skipped before the division and the root: the same walls pass, with the same arithmetic
        reach = abs(r + margin[a]) + 1e-9
        reach2 = reach * reach
        if px - px == 0.0 and py - py == 0.0:
            _box_distances2(px, py, boxes, box_d2)  # all walls at once, without branches (SIMD lanes)
        else:  # a NaN or infinite centre takes the full test, as before
            box_d2[:] = -1.0
        for k in range(segments.shape[0]):
            if box_d2[k] > reach2:
                continue
            cx, cy, t = closest_point_on_segment(px, py, segments[k, 0], segments[k, 1], segments[k, 2], segments[k, 3])
            dx = px - cx
            dy = py - cy
            d = np.sqrt(dx * dx + dy * dy)
            gap = d - r
            if gap > margin[a]:  # the cheap test first: most walls are far
                continue
            if (t == 0.0 and not _counts_vertex(px, py, k, 0, segments, owner)) or \
                    (t == 1.0 and not _counts_vertex(px, py, k, 1, segments, owner)):
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
                return -1
            ped[m] = a
            seg[m] = k
            out[m, 0] = gap
            out[m, 1] = nx
            out[m, 2] = ny
            out[m, 3] = cx
            out[m, 4] = cy
            m += 1
    return m


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
