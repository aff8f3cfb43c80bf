"""External QP solvers, PIQP and Clarabel (sparse interior point methods), wrapped for the impact and the projection.

Both are optional (``pip install "crowd_env[solvers]"``, which the test command installs): the
:class:`~crowd_env.core.solvers.cascade.SolverCascade` calls them only when the package's own methods
miss, and skips a missing one as its docstring describes. Here:

* :func:`project_gaps_ipm`: the gap projection on all candidates by PIQP (a proximal interior point
  method), tried when the own interior point projection does not converge;
* :func:`project_gaps_qp`: the same by Clarabel, when sparse pivoting cannot certify a degenerate jam
  (:func:`~crowd_env.core.solvers.cascade.project_gaps_large`);
* :func:`solve_rows_qp`: the Frémond impact of a cluster (Kabalan 2016, Eq. 7) by Clarabel, when sparse
  pivoting fails on it.

An import of a missing solver raises :class:`~crowd_env.errors.SimulationError` naming it;
:func:`installed_solvers` says which are present.
"""
from __future__ import annotations

import functools
import importlib
import importlib.util

import numpy as np

from ..contacts import NORMAL
from .graph import normal_rows_sparse, sparse_rows, touched_projection_rows
from crowd_env.errors import SimulationError

OPTIONAL_SOLVERS = ("piqp", "clarabel")
IPM_TOL_M_S = 1e-9  # absolute KKT tolerance (m/s) of the interior point projection (project_gaps_ipm)


@functools.lru_cache(maxsize=None)
def installed_solvers() -> frozenset:
    """The optional solvers of :data:`OPTIONAL_SOLVERS` that can be imported here (looked up once)."""
    return frozenset(name for name in OPTIONAL_SOLVERS if importlib.util.find_spec(name) is not None)


def _import(name):
    """The module of the optional solver ``name``; :class:`SimulationError` naming it when it is missing."""
    try:
        return importlib.import_module(name)
    except ImportError as exc:
        raise SimulationError(f"the optional solver {name} is not installed (pip install \"crowd_env[solvers]\")") \
            from exc


def project_gaps_qp(vel, mass, c_a, c_b, c_gap, c_nx, c_ny, dt_s):
    """The projection of :func:`~crowd_env.core.solvers.dense_projection.project_gaps` solved as a sparse QP
    by Clarabel (interior point).

    Used when pivoting cannot certify a solution (very degenerate jammed packings, where contacts
    outnumber degrees of freedom several times over): the primal is strictly convex in v, so v is
    unique even where λ is not. Modifies ``vel[:, :2]`` in place; returns λ per contact.
    """
    import scipy.sparse as sp

    n = vel.shape[0]
    Bn = normal_rows_sparse(n, c_a, c_b, c_nx, c_ny).tocsc()
    mdiag = np.repeat(mass, 2)
    P = sp.diags(mdiag).tocsc()  # the mass metric
    v0 = vel[:, :2].ravel().copy()
    # min ½ vᵀ M v − (M v')ᵀ v  s.t.  −B_n v + s = gap/h, s ≥ 0
    x, z = _clarabel_solve(P, -mdiag * v0, (-Bn).tocsc(), c_gap / dt_s, "projection")
    vel[:, :2] = x.reshape(n, 2)
    return z


def project_gaps_ipm(vel, mass, c_a, c_b, c_gap, c_nx, c_ny, dt_s):
    """The projection of :func:`~crowd_env.core.solvers.dense_projection.project_gaps` by PIQP (a proximal
    interior point method, sparse LDLᵀ).

    An interior point method's iterations do not grow with the jam's diameter, as the augmented
    Lagrangian's Newton steps do. Its KKT residuals are ≤ ``IPM_TOL_M_S``: slack ≥ −1e-9 m/s (overlap
    ≤ 1e-11 m per step) and v close to the augmented Lagrangian's exact one (the tests check 1e-6 m/s on
    their jams; ``benchmarks/scaling.py`` compares them on door jams). Modifies ``vel[:, :2]`` in place
    on success; returns ``(λ per contact, ok)`` (not ok: ``vel`` left alone)."""
    import scipy.sparse as sp

    n = vel.shape[0]
    m = c_a.shape[0]
    if m == 0:
        return np.zeros(0), True
    piqp = _import("piqp")
    bodies, _, _, mdiag, B = touched_projection_rows(n, mass, c_a, c_b, c_nx, c_ny)
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


def _clarabel_solve(P, c, A, b, what):
    """Clarabel on min ½xᵀPx + cᵀx s.t. Ax + s = b, s ≥ 0; tight tolerances, default ones as retry.
    :class:`SimulationError` when it solves at neither."""
    clarabel = _import("clarabel")

    for tol in (1e-11, 1e-8):
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        settings.tol_gap_abs = settings.tol_gap_rel = tol
        settings.tol_feas = tol
        sol = clarabel.DefaultSolver(P, c, A, b, [clarabel.NonnegativeConeT(A.shape[0])], settings).solve()
        if str(sol.status) in ("Solved", "AlmostSolved"):
            return np.asarray(sol.x), np.asarray(sol.z)
    raise SimulationError(f"sparse {what} solve failed: {sol.status}")


def solve_rows_qp(mass_diag, row_a, row_b, coef_a, coef_b, row_k, row_kind, v_minus, p_ext=None):
    """Same problem and inputs as :func:`~crowd_env.core.solvers.impact.solve_rows`, solved as a sparse QP
    by Clarabel.

    The sparse interior-point path for clusters too large or too degenerate for dense pivoting.
    Returns ``(v_plus, λ)`` (λ: reactive percussion per normal row).
    """
    import scipy.sparse as sp

    nd = mass_diag.shape[0]
    p_ext = np.zeros(nd) if p_ext is None else p_ext
    B = sparse_rows(nd // 3, row_a, row_b, coef_a, coef_b)
    H = (sp.diags(mass_diag) + B.T @ sp.diags(row_k) @ B).tocsc()
    normal = row_kind == NORMAL
    Bn = B[np.flatnonzero(normal)]
    # min ½ Yᵀ H Y − rᵀ Y  s.t. −2 B_n Y + s = −B_n v⁻, s ≥ 0
    y, z = _clarabel_solve(sp.triu(H).tocsc(), -(mass_diag * v_minus + 0.5 * p_ext), (-2.0 * Bn).tocsc(),
                           -(Bn @ v_minus), "impact")
    return 2.0 * y - v_minus, 4.0 * z
