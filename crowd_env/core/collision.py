"""The Frémond impact (Kabalan Eq. 4-8) solved exactly, compiled with numba.

Primal, in the convention that reproduces the paper's Eq. 17-19 (see ``docs/collision-problem.md``)::

    minimise  ½ Yᵀ H Y − rᵀ Y,   H = M + Bᵀ K B,   r = M v⁻ + ½ p_ext
    subject to 2 B_n Y ≥ B_n v⁻,   then v⁺ = 2 Y − v⁻.

Dual: with z = 2 H⁻¹ r − v⁻, G = H⁻¹ B_nᵀ, W = B_n G, q = B_n z, find λ ≥ 0 with
w = W λ + q ≥ 0 and λ·w = 0 (an LCP, solved by block principal pivoting with Murty's single-pivot
fallback, which terminates for the P-matrix W + εI); then v⁺ = z + G λ. λ are the reactive
percussions (kg m/s). The same dual code, with K = 0, projects velocities so that no candidate gap
closes within the step.
"""
from __future__ import annotations

import numba as nb
import numpy as np

from .contacts import NORMAL, build_rows
from .linalg import SAME_ROUNDING_FASTMATH, cholesky, cholesky_solve, dot_range, profile_cholesky, sub_scaled

STATUS_OK = 0
STATUS_MAX_ITER = 1
STATUS_TOO_LARGE = 2
# Impact clusters with more normal rows or bodies than these go to the sparse path (solve_rows_sparse):
# the dense solve costs O(n³ + n² m) and the sparse one a few ms of Python overhead; they break even there.
MAX_DENSE_ROWS = 600
MAX_DENSE_BODIES = 200
MAX_DENSE_PROJECTION_ROWS = 200  # same for components of the velocity projection (project_gaps_sparse)
# Pivoting rarely needs more than a dozen factorisations; degenerate jams can make it cycle through
# Murty's single pivots for hundreds: stop there and hand the cluster to the next solver in line.
DENSE_MAX_ITER = 40
LCP_PGS_SWEEPS = 8  # projected Gauss-Seidel sweeps (at most) that guess the starting free set of pivoting
PGS_SWEEPS = 300  # projected Gauss-Seidel sweeps that guess the first active set of a large projection
SPARSE_MAX_ITER = 6  # factorisations allowed to sparse pivoting on a large projection before the fallback
IPM_TOL_M_S = 1e-9  # absolute KKT tolerance (m/s) of the interior point projection (project_gaps_ipm)
REG_RELATIVE = 1e-8  # Tikhonov regularisation of W relative to its mean diagonal (W is singular in dense packings)


@nb.njit(cache=True)
def _factor_free(W, q, free, eps):
    """Indices F of the free set, A = W_FF + εI, its Cholesky factor and the solution of
    A λ_F = −q_F."""
    m = q.shape[0]
    nf = 0
    for i in range(m):
        if free[i]:
            nf += 1
    idx = np.empty(nf, np.int64)
    c = 0
    for i in range(m):
        if free[i]:
            idx[c] = i
            c += 1
    A = np.empty((nf, nf))
    rhs = np.empty(nf)
    for a in range(nf):
        Wa = W[idx[a]]
        for b in range(nf):
            A[a, b] = Wa[idx[b]]
        A[a, a] += eps
        rhs[a] = -q[idx[a]]
    L = cholesky(A)
    return idx, A, L, cholesky_solve(L, rhs)


@nb.njit(cache=True, fastmath=SAME_ROUNDING_FASTMATH)
def _refined(A, eps, q, idx, L, sol, refine):
    """λ (full length) from the free-set solution ``sol`` after ``refine`` steps of iterative
    refinement towards W_FF λ_F = −q_F with W_FF = A − εI (converges to a solution of the singular
    system when it is consistent)."""
    nf = idx.shape[0]
    sol = sol.copy()
    for _ in range(refine):
        res = np.empty(nf)
        for a in range(nf):
            res[a] = -q[idx[a]] - dot_range(A[a], 0, sol, 0, nf) + eps * sol[a]
        sol += cholesky_solve(L, res)
    lam = np.zeros(q.shape[0])
    for a in range(nf):
        lam[idx[a]] = sol[a]
    return lam


@nb.njit(cache=True, fastmath=SAME_ROUNDING_FASTMATH)
def _residual_w(W, q, lam, free):
    m = q.shape[0]
    w = np.empty(m)
    for i in range(m):  # λ is zero off the free set, so full rows of the symmetric W serve
        w[i] = 0.0 if free[i] else q[i] + dot_range(W[i], 0, lam, 0, m)
    return w


@nb.njit(cache=True, fastmath=SAME_ROUNDING_FASTMATH)
def _polish_keeps_lcp(W, q, lam, free, tol_l, tol_w):
    """Whether the polished λ still solves the LCP: λ ≥ −tol_l on the free set and w = Wλ + q ≥ −tol_w
    off it (as :func:`qp_bpp_sparse` checks its polish)."""
    m = q.shape[0]
    for i in range(m):
        if free[i]:
            if lam[i] < -tol_l:
                return False
        elif q[i] + dot_range(W[i], 0, lam, 0, m) < -tol_w:
            return False
    return True


@nb.njit(cache=True)
def _bpp(W, q, free, eps, diag_mean, qmax, max_iter):
    """Block principal pivoting from the free set ``free`` (modified in place).

    Returns ``(λ, success)``. λ is polished by iterative refinement on the final free set towards the
    unregularised W_FF λ_F = −q_F, and the polish is kept only if λ still solves the LCP
    (:func:`_polish_keeps_lcp`); otherwise the regularised solution (off by O(ε λ)) is returned. When
    W_FF is singular (linearly dependent contacts, as in jams) and q_F has a part outside its range
    (gaps that the dependent contacts cannot all hold: a closed loop of contacts with unequal gaps),
    each refinement step adds that part divided by ε along the null space of W_FF: Wλ does not change,
    but λ drifts below zero (−21 kg m/s in four steps on a jam of 51 contacts), and clipping it to 0
    then opens a violation of 0.15 m/s (1.5 mm of overlap in one step)."""
    m = q.shape[0]
    best = m + 1
    backup = 3
    for _ in range(max_iter):
        idx, A, L, sol = _factor_free(W, q, free, eps)
        lam = _refined(A, eps, q, idx, L, sol, 0)
        w = _residual_w(W, q, lam, free)
        lmax = 0.0
        for i in range(m):
            lmax = max(lmax, abs(lam[i]))
        tol_w = 1e-11 * (qmax + diag_mean * lmax) + 1e-300
        tol_l = tol_w / diag_mean
        n_bad = 0
        last_bad = -1
        for i in range(m):
            if (free[i] and lam[i] < -tol_l) or ((not free[i]) and w[i] < -tol_w):
                n_bad += 1
                last_bad = i
        if n_bad == 0:
            polished = _refined(A, eps, q, idx, L, sol, 4)  # polish with the same factor
            if _polish_keeps_lcp(W, q, polished, free, tol_l, tol_w):
                return polished, True
            return lam, True
        if n_bad < best:
            best = n_bad
            backup = 3
            flip_all = True
        elif backup > 0:
            backup -= 1
            flip_all = True
        else:
            flip_all = False
        if flip_all:
            for i in range(m):
                if (free[i] and lam[i] < -tol_l) or ((not free[i]) and w[i] < -tol_w):
                    free[i] = not free[i]
        else:
            free[last_bad] = not free[last_bad]
    return np.zeros(m), False


@nb.njit(cache=True, fastmath=SAME_ROUNDING_FASTMATH)
def _pgs_free_guess(W, q, max_sweeps):
    """Projected Gauss-Seidel on the LCP from λ = 0 until a sweep leaves the sign pattern of λ
    unchanged (at most ``max_sweeps``); returns the guessed free set {λ > 0}. Keeps w = Wλ + q up to
    date by a row update (W is symmetric) whenever some λ_i moves, so rows that stay at zero cost
    nothing."""
    m = q.shape[0]
    lam = np.zeros(m)
    w = q.copy()
    free = np.zeros(m, np.bool_)
    for _ in range(max_sweeps):
        changed = False
        for i in range(m):
            v = lam[i] - w[i] / W[i, i]
            v = v if v > 0.0 else 0.0
            d = v - lam[i]
            if d != 0.0:
                lam[i] = v
                sub_scaled(w, 0, W[i], 0, -d, m)
            if (v > 0.0) != free[i]:
                free[i] = v > 0.0
                changed = True
        if not changed:
            break
    return free


@nb.njit(cache=True)
def lcp_bpp(W, q):
    """Solve the LCP w = Wλ + q ≥ 0, λ ≥ 0, λᵀw = 0 for symmetric positive semi-definite W.

    Block principal pivoting (Júdice & Pires 1994) with Murty's single-pivot fallback on
    W + εI (ε = 1e-8 · mean diag W; W is singular when contacts outnumber degrees of freedom),
    with tolerances scaled by the size of the terms. It starts from the free set that a few sweeps
    of projected Gauss-Seidel guess (``LCP_PGS_SWEEPS``; usually right, which leaves one
    factorisation instead of four or five); should pivoting from that guess fail, it restarts from
    the empty set. The final λ is polished by iterative refinement on the free set so the
    regularisation leaves no bias (where that keeps it a solution: :func:`_bpp`). A single contact is
    solved in closed form. Every returned λ is checked: w = Wλ + q ≥ −tol on every row, tol covering
    round-off and the regularisation's bias 2 ε max λ; otherwise STATUS_MAX_ITER. Returns
    ``(λ, status)``.
    """
    m = q.shape[0]
    if m == 0:
        return np.zeros(0), STATUS_OK
    if m == 1 and W[0, 0] > 0.0:  # one contact: λ = max(0, −q/W) in closed form
        lam = np.zeros(1)
        if q[0] < 0.0:
            lam[0] = -q[0] / W[0, 0]
        return lam, STATUS_OK
    diag_mean = 0.0
    for i in range(m):
        diag_mean += W[i, i]
    diag_mean /= m
    if diag_mean <= 0.0:
        diag_mean = 1.0
    eps = REG_RELATIVE * diag_mean
    qmax = 0.0
    for i in range(m):
        qmax = max(qmax, abs(q[i]))
    max_iter = min(2 * m + 20, DENSE_MAX_ITER)
    free = _pgs_free_guess(W, q, LCP_PGS_SWEEPS)
    lam, ok = _bpp(W, q, free, eps, diag_mean, qmax, max_iter)
    if not ok:
        free[:] = False
        lam, ok = _bpp(W, q, free, eps, diag_mean, qmax, max_iter)
    if not ok:
        return np.zeros(m), STATUS_MAX_ITER
    lmax = 0.0
    for i in range(m):
        if lam[i] < 0.0:
            lam[i] = 0.0
        lmax = max(lmax, lam[i])
    # The answer is checked, not trusted: w = Wλ + q ≥ 0 on every row up to the regularisation's bias
    # (ε λ on the free set when the polish was not kept) and round-off; otherwise the caller's next
    # solver takes over (the sparse or interior point path), never a violated constraint.
    tol = 100.0 * 1e-11 * (qmax + diag_mean * lmax) + 2.0 * eps * lmax
    for i in range(m):
        if q[i] + dot_range(W[i], 0, lam, 0, m) < -tol:
            return np.zeros(m), STATUS_MAX_ITER
    return lam, STATUS_OK


@nb.njit(cache=True)
def _order_dofs(nb_, row_a, row_b, coef_a, coef_b):
    """Bodies in reverse Cuthill-McKee order of the row graph, and their degrees of freedom that
    some row uses (the others decouple: H is diagonal there). Returns ``(perm, pos)``: new → old
    DOF index, and old → new (−1 for an unused DOF). A banded ordering keeps the Cholesky factor of
    H = M + Bᵀ K B inside a narrow profile, which :func:`solve_rows` exploits."""
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


@nb.njit(cache=True, fastmath=SAME_ROUNDING_FASTMATH)
def _forward_columns(L, first, Z, col_start):
    """Z ← L⁻¹ Z in place, row by row. Column e of Z is zero above row ``col_start[e]`` and the
    columns are sorted by it, so row i only touches the prefix of columns already started."""
    n = L.shape[0]
    ncol = Z.shape[1]
    cnt = 0
    for i in range(n):
        while cnt < ncol and col_start[cnt] <= i:
            cnt += 1
        Zi = Z[i]
        for j in range(first[i], i):
            lij = L[i, j]
            if lij != 0.0:
                sub_scaled(Zi, 0, Z[j], 0, lij, cnt)
        inv = 1.0 / L[i, i]
        for e in range(cnt):
            Zi[e] *= inv


@nb.njit(cache=True)
def solve_rows(mass_diag, row_a, row_b, coef_a, coef_b, row_k, row_kind, v_minus, p_ext):
    """Frémond impact of one cluster given in the two-body row form of :mod:`contacts`.

    ``mass_diag`` (3n,) is diag(M); ``v_minus``/``p_ext`` (3n,). Returns ``(v_plus, λ, status)``
    with λ the reactive percussion of each normal row (rows of kind 0, in order).

    Dense, but in an order that keeps it cheap: degrees of freedom no row touches are solved
    directly (v⁺ = v⁻ + M⁻¹ p_ext), the others are numbered by reverse Cuthill-McKee over the
    bodies so that H = M + Bᵀ K B and its Cholesky factor L have a narrow profile; then
    X = L⁻ᵀ L⁻¹ [r, B_nᵀ] = H⁻¹ [r, B_nᵀ] (columns sorted by their first nonzero row, so each row
    of the forward substitution only touches the columns already started), W = B_n X_n and
    q = 2 B_n x₀ − B_n v⁻ from the at most 6 entries of each row of B_n (about 7× fewer operations
    than the Gram matrix Z_nᵀ Z_n), the LCP by :func:`lcp_bpp`, and v⁺ = 2 x₀ + X_n λ − v⁻.
    """
    nd_all = mass_diag.shape[0]
    m = row_a.shape[0]
    perm, pos = _order_dofs(nd_all // 3, row_a, row_b, coef_a, coef_b)
    nd = perm.shape[0]
    H = np.zeros((nd, nd))
    for i in range(nd):
        H[i, i] = mass_diag[perm[i]]
    cols = np.empty(6, np.int64)
    vals = np.empty(6)
    nn = 0
    for r in range(m):
        if row_kind[r] == NORMAL:
            nn += 1
        k = row_k[r]
        if k == 0.0:
            continue
        cnt = 0
        for d in range(3):
            if coef_a[r, d] != 0.0:
                cols[cnt] = pos[3 * row_a[r] + d]
                vals[cnt] = coef_a[r, d]
                cnt += 1
        if row_b[r] >= 0:
            for d in range(3):
                if coef_b[r, d] != 0.0:
                    cols[cnt] = pos[3 * row_b[r] + d]
                    vals[cnt] = coef_b[r, d]
                    cnt += 1
        for p in range(cnt):
            for s in range(cnt):
                H[cols[p], cols[s]] += k * vals[p] * vals[s]
    first = np.empty(nd, np.int64)
    for i in range(nd):
        f = i
        for j in range(i):
            if H[i, j] != 0.0:
                f = j
                break
        first[i] = f
    L = profile_cholesky(H, first)
    # Normal rows sorted by the first (new) DOF they touch: their columns of Z start there.
    nstart = np.empty(nn, np.int64)
    nrow = np.empty(nn, np.int64)
    c = 0
    for r in range(m):
        if row_kind[r] != NORMAL:
            continue
        s0 = nd
        for d in range(3):
            if coef_a[r, d] != 0.0:
                s0 = min(s0, pos[3 * row_a[r] + d])
            if row_b[r] >= 0 and coef_b[r, d] != 0.0:
                s0 = min(s0, pos[3 * row_b[r] + d])
        nstart[c] = s0
        nrow[c] = r
        c += 1
    order = np.argsort(nstart, kind="mergesort")
    col_start = np.empty(1 + nn, np.int64)
    col_start[0] = 0
    Z = np.zeros((nd, 1 + nn))
    for i in range(nd):
        Z[i, 0] = mass_diag[perm[i]] * v_minus[perm[i]] + 0.5 * p_ext[perm[i]]
    bv = np.zeros(nn)  # B_n v⁻, sorted order
    for e in range(nn):
        r = nrow[order[e]]
        col_start[1 + e] = nstart[order[e]]
        for d in range(3):
            if coef_a[r, d] != 0.0:
                Z[pos[3 * row_a[r] + d], 1 + e] += coef_a[r, d]
            bv[e] += coef_a[r, d] * v_minus[3 * row_a[r] + d]
            if row_b[r] >= 0:
                if coef_b[r, d] != 0.0:
                    Z[pos[3 * row_b[r] + d], 1 + e] += coef_b[r, d]
                bv[e] += coef_b[r, d] * v_minus[3 * row_b[r] + d]
    _forward_columns(L, first, Z, col_start)
    for i in range(nd - 1, -1, -1):  # back substitution with Lᵀ (row access of L): Z ← H⁻¹ [r, B_nᵀ]
        Zi = Z[i]
        inv = 1.0 / L[i, i]
        for e in range(1 + nn):
            Zi[e] *= inv
        for j in range(first[i], i):
            sub_scaled(Z[j], 0, Zi, 0, L[i, j], 1 + nn)
    # W = B_n (H⁻¹ B_nᵀ) and q = 2 B_n H⁻¹ r − B_n v⁻: each row of B_n has at most 6 entries
    W = np.zeros((nn, nn))
    q = np.empty(nn)
    for e in range(nn):
        r = nrow[order[e]]
        We = W[e]
        s = -bv[e]
        for side in range(2):
            body = row_a[r] if side == 0 else row_b[r]
            if body < 0:
                continue
            for d in range(3):
                cf = coef_a[r, d] if side == 0 else coef_b[r, d]
                if cf != 0.0:
                    Zp = Z[pos[3 * body + d]]
                    s += 2.0 * cf * Zp[0]
                    sub_scaled(We, e, Zp, 1 + e, -cf, nn - e)  # upper triangle only
        q[e] = s
    for a in range(nn):  # mirror: W exactly symmetric
        for b in range(a):
            W[a, b] = W[b, a]
    lam_sorted, status = lcp_bpp(W, q)
    y = np.empty(nd)  # v⁺ + v⁻ = H⁻¹ (2 r + B_nᵀ λ)
    for i in range(nd):
        Zi = Z[i]
        y[i] = 2.0 * Zi[0] + dot_range(Zi, 1, lam_sorted, 0, nn)
    v_plus = np.empty(nd_all)
    for i in range(nd_all):
        v_plus[i] = v_minus[i] + p_ext[i] / mass_diag[i] if pos[i] < 0 else 0.0
    for i in range(nd):
        v_plus[perm[i]] = y[i] - v_minus[perm[i]]
    lam = np.empty(nn)
    for e in range(nn):
        lam[order[e]] = lam_sorted[e]
    return v_plus, lam, status


@nb.njit(cache=True)
def _find(parent, x):
    root = x
    while parent[root] != root:
        root = parent[root]
    while parent[x] != root:
        nxt = parent[x]
        parent[x] = root
        x = nxt
    return root


@nb.njit(cache=True)
def _union(parent, x, y):
    rx = _find(parent, x)
    ry = _find(parent, y)
    if rx != ry:
        if rx < ry:
            parent[ry] = rx
        else:
            parent[rx] = ry


@nb.njit(cache=True)
def _normal_velocity(vel, a, b, nx, ny):
    vn = vel[a, 0] * nx + vel[a, 1] * ny
    if b >= 0:
        vn -= vel[b, 0] * nx + vel[b, 1] * ny
    return vn


@nb.njit(cache=True)
def _group_by(keys, n_keys):
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
def resolve_impacts(vel, mass, inertia, c_a, c_b, c_gap, c_nx, c_ny, c_rho_a, c_rho_b,
                    l_a, l_b, dvec, gi, gj, k_n, k_tg, k_v, eps_m, vtol, rotation, max_dense_rows,
                    max_dense_bodies=MAX_DENSE_BODIES):
    """Frémond impacts of every connected cluster, in place on ``vel`` ((n, 3): u_x, u_y, ω).

    The impact set holds the contacts that touch (gap ≤ ε) and approach or rest (Δ·n ≤ vtol), plus
    the hand links; clusters are connected components of that graph, solved when they contain a
    strictly approaching contact or a link. Contacts that touch but already separate are left out,
    so kinetic energy cannot increase (collision-problem.md, "Energy").
    Clusters with more than ``max_dense_rows`` normal rows or ``max_dense_bodies`` bodies (pass −1 to
    route every cluster), or where pivoting fails, are left untouched and their root reported in
    ``unsolved`` for :func:`solve_clusters` (sparse or reference solvers).
    Returns ``(p_normal, p_tangent, in_impact, root, unsolved, n_clusters, max_cluster)``: total normal and
    tangential percussion per contact (kg m/s; reactive + dissipative), the impact-set mask, counts.
    """
    n = vel.shape[0]
    nc = c_a.shape[0]
    nl = l_a.shape[0] if k_v > 0.0 else 0
    p_normal = np.zeros(nc)
    p_tangent = np.zeros(nc)
    in_impact = np.zeros(nc, np.bool_)
    vn = np.empty(nc)
    parent = np.arange(n)
    any_imp = False
    for c in range(nc):
        vn[c] = _normal_velocity(vel, c_a[c], c_b[c], c_nx[c], c_ny[c])
        if c_gap[c] <= eps_m and vn[c] <= vtol:
            in_impact[c] = True
            any_imp = True
            if c_b[c] >= 0:
                _union(parent, c_a[c], c_b[c])
    for l in range(nl):
        _union(parent, l_a[l], l_b[l])
    root = np.empty(n, np.int64)
    unsolved = np.zeros(0, np.int64)
    if not any_imp and nl == 0:
        return p_normal, p_tangent, in_impact, root, unsolved, 0, 0
    for i in range(n):
        root[i] = _find(parent, i)
    need = np.zeros(n, np.bool_)
    for c in range(nc):
        if in_impact[c] and vn[c] < -vtol:
            need[root[c_a[c]]] = True
    for l in range(nl):
        need[root[l_a[l]]] = True
    # Group bodies, impact contacts and links by root.
    body_order, body_start = _group_by(root, n)
    imp_ids = np.flatnonzero(in_impact)
    imp_root = np.empty(imp_ids.shape[0], np.int64)
    for k in range(imp_ids.shape[0]):
        imp_root[k] = root[c_a[imp_ids[k]]]
    imp_order, con_start = _group_by(imp_root, n)
    imp_sorted = imp_ids[imp_order]
    link_root = np.empty(nl, np.int64)
    for l in range(nl):
        link_root[l] = root[l_a[l]]
    link_sorted, link_start = _group_by(link_root, n)
    local = np.full(n, -1, np.int64)
    n_clusters = 0
    max_cluster = 0
    failed = np.zeros(n, np.bool_)
    for rt in range(n):
        if not need[rt]:
            continue
        bodies = body_order[body_start[rt]:body_start[rt + 1]]
        nb_ = bodies.shape[0]
        n_clusters += 1
        max_cluster = max(max_cluster, nb_)
        for k in range(nb_):
            local[bodies[k]] = k
        cids = imp_sorted[con_start[rt]:con_start[rt + 1]]
        lids = link_sorted[link_start[rt]:link_start[rt + 1]]
        if cids.shape[0] > max_dense_rows or (max_dense_rows >= 0 and nb_ > max_dense_bodies):
            failed[rt] = True
            for k in range(nb_):
                local[bodies[k]] = -1
            continue
        row_a, row_b, coef_a, coef_b, row_k, row_kind = build_rows(
            cids, c_a, c_b, c_nx, c_ny, c_rho_a, c_rho_b, lids, l_a, l_b, dvec, gi, gj,
            local, k_n, k_tg, k_v, rotation)
        mass_diag = np.empty(3 * nb_)
        v_minus = np.empty(3 * nb_)
        for k in range(nb_):
            i = bodies[k]
            mass_diag[3 * k] = mass[i]
            mass_diag[3 * k + 1] = mass[i]
            mass_diag[3 * k + 2] = inertia[i]
            v_minus[3 * k] = vel[i, 0]
            v_minus[3 * k + 1] = vel[i, 1]
            v_minus[3 * k + 2] = vel[i, 2]
        v_plus, lam, st = solve_rows(mass_diag, row_a, row_b, coef_a, coef_b, row_k, row_kind,
                                     v_minus, np.zeros(3 * nb_))
        if st != STATUS_OK:
            failed[rt] = True
            for k in range(nb_):
                local[bodies[k]] = -1
            continue
        for k in range(nb_):
            i = bodies[k]
            vel[i, 0] = v_plus[3 * k]
            vel[i, 1] = v_plus[3 * k + 1]
            vel[i, 2] = v_plus[3 * k + 2] if rotation else vel[i, 2]
        # Percussions: reactive λ plus dissipative −K (B (v⁺ + v⁻)) on each row.
        ncid = cids.shape[0]
        for r in range(row_a.shape[0]):
            s = 0.0
            for d in range(3):
                s += coef_a[r, d] * (v_plus[3 * row_a[r] + d] + v_minus[3 * row_a[r] + d])
                if row_b[r] >= 0:
                    s += coef_b[r, d] * (v_plus[3 * row_b[r] + d] + v_minus[3 * row_b[r] + d])
            if r < ncid:
                p_normal[cids[r]] = lam[r] - row_k[r] * s
            elif row_kind[r] == 1:
                p_tangent[cids[r - ncid]] = -row_k[r] * s
        for k in range(nb_):
            local[bodies[k]] = -1
    unsolved = np.flatnonzero(failed)
    return p_normal, p_tangent, in_impact, root, unsolved, n_clusters, max_cluster


@nb.njit(cache=True)
def project_gaps(vel, mass, c_a, c_b, c_gap, c_nx, c_ny, dt_s, tol, max_rows=MAX_DENSE_PROJECTION_ROWS):
    """Velocity projection: v = argmin ‖v − v'‖_M s.t. gap_k + h (B_n v)_k ≥ 0 for every candidate.

    Solved as the LCP with W = B_n M⁻¹ B_nᵀ, q = B_n v' + gap/h on a growing set of violated
    constraints (exact for the full set at termination). Only translational velocities change.
    A component with more than ``max_rows`` active constraints stops it with STATUS_TOO_LARGE
    (velocities restored): the caller then uses :func:`project_gaps_large`.
    A projection onto a convex set containing 0 cannot add kinetic energy. Returns
    ``(λ per contact, rounds, status)``; λ is the projection percussion (kg m/s).
    """
    n = vel.shape[0]
    nc = c_a.shape[0]
    lam_out = np.zeros(nc)
    active = np.zeros(nc, np.bool_)
    n_act = 0
    for c in range(nc):
        if c_gap[c] / dt_s + _normal_velocity(vel, c_a[c], c_b[c], c_nx[c], c_ny[c]) < -tol:
            active[c] = True
            n_act += 1
    if n_act == 0:
        return lam_out, 0, STATUS_OK
    v0 = vel[:, :2].copy()
    status = STATUS_OK
    local = np.full(n, -1, np.int64)
    rounds = 0
    for rounds in range(1, 101):
        parent = np.arange(n)
        for c in range(nc):
            if active[c] and c_b[c] >= 0:
                _union(parent, c_a[c], c_b[c])
        root = np.empty(n, np.int64)
        for i in range(n):
            root[i] = _find(parent, i)
        vel[:, :2] = v0
        act_ids = np.flatnonzero(active)
        act_root = np.empty(act_ids.shape[0], np.int64)
        for k in range(act_ids.shape[0]):
            act_root[k] = root[c_a[act_ids[k]]]
        order = np.argsort(act_root, kind="mergesort")
        start = 0
        while start < order.shape[0]:
            rt = act_root[order[start]]
            stop = start
            while stop < order.shape[0] and act_root[order[stop]] == rt:
                stop += 1
            cids = act_ids[order[start:stop]]
            m = cids.shape[0]
            if m > max_rows:
                vel[:, :2] = v0
                return lam_out, rounds, STATUS_TOO_LARGE
            # Bodies of this cluster.
            nb_ = 0
            for c in cids:
                for body in (c_a[c], c_b[c]):
                    if body >= 0 and local[body] < 0:
                        local[body] = nb_
                        nb_ += 1
            bodies = np.empty(nb_, np.int64)
            for c in cids:
                for body in (c_a[c], c_b[c]):
                    if body >= 0:
                        bodies[local[body]] = body
            # W = B_n M⁻¹ B_nᵀ assembled body by body; q = B_n v' + gap / h.
            W = np.zeros((m, m))
            q = np.empty(m)
            for r in range(m):
                c = cids[r]
                q[r] = c_gap[c] / dt_s + _normal_velocity(vel, c_a[c], c_b[c], c_nx[c], c_ny[c])
                for s in range(m):
                    c2 = cids[s]
                    dot = c_nx[c] * c_nx[c2] + c_ny[c] * c_ny[c2]
                    acc = 0.0
                    if c_a[c] == c_a[c2]:
                        acc += dot / mass[c_a[c]]
                    if c_b[c] >= 0 and c_b[c] == c_b[c2]:
                        acc += dot / mass[c_b[c]]
                    if c_b[c2] >= 0 and c_a[c] == c_b[c2]:
                        acc -= dot / mass[c_a[c]]
                    if c_b[c] >= 0 and c_b[c] == c_a[c2]:
                        acc -= dot / mass[c_b[c]]
                    W[r, s] = acc
            lam, st = lcp_bpp(W, q)
            if st != STATUS_OK:
                vel[:, :2] = v0
                return lam_out, rounds, st
            for r in range(m):
                c = cids[r]
                lam_out[c] = lam[r]
                if lam[r] != 0.0:
                    a = c_a[c]
                    vel[a, 0] += lam[r] * c_nx[c] / mass[a]
                    vel[a, 1] += lam[r] * c_ny[c] / mass[a]
                    b = c_b[c]
                    if b >= 0:
                        vel[b, 0] -= lam[r] * c_nx[c] / mass[b]
                        vel[b, 1] -= lam[r] * c_ny[c] / mass[b]
            for k in range(nb_):
                local[bodies[k]] = -1
            start = stop
        added = 0
        for c in range(nc):
            if not active[c]:
                if c_gap[c] / dt_s + _normal_velocity(vel, c_a[c], c_b[c], c_nx[c], c_ny[c]) < -tol:
                    active[c] = True
                    added += 1
        if added == 0:
            return lam_out, rounds, status
    # The active set still grew in the last round: the last solve missed some constraints.
    vel[:, :2] = v0
    return lam_out, rounds, STATUS_MAX_ITER


def qp_bpp_sparse(H, c, B, d, free0=None, max_iter=None):
    """Exact solution of  min ½ xᵀ H x − cᵀ x  s.t.  B x ≥ d  for large sparse problems.

    Block principal pivoting (block flips, then Murty single pivots after three non-improving
    ones) on the dual LCP, each trial active set F solved with a sparse factorisation (SuperLU)
    instead of the dense Delassus matrix B H⁻¹ Bᵀ: of the quasi-definite KKT system
    [[H, B_Fᵀ], [B_F, −εI]], or, when H is diagonal, of its Schur complement B_F H⁻¹ B_Fᵀ + εI.
    Pivoting works on the regularised dual (W + εI, a P-matrix, ε = 1e-8 · a Jacobi estimate of the
    mean diagonal of W; W itself is singular when contacts are linearly dependent, as in jams), so it
    terminates; the final active set is then polished by iterative refinement towards the
    unregularised system, kept only if it stays feasible with λ ≥ 0 (otherwise the regularised
    solution, off by O(ε), is returned). ``H`` (n, n) sparse symmetric positive definite, ``B``
    (m, n) sparse, ``free0`` an optional initial active set (bool (m,)). Returns
    ``(x, ν, status, iterations)`` with ν ≥ 0 the multipliers (H x = c + Bᵀ ν).
    """
    import scipy.sparse as sp
    from scipy.sparse.linalg import splu

    n = H.shape[0]
    m = B.shape[0]
    H = sp.csc_matrix(H)
    B = sp.csr_matrix(B)
    c = np.asarray(c, dtype=np.float64)
    d = np.asarray(d, dtype=np.float64)
    hdiag = H.diagonal()
    diagonal = H.nnz == np.count_nonzero(hdiag)
    free = np.zeros(m, np.bool_) if free0 is None else np.array(free0, dtype=np.bool_)
    diag_mean = float((B.multiply(B) @ (1.0 / hdiag)).mean()) if m else 1.0
    diag_mean = diag_mean if diag_mean > 0.0 else 1.0
    eps = REG_RELATIVE * diag_mean
    x_free = c / hdiag if diagonal else None

    def factor(F):
        """Returns solve(refine_unregularised) -> (x, ν_F) for the active set F."""
        nf = F.shape[0]
        if diagonal:
            BF = B[F]
            hinv = sp.diags(1.0 / hdiag)
            HiBt = (hinv @ BF.T).tocsc()
            S0 = (BF @ HiBt).tocsc()
            S = (S0 + eps * sp.identity(nf)).tocsc() if nf else S0
            lu = splu(S) if nf else None
            rhs = d[F] - BF @ x_free

            def solve(polish):
                if nf == 0:
                    return x_free.copy(), np.zeros(0)
                lam = lu.solve(rhs)
                lam += lu.solve(rhs - S @ lam)
                for _ in range(4 if polish else 0):
                    lam += lu.solve(rhs - S0 @ lam)
                return x_free + HiBt @ lam, lam
            return solve
        rhs = np.concatenate([c, d[F]])
        if nf:
            BF = B[F]
            K = sp.bmat([[H, BF.T], [BF, -eps * sp.identity(nf)]], format="csc")
        else:
            K = H
        lu = splu(K)

        def solve(polish):
            sol = lu.solve(rhs)
            sol += lu.solve(rhs - K @ sol)
            if polish and nf:
                K0 = sp.bmat([[H, BF.T], [BF, None]], format="csc")
                for _ in range(4):
                    sol += lu.solve(rhs - K0 @ sol)
            return sol[:n], -sol[n:]
        return solve

    max_iter = min(2 * m + 20, DENSE_MAX_ITER) if max_iter is None else max_iter
    best = m + 1
    backup = 3
    status = STATUS_MAX_ITER
    for it in range(1, max_iter + 1):
        F = np.flatnonzero(free)
        solve = factor(F)
        x, nu_f = solve(False)
        nu = np.zeros(m)
        nu[F] = nu_f
        w = B @ x - d
        w[F] += eps * nu_f  # residual of the regularised LCP: zero on the free set
        nf = F.shape[0]
        scale = (float(np.abs(w[~free]).max()) if nf < m else 0.0) + diag_mean * (float(np.abs(nu).max()) if m else 0.0)
        tol_w = 1e-11 * scale + 1e-300
        tol_l = tol_w / diag_mean
        bad = (free & (nu < -tol_l)) | (~free & (w < -tol_w))
        n_bad = int(bad.sum())
        if n_bad == 0:
            status = STATUS_OK
            break
        if n_bad < best:
            best = n_bad
            backup = 3
            free ^= bad
        elif backup > 0:
            backup -= 1
            free ^= bad
        else:
            k = int(np.flatnonzero(bad)[-1])
            free[k] = not free[k]
    if status != STATUS_OK:
        return x, np.maximum(nu, 0.0), status, max_iter
    if F.shape[0]:  # polish: remove the O(ε) bias where the unregularised system is consistent
        x2, nu2_f = solve(True)
        w2 = B @ x2 - d
        if np.all(nu2_f >= -tol_l) and np.all(w2[~free] >= -tol_w) and np.all(np.abs(w2[F]) <= 1e3 * tol_w):
            x = x2
            nu = np.zeros(m)
            nu[F] = nu2_f
    return x, np.maximum(nu, 0.0), STATUS_OK, it


def solve_rows_sparse(mass_diag, row_a, row_b, coef_a, coef_b, row_k, row_kind, v_minus, p_ext=None, free0=None):
    """Same problem, inputs and outputs as :func:`solve_rows` (plus ``status``), for large clusters:
    the primal  min ½ Yᵀ H Y − rᵀ Y  s.t.  B_n Y ≥ ½ B_n v⁻  by :func:`qp_bpp_sparse` (exact, sparse).
    Returns ``(v_plus, λ, status)``; λ = 2ν are the reactive percussions of the normal rows."""
    import scipy.sparse as sp

    nd = mass_diag.shape[0]
    p_ext = np.zeros(nd) if p_ext is None else p_ext
    B = _sparse_rows(nd // 3, row_a, row_b, coef_a, coef_b)
    H = (sp.diags(mass_diag) + B.T @ sp.diags(row_k) @ B).tocsc()
    Bn = B[np.flatnonzero(row_kind == NORMAL)]
    y, nu, status, _ = qp_bpp_sparse(H, mass_diag * v_minus + 0.5 * p_ext, Bn, 0.5 * (Bn @ v_minus), free0)
    return 2.0 * y - v_minus, 2.0 * nu, status


def _touched_projection_rows(n, mass, c_a, c_b, c_nx, c_ny):
    """The large projections' data on the pedestrians some candidate touches (the others keep their
    velocity): ``(bodies, rows a, rows b renumbered into bodies, mass per velocity component (2k,),
    B_n (m, 2k) CSR)``."""
    bodies, la, lb = touched_bodies(n, c_a, c_b)
    return bodies, la, lb, np.repeat(mass[bodies], 2), _normal_rows_sparse(bodies.shape[0], la, lb, c_nx, c_ny)


def _normal_rows_sparse(n, c_a, c_b, c_nx, c_ny):
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
def _pgs_projection(u, inv_mass, c_a, c_b, c_nx, c_ny, q0, sweeps):
    """Projected Gauss-Seidel on the projection's dual (in place on ``u`` (n, 2)): an approximate
    λ whose support is a good first active set for :func:`qp_bpp_sparse`."""
    m = c_a.shape[0]
    lam = np.zeros(m)
    for _ in range(sweeps):
        for k in range(m):
            a = c_a[k]
            b = c_b[k]
            w = q0[k] + c_nx[k] * u[a, 0] + c_ny[k] * u[a, 1]
            dk = inv_mass[a]
            if b >= 0:
                w -= c_nx[k] * u[b, 0] + c_ny[k] * u[b, 1]
                dk += inv_mass[b]
            new = lam[k] - w / dk
            if new < 0.0:
                new = 0.0
            dl = new - lam[k]
            if dl != 0.0:
                lam[k] = new
                u[a, 0] += dl * c_nx[k] * inv_mass[a]
                u[a, 1] += dl * c_ny[k] * inv_mass[a]
                if b >= 0:
                    u[b, 0] -= dl * c_nx[k] * inv_mass[b]
                    u[b, 1] -= dl * c_ny[k] * inv_mass[b]
    return lam


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
        r[k] = g[k] + _normal_velocity(u, c_a[k], c_b[k], c_nx[k], c_ny[k])
    return r


def project_gaps_sparse(vel, mass, c_a, c_b, c_gap, c_nx, c_ny, dt_s, free0=None, max_iter=None):
    """The projection of :func:`project_gaps` on all candidates at once, solved exactly by
    :func:`qp_bpp_sparse` (for clusters too large for the dense path). Only the pedestrians that
    appear in a candidate take part. Modifies ``vel[:, :2]`` in place when it succeeds; returns
    ``(λ per contact, status)``. The first active set comes from a few hundred projected Gauss-Seidel
    sweeps unless ``free0`` is given; pivoting stops after ``SPARSE_MAX_ITER`` factorisations
    (degenerate jams can cycle for long) and then reports STATUS_MAX_ITER, leaving ``vel`` alone."""
    import scipy.sparse as sp

    m = c_a.shape[0]
    if m == 0:
        return np.zeros(0), STATUS_OK
    bodies, la, lb, mdiag, B = _touched_projection_rows(vel.shape[0], mass, c_a, c_b, c_nx, c_ny)
    q0 = np.asarray(c_gap) / dt_s
    if free0 is None:
        guess = _pgs_projection(vel[bodies, :2].copy(), 1.0 / mass[bodies], la, lb, np.ascontiguousarray(c_nx),
                                np.ascontiguousarray(c_ny), q0, PGS_SWEEPS)
        free0 = guess > 0.0
    x, nu, status, _ = qp_bpp_sparse(sp.diags(mdiag), mdiag * vel[bodies, :2].ravel(), B, -q0, free0,
                                     max_iter=SPARSE_MAX_ITER if max_iter is None else max_iter)
    if status == STATUS_OK:
        vel[bodies, :2] = x.reshape(-1, 2)
    return nu, status


def project_gaps_qp(vel, mass, c_a, c_b, c_gap, c_nx, c_ny, dt_s):
    """The projection of :func:`project_gaps` solved as a sparse QP by Clarabel (interior point).

    Used when pivoting cannot certify a solution (very degenerate jammed packings, where contacts
    outnumber degrees of freedom several times over): the primal is strictly convex in v, so v is
    unique even where λ is not. Modifies ``vel[:, :2]`` in place; returns λ per contact.
    """
    import scipy.sparse as sp

    n = vel.shape[0]
    Bn = _normal_rows_sparse(n, c_a, c_b, c_nx, c_ny).tocsc()
    mdiag = np.repeat(mass, 2)
    P = sp.diags(mdiag).tocsc()  # the mass metric
    v0 = vel[:, :2].ravel().copy()
    # min ½ vᵀ M v − (M v')ᵀ v  s.t.  −B_n v + s = gap/h, s ≥ 0
    x, z = _clarabel_solve(P, -mdiag * v0, (-Bn).tocsc(), c_gap / dt_s, "projection")
    vel[:, :2] = x.reshape(n, 2)
    return z


def project_gaps_ipm(vel, mass, c_a, c_b, c_gap, c_nx, c_ny, dt_s):
    """The projection of :func:`project_gaps` by PIQP (a proximal interior point method, sparse LDLᵀ).

    For large jams, where the augmented Lagrangian needs many Newton steps (each adds the constraints a
    push passes on, so their number grows with the jam's diameter: 10-21 steps at 400 pedestrians,
    30-75 at 1400) while an interior point method needs 14-22 iterations at any size. Its KKT residuals
    are ≤ ``IPM_TOL_M_S``: slack ≥ −1e-9 m/s (overlap ≤ 1e-11 m per step; measured ≥ −6e-12 m/s) and v
    close to the augmented Lagrangian's exact one (the tests check 1e-6 m/s on their jams; up to 7e-6 m/s
    was measured on the door jams of ``benchmarks/scaling.py``). Modifies ``vel[:, :2]`` in place on
    success; returns ``(λ per contact, ok)`` (not ok: ``vel`` left alone)."""
    import piqp
    import scipy.sparse as sp

    n = vel.shape[0]
    m = c_a.shape[0]
    if m == 0:
        return np.zeros(0), True
    bodies, _, _, mdiag, B = _touched_projection_rows(n, mass, c_a, c_b, c_nx, c_ny)
    solver = piqp.SparseSolver()
    solver.settings.eps_abs = IPM_TOL_M_S
    solver.settings.eps_rel = 0.0
    solver.settings.kkt_solver = piqp.KKTSolver.sparse_ldlt_cond  # normal equations M + Bᵀ D B
    # min ½ vᵀ M v − (M v')ᵀ v  s.t.  B_n v ≥ −gap/h
    solver.setup(sp.diags(mdiag).tocsc(), -mdiag * vel[bodies, :2].ravel(), None, None, B.tocsc(),
                 -np.asarray(c_gap) / dt_s, None)
    status = solver.solve()
    if status != piqp.Status.PIQP_SOLVED:
        return np.zeros(m), False
    vel[bodies, :2] = solver.result.x.reshape(-1, 2)
    return np.maximum(np.asarray(solver.result.z_l), 0.0), True


def project_gaps_large(vel, mass, c_a, c_b, c_gap, c_nx, c_ny, dt_s):
    """The projection for clusters too large for :func:`project_gaps`, in place on ``vel[:, :2]``.

    1. :func:`project_gaps_sparse` (projected Gauss-Seidel guess, then exact sparse pivoting with
       at most ``SPARSE_MAX_ITER`` factorisations);
    2. if pivoting cycles (degenerate jams: linearly dependent contacts make λ non-unique), Clarabel
       on the primal, whose v is unique, then a polish: pivoting started from the constraints
       Clarabel leaves tight, which certifies the exact solution in one or two factorisations;
    3. if even that fails, Clarabel's solution as it is (feasible to ~1e-12, v within ~1e-6).
    Returns ``(λ per contact, path)`` with path 0, 1 or 2 as above.
    """
    v_in = vel[:, :2].copy()
    lam, status = project_gaps_sparse(vel, mass, c_a, c_b, c_gap, c_nx, c_ny, dt_s)
    if status == STATUS_OK:
        return lam, 0
    vel[:, :2] = v_in
    lam = project_gaps_qp(vel, mass, c_a, c_b, c_gap, c_nx, c_ny, dt_s)
    slack = gap_residuals(vel, c_gap / dt_s, c_a, c_b, c_nx, c_ny)
    tight = slack <= 1e-9 * (1.0 + float(np.abs(c_gap).max()) / dt_s)
    v_qp = vel[:, :2].copy()
    vel[:, :2] = v_in
    lam2, status = project_gaps_sparse(vel, mass, c_a, c_b, c_gap, c_nx, c_ny, dt_s, free0=tight, max_iter=3)
    if status == STATUS_OK:
        return lam2, 1
    vel[:, :2] = v_qp
    return lam, 2


def _clarabel_solve(P, c, A, b, what):
    """Clarabel on min ½xᵀPx + cᵀx s.t. Ax + s = b, s ≥ 0; tight tolerances, default ones as retry."""
    import clarabel

    for tol in (1e-11, 1e-8):
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        settings.tol_gap_abs = settings.tol_gap_rel = tol
        settings.tol_feas = tol
        sol = clarabel.DefaultSolver(P, c, A, b, [clarabel.NonnegativeConeT(A.shape[0])], settings).solve()
        if str(sol.status) in ("Solved", "AlmostSolved"):
            return np.asarray(sol.x), np.asarray(sol.z)
    raise RuntimeError(f"sparse {what} solve failed: {sol.status}")


def _sparse_rows(n_bodies, row_a, row_b, coef_a, coef_b):
    import scipy.sparse as sp

    m = row_a.shape[0]
    r = np.repeat(np.arange(m), 3)
    ca = (3 * row_a[:, None] + np.arange(3)).ravel()
    wall = row_b < 0
    cb = (3 * np.where(wall, 0, row_b)[:, None] + np.arange(3)).ravel()
    vb = (coef_b * (~wall)[:, None]).ravel()
    return sp.csc_matrix((np.concatenate([coef_a.ravel(), vb]), (np.concatenate([r, r]), np.concatenate([ca, cb]))),
                         shape=(m, 3 * n_bodies))


def solve_rows_qp(mass_diag, row_a, row_b, coef_a, coef_b, row_k, row_kind, v_minus, p_ext=None):
    """Same problem and inputs as :func:`solve_rows`, solved as a sparse QP by Clarabel.

    The sparse interior-point path for clusters too large or too degenerate for dense pivoting.
    Returns ``(v_plus, λ)`` (λ: reactive percussion per normal row).
    """
    import scipy.sparse as sp

    nd = mass_diag.shape[0]
    p_ext = np.zeros(nd) if p_ext is None else p_ext
    B = _sparse_rows(nd // 3, row_a, row_b, coef_a, coef_b)
    H = (sp.diags(mass_diag) + B.T @ sp.diags(row_k) @ B).tocsc()
    normal = row_kind == NORMAL
    Bn = B[np.flatnonzero(normal)]
    # min ½ Yᵀ H Y − rᵀ Y  s.t. −2 B_n Y + s = −B_n v⁻, s ≥ 0
    y, z = _clarabel_solve(sp.triu(H).tocsc(), -(mass_diag * v_minus + 0.5 * p_ext), (-2.0 * Bn).tocsc(),
                           -(Bn @ v_minus), "impact")
    return 2.0 * y - v_minus, 4.0 * z


def solve_clusters(roots, root, vel, mass, inertia, in_impact, c_a, c_b, c_nx, c_ny, c_rho_a, c_rho_b,
                   l_a, l_b, dvec, gi, gj, k_n, k_tg, k_v, rotation, solve, p_normal, p_tangent):
    """Solve the listed clusters (roots from :func:`resolve_impacts`) with ``solve`` (a function of
    the :func:`solve_rows` inputs returning ``(v_plus, λ)``), in place on ``vel`` and the percussions."""
    imp = np.flatnonzero(in_impact)
    local = np.full(vel.shape[0], -1, np.int64)
    nl = l_a.shape[0] if k_v > 0 else 0
    for rt in roots:
        bodies = np.flatnonzero(root == rt)
        local[bodies] = np.arange(bodies.shape[0])
        cids = imp[root[c_a[imp]] == rt]
        lids = np.flatnonzero(root[l_a[:nl]] == rt) if nl else np.zeros(0, np.int64)
        rows = build_rows(cids, c_a, c_b, c_nx, c_ny, c_rho_a, c_rho_b, lids, l_a, l_b, dvec, gi, gj,
                          local, k_n, k_tg, k_v, rotation)
        mass_diag = np.stack([mass[bodies], mass[bodies], inertia[bodies]], axis=1).ravel()
        v_minus = vel[bodies].ravel().copy()
        v_plus, lam = solve(mass_diag, *rows, v_minus, np.zeros_like(v_minus))
        v_plus = v_plus.reshape(-1, 3)
        if not rotation:
            v_plus[:, 2] = vel[bodies, 2]
        vel[bodies] = v_plus
        row_a, row_b, coef_a, coef_b, row_k, row_kind = rows
        vsum = v_plus.ravel() + v_minus
        s = (coef_a * vsum.reshape(-1, 3)[row_a]).sum(axis=1)
        s += np.where(row_b >= 0, (coef_b * vsum.reshape(-1, 3)[np.maximum(row_b, 0)]).sum(axis=1), 0.0)
        nc = cids.shape[0]
        p_normal[cids] = lam[:nc] - row_k[:nc] * s[:nc]
        tang = np.flatnonzero(row_kind == 1)
        p_tangent[cids[tang - nc]] = -row_k[tang] * s[tang]
        local[bodies] = -1
