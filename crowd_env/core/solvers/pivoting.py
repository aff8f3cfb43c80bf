"""The dense pivoting LCP solver: block principal pivoting on w = Wλ + q ≥ 0, λ ≥ 0, λᵀw = 0.

Every dense solve of the package ends here. The Frémond impact (Kabalan 2016, Eq. 4-8) is the LCP of
its dual, W = B_n H⁻¹ B_nᵀ with H = M + Bᵀ K B (:mod:`~crowd_env.core.solvers.impact`); the gap
projection is the same LCP with K = 0, W = B_n M⁻¹ B_nᵀ (:mod:`~crowd_env.core.solvers.dense_projection`).
W is symmetric positive semi-definite, and singular when contacts outnumber degrees of freedom (jams):
pivoting works on W + εI (a P-matrix, so it terminates), starts from a projected Gauss-Seidel guess of
the free set, and checks every answer before returning it. Used for every cluster within the dense size
limits (``MAX_DENSE_ROWS``, ``MAX_DENSE_BODIES``, ``MAX_DENSE_PROJECTION_ROWS``); larger or degenerate
problems go to the sparse or Newton-type solvers (:mod:`~crowd_env.core.solvers.cascade`).
"""
from __future__ import annotations

import numba as nb
import numpy as np

from .linalg import SAME_ROUNDING_FASTMATH, cholesky, cholesky_solve, dot_range, sub_scaled
from .status import STATUS_MAX_ITER, STATUS_OK

# Pivoting rarely needs more than a dozen factorisations; degenerate jams can make it cycle through
# Murty's single pivots for hundreds: stop there and hand the cluster to the next solver in line.
DENSE_MAX_ITER = 40
LCP_PGS_SWEEPS = 8  # projected Gauss-Seidel sweeps (at most) that guess the starting free set of pivoting
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
    off it (as :func:`~crowd_env.core.solvers.sparse_qp.qp_bpp_sparse` checks its polish)."""
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
