"""The large gap projections (crowd_env.core.solvers.large_projection: the augmented Lagrangian, the interior
point and the working set methods) on degenerate jammed packings: feasible, a KKT point, no kinetic energy
added, and the same v as the exact solvers."""
import numpy as np
import pytest

from crowd_env.core.solvers.cascade import project_gaps_large
from crowd_env.core.solvers.dense_projection import project_gaps
from crowd_env.core.solvers.external import project_gaps_qp
from crowd_env.core.solvers.large_projection import project_gaps_alm, project_gaps_interior_point, project_gaps_working_set
from crowd_env.core.solvers.status import STATUS_OK
from tests.core.conftest import H, gap_residual, hex_jam, jam_and_exact_projection, percussion


def _objective(v, v0, mass):
    return 0.5 * float((mass[:, None] * (v[:, :2] - v0[:, :2]) ** 2).sum())


@pytest.mark.parametrize("seed", range(4))
def test_alm_is_exact_on_degenerate_jams(seed):
    rng = np.random.default_rng(seed)
    vel, mass, a, b, gap, nx, ny = hex_jam(8 + seed, 10, rng, squeeze=float(seed % 2))
    assert a.shape[0] > 2 * vel.shape[0]  # more contacts than degrees of freedom
    v = vel.copy()
    lam, steps, status = project_gaps_alm(v, mass, a, b, gap, nx, ny, H, np.zeros(a.shape[0]))
    assert status == STATUS_OK
    r = gap_residual(v, a, b, gap, nx, ny)
    assert r.min() >= -1e-9  # feasible
    assert np.all(lam >= 0.0) and np.all(lam * np.abs(r) <= 1e-7 * (1.0 + lam.max()))  # complementarity
    # stationarity: M (v − v') = B_nᵀ λ
    np.testing.assert_allclose(mass[:, None] * (v[:, :2] - vel[:, :2]), percussion(v.shape[0], lam, a, b, nx, ny),
                               atol=1e-7)
    # no energy added
    ke = lambda w: 0.5 * float((mass * (w[:, 0] ** 2 + w[:, 1] ** 2)).sum())
    assert ke(v) <= ke(vel) * (1 + 1e-9) + 1e-9
    # Clarabel (interior point, feasible, v to ~1e-6 in jams) cannot do better; the exact large path agrees
    vq = vel.copy()
    project_gaps_qp(vq, mass, a, b, gap, nx, ny, H)
    assert _objective(v, vel, mass) <= _objective(vq, vel, mass) + 1e-9
    np.testing.assert_allclose(v[:, :2], vq[:, :2], atol=1e-3)
    vl = vel.copy()
    _, path = project_gaps_large(vl, mass, a, b, gap, nx, ny, H)
    if path < 2:  # certified by pivoting
        np.testing.assert_allclose(v[:, :2], vl[:, :2], atol=1e-7)


@pytest.mark.parametrize("seed", range(1, 6))
def test_alm_matches_dense_projection_on_small_packings(seed):
    rng = np.random.default_rng(100 + seed)
    vel, mass, a, b, gap, nx, ny = hex_jam(3, 4, rng)
    vd = vel.copy()
    _, _, status = project_gaps(vd, mass, a, b, gap, nx, ny, H, 1e-10)
    assert status == STATUS_OK  # the dense pivoting reference certifies these small packings
    v = vel.copy()
    lam, _, status = project_gaps_alm(v, mass, a, b, gap, nx, ny, H, np.zeros(a.shape[0]))
    assert status == STATUS_OK
    np.testing.assert_allclose(v, vd, atol=1e-6)  # the 1e-9 m jitter makes gap/h inconsistent by ~1e-7 m/s


def test_alm_non_convergence_is_reported_and_leaves_velocities_untouched():
    """A known weakness: on this small, nearly perfect lattice the multipliers stall on a flat face of
    the dual. The solver must then say so and change nothing (the simulator falls back to
    project_gaps_large, which certifies the solution by pivoting)."""
    rng = np.random.default_rng(100)
    vel, mass, a, b, gap, nx, ny = hex_jam(3, 4, rng)
    v = vel.copy()
    _, _, status = project_gaps_alm(v, mass, a, b, gap, nx, ny, H, np.zeros(a.shape[0]))
    assert status != STATUS_OK
    np.testing.assert_array_equal(v, vel)
    _, path = project_gaps_large(v, mass, a, b, gap, nx, ny, H)
    assert path < 2 and gap_residual(v, a, b, gap, nx, ny).min() >= -1e-6  # jitter: gap/h inconsistent ~1e-7


def test_alm_warm_start_from_exact_multipliers_takes_one_step():
    rng = np.random.default_rng(7)
    vel, mass, a, b, gap, nx, ny = hex_jam(6, 6, rng)
    v = vel.copy()
    lam, _, _ = project_gaps_alm(v, mass, a, b, gap, nx, ny, H, np.zeros(a.shape[0]))
    v2 = vel.copy()
    _, steps, status = project_gaps_alm(v2, mass, a, b, gap, nx, ny, H, lam)
    assert status == STATUS_OK and steps <= 3
    np.testing.assert_allclose(v2, v, atol=1e-9)


def test_alm_without_candidates_and_when_already_feasible():
    v = np.ones((3, 3))
    assert project_gaps_alm(v, np.ones(3), np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0), np.zeros(0),
                            np.zeros(0), H, np.zeros(0))[2] == STATUS_OK
    a, b = np.array([0]), np.array([1])
    v = np.zeros((2, 3))
    v[:, 0] = [-1.0, 1.0]  # separating
    lam, steps, status = project_gaps_alm(v, np.ones(2), a, b, np.array([0.1]), np.array([1.0]), np.array([0.0]), H,
                                          np.zeros(1))
    assert status == STATUS_OK and steps == 0 and lam[0] == 0.0 and v[0, 0] == -1.0


@pytest.mark.parametrize("seed", range(4))
def test_own_interior_point_projection_agrees_with_the_exact_one(seed):
    """project_gaps_interior_point (Mehrotra with dual regularisation) on degenerate jams, where the
    unregularised weights would break the Cholesky factorisation: converged, feasible to round-off,
    percussions ≥ 0 that satisfy stationarity M (v − v') = B_nᵀ z, the exact objective to 1e-9, and v
    within 1e-8 m/s of the augmented Lagrangian's exact v."""
    vel, mass, a, b, gap, nx, ny, v_exact = jam_and_exact_projection(seed)
    v = vel.copy()
    z, iterations, status = project_gaps_interior_point(v, mass, a, b, gap, nx, ny, H)
    assert status == STATUS_OK and 5 <= iterations <= 40
    assert gap_residual(v, a, b, gap, nx, ny).min() >= -1e-11
    np.testing.assert_allclose(v, v_exact, rtol=0, atol=1e-8)
    assert z.min() >= 0.0
    np.testing.assert_allclose(mass[:, None] * (v[:, :2] - vel[:, :2]), percussion(v.shape[0], z, a, b, nx, ny),
                               atol=1e-9 * mass.max())
    assert _objective(v, vel, mass) == pytest.approx(_objective(v_exact, vel, mass), rel=1e-9)
    np.testing.assert_array_equal(v[:, 2], vel[:, 2])
    # only closed contacts push: z is exactly 0 on every open gap, and positive wherever the augmented
    # Lagrangian's exact multiplier is
    slack = gap_residual(v, a, b, gap, nx, ny)
    lam_exact, _, _ = project_gaps_alm(vel.copy(), mass, a, b, gap, nx, ny, H, np.zeros(a.shape[0]), 400)
    assert (slack > 1e-9).any() and np.all(z[slack > 1e-9] == 0.0)
    assert np.all(z[lam_exact > 1e-6 * lam_exact.max()] > 0.0)
    v = vel.copy()
    _, iterations, status = project_gaps_interior_point(v, mass, a, b, gap, nx, ny, H, 3)
    assert status != STATUS_OK and iterations == 3 and np.array_equal(v, vel)  # a miss leaves vel alone
    v = np.ones((3, 3))
    z, iterations, status = project_gaps_interior_point(v, np.ones(3), np.zeros(0, np.int64), np.zeros(0, np.int64),
                                                        np.zeros(0), np.zeros(0), np.zeros(0), H)
    assert status == STATUS_OK and z.shape == (0,) and iterations == 0 and np.all(v == 1.0)


@pytest.mark.parametrize("seed", range(4))
def test_interior_point_warm_start_from_a_nearby_solution(seed):
    """Started from the exact percussions of a nearby problem (the same jam with v' perturbed by
    2 cm/s, as from one step to the next), the interior point method ends at the same exact v in fewer
    iterations than from its cold start (measured: 9-11 against 15-17); from a poor guess (50× too
    large) it still ends there, only later."""
    vel, mass, a, b, gap, nx, ny, v_exact = jam_and_exact_projection(seed)
    nearby = vel.copy()
    nearby[:, :2] += np.random.default_rng(seed).normal(0.0, 0.02, (vel.shape[0], 2))
    z_nearby, _, status = project_gaps_alm(nearby, mass, a, b, gap, nx, ny, H, np.zeros(a.shape[0]), 400)
    assert status == STATUS_OK
    v = vel.copy()
    _, cold, _ = project_gaps_interior_point(v, mass, a, b, gap, nx, ny, H)
    for guess, faster in ((z_nearby, True), (50.0 * z_nearby + 100.0, False)):
        v = vel.copy()
        z, iterations, status = project_gaps_interior_point(v, mass, a, b, gap, nx, ny, H, 60, guess)
        assert status == STATUS_OK and (iterations <= cold - 3 if faster else iterations > cold)
        np.testing.assert_allclose(v, v_exact, rtol=0, atol=1e-8)
        assert z.min() >= 0.0 and gap_residual(v, a, b, gap, nx, ny).min() >= -1e-11


@pytest.mark.parametrize("seed", range(4))
def test_working_set_projection_grows_to_the_exact_one(seed):
    """project_gaps_working_set from the candidates violated at v' alone: the first answer violates
    others, they join and it solves again; the end is the exact projection (within 1e-7 m/s of the
    augmented Lagrangian's v), a KKT point with zero percussion outside the final working set. From
    all candidates it solves once."""
    vel, mass, a, b, gap, nx, ny, v_exact = jam_and_exact_projection(seed)
    violated = gap_residual(vel, a, b, gap, nx, ny) < 0.0
    assert 0 < violated.sum() < a.shape[0]
    v = vel.copy()
    lam, solves, status = project_gaps_working_set(v, mass, a, b, gap, nx, ny, H, violated, max_rounds=50)
    assert status == STATUS_OK and solves >= 2
    np.testing.assert_allclose(v, v_exact, atol=1e-7)
    assert gap_residual(v, a, b, gap, nx, ny).min() >= -1e-9 and lam.min() >= 0.0
    assert np.all(lam[violated] >= 0.0) and np.count_nonzero(lam) < a.shape[0]  # some never joined
    np.testing.assert_allclose(mass[:, None] * (v[:, :2] - vel[:, :2]), percussion(v.shape[0], lam, a, b, nx, ny),
                               atol=1e-7 * mass.max())
    v_all = vel.copy()
    _, solves_all, status_all = project_gaps_working_set(v_all, mass, a, b, gap, nx, ny, H, np.ones(a.shape[0], bool))
    v_ipm = vel.copy()
    project_gaps_interior_point(v_ipm, mass, a, b, gap, nx, ny, H)
    assert status_all == STATUS_OK and solves_all == 1
    np.testing.assert_array_equal(v_all, v_ipm)


def test_working_set_projection_reports_a_miss_and_bad_input():
    """Out of solves, the working set method says so and leaves the velocities alone; a working set of
    the wrong shape, or a start z0 of the wrong shape, not finite or negative, is refused by name."""
    vel, mass, a, b, gap, nx, ny, _ = jam_and_exact_projection(0)
    violated = gap_residual(vel, a, b, gap, nx, ny) < 0.0
    v = vel.copy()
    _, solves, status = project_gaps_working_set(v, mass, a, b, gap, nx, ny, H, violated, max_rounds=1)
    assert status != STATUS_OK and solves == 1
    np.testing.assert_array_equal(v, vel)
    with pytest.raises(ValueError, match="working"):
        project_gaps_working_set(v, mass, a, b, gap, nx, ny, H, violated[:-1])
    for z0 in (np.zeros(a.shape[0] - 1), np.full(a.shape[0], np.nan), np.full(a.shape[0], -1.0)):
        with pytest.raises(ValueError, match="z0"):
            project_gaps_working_set(v, mass, a, b, gap, nx, ny, H, violated, z0=z0)


def test_envelope_factor_is_the_cholesky_factor_of_the_newton_matrix():
    """The interior point method's Newton matrix M + Σ_k w_k B_kᵀ B_k, assembled by scattering weights
    into the entries _envelope_entries precomputes and factorised in envelope storage, is L Lᵀ for the
    same matrix assembled densely from the rows B_k (with wall rows and rows left out)."""
    from crowd_env.core.solvers.large_projection import (_envelope_entries, _envelope_factor, _envelope_pattern,
                                                         _projection_dofs)

    rng = np.random.default_rng(3)
    vel, mass, a, b, gap, nx, ny = hex_jam(6, 7, rng)
    n, m = vel.shape[0], a.shape[0]
    b = b.copy()
    b[::5] = -1  # some wall contacts: one body only
    weight = np.exp(rng.uniform(-3.0, 12.0, m))
    used = rng.random(m) < 0.8
    pos = _projection_dofs(n, a, b, nx, ny)
    dof, first, off = _envelope_pattern(n, used, a, b, pos)
    env = np.empty(off[-1])
    # the unused rows get weights too: the entries must leave them out
    _envelope_factor(mass, weight, dof, first, off, _envelope_entries(used, a, b, nx, ny, pos, first, off), env)
    dense = np.diag(np.repeat(mass, 2))
    for k in np.flatnonzero(used):
        row = np.zeros(2 * n)
        row[2 * a[k]: 2 * a[k] + 2] = nx[k], ny[k]
        if b[k] >= 0:
            row[2 * b[k]: 2 * b[k] + 2] = -nx[k], -ny[k]
        dense += weight[k] * np.outer(row, row)
    nd = dof.shape[0]
    lower = np.zeros((nd, nd))
    for i in range(nd):
        lower[i, first[i]: i + 1] = env[off[i]: off[i + 1]]
    np.testing.assert_allclose(lower @ lower.T, dense[np.ix_(dof, dof)], rtol=1e-12, atol=1e-9 * dense.max())
    assert np.all(lower[np.triu_indices(nd, 1)] == 0.0) and np.all(np.diag(lower) > 0.0)
