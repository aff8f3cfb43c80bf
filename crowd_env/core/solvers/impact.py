"""The dense Frémond impact (Kabalan 2016, Eq. 4-8; the primal Eq. 7) of each cluster, and the compiled impact stage.

Primal, in the convention that reproduces the paper's closed forms Eq. 17-19
(:mod:`~crowd_env.core.solvers.closed_form`)::

    minimise  ½ Yᵀ H Y − rᵀ Y,   H = M + Bᵀ K B,   r = M v⁻ + ½ p_ext
    subject to 2 B_n Y ≥ B_n v⁻,   then v⁺ = 2 Y − v⁻.

Dual: with z = 2 H⁻¹ r − v⁻, G = H⁻¹ B_nᵀ, W = B_n G, q = B_n z, find λ ≥ 0 with
w = W λ + q ≥ 0 and λ·w = 0 (an LCP, solved by :func:`~crowd_env.core.solvers.pivoting.lcp_bpp`);
then v⁺ = z + G λ. λ are the reactive percussions (kg m/s).

:func:`resolve_impacts` is the impact stage of a step: it forms the impact set, splits it into clusters
(union-find over the contact graph, :mod:`~crowd_env.core.solvers.graph`) and solves each one within
the dense limits (``MAX_DENSE_ROWS`` normal rows, ``MAX_DENSE_BODIES`` bodies) by :func:`solve_rows`, a
dense solve in reverse Cuthill-McKee order. The clusters it leaves (too large, or pivoting failed) are
solved by :func:`solve_clusters` with the method the :class:`~crowd_env.core.solvers.cascade.SolverCascade`
picks (sparse pivoting, Clarabel, or the cvxpy reference).
"""
from __future__ import annotations

import numba as nb
import numpy as np

from ..contacts import NORMAL, build_rows, turning_rate
from .graph import find_root, group_by, normal_velocity, order_dofs, union
from .linalg import SAME_ROUNDING_FASTMATH, dot_range, profile_cholesky, sub_scaled
from .pivoting import lcp_bpp
from .status import STATUS_OK

# Impact clusters with more normal rows or bodies than these go to the sparse path (solve_rows_sparse):
# the dense solve costs O(n³ + n² m), the sparse one a fixed Python overhead; they break even about there
# (benchmarks/solver.py times both paths on random clusters).
MAX_DENSE_ROWS = 600
MAX_DENSE_BODIES = 200
VTOL_M_S = 1e-9  # normal speed below which a touching contact counts as approaching or resting


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
    perm, pos = order_dofs(nd_all // 3, row_a, row_b, coef_a, coef_b)
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
def resolve_impacts(vel, mass, inertia, contacts, links, params, vtol):
    """Frémond impacts of every connected cluster, in place on ``vel`` ((n, 3): u_x, u_y, ω), of the contact
    candidates ``contacts`` (:class:`~crowd_env.core.bundles.Candidates`) and hand links ``links``
    (:class:`~crowd_env.core.bundles.Links`), with the step's numbers ``params``
    (:class:`~crowd_env.core.bundles.StepParams`: ε, K_n, K_tg, K_v, rotation, the dense limits).

    The impact set holds the contacts that touch (gap ≤ ε) and approach or rest (Δ·n ≤ vtol), plus
    the hand links; clusters are connected components of that graph, solved when they contain a
    strictly approaching contact or a link. Contacts that touch but already separate are left out,
    so kinetic energy cannot increase.
    Clusters with more than ``params.max_dense_rows`` normal rows or ``params.max_dense_bodies`` bodies (rows −1
    routes every cluster), or where pivoting fails, are left untouched and their root reported in
    ``unsolved`` for :func:`solve_clusters` (sparse or reference solvers).
    Returns ``(p_normal, p_tangent, in_impact, root, unsolved, n_clusters, max_cluster)``: total normal and
    tangential percussion per contact (kg m/s; reactive + dissipative), the impact-set mask, counts.
    """
    c_a, c_b, c_gap, c_nx, c_ny = contacts.a, contacts.b, contacts.gap, contacts.nx, contacts.ny
    l_a, l_b = links.a, links.b
    k_n, k_tg, k_v = params.normal_dissipation_kg, params.tangential_dissipation_kg, params.link_dissipation_kg_per_m2
    eps_m, rotation = params.contact_tolerance_m, params.rotation
    turning = params.body_depth_m > 0.0 and rotation
    max_dense_rows, max_dense_bodies = params.max_dense_rows, params.max_dense_bodies
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
        vn[c] = normal_velocity(vel, c_a[c], c_b[c], c_nx[c], c_ny[c])
        if turning:  # bodies of three circles: a shoulder closes on the other body as the body turns
            vn[c] += turning_rate(vel, contacts, c)
        if c_gap[c] <= eps_m and vn[c] <= vtol:
            in_impact[c] = True
            any_imp = True
            if c_b[c] >= 0:
                union(parent, c_a[c], c_b[c])
    for l in range(nl):
        union(parent, l_a[l], l_b[l])
    root = np.empty(n, np.int64)
    unsolved = np.zeros(0, np.int64)
    if not any_imp and nl == 0:
        return p_normal, p_tangent, in_impact, root, unsolved, 0, 0
    for i in range(n):
        root[i] = find_root(parent, i)
    need = np.zeros(n, np.bool_)
    for c in range(nc):
        if in_impact[c] and vn[c] < -vtol:
            need[root[c_a[c]]] = True
    for l in range(nl):
        need[root[l_a[l]]] = True
    # Group bodies, impact contacts and links by root.
    body_order, body_start = group_by(root, n)
    imp_ids = np.flatnonzero(in_impact)
    imp_root = np.empty(imp_ids.shape[0], np.int64)
    for k in range(imp_ids.shape[0]):
        imp_root[k] = root[c_a[imp_ids[k]]]
    imp_order, con_start = group_by(imp_root, n)
    imp_sorted = imp_ids[imp_order]
    link_root = np.empty(nl, np.int64)
    for l in range(nl):
        link_root[l] = root[l_a[l]]
    link_sorted, link_start = group_by(link_root, n)
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
        row_a, row_b, coef_a, coef_b, row_k, row_kind = build_rows(cids, contacts, lids, links, local, k_n, k_tg,
                                                                   k_v, rotation)
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


def solve_clusters(roots, root, vel, mass, inertia, in_impact, contacts, links, params, solve, p_normal, p_tangent):
    """Solve the listed clusters (roots from :func:`resolve_impacts`, with its ``contacts``, ``links`` and
    ``params``) with ``solve`` (a function of the :func:`solve_rows` inputs returning ``(v_plus, λ)``), in place on
    ``vel`` and the percussions."""
    c_a, l_a = contacts.a, links.a
    k_n, k_tg, k_v = params.normal_dissipation_kg, params.tangential_dissipation_kg, params.link_dissipation_kg_per_m2
    rotation = params.rotation
    imp = np.flatnonzero(in_impact)
    local = np.full(vel.shape[0], -1, np.int64)
    nl = l_a.shape[0] if k_v > 0 else 0
    for rt in roots:
        bodies = np.flatnonzero(root == rt)
        local[bodies] = np.arange(bodies.shape[0])
        cids = imp[root[c_a[imp]] == rt]
        lids = np.flatnonzero(root[l_a[:nl]] == rt) if nl else np.zeros(0, np.int64)
        rows = build_rows(cids, contacts, lids, links, local, k_n, k_tg, k_v, rotation)
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
