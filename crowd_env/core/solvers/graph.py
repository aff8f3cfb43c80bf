"""The contact graph and its operators, shared by the solvers (public: any solver may import them).

Bodies are the nodes, contact rows (a, b; b < 0 for a wall) the edges. Here:

* union-find (:func:`find_root`, :func:`union`) and :func:`group_by`, which split the impact set into
  clusters (connected components: Kabalan 2016 solves Eq. 7 on each cluster of touching, approaching
  pedestrians independently) and the dense projection's active set into components;
* :func:`order_dofs`, the reverse Cuthill-McKee order of the bodies that keeps the Cholesky factor of
  H = M + Bᵀ K B (impacts) or of the projections' Newton matrices inside a narrow profile;
* :func:`touched_bodies`, :func:`renumber_rows`: the sub-problem on the bodies some row touches;
* :func:`contact_keys`: one integer per contact that identifies it across candidate lists (warm starts);
* the normal rows B_n (the normal relative velocity of each contact), as the impact set and the gap
  projection (gap_k + h (B_n v)_k ≥ 0: no gap closes within the step) use them: :func:`normal_velocity`, :func:`gap_residuals`, and the sparse matrices :func:`sparse_rows`
  (impact rows on (u_x, u_y, ω)), :func:`normal_rows_sparse` and :func:`touched_projection_rows`
  (projection rows on (u_x, u_y)).
"""
from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True)
def find_root(parent, x):
    """Root of ``x`` in the union-find forest ``parent`` (int array, modified: path compression)."""
    root = x
    while parent[root] != root:
        root = parent[root]
    while parent[x] != root:
        nxt = parent[x]
        parent[x] = root
        x = nxt
    return root


@nb.njit(cache=True)
def union(parent, x, y):
    """Join the sets of ``x`` and ``y`` in ``parent``; the smaller root becomes the root of both, so
    that a component's root is its smallest body (the order in which clusters are solved)."""
    rx = find_root(parent, x)
    ry = find_root(parent, y)
    if rx != ry:
        if rx < ry:
            parent[ry] = rx
        else:
            parent[rx] = ry


@nb.njit(cache=True)
def normal_velocity(vel, a, b, nx, ny):
    """(B_n v) of one contact: the normal relative velocity n·(u_a − u_b) (n·u_a for a wall, b < 0)
    for velocities ``vel`` ((n, ≥2))."""
    vn = vel[a, 0] * nx + vel[a, 1] * ny
    if b >= 0:
        vn -= vel[b, 0] * nx + vel[b, 1] * ny
    return vn


@nb.njit(cache=True)
def group_by(keys, n_keys):
    """Stable order of ``keys`` (ints in [0, n_keys)) and the start of each key's run in it:
    the items with key k are ``order[start[k]:start[k + 1]]``."""
    order = np.argsort(keys, kind="mergesort")
    start = np.zeros(n_keys + 1, np.int64)
    for i in range(keys.shape[0]):
        start[keys[i] + 1] += 1
    for k in range(n_keys):
        start[k + 1] += start[k]
    return order, start


@nb.njit(cache=True)
def order_dofs(nb_, row_a, row_b, coef_a, coef_b):
    """Bodies in reverse Cuthill-McKee order of the row graph, and their degrees of freedom that
    some row uses (the others decouple: H is diagonal there). Returns ``(perm, pos)``: new → old
    DOF index, and old → new (−1 for an unused DOF). A banded ordering keeps the Cholesky factor of
    H = M + Bᵀ K B inside a narrow profile, which :func:`~crowd_env.core.solvers.impact.solve_rows` and the large projections'
    envelope factorisations exploit."""
    m = row_a.shape[0]
    used = np.zeros(3 * nb_, np.bool_)
    deg = np.zeros(nb_, np.int64)
    for r in range(m):
        for d in range(3):
            if coef_a[r, d] != 0.0:
                used[3 * row_a[r] + d] = True
            if row_b[r] >= 0 and coef_b[r, d] != 0.0:
                used[3 * row_b[r] + d] = True
        if row_b[r] >= 0:
            deg[row_a[r]] += 1
            deg[row_b[r]] += 1
    start = np.zeros(nb_ + 1, np.int64)
    for i in range(nb_):
        start[i + 1] = start[i] + deg[i]
    fill = start[:-1].copy()
    adj = np.empty(start[nb_], np.int64)
    for r in range(m):
        if row_b[r] >= 0:
            adj[fill[row_a[r]]] = row_b[r]
            fill[row_a[r]] += 1
            adj[fill[row_b[r]]] = row_a[r]
            fill[row_b[r]] += 1
    order = np.empty(nb_, np.int64)
    seen = np.zeros(nb_, np.bool_)
    head = 0
    tail = 0
    by_degree = np.argsort(deg, kind="mergesort")
    for s in by_degree:  # one BFS per connected component, from a body of least degree
        if seen[s]:
            continue
        seen[s] = True
        order[tail] = s
        tail += 1
        while head < tail:
            u = order[head]
            head += 1
            nbrs = adj[start[u]:start[u + 1]]
            nd_ = np.argsort(deg[nbrs], kind="mergesort")
            for t in nd_:
                w = nbrs[t]
                if not seen[w]:
                    seen[w] = True
                    order[tail] = w
                    tail += 1
    perm = np.empty(3 * nb_, np.int64)
    pos = np.full(3 * nb_, -1, np.int64)
    k = 0
    for q in range(nb_ - 1, -1, -1):
        b = order[q]
        for d in range(3):
            if used[3 * b + d]:
                perm[k] = 3 * b + d
                pos[3 * b + d] = k
                k += 1
    return perm[:k], pos


def renumber_rows(table, c_a, c_b):
    """Contact rows (a, b; b < 0 for a wall) renumbered through ``table``: ``(table[a], table[b] or −1)``."""
    return table[c_a], np.where(c_b >= 0, table[np.maximum(c_b, 0)], -1)


def touched_bodies(n, c_a, c_b):
    """The bodies (of ``n``) that contact rows (a, b; b < 0 for a wall) touch, sorted, and the rows
    renumbered into them: ``(bodies, a_local, b_local)``. The large projection solvers work on these
    only; the others keep their velocities."""
    used = np.zeros(n, np.bool_)
    used[c_a] = True
    used[c_b[c_b >= 0]] = True
    bodies = np.flatnonzero(used)
    local = np.full(n, -1, np.int64)
    local[bodies] = np.arange(bodies.shape[0])
    return (bodies, *renumber_rows(local, c_a, c_b))


@nb.njit(cache=True)
def gap_residuals(u, g, c_a, c_b, c_nx, c_ny):
    """r_k = g_k + (B_n u)_k for velocities ``u`` ((n, ≥2)) and g = gap/h: the slack of each
    projection constraint (negative: the gap closes within the step)."""
    m = c_a.shape[0]
    r = np.empty(m)
    for k in range(m):
        r[k] = g[k] + normal_velocity(u, c_a[k], c_b[k], c_nx[k], c_ny[k])
    return r


def sparse_rows(n_bodies, row_a, row_b, coef_a, coef_b):
    """B (m, 3 n_bodies) CSC: the rows of :func:`~crowd_env.core.contacts.build_rows` (two-body form) on
    the velocities (u_x, u_y, ω) of every body."""
    import scipy.sparse as sp

    m = row_a.shape[0]
    r = np.repeat(np.arange(m), 3)
    ca = (3 * row_a[:, None] + np.arange(3)).ravel()
    wall = row_b < 0
    cb = (3 * np.where(wall, 0, row_b)[:, None] + np.arange(3)).ravel()
    vb = (coef_b * (~wall)[:, None]).ravel()
    return sp.csc_matrix((np.concatenate([coef_a.ravel(), vb]), (np.concatenate([r, r]), np.concatenate([ca, cb]))),
                         shape=(m, 3 * n_bodies))


def touched_projection_rows(n, mass, c_a, c_b, c_nx, c_ny):
    """The large projections' data on the pedestrians some candidate touches (the others keep their
    velocity): ``(bodies, rows a, rows b renumbered into bodies, mass per velocity component (2k,),
    B_n (m, 2k) CSR)``."""
    bodies, la, lb = touched_bodies(n, c_a, c_b)
    return bodies, la, lb, np.repeat(mass[bodies], 2), normal_rows_sparse(bodies.shape[0], la, lb, c_nx, c_ny)


def normal_rows_sparse(n, c_a, c_b, c_nx, c_ny):
    """B_n (m, 2n) on translational velocities only (the projection leaves ω alone)."""
    import scipy.sparse as sp

    m = c_a.shape[0]
    rows = np.repeat(np.arange(m), 2)
    cols_a = np.stack([2 * c_a, 2 * c_a + 1], axis=1).ravel()
    vals_a = np.stack([c_nx, c_ny], axis=1).ravel()
    wall = c_b < 0
    bb = np.where(wall, 0, c_b)
    cols_b = np.stack([2 * bb, 2 * bb + 1], axis=1).ravel()
    vals_b = -np.stack([c_nx, c_ny], axis=1).ravel() * np.repeat(~wall, 2)
    return sp.csr_matrix((np.concatenate([vals_a, vals_b]), (np.concatenate([rows, rows]), np.concatenate([cols_a, cols_b]))),
                         shape=(m, 2 * n))


@nb.njit(cache=True)
def contact_keys(a, b, wall, sub, n, n_walls, n_sub=1):
    """One int64 per contact, equal for the same pair (a < b, pedestrian numbers below ``n``) or the
    same pedestrian and wall segment (b < 0, segment ``wall`` of ``n_walls``) and the same circles of the bodies
    (``sub`` below ``n_sub``: K² for bodies of K circles, :mod:`crowd_env.core.body`; 1 for disks) wherever it
    stands in a candidate list: matches contacts across lists (re-detection, the previous step's projection).
    A candidate list holds each pair of circles and each circle-segment contact once, so its keys are unique
    (``tests/core/test_simulator.py`` checks it). ``a``, ``b``, ``wall``, ``sub``: int64 arrays."""
    out = np.empty(a.shape[0], np.int64)
    stride = max(1, n_walls)
    for k in range(a.shape[0]):
        body = a[k] * n + b[k] if b[k] >= 0 else n * n + a[k] * stride + wall[k]
        out[k] = body * n_sub + sub[k] if n_sub > 1 else body
    return out
