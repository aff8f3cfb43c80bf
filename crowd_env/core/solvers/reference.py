"""Reference Frémond impact in cvxpy: the primal of Kabalan 2016, Eq. 7, written literally.

It takes exactly the inputs of :func:`crowd_env.core.solvers.impact.solve_rows` (the two-body row form
of :mod:`crowd_env.core.contacts`) but builds the dense operator and hands the convex problem to a
general conic solver, so it shares no solution code with the production solver. Used by the tests and
benchmarks as an independent check, and for every impact cluster of a simulation run with
``ModelParams(solver="cvxpy")`` (slow; small cases only). :func:`random_cluster` makes test clusters.
"""
from __future__ import annotations

from crowd_env.errors import SolverError

import cvxpy as cp
import numpy as np

from ..contacts import NORMAL, rows_to_dense


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
        raise SolverError(f"cvxpy reference solver failed: status {problem.status}")
    v_plus = 2.0 * np.asarray(Y.value) - v_minus
    lam = 4.0 * np.asarray(constraints[0].dual_value) if constraints else np.zeros(0)
    return v_plus, lam


def random_cluster(n, rng, *, k_n=1.0e5, k_tg=0.0, k_v=0.0, n_links=0, wall=True, rotation=True,
                   radius_m=0.23, max_gap_m=4e-4, speed_m_s=1.0):
    """A random dense cluster for tests and benchmarks, in the inputs of :func:`solve_rows_cvxpy`.

    ``n`` disks on a hexagonal patch with spacing 2 r and radii r − U(0, max_gap/2): every lattice
    neighbour touches (gap ≤ max_gap), about 3 contacts per disk, so contacts outnumber the 2n
    translational degrees of freedom. ``wall``: a wall tangent to the lowest disks; ``n_links`` hand
    links between random lattice neighbours (shoulders at ±r across the heading); masses 50-100 kg,
    velocities N(0, speed²), spins N(0, 1). Rows come from :func:`crowd_env.core.contacts.build_rows`.
    Returns a dict with ``mass_diag``, the six row arrays, ``v_minus``, ``position``, ``radius``,
    ``contacts`` (the detect_contacts dict) and ``links``.
    """
    from ..bundles import Candidates, Links
    from ..contacts import CONTACT_FIELDS, build_rows, detect_contacts, link_geometry
    from ..segments import as_segments, endpoint_owners

    spacing = 2.0 * radius_m
    k = int(np.ceil(np.sqrt(n))) + 3
    ii, jj = np.meshgrid(np.arange(-k, k + 1), np.arange(-k, k + 1))
    pts = np.stack([spacing * (ii + 0.5 * (jj % 2)), spacing * np.sqrt(3.0) / 2.0 * jj], axis=-1).reshape(-1, 2)
    pts = pts + 1e-9 * rng.standard_normal(pts.shape)  # break distance ties reproducibly
    pts = pts[np.argsort(np.hypot(pts[:, 0], pts[:, 1]))[:n]]
    pts = pts[rng.permutation(n)]
    radius = radius_m - rng.uniform(0.0, 0.5 * max_gap_m, n)
    mass = rng.uniform(50.0, 100.0, n)
    inertia = 0.5 * mass * radius ** 2
    heading = rng.uniform(-np.pi, np.pi, n)
    index = np.arange(n, dtype=np.int64)
    from scipy.spatial import cKDTree
    pairs = cKDTree(pts).query_pairs(spacing + 2 * max_gap_m, output_type="ndarray").astype(np.int64)
    walls = np.zeros((0, 4))
    if wall and n >= 1:
        y0 = float((pts[:, 1] - radius).min())
        x_lo, x_hi = pts[:, 0].min() - 1.0, pts[:, 0].max() + 1.0
        walls = as_segments([[x_lo, y0, x_hi, y0]])
    con = detect_contacts(pts, radius, np.zeros((n, 2)), index, pairs, walls, endpoint_owners(walls),
                          max_gap_m + 1e-12, 0.01)
    links = np.zeros((0, 2), np.int64)
    if n_links and pairs.shape[0]:
        links = pairs[rng.choice(pairs.shape[0], size=min(n_links, pairs.shape[0]), replace=False)]
    offsets = np.tile([0.0, radius_m, 0.0, -radius_m], (links.shape[0], 1))
    dvec, gi, gj = link_geometry(pts, heading, links, offsets)
    cids = np.arange(con["a"].shape[0], dtype=np.int64)
    rows = build_rows(cids, Candidates(*(con[k] for k in CONTACT_FIELDS)), np.arange(links.shape[0], dtype=np.int64),
                      Links(links[:, 0].copy(), links[:, 1].copy(), dvec, gi, gj), index, k_n, k_tg, k_v, rotation)
    v_minus = np.stack([speed_m_s * rng.standard_normal(n), speed_m_s * rng.standard_normal(n),
                        rng.standard_normal(n)], axis=1).ravel()
    mass_diag = np.stack([mass, mass, inertia], axis=1).ravel()
    return {"mass_diag": mass_diag, "rows": rows, "v_minus": v_minus, "position": pts, "radius": radius,
            "heading": heading, "contacts": con, "links": links, "link_offsets": offsets, "walls": walls}
