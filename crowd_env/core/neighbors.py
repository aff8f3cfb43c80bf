"""Fixed-radius neighbour pairs on a uniform cell grid (compiled; the broad phase of every step).

One call sorts the pedestrians into square cells of side ≥ the query radius (counting sort) and
tests each cell against itself and four neighbouring cells (half stencil), so every pair within the
radius is found exactly once in O(n) time for a crowd of bounded density. It serves the contact
candidates, the social forces (Eq. 16) and the gap checks of :class:`~crowd_env.core.Simulator`;
:func:`grid_k_nearest` searches the same grid ring by ring for the k nearest neighbours (the RL
observations).

Periodic along x (``period_m`` L > 0, the periodic corridor; :mod:`crowd_env.core.periodic`): the cell
columns tile [0, L) and wrap, so the cells beside the seam x = 0 ≡ L are neighbours; distances are taken
to the nearest image (:func:`~crowd_env.core.periodic.minimum_image_dx`), and a pair across the seam is
found exactly once. ``period_m`` = 0 (the default) is the plain grid, unchanged to the bit.
"""
from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np

from .periodic import minimum_image_dx, wrap_x

# Cells per pedestrian allowed before the cell side grows (a crowd spread thinly over a huge area
# would otherwise allocate a huge grid): memory stays O(n).
MAX_CELLS_PER_PEDESTRIAN = 4


@nb.njit(cache=True)
def _bounds(position, index):
    """Bounding box ``(xmin, ymin, xmax, ymax)`` of the pedestrians ``index``."""
    xmin = np.inf
    ymin = np.inf
    xmax = -np.inf
    ymax = -np.inf
    for k in range(index.shape[0]):
        x = position[index[k], 0]
        y = position[index[k], 1]
        xmin = min(xmin, x)
        xmax = max(xmax, x)
        ymin = min(ymin, y)
        ymax = max(ymax, y)
    return xmin, ymin, xmax, ymax


class CellGrid(NamedTuple):
    """The rows of an ``index`` sorted into cells (:func:`_cell_grid`): cell c = cx + ncx·cy holds the rows
    ``order[start[c]:start[c + 1]]``; ``ncx`` × ``ncy`` cells of ``cell_x`` × ``cell_y`` m from (``xmin``, ``ymin``)."""

    order: np.ndarray
    start: np.ndarray
    ncx: int
    ncy: int
    xmin: float
    ymin: float
    cell_x: float
    cell_y: float


@nb.njit(cache=True)
def _cell_grid(position, index, radius_m, period_m):
    """Counting sort of the rows of ``index`` into cells of sides ≥ ``radius_m``: a :class:`CellGrid`. Periodic
    (``period_m`` > 0): ncx columns of width L/ncx tile [0, L) (square cells otherwise)."""
    n = index.shape[0]
    xmin, ymin, xmax, ymax = _bounds(position, index)
    if period_m > 0.0:
        xmin = 0.0
    cell = radius_m
    while True:
        if period_m > 0.0:
            ncx = max(int(period_m / cell), 1)
        else:
            ncx = int((xmax - xmin) / cell) + 1
        ncy = int((ymax - ymin) / cell) + 1
        if ncx * ncy <= MAX_CELLS_PER_PEDESTRIAN * n + 16:
            break
        cell *= 2.0
    cell_x = period_m / ncx if period_m > 0.0 else cell
    n_cells = ncx * ncy
    cell_of = np.empty(n, np.int64)
    start = np.zeros(n_cells + 1, np.int64)
    for k in range(n):
        cell_of[k] = _cell_index(position[index[k], 0], position[index[k], 1], xmin, ymin, cell_x, cell, ncx, ncy,
                                 period_m)
        start[cell_of[k] + 1] += 1
    for c in range(n_cells):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(n, np.int64)
    for k in range(n):
        c = cell_of[k]
        order[fill[c]] = k
        fill[c] += 1
    return CellGrid(order, start, ncx, ncy, xmin, ymin, cell_x, cell)


@nb.njit(cache=True, inline="always")
def _cell_index(x, y, xmin, ymin, cell_x, cell_y, ncx, ncy, period_m):
    if period_m > 0.0:
        x = wrap_x(x, period_m)
    cx = min(int((x - xmin) / cell_x), ncx - 1)
    cy = min(int((y - ymin) / cell_y), ncy - 1)
    return cx + ncx * cy


@nb.njit(cache=True, inline="always")
def _append_if_within(position, index, a, b, xa, ya, r2, out, m, period_m):
    """Append the pair (a, b), smaller row first, at ``out[m]`` when b lies within √r2 of (xa, ya) (nearest
    image); returns the new count, or −1 when the pair is within but ``out`` is full."""
    dx = minimum_image_dx(position[index[b], 0] - xa, period_m)
    dy = position[index[b], 1] - ya
    if dx * dx + dy * dy > r2:
        return m
    if m == out.shape[0]:
        return -1
    out[m, 0] = min(a, b)
    out[m, 1] = max(a, b)
    return m + 1


@nb.njit(cache=True, inline="always")
def _column_offsets(ncx, period_m):
    """The column offsets (lo, hi) of a 3 × 3 block around a cell that reach distinct columns: −1..1, but
    fewer when a periodic grid has under three columns (offsets −1 and +1 would meet the same one)."""
    if period_m > 0.0 and ncx < 3:
        return 0, ncx - 1
    return -1, 1


@nb.njit(cache=True)
def grid_pairs_around(position, index, rows, radius_m, period_m=0.0):
    """Pairs (P, 2) of rows into ``index``, within ``radius_m``, that involve at least one of the
    distinct ``rows`` (each pair once, smaller row first): the neighbours of a few pedestrians without enumerating
    every pair of the crowd (O(n) for the grid plus the few neighbourhoods). ``period_m``: module docstring."""
    n = index.shape[0]
    if n < 2 or rows.shape[0] == 0 or not radius_m > 0.0:
        return np.zeros((0, 2), np.int64)
    grid = _cell_grid(position, index, radius_m, period_m)
    marked = np.zeros(n, np.bool_)
    for k in range(rows.shape[0]):
        marked[rows[k]] = True
    cap = 16 * rows.shape[0] + 16
    while True:  # as grid_pairs: retry with a larger buffer when full
        out = np.empty((cap, 2), np.int64)
        m = _fill_pairs_around(position, index, rows, marked, grid, radius_m * radius_m, out, period_m)
        if m >= 0:
            return out[:m].copy()
        cap *= 4


@nb.njit(cache=True)
def _fill_pairs_around(position, index, rows, marked, grid, r2, out, period_m):
    """Write the pairs of :func:`grid_pairs_around` (the rows ``rows``, ``marked`` among all, sorted into the
    :class:`CellGrid` ``grid``) into ``out``; their number, or −1 when too small."""
    order, start, ncx, ncy, xmin, ymin, cell_x, cell_y = grid
    m = 0
    lo, hi = _column_offsets(ncx, period_m)
    for k in range(rows.shape[0]):
        a = rows[k]
        xa = position[index[a], 0]
        ya = position[index[a], 1]
        c = _cell_index(xa, ya, xmin, ymin, cell_x, cell_y, ncx, ncy, period_m)
        cx = c % ncx
        cy = c // ncx
        for qy in range(max(cy - 1, 0), min(cy + 2, ncy)):
            for ox in range(lo, hi + 1):
                qx = cx + ox
                if period_m > 0.0:
                    qx %= ncx  # the columns wrap round the seam
                elif qx < 0 or qx >= ncx:
                    continue
                q = qx + ncx * qy
                for t in range(start[q], start[q + 1]):
                    b = order[t]
                    if b == a or (marked[b] and b < a):
                        continue  # itself, or a pair of two marked rows found from the smaller one
                    m = _append_if_within(position, index, a, b, xa, ya, r2, out, m, period_m)
                    if m < 0:
                        return -1
    return m


@nb.njit(cache=True)
def grid_pairs(position, index, radius_m, period_m=0.0):
    """Pairs (P, 2) of rows into ``index`` whose centres are at most ``radius_m`` apart.

    ``position`` (N, 2) in metres, ``index`` (n,) int64 rows of ``position`` to consider. Each pair
    appears once with its smaller row first; the order is deterministic (by cell, then by row).
    ``period_m`` L > 0: x is periodic (module docstring); ``radius_m`` must stay below L/2 for the nearest
    image to be the only one within reach.
    """
    n = index.shape[0]
    if n < 2 or not radius_m > 0.0:
        return np.zeros((0, 2), np.int64)
    order, start, ncx, ncy, xmin, ymin, cell_x, cell_y = _cell_grid(position, index, radius_m, period_m)
    cap = 8 * n
    while True:  # a crowd denser than ~8 neighbours each within the radius needs a larger buffer
        out = np.empty((cap, 2), np.int64)
        m = _fill_pairs(position, index, order, start, ncx, ncy, radius_m * radius_m, out, period_m)
        if m >= 0:
            return out[:m].copy()
        cap *= 4


@nb.njit(cache=True)
def _fill_pairs(position, index, order, start, ncx, ncy, r2, out, period_m):
    """Write the pairs of :func:`grid_pairs` into ``out``; their number, or −1 when ``out`` is too small."""
    m = 0
    periodic = period_m > 0.0
    for cy in range(ncy):
        for cx in range(ncx):
            c = cx + ncx * cy
            for s in range(start[c], start[c + 1]):
                a = order[s]
                xa = position[index[a], 0]
                ya = position[index[a], 1]
                # own cell (later members only), then the half stencil (+1,0), (−1,+1), (0,+1), (+1,+1)
                for nbr in range(5):
                    if nbr == 0:
                        ox, oy = 0, 0
                    elif nbr == 1:
                        ox, oy = 1, 0
                    elif nbr == 2:
                        ox, oy = -1, 1
                    elif nbr == 3:
                        ox, oy = 0, 1
                    else:
                        ox, oy = 1, 1
                    qx = cx + ox
                    qy = cy + oy
                    if periodic:  # columns wrap; with under three columns visit each neighbouring cell once
                        if ox != 0 and (ncx == 1 or (ncx == 2 and (ox == -1 or (oy == 0 and cx == 1)))):
                            continue
                        qx %= ncx
                    if qx < 0 or qx >= ncx or qy >= ncy:
                        continue
                    q = qx + ncx * qy
                    t0 = s + 1 if nbr == 0 else start[q]
                    for t in range(t0, start[q + 1]):
                        b = order[t]
                        m = _append_if_within(position, index, a, b, xa, ya, r2, out, m, period_m)
                        if m < 0:
                            return -1
    return m


@nb.njit(cache=True)
def grid_k_nearest(position, index, query, k, radius_m, period_m=0.0):
    """The k nearest of the pedestrians ``index`` to each pedestrian ``query`` (both global rows of
    ``position``; a query's own row is left out), within ``radius_m``: (m, k) int64 rows into
    ``index``, nearest first, −1 where fewer than k lie within the radius (all −1 for a query whose
    position is not finite).

    Cells of side ≈ √(k · bounding-box area / n) (at most ``radius_m``), so that the k nearest of a
    uniform crowd usually lie in the 3 × 3 block around the query's cell; rings of cells are added
    until the k-th distance found is within the rings' reach (every unseen cell is farther) or the
    rings cover the radius or the grid. Exact, O(n + m) for a crowd of bounded density. ``period_m`` L > 0:
    x is periodic (module docstring; nearest images, each column searched once).
    """
    m = query.shape[0]
    out = np.full((m, k), -1, np.int64)
    n = index.shape[0]
    if n == 0 or k <= 0 or not radius_m > 0.0:
        return out
    xmin, ymin, xmax, ymax = _bounds(position, index)
    periodic = period_m > 0.0
    if periodic:
        xmin, xmax = 0.0, period_m
    side = min(radius_m, np.sqrt(k * (xmax - xmin) * (ymax - ymin) / n))
    order, start, ncx, ncy, x0, y0, cell_x, cell = _cell_grid(position, index, max(side, 1e-6 * radius_m), period_m)
    lo_x = -((ncx - 1) // 2)  # periodic: the column offsets lo_x..hi_x reach each column once
    hi_x = ncx // 2
    r2 = radius_m * radius_m
    best_d2 = np.empty(k)
    xs = np.empty(n)  # coordinates in cell order: the scans below read memory in sequence
    ys = np.empty(n)
    for t in range(n):
        xs[t] = position[index[order[t]], 0]
        ys[t] = position[index[order[t]], 1]
    for a in range(m):
        i = query[a]
        xa = position[i, 0]
        ya = position[i, 1]
        if not (np.isfinite(xa) and np.isfinite(ya)):
            continue  # no position, no neighbours
        if periodic:
            cx = min(int(wrap_x(xa, period_m) / cell_x), ncx - 1)
            last_x = max(hi_x, -lo_x)
        else:
            cx = int(np.floor((xa - x0) / cell))  # may lie outside the grid: its cells are empty
            last_x = max(cx, ncx - 1 - cx)
        cy = int(np.floor((ya - y0) / cell))
        last = max(last_x, max(cy, ncy - 1 - cy))  # ring that covers the whole grid
        cnt = 0
        ring = 0
        while True:
            for qy in range(max(cy - ring, 0), min(cy + ring, ncy - 1) + 1):
                edge = qy == cy - ring or qy == cy + ring
                qx = cx - ring
                while qx <= cx + ring:
                    col = qx
                    if periodic:
                        col = (qx % ncx) if lo_x <= qx - cx <= hi_x else -1
                    if 0 <= col < ncx:
                        q = col + ncx * qy
                        for t in range(start[q], start[q + 1]):
                            dx = minimum_image_dx(xs[t] - xa, period_m)
                            dy = ys[t] - ya
                            d2 = dx * dx + dy * dy
                            if d2 > r2 or (cnt == k and d2 >= best_d2[k - 1]):
                                continue
                            b = order[t]
                            if index[b] == i:
                                continue
                            p = cnt if cnt < k else k - 1
                            while p > 0 and best_d2[p - 1] > d2:  # insertion into the sorted best k
                                best_d2[p] = best_d2[p - 1]
                                out[a, p] = out[a, p - 1]
                                p -= 1
                            best_d2[p] = d2
                            out[a, p] = b
                            if cnt < k:
                                cnt += 1
                    # inner rows of the ring: only its left and right cells
                    qx += 1 if (edge or ring == 0) else 2 * ring
            reach = ring * cell  # cells outside the rings so far are at least this far (cell_x ≥ cell)
            if ring >= last or reach >= radius_m or (cnt == k and best_d2[k - 1] <= reach * reach):
                break
            ring += 1
    return out
