"""The sparse pivoting QP: block principal pivoting with sparse factorisations (SciPy's SuperLU).

Solves  min ½ xᵀ H x − cᵀ x  s.t.  B x ≥ d  exactly (:func:`qp_bpp_sparse`), for problems too large
for the dense solvers: the Frémond impact of a large cluster (Kabalan 2016, Eq. 7 with the rows of
:mod:`~crowd_env.core.contacts`, :func:`solve_rows_sparse`) and the gap projection on all candidates
(:func:`project_gaps_sparse`). Each trial active set is solved through a sparse factorisation instead
of the dense Delassus matrix. Used by the :class:`~crowd_env.core.solvers.cascade.SolverCascade` for
impact clusters beyond the dense limits, and as the last exact resort of the large projection
(:func:`~crowd_env.core.solvers.cascade.project_gaps_large`).
"""
from __future__ import annotations

import numba as nb
import numpy as np

from ..contacts import NORMAL
from .graph import sparse_rows, touched_projection_rows
from .pivoting import DENSE_MAX_ITER, REG_RELATIVE
from .status import STATUS_MAX_ITER, STATUS_OK

PGS_SWEEPS = 300  # projected Gauss-Seidel sweeps that guess the first active set of a large projection
SPARSE_MAX_ITER = 6  # factorisations allowed to sparse pivoting on a large projection before the fallback


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

    if diagonal:
        def factor(F):
            return _schur_solver(B, F, hdiag, x_free, d, eps)
    else:
        def factor(F):
            return _kkt_solver(H, B, F, c, d, eps)

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
        bad, tol_w, tol_l = _violations(B, x, d, F, free, nu, nu_f, eps, diag_mean)
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
    """Same problem, inputs and outputs as :func:`~crowd_env.core.solvers.impact.solve_rows` (plus ``status``), for large clusters:
    the primal  min ½ Yᵀ H Y − rᵀ Y  s.t.  B_n Y ≥ ½ B_n v⁻  by :func:`qp_bpp_sparse` (exact, sparse).
    Returns ``(v_plus, λ, status)``; λ = 2ν are the reactive percussions of the normal rows."""
    import scipy.sparse as sp

    nd = mass_diag.shape[0]
    p_ext = np.zeros(nd) if p_ext is None else p_ext
    B = sparse_rows(nd // 3, row_a, row_b, coef_a, coef_b)
    H = (sp.diags(mass_diag) + B.T @ sp.diags(row_k) @ B).tocsc()
    Bn = B[np.flatnonzero(row_kind == NORMAL)]
    y, nu, status, _ = qp_bpp_sparse(H, mass_diag * v_minus + 0.5 * p_ext, Bn, 0.5 * (Bn @ v_minus), free0)
    return 2.0 * y - v_minus, 2.0 * nu, status


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


def project_gaps_sparse(vel, mass, c_a, c_b, c_gap, c_nx, c_ny, dt_s, free0=None, max_iter=None):
    """The projection of :func:`~crowd_env.core.solvers.dense_projection.project_gaps` on all candidates
    at once, solved exactly by :func:`qp_bpp_sparse` (for clusters too large for the dense path). Only
    the pedestrians that appear in a candidate take part. Modifies ``vel[:, :2]`` in place when it succeeds; returns
    ``(λ per contact, status)``. The first active set comes from a few hundred projected Gauss-Seidel
    sweeps unless ``free0`` is given; pivoting stops after ``SPARSE_MAX_ITER`` factorisations
    (degenerate jams can cycle for long) and then reports STATUS_MAX_ITER, leaving ``vel`` alone."""
    import scipy.sparse as sp

    m = c_a.shape[0]
    if m == 0:
        return np.zeros(0), STATUS_OK
    bodies, la, lb, mdiag, B = touched_projection_rows(vel.shape[0], mass, c_a, c_b, c_nx, c_ny)
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


def _schur_solver(B, F, hdiag, x_free, d, eps):
    """For a diagonal H: ``solve(polish) -> (x, ν_F)`` on the active set F from a sparse LU of the Schur
    complement B_F H⁻¹ B_Fᵀ + εI, one refinement step, and with ``polish`` four towards the unregularised system."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import splu

    nf = F.shape[0]
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


def _kkt_solver(H, B, F, c, d, eps):
    """For a general H: ``solve(polish) -> (x, ν_F)`` on the active set F from a sparse LU of the quasi-definite
    KKT system [[H, B_Fᵀ], [B_F, −εI]], one refinement step, and with ``polish`` four towards ε = 0."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import splu

    n, nf = H.shape[0], F.shape[0]
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


def _violations(B, x, d, F, free, nu, nu_f, eps, diag_mean) -> tuple:
    """(the complementarity violations of the regularised LCP as a bool mask, tol_w, tol_λ): a free contact
    with ν < −tol_λ or a blocked one with w = Bx − d < −tol_w, tolerances relative to the iterate's scale."""
    m = B.shape[0]
    w = B @ x - d
    w[F] += eps * nu_f  # residual of the regularised LCP: zero on the free set
    nf = F.shape[0]
    scale = (float(np.abs(w[~free]).max()) if nf < m else 0.0) + diag_mean * (float(np.abs(nu).max()) if m else 0.0)
    tol_w = 1e-11 * scale + 1e-300
    tol_l = tol_w / diag_mean
    return (free & (nu < -tol_l)) | (~free & (w < -tol_w)), tol_w, tol_l
