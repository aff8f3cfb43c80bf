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

STATUS_OK = 0
STATUS_MAX_ITER = 1
STATUS_TOO_LARGE = 2
MAX_DENSE_ROWS = 200  # clusters with more normal rows go to the sparse pivoting path (qp_bpp_sparse)
REG_RELATIVE = 1e-8  # Tikhonov regularisation of W relative to its mean diagonal (W is singular in dense packings)


@nb.njit(cache=True)
def _cholesky_solve(L, B):
    """Solve (L Lᵀ) X = B for X (B is (n, k)), L lower triangular."""
    n = L.shape[0]
    k = B.shape[1]
    X = B.copy()
    for c in range(k):
        for i in range(n):
            s = X[i, c]
            for j in range(i):
                s -= L[i, j] * X[j, c]
            X[i, c] = s / L[i, i]
        for i in range(n - 1, -1, -1):
            s = X[i, c]
            for j in range(i + 1, n):
                s -= L[j, i] * X[j, c]
            X[i, c] = s / L[i, i]
    return X


@nb.njit(cache=True)
def _solve_free(W, q, free, eps, refine):
    """λ_F solving (W_FF + εI) λ_F = −q_F, then ``refine`` steps of iterative refinement towards
    W_FF λ_F = −q_F (converges to a solution of the singular system when it is consistent)."""
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
    lam = np.zeros(m)
    if nf == 0:
        return lam
    A = np.empty((nf, nf))
    rhs = np.empty((nf, 1))
    for a in range(nf):
        for b in range(nf):
            A[a, b] = W[idx[a], idx[b]]
        A[a, a] += eps
        rhs[a, 0] = -q[idx[a]]
    L = np.linalg.cholesky(A)
    sol = _cholesky_solve(L, rhs)
    for _ in range(refine):
        res = np.empty((nf, 1))
        for a in range(nf):
            s = -q[idx[a]]
            for b in range(nf):
                s -= W[idx[a], idx[b]] * sol[b, 0]
            res[a, 0] = s
        sol += _cholesky_solve(L, res)
    for a in range(nf):
        lam[idx[a]] = sol[a, 0]
    return lam


@nb.njit(cache=True)
def _residual_w(W, q, lam, free):
    m = q.shape[0]
    w = np.empty(m)
    for i in range(m):
        if free[i]:
            w[i] = 0.0
        else:
            s = q[i]
            for j in range(m):
                if free[j]:
                    s += W[i, j] * lam[j]
            w[i] = s
    return w


@nb.njit(cache=True)
def _bpp(W, q, free, eps, diag_mean, qmax, max_iter):
    """Block principal pivoting from the free set ``free`` (modified in place); True on success."""
    m = q.shape[0]
    best = m + 1
    backup = 3
    for _ in range(max_iter):
        lam = _solve_free(W, q, free, eps, 0)
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
            return True
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
    return False


@nb.njit(cache=True)
def lcp_bpp(W, q):
    """Solve the LCP w = Wλ + q ≥ 0, λ ≥ 0, λᵀw = 0 for symmetric positive semi-definite W.

    Block principal pivoting (Júdice & Pires 1994) with Murty's single-pivot fallback on
    W + εI (ε = 1e-8 · mean diag W; W is singular when contacts outnumber degrees of freedom),
    with tolerances scaled by the size of the terms. Degenerate packings can make pivoting cycle:
    then projected Gauss-Seidel finds the active set and pivoting restarts from it. The final λ is
    polished by iterative refinement on the free set so the regularisation leaves no bias.
    Returns ``(λ, status)``.
    """
    m = q.shape[0]
    if m == 0:
        return np.zeros(0), STATUS_OK
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
    free = np.zeros(m, np.bool_)
    if not _bpp(W, q, free, eps, diag_mean, qmax, 2 * m + 20):
        return np.zeros(m), STATUS_MAX_ITER
    lam = _solve_free(W, q, free, eps, 4)
    for i in range(m):
        if lam[i] < 0.0:
            lam[i] = 0.0
    return lam, STATUS_OK


@nb.njit(cache=True)
def solve_rows(mass_diag, row_a, row_b, coef_a, coef_b, row_k, row_kind, v_minus, p_ext):
    """Frémond impact of one cluster given in the two-body row form of :mod:`contacts`.

    ``mass_diag`` (3n,) is diag(M); ``v_minus``/``p_ext`` (3n,). Returns ``(v_plus, λ, status)``
    with λ the reactive percussion of each normal row (rows of kind 0, in order).
    """
    nd = mass_diag.shape[0]
    m = row_a.shape[0]
    H = np.zeros((nd, nd))
    for i in range(nd):
        H[i, i] = mass_diag[i]
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
            cols[cnt] = 3 * row_a[r] + d
            vals[cnt] = coef_a[r, d]
            cnt += 1
        if row_b[r] >= 0:
            for d in range(3):
                cols[cnt] = 3 * row_b[r] + d
                vals[cnt] = coef_b[r, d]
                cnt += 1
        for p in range(cnt):
            for s in range(cnt):
                H[cols[p], cols[s]] += k * vals[p] * vals[s]
    L = np.linalg.cholesky(H)
    # Right-hand sides: r = M v⁻ + ½ p_ext, and B_nᵀ.
    R = np.zeros((nd, 1 + nn))
    for i in range(nd):
        R[i, 0] = mass_diag[i] * v_minus[i] + 0.5 * p_ext[i]
    c = 0
    for r in range(m):
        if row_kind[r] != NORMAL:
            continue
        c += 1
        for d in range(3):
            R[3 * row_a[r] + d, c] += coef_a[r, d]
            if row_b[r] >= 0:
                R[3 * row_b[r] + d, c] += coef_b[r, d]
    X = _cholesky_solve(L, R)  # X[:, 0] = Y0, X[:, 1:] = G
    z = 2.0 * X[:, 0] - v_minus
    W = np.zeros((nn, nn))
    q = np.zeros(nn)
    c = 0
    for r in range(m):
        if row_kind[r] != NORMAL:
            continue
        # W[c, :] = B_n[c] · G  ;  q[c] = B_n[c] · z
        for d in range(3):
            ia = 3 * row_a[r] + d
            q[c] += coef_a[r, d] * z[ia]
            for e in range(nn):
                W[c, e] += coef_a[r, d] * X[ia, 1 + e]
            if row_b[r] >= 0:
                ib = 3 * row_b[r] + d
                q[c] += coef_b[r, d] * z[ib]
                for e in range(nn):
                    W[c, e] += coef_b[r, d] * X[ib, 1 + e]
        c += 1
    # Symmetrise against round-off.
    for a in range(nn):
        for b in range(a + 1, nn):
            s = 0.5 * (W[a, b] + W[b, a])
            W[a, b] = s
            W[b, a] = s
    lam, status = lcp_bpp(W, q)
    v_plus = z.copy()
    for e in range(nn):
        if lam[e] != 0.0:
            for i in range(nd):
                v_plus[i] += X[i, 1 + e] * lam[e]
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
def resolve_impacts(vel, mass, inertia, c_a, c_b, c_gap, c_nx, c_ny, c_rho_a, c_rho_b,
                    l_a, l_b, dvec, gi, gj, k_n, k_tg, k_v, eps_m, vtol, rotation, max_dense_rows):
    """Frémond impacts of every connected cluster, in place on ``vel`` ((n, 3): u_x, u_y, ω).

    The impact set holds the contacts that touch (gap ≤ ε) and approach or rest (Δ·n ≤ vtol), plus
    the hand links; clusters are connected components of that graph, solved when they contain a
    strictly approaching contact or a link. Contacts that touch but already separate are left out,
    so kinetic energy cannot increase (collision-problem.md, "Energy").
    Clusters with more than ``max_dense_rows`` normal rows (pass −1 to route every cluster), or where pivoting fails, are left
    untouched and their root reported in ``unsolved`` for :func:`solve_cluster_qp`.
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
    # Group bodies, impact contacts and links by root (counting sort).
    body_order = np.argsort(root, kind="mergesort")
    body_start = np.zeros(n + 1, np.int64)
    for i in range(n):
        body_start[root[i] + 1] += 1
    for i in range(n):
        body_start[i + 1] += body_start[i]
    imp_ids = np.flatnonzero(in_impact)
    imp_root = np.empty(imp_ids.shape[0], np.int64)
    for k in range(imp_ids.shape[0]):
        imp_root[k] = root[c_a[imp_ids[k]]]
    imp_sorted = imp_ids[np.argsort(imp_root, kind="mergesort")]
    con_start = np.zeros(n + 1, np.int64)
    for k in range(imp_ids.shape[0]):
        con_start[imp_root[k] + 1] += 1
    for i in range(n):
        con_start[i + 1] += con_start[i]
    link_root = np.empty(nl, np.int64)
    for l in range(nl):
        link_root[l] = root[l_a[l]]
    link_sorted = np.argsort(link_root, kind="mergesort")
    link_start = np.zeros(n + 1, np.int64)
    for l in range(nl):
        link_start[link_root[l] + 1] += 1
    for i in range(n):
        link_start[i + 1] += link_start[i]
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
        if cids.shape[0] > max_dense_rows:
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
def project_gaps(vel, mass, c_a, c_b, c_gap, c_nx, c_ny, dt_s, tol):
    """Velocity projection: v = argmin ‖v − v'‖_M s.t. gap_k + h (B_n v)_k ≥ 0 for every candidate.

    Solved as the LCP with W = B_n M⁻¹ B_nᵀ, q = B_n v' + gap/h on a growing set of violated
    constraints (exact for the full set at termination). Only translational velocities change.
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
            if m > MAX_DENSE_ROWS:
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

    The same block principal pivoting as :func:`lcp_bpp` (block flips, then Murty single pivots) on
    the dual, but each trial active set F is solved through the sparse quasi-definite KKT system
    [[H, B_Fᵀ], [B_F, −εI]] (SuperLU), never forming the dense Delassus matrix B H⁻¹ Bᵀ, followed
    by iterative refinement on the unregularised system (ε = 1e-8 · a Jacobi estimate of its mean
    diagonal: dependent rows make it singular in jams). ``H`` (n, n) sparse symmetric positive
    definite, ``B`` (m, n) sparse, ``free0`` an optional initial active set (bool (m,), e.g. last
    step's: a good guess needs one or two factorisations). Returns ``(x, ν, status, iterations)``
    with ν ≥ 0 the multipliers (H x = c + Bᵀ ν).
    """
    import scipy.sparse as sp
    from scipy.sparse.linalg import splu

    n = H.shape[0]
    m = B.shape[0]
    H = sp.csc_matrix(H)
    B = sp.csr_matrix(B)
    c = np.asarray(c, dtype=np.float64)
    d = np.asarray(d, dtype=np.float64)
    free = np.zeros(m, np.bool_) if free0 is None else np.array(free0, dtype=np.bool_)
    if m:
        diag_mean = float((B.multiply(B) @ (1.0 / H.diagonal())).mean())
    else:
        diag_mean = 1.0
    diag_mean = diag_mean if diag_mean > 0.0 else 1.0
    eps = REG_RELATIVE * diag_mean
    max_iter = 2 * m + 20 if max_iter is None else max_iter
    best = m + 1
    backup = 3
    x = np.zeros(n)
    nu = np.zeros(m)
    for it in range(1, max_iter + 1):
        F = np.flatnonzero(free)
        nf = F.shape[0]
        rhs = np.concatenate([c, d[F]])
        if nf:
            BF = B[F]
            K = sp.bmat([[H, BF.T], [BF, -eps * sp.identity(nf)]], format="csc")
            K0 = sp.bmat([[H, BF.T], [BF, None]], format="csc")
        else:
            K = K0 = H
        lu = splu(K)
        sol = lu.solve(rhs)
        for _ in range(4):  # refinement towards the unregularised (consistent) system
            sol += lu.solve(rhs - K0 @ sol)
        x = sol[:n]
        nu = np.zeros(m)
        nu[F] = -sol[n:]
        w = B @ x - d
        scale = (float(np.abs(w[~free]).max()) if nf < m else 0.0) + diag_mean * (float(np.abs(nu).max()) if m else 0.0)
        tol_w = 1e-11 * scale + 1e-300
        tol_l = tol_w / diag_mean
        bad = (free & (nu < -tol_l)) | (~free & (w < -tol_w))
        n_bad = int(bad.sum())
        if n_bad == 0:
            return x, np.maximum(nu, 0.0), STATUS_OK, it
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
    return x, np.maximum(nu, 0.0), STATUS_MAX_ITER, max_iter


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


def project_gaps_sparse(vel, mass, c_a, c_b, c_gap, c_nx, c_ny, dt_s, free0=None):
    """The projection of :func:`project_gaps` on all candidates at once, solved exactly by
    :func:`qp_bpp_sparse` (for clusters too large for the dense path). Only the pedestrians that
    appear in a candidate take part. Modifies ``vel[:, :2]`` in place when it succeeds; returns
    ``(λ per contact, status)``. ``free0``: optional initial active set (e.g. last step's)."""
    import scipy.sparse as sp

    m = c_a.shape[0]
    if m == 0:
        return np.zeros(0), STATUS_OK
    bodies = np.unique(np.concatenate([c_a, c_b[c_b >= 0]]))
    local = np.full(vel.shape[0], -1, np.int64)
    local[bodies] = np.arange(bodies.shape[0])
    la = local[c_a]
    lb = np.where(c_b >= 0, local[np.maximum(c_b, 0)], -1)
    B = _normal_rows_sparse(bodies.shape[0], la, lb, c_nx, c_ny)
    mdiag = np.repeat(mass[bodies], 2)
    x, nu, status, _ = qp_bpp_sparse(sp.diags(mdiag), mdiag * vel[bodies, :2].ravel(), B, -np.asarray(c_gap) / dt_s,
                                     free0)
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
    m = c_a.shape[0]
    rows = np.repeat(np.arange(m), 2)
    cols_a = np.stack([2 * c_a, 2 * c_a + 1], axis=1).ravel()
    vals_a = np.stack([c_nx, c_ny], axis=1).ravel()
    wall = c_b < 0
    bb = np.where(wall, 0, c_b)
    cols_b = np.stack([2 * bb, 2 * bb + 1], axis=1).ravel()
    vals_b = -np.stack([c_nx, c_ny], axis=1).ravel() * np.repeat(~wall, 2)
    Bn = sp.csc_matrix((np.concatenate([vals_a, vals_b]), (np.concatenate([rows, rows]), np.concatenate([cols_a, cols_b]))),
                       shape=(m, 2 * n))
    mdiag = np.repeat(mass, 2)
    P = sp.diags(mdiag).tocsc()  # the mass metric
    v0 = vel[:, :2].ravel().copy()
    # min ½ vᵀ M v − (M v')ᵀ v  s.t.  −B_n v + s = gap/h, s ≥ 0
    x, z = _clarabel_solve(P, -mdiag * v0, (-Bn).tocsc(), c_gap / dt_s, "projection")
    vel[:, :2] = x.reshape(n, 2)
    return z


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
