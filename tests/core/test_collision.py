"""The Frémond impact solver (Kabalan Eq. 4-8, 17-21; docs/collision-problem.md) and contact rows.

Analytic head-on cases of Section 3.1, the K_n = μ convention, conservation laws, complementarity,
energy, the production solver against an independent cvxpy reference on random dense clusters, hand
links and the velocity projection. (Shared wall corners: tests/core/test_segments.py.)
"""
import math

import numpy as np
import pytest

from crowd_env.core.solvers import closed_form
from crowd_env.core.solvers.cascade import project_gaps_large
from crowd_env.core.solvers.dense_projection import project_gaps
from crowd_env.core.solvers.external import project_gaps_qp, solve_rows_qp
from crowd_env.core.bundles import Candidates, Links, StepParams
from crowd_env.core.solvers.impact import MAX_DENSE_BODIES, resolve_impacts, solve_rows
from crowd_env.core.solvers.pivoting import lcp_bpp
from crowd_env.core.solvers.sparse_qp import project_gaps_sparse, solve_rows_sparse
from crowd_env.core.solvers.status import STATUS_OK
from crowd_env.core.contacts import CONTACT_FIELDS, LINK, NORMAL, TANGENT, rows_to_dense
from crowd_env.core.solvers.reference import random_cluster, solve_rows_cvxpy
from tests.conftest import DATA

K_GRID = np.logspace(0.0, 6.0, 25)


def _solve(cl, rows=None, v_minus=None):
    rows = cl["rows"] if rows is None else rows
    v_minus = cl["v_minus"] if v_minus is None else v_minus
    v, lam, status = solve_rows(cl["mass_diag"], *rows, v_minus, np.zeros_like(v_minus))
    assert status == STATUS_OK
    return v, lam


def _only_approaching(cl):
    """Keep the normal rows that approach or rest (B_n v⁻ ≤ 0) and their tangent rows: the impact
    set of the simulator (collision-problem.md, "Energy")."""
    row_a, row_b, coef_a, coef_b, row_k, row_kind = cl["rows"]
    B = rows_to_dense(cl["mass_diag"].size // 3, row_a, row_b, coef_a, coef_b)
    bv = B @ cl["v_minus"]
    normal = np.flatnonzero(row_kind == NORMAL)
    keep_contact = bv[normal] <= 0.0
    keep = np.ones(row_a.size, bool)
    keep[normal] = keep_contact
    tang = np.flatnonzero(row_kind == TANGENT)
    if tang.size:
        keep[tang] = keep_contact
    return tuple(x[keep] for x in cl["rows"])


# ---------------------------------------------------------------- Section 3.1: head-on collisions
@pytest.mark.parametrize("case", ["a", "b"])
def test_head_on_matches_eq17_to_19_over_kn_grid(case):
    c = closed_form.PAPER_CASES[case]
    for k in K_GRID:
        u1, u2, _ = closed_form.head_on_numeric(c["m1"], c["m2"], c["u1"], c["u2"], k)
        a1, a2 = closed_form.head_on_analytic(c["m1"], c["m2"], c["u1"], c["u2"], k)
        assert abs(u1 - a1) < 1e-9 and abs(u2 - a2) < 1e-9, (k, u1, a1, u2, a2)


@pytest.mark.parametrize("case", ["a", "b"])
def test_head_on_threshold_exactly_at_reduced_mass(case):
    """Plastic (common velocity, reactive percussion active) for K_n ≤ μ = m1 m2/(m1 + m2), separating
    for K_n > μ. The literal reading of Eq. 7 would put the threshold at 2μ: this pins the convention."""
    c = closed_form.PAPER_CASES[case]
    m1, m2, u1, u2 = c["m1"], c["m2"], c["u1"], c["u2"]
    mu = m1 * m2 / (m1 + m2)
    common = (m1 * u1 + m2 * u2) / (m1 + m2)
    for k in (0.1 * mu, 0.5 * mu, 0.999 * mu, mu):
        p1, p2, lam = closed_form.head_on_numeric(m1, m2, u1, u2, k)
        assert abs(p1 - common) < 1e-12 and abs(p2 - common) < 1e-12
    for k in (0.5 * mu, 0.999 * mu):
        assert closed_form.head_on_numeric(m1, m2, u1, u2, k)[2] > 1e-6  # the constraint carries a percussion
    for k in (1.001 * mu, 1.5 * mu, 2.0 * mu):
        p1, p2, lam = closed_form.head_on_numeric(m1, m2, u1, u2, k)
        assert p2 - p1 > 1e-6  # separating: the dissipation alone stops the approach
        assert lam == 0.0
        a1, a2 = closed_form.head_on_analytic(m1, m2, u1, u2, k)
        assert abs(p1 - a1) < 1e-12 and abs(p2 - a2) < 1e-12
    # At K_n = 2μ (the literal-Eq. 7 threshold) the relative velocity is w (μ − 2μ)/(μ + 2μ) = −w/3.
    p1, p2, _ = closed_form.head_on_numeric(m1, m2, u1, u2, 2.0 * mu)
    assert (p1 - p2) == pytest.approx(-(u1 - u2) / 3.0, abs=1e-12)


@pytest.mark.parametrize("case", ["a", "b"])
def test_head_on_elastic_limit_eq18_19(case):
    c = closed_form.PAPER_CASES[case]
    e1, e2 = closed_form.head_on_elastic(c["m1"], c["m2"], c["u1"], c["u2"])
    for k in (1e7, 1e8):  # beyond ~1e9 round-off (cond H ~ K/m) exceeds the physical difference
        p1, p2, _ = closed_form.head_on_numeric(c["m1"], c["m2"], c["u1"], c["u2"], k)
        mu = c["m1"] * c["m2"] / (c["m1"] + c["m2"])
        bound = 2.0 * mu / k * abs(c["u1"] - c["u2"])  # relative velocity error of the finite-K formula
        assert abs(p1 - e1) <= bound and abs(p2 - e2) <= bound
    if c["m1"] == c["m2"]:  # Eq. 19: exchange
        assert e1 == c["u2"] and e2 == c["u1"]


@pytest.mark.parametrize("mass", [62.0, 83.0])
def test_disk_against_wall(mass):
    """A wall has infinite mass: u⁺ = u (m − K_n)/(m + K_n) for K_n > m, else 0."""
    rows = lambda k: (np.array([0]), np.array([-1]), np.array([[0.0, 1.0, 0.0]]), np.zeros((1, 3)),
                      np.array([k]), np.array([NORMAL]))
    u = -1.3  # towards the wall (normal +y from the wall into the disk)
    for k in np.concatenate([K_GRID, [mass, 0.5 * mass, 2.0 * mass]]):
        v, lam, st = solve_rows(np.array([mass, mass, 1.0]), *rows(k), np.array([0.2, u, 0.0]), np.zeros(3))
        expect = u * (mass - k) / (mass + k) if k > mass else 0.0
        assert st == STATUS_OK
        assert v[1] == pytest.approx(expect, abs=1e-12)
        assert v[0] == pytest.approx(0.2, abs=1e-15)  # no tangential dissipation: sliding is free


# ---------------------------------------------------------------- oblique impacts, rotation (Section 3.2)
def test_oblique_impact_spin_depends_on_ktg_not_kn():
    assert closed_form.oblique_spin(0.0)[0] == 0.0  # without tangential dissipation no spin
    spins = [closed_form.oblique_spin(k)[0] for k in (1.0, 10.0, 100.0, 1e3, 1e4)]
    assert all(s > 0 for s in spins) and np.all(np.diff(spins) > 0)
    for k_tg in (10.0, 1e3, 1e5):
        ref = closed_form.oblique_spin(k_tg, k_n=2e3)
        for k_n in (5e3, 1e4, 1e5, 1e6):
            got = closed_form.oblique_spin(k_tg, k_n=k_n)
            assert got == pytest.approx(ref, rel=1e-9, abs=1e-12)
    # Saturation: both contact points end up rolling without slip (tangential rows are "elastic").
    s5, s6 = closed_form.oblique_spin(1e5)[0], closed_form.oblique_spin(1e6)[0]
    assert abs(s6 - s5) < 1e-3 * s6


def test_fig7_theta_max_surface_is_eq21():
    td, kk, surf = closed_form.fig7_data(np.linspace(0.0, 2.0, 5), np.array([0.5, 18.5]))
    inertia = 0.5 * closed_form.MASS_KG * closed_form.RADIUS_M ** 2
    for i, k in enumerate(kk):
        np.testing.assert_allclose(surf[i], td / (math.sqrt(k / inertia) * math.e), rtol=1e-14)
    assert surf[0, -1] > surf[1, -1]  # a stiffer heading turns less


# ---------------------------------------------------------------- conservation, complementarity, energy
def _momenta(cl, v):
    n = cl["mass_diag"].size // 3
    m = cl["mass_diag"][0::3]
    inertia = cl["mass_diag"][2::3]
    u = v.reshape(n, 3)
    p = (m[:, None] * u[:, :2]).sum(axis=0)
    x = cl["position"]
    ang = float((m * (x[:, 0] * u[:, 1] - x[:, 1] * u[:, 0]) + inertia * u[:, 2]).sum())
    return p, ang


@pytest.mark.parametrize("seed", range(6))
def test_free_cluster_conserves_momentum_and_angular_momentum(seed):
    rng = np.random.default_rng(seed)
    cl = random_cluster(int(rng.integers(3, 25)), rng, k_tg=float(rng.choice([0.0, 50.0, 1e4])),
                        k_v=float(rng.choice([0.0, 1e3])), n_links=3, wall=False)
    v, _ = _solve(cl)
    p0, l0 = _momenta(cl, cl["v_minus"])
    p1, l1 = _momenta(cl, v)
    m = cl["mass_diag"][0::3]
    scale_p = float((m * np.abs(cl["v_minus"][0::3] + 1j * cl["v_minus"][1::3])).sum())
    scale_l = scale_p * float(np.abs(cl["position"]).max() + 1.0)
    assert np.abs(p1 - p0).max() <= 1e-10 * scale_p
    assert abs(l1 - l0) <= 1e-10 * scale_l


@pytest.mark.parametrize("seed", range(8))
def test_complementarity_and_energy(seed):
    rng = np.random.default_rng(100 + seed)
    cl = random_cluster(int(rng.integers(2, 40)), rng, k_n=float(rng.choice([10.0, 1e3, 1e5])),
                        k_tg=float(rng.choice([0.0, 1e2])), k_v=float(rng.choice([0.0, 1e4])), n_links=2)
    rows = _only_approaching(cl)
    v, lam = _solve(cl, rows)
    row_a, row_b, coef_a, coef_b, row_k, row_kind = rows
    B = rows_to_dense(cl["mass_diag"].size // 3, row_a, row_b, coef_a, coef_b)
    bn = B[row_kind == NORMAL] @ v
    assert np.all(lam >= 0.0)
    assert np.all(bn >= -1e-10)
    assert np.all(np.abs(lam * bn) <= 1e-9 * (1.0 + np.abs(lam).max()))
    ke0 = 0.5 * cl["mass_diag"] @ cl["v_minus"] ** 2
    ke1 = 0.5 * cl["mass_diag"] @ v ** 2
    assert ke1 <= ke0 * (1.0 + 1e-12)


def _three_disks(u):
    """Three unit disks (m = 1, r = 1, I = ½) in a row at x = 0, 2, 4, the middle one touching both."""
    mass_diag = np.tile([1.0, 1.0, 0.5], 3)
    v_minus = np.array([u[0], 0, 0, u[1], 0, 0, u[2], 0, 0], dtype=float)
    # contact (0, 1): normal from 1 to 0 is −x; contact (1, 2): normal from 2 to 1 is −x
    con = dict(a=np.array([0, 1]), b=np.array([1, 2]), gap=np.zeros(2), nx=np.array([-1.0, -1.0]),
               ny=np.zeros(2), rho_a=np.ones(2), rho_b=np.ones(2), sub=np.zeros(2, np.int64), arm_a=np.zeros((2, 2)),
               arm_b=np.zeros((2, 2)))
    return mass_diag, v_minus, con


def test_three_disk_energy_regression():
    """Documented regression (collision-problem.md, "Energy"): disk 0 hits the middle disk while
    disk 2 is already separating from it. Putting the separating contact into the impact set (a
    literal reading of the paper) makes a nearly elastic impact add about 13 % kinetic energy; the
    production impact set (touching and approaching or resting) does not."""
    mass_diag, v_minus, con = _three_disks([1.0, 0.0, 0.5])
    rows_all = (np.array([0, 1]), np.array([1, 2]), np.array([[-1.0, 0, 0], [-1.0, 0, 0]]),
                np.array([[1.0, 0, 0], [1.0, 0, 0]]), np.array([1e8, 1e8]), np.array([NORMAL, NORMAL]))
    v_lit, _, st = solve_rows(mass_diag, *rows_all, v_minus, np.zeros(9))
    ke0 = 0.5 * mass_diag @ v_minus ** 2
    ke_lit = 0.5 * mass_diag @ v_lit ** 2
    assert st == STATUS_OK
    assert ke_lit / ke0 - 1.0 == pytest.approx(0.1333, abs=2e-3)  # +13.3 %
    # The simulator's impact set: resolve_impacts keeps only the approaching contact.
    vel = v_minus.reshape(3, 3).copy()
    z = np.zeros(0, np.int64)
    e = np.zeros((0, 2))
    contacts = Candidates(*(con.get(k, np.full(2, -1)) for k in CONTACT_FIELDS))  # no wall: -1
    params = StepParams(0.01, 1e-3, 1e8, 0.0, 0.0, True, 400, MAX_DENSE_BODIES, 0, 0.0)
    p_n, p_t, in_impact, *_ = resolve_impacts(vel, np.ones(3), np.full(3, 0.5), contacts, Links(z, z, e, e, e), params,
                                              1e-9)
    assert in_impact.tolist() == [True, False]
    ke_ours = 0.5 * mass_diag @ vel.ravel() ** 2
    assert ke_ours <= ke0 * (1.0 + 1e-12)
    np.testing.assert_allclose(vel[:, 0], [0.0, 1.0, 0.5], atol=1e-7)  # elastic exchange, disk 2 untouched


# ---------------------------------------------------------------- against the cvxpy reference
def _random_reference_cluster(i):
    rng = np.random.default_rng(1000 + i)
    n = int(rng.integers(2, 13))
    return random_cluster(n, rng, k_n=float(10 ** rng.uniform(0.0, 6.0)),
                          k_tg=float(rng.choice([0.0, 10 ** rng.uniform(0.0, 4.0)])),
                          k_v=float(rng.choice([0.0, 10 ** rng.uniform(1.0, 5.0)])),
                          n_links=int(rng.integers(0, 3)), wall=bool(rng.random() < 0.7),
                          rotation=bool(rng.random() < 0.8))


def test_production_solver_matches_cvxpy_reference_on_random_clusters():
    n_more_contacts = 0
    kinds = set()
    for i in range(56):
        cl = _random_reference_cluster(i)
        rows = cl["rows"]
        n = cl["mass_diag"].size // 3
        n_more_contacts += int((rows[5] == NORMAL).sum() > 2 * n)
        kinds |= set(rows[5].tolist())
        kinds |= {"wall"} if np.any(rows[1] < 0) else set()
        v, lam = _solve(cl)
        v_ref, lam_ref = solve_rows_cvxpy(cl["mass_diag"], *rows, cl["v_minus"])
        np.testing.assert_allclose(v, v_ref, atol=1e-5, err_msg=f"cluster {i}")
        v_qp, _ = solve_rows_qp(cl["mass_diag"], *rows, cl["v_minus"])
        np.testing.assert_allclose(v, v_qp, atol=1e-5, err_msg=f"cluster {i} (Clarabel)")
        v_sp, lam_sp, st = solve_rows_sparse(cl["mass_diag"], *rows, cl["v_minus"])
        assert st == STATUS_OK
        np.testing.assert_allclose(v, v_sp, atol=1e-9, err_msg=f"cluster {i} (sparse pivoting)")
    assert n_more_contacts >= 10  # the interesting, degenerate case (W singular) is well represented
    assert {NORMAL, TANGENT, LINK, "wall"} <= kinds


def test_production_solver_matches_exact_qp_reference():
    """DAQP (an exact dual active-set QP solver, dev dependency) as a 1e-9 reference."""
    qpsolvers = pytest.importorskip("qpsolvers")
    pytest.importorskip("daqp")
    for i in range(20):
        cl = _random_reference_cluster(i)
        row_a, row_b, coef_a, coef_b, row_k, row_kind = cl["rows"]
        nd = cl["mass_diag"].size
        B = rows_to_dense(nd // 3, row_a, row_b, coef_a, coef_b)
        H = np.diag(cl["mass_diag"]) + B.T @ (row_k[:, None] * B)
        Bn = B[row_kind == NORMAL]
        y = qpsolvers.solve_qp(H, -cl["mass_diag"] * cl["v_minus"], G=-2.0 * Bn, h=-(Bn @ cl["v_minus"]),
                               solver="daqp")
        v, _ = _solve(cl)
        np.testing.assert_allclose(v, 2.0 * y - cl["v_minus"], atol=1e-9, err_msg=f"cluster {i}")


def test_sparse_path_matches_dense_on_large_clusters():
    rng = np.random.default_rng(7)
    for n, k_tg, k_v in ((80, 0.0, 0.0), (120, 30.0, 1e3)):
        cl = random_cluster(n, rng, k_tg=k_tg, k_v=k_v, n_links=5)
        v, lam = _solve(cl)
        v_sp, lam_sp, st = solve_rows_sparse(cl["mass_diag"], *cl["rows"], cl["v_minus"])
        assert st == STATUS_OK
        np.testing.assert_allclose(v_sp, v, atol=1e-9)


def test_lcp_bpp_on_singular_psd_matrix():
    """More constraints than unknowns: W = A Aᵀ is singular; λ need not be unique but w is. q is
    built from a known solution (a random q could make the LCP infeasible)."""
    rng = np.random.default_rng(3)
    A = rng.standard_normal((12, 5))
    W = A @ A.T
    act = rng.random(12) < 0.5
    lam_star = np.where(act, rng.uniform(0.1, 1.0, 12), 0.0)
    w_star = np.where(act, 0.0, rng.uniform(0.1, 1.0, 12))
    q = w_star - W @ lam_star
    lam, st = lcp_bpp(W, q)
    w = W @ lam + q
    assert st == STATUS_OK
    assert lam.min() >= 0.0 and w.min() >= -1e-9 and abs(lam @ w) < 1e-8
    np.testing.assert_allclose(w, w_star, atol=1e-9)


def test_lcp_bpp_keeps_a_solution_when_the_polish_drifts_on_a_singular_free_set():
    """Regression (issue 20): the projection LCP of a 51-contact cluster of the Seyfried jam (b = 1.0 m,
    N = 180, seed 2, t = 6.27 s; W of rank 50). Pivoting ends on a free set whose W_FF is singular with
    q_F partly outside its range: iterative refinement then moved λ along the null space of W_FF by
    about 6 kg m/s per step, down to −21, and clipping that to 0 left w = −0.153 m/s: 1.53 mm of
    overlap in one step. The polish is now kept only while λ stays a solution."""
    data = np.load(DATA / "jam_lcp_singular.npz")
    W, q = data["W"], data["q"]
    assert np.linalg.matrix_rank(W) < W.shape[0]
    lam, st = lcp_bpp(W, q)
    w = W @ lam + q
    assert st == STATUS_OK
    assert lam.min() >= 0.0
    assert w.min() >= -1e-7  # m/s: below 1e-9 m of overlap per 0.01 s step (was -0.153 m/s)
    assert np.abs(lam * w).max() < 1e-6


# ---------------------------------------------------------------- hand-holding links (Eq. 2)
def _linked_pair(k_v, u_apart=1.0, spin=0.0):
    """Two disks side by side (not touching), holding hands: shoulders at (±0.25, 0) in the body
    frame of each, pulled apart along x."""
    r = 0.23
    pos = np.array([[0.0, 0.0], [0.8, 0.0]])
    mass = np.array([70.0, 80.0])
    inertia = 0.5 * mass * r ** 2
    gi = np.array([0.25, 0.0])
    gj = np.array([-0.25, 0.0])
    d = pos[0] + gi - pos[1] - gj  # A_i − A_j
    row_a, row_b = np.array([0]), np.array([1])
    coef_a = np.array([[2 * d[0], 2 * d[1], 2 * (gi[0] * d[1] - gi[1] * d[0])]])
    coef_b = -np.array([[2 * d[0], 2 * d[1], 2 * (gj[0] * d[1] - gj[1] * d[0])]])
    rows = (row_a, row_b, coef_a, coef_b, np.array([k_v]), np.array([LINK]))
    mass_diag = np.array([mass[0], mass[0], inertia[0], mass[1], mass[1], inertia[1]])
    v_minus = np.array([-u_apart, 0.1, spin, u_apart, -0.2, 0.0])
    return mass_diag, rows, v_minus


def test_hand_link_resists_separation():
    mass_diag, rows, v_minus = _linked_pair(0.0)
    B = rows_to_dense(2, *rows[:4])
    rate0 = float((B @ v_minus)[0])  # Δ* = d/dt |A_i A_j|² > 0: separating
    assert rate0 > 0
    mu_link = 1.0 / float(B[0] @ (B[0] / mass_diag))
    for k_v in (0.05 * mu_link, 0.5 * mu_link, 2 * mu_link, 1e3 * mu_link):
        mass_diag, rows, v_minus = _linked_pair(k_v)
        v, lam, st = solve_rows(mass_diag, *rows, v_minus, np.zeros(6))
        rate1 = float((B @ v)[0])
        assert st == STATUS_OK and lam.size == 0  # links carry no unilateral constraint
        assert rate1 == pytest.approx(rate0 * (mu_link - k_v) / (mu_link + k_v), rel=1e-9)
        if k_v < mu_link:
            assert 0 < rate1 < rate0  # damped
        else:
            assert rate1 < 0  # large K_v: the pair bounces back together
    # without a link, nothing happens
    mass_diag, rows, v_minus = _linked_pair(0.0)
    v, _, _ = solve_rows(mass_diag, *rows, v_minus, np.zeros(6))
    np.testing.assert_allclose(v, v_minus, atol=1e-15)


# ---------------------------------------------------------------- the velocity projection
def _projection_case(seed, n=40):
    rng = np.random.default_rng(seed)
    cl = random_cluster(n, rng, max_gap_m=4e-3)
    con = cl["contacts"]
    vel = np.zeros((n, 3))
    vel[:, :2] = rng.normal(0.0, 1.0, (n, 2))
    mass = cl["mass_diag"][0::3]
    return vel, mass, con


@pytest.mark.parametrize("seed", range(3))
def test_projection_paths_agree_and_close_no_gap(seed):
    vel, mass, con = _projection_case(seed)
    args = (mass, con["a"], con["b"], con["gap"], con["nx"], con["ny"], 0.01)
    v_dense = vel.copy()
    lam, _, st = project_gaps(v_dense, *args, 1e-10)
    assert st == STATUS_OK
    v_sp = vel.copy()
    lam_sp, st = project_gaps_sparse(v_sp, *args)
    assert st == STATUS_OK
    v_large = vel.copy()
    project_gaps_large(v_large, *args)
    v_qp = vel.copy()
    project_gaps_qp(v_qp, *args)
    np.testing.assert_allclose(v_sp, v_dense, atol=1e-9)
    np.testing.assert_allclose(v_large, v_dense, atol=1e-9)
    np.testing.assert_allclose(v_qp, v_dense, atol=1e-5)
    b = np.maximum(con["b"], 0)
    rel = (v_dense[con["a"], :2] - np.where(con["b"][:, None] >= 0, v_dense[b, :2], 0.0))
    gap_next = con["gap"] + 0.01 * (rel[:, 0] * con["nx"] + rel[:, 1] * con["ny"])
    assert gap_next.min() >= -1e-12
    ke0 = 0.5 * mass @ (vel[:, :2] ** 2).sum(axis=1)
    ke1 = 0.5 * mass @ (v_dense[:, :2] ** 2).sum(axis=1)
    assert ke1 <= ke0 * (1 + 1e-12)  # a projection onto a convex set containing 0
    assert np.all(lam >= 0)
