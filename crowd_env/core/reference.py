"""Reference Frémond impact in cvxpy: the primal of Eq. 7 written literally (for tests and small cases).

It takes exactly the inputs of :func:`crowd_env.core.collision.solve_rows` (the two-body row form of
:mod:`crowd_env.core.contacts`) but builds the dense operator and hands the convex problem to a
general conic solver, so it shares no solution code with the production solver.
"""
from __future__ import annotations

import cvxpy as cp
import numpy as np

from .contacts import NORMAL, rows_to_dense


def solve_rows_cvxpy(mass_diag, row_a, row_b, coef_a, coef_b, row_k, row_kind, v_minus, p_ext=None,
                     solver: str | None = None):
    """Post-impact velocities ``(v_plus, λ)`` from the primal problem

    minimise ½ Yᵀ M Y + ½ Σ_k K_k (B_k Y)² − (M v⁻ + ½ p_ext)ᵀ Y  s.t.  2 B_n Y ≥ B_n v⁻,
    v⁺ = 2Y − v⁻; λ are the duals of the constraints scaled to reactive percussions (λ = 4 μ).
    Accuracy is that of the conic solver (about 1e-6 on stiff cases).
    """
    mass_diag = np.asarray(mass_diag, dtype=float)
    v_minus = np.asarray(v_minus, dtype=float)
    p_ext = np.zeros_like(v_minus) if p_ext is None else np.asarray(p_ext, dtype=float)
    nd = mass_diag.shape[0]
    B = rows_to_dense(nd // 3, np.asarray(row_a), np.asarray(row_b), np.asarray(coef_a), np.asarray(coef_b))
    k = np.asarray(row_k, dtype=float)
    normal = np.asarray(row_kind) == NORMAL
    Y = cp.Variable(nd)
    dissipative = B[k > 0] * np.sqrt(k[k > 0])[:, None]
    objective = 0.5 * cp.sum_squares(cp.multiply(np.sqrt(mass_diag), Y))
    if dissipative.shape[0]:
        objective = objective + 0.5 * cp.sum_squares(dissipative @ Y)
    objective = objective - (mass_diag * v_minus + 0.5 * p_ext) @ Y
    constraints = []
    Bn = B[normal]
    if Bn.shape[0]:
        constraints = [2.0 * Bn @ Y >= Bn @ v_minus]
    problem = cp.Problem(cp.Minimize(objective), constraints)
    problem.solve(solver=solver or cp.CLARABEL)
    if problem.status not in ("optimal", "optimal_inaccurate"):
        raise RuntimeError(f"cvxpy reference solver failed: status {problem.status}")
    v_plus = 2.0 * np.asarray(Y.value) - v_minus
    lam = 4.0 * np.asarray(constraints[0].dual_value) if constraints else np.zeros(0)
    return v_plus, lam
