"""The augmented Lagrangian gap projection (crowd_env.core.solvers.large_projection) on degenerate jammed packings:
feasible, a KKT point, no kinetic energy added, and the same v as the exact solvers."""
import numpy as np
import pytest

from crowd_env.core.solvers import cascade as cascade_module
from crowd_env.core.solvers.cascade import SolverCascade, project_gaps_large
from crowd_env.core.solvers.dense_projection import project_gaps
from crowd_env.core.solvers.external import IPM_TOL_M_S, project_gaps_ipm, project_gaps_qp
from crowd_env.core.solvers.graph import contact_keys
from crowd_env.core.solvers.large_projection import project_gaps_alm, project_gaps_interior_point, project_gaps_working_set
from crowd_env.core.solvers.status import STATUS_OK

H = 0.01


def _hex_jam(rows, cols, rng, squeeze=0.0):
    """Disks of radius 0.25 m on a slightly jittered (1e-9 m) triangular lattice in a box, all touching,
    pushed together: about three contacts per disk, degenerate. (A perfect lattice with gaps exactly 0
    makes the ALM multipliers stall: it then reports STATUS_MAX_ITER and the simulator falls back.)"""
    r = 0.25
    pos = np.array([[2 * r * c + (r if k % 2 else 0.0), np.sqrt(3) * r * k] for k in range(rows) for c in range(cols)])
    pos += rng.normal(0.0, 1e-9, pos.shape)
    n = pos.shape[0]
    a, b, gap, nx, ny = [], [], [], [], []
    for i in range(n):
        for j in range(i + 1, n):
            d = pos[i] - pos[j]
            dist = np.hypot(*d)
            if dist < 2 * r + 0.05:
                a.append(i), b.append(j), gap.append(dist - 2 * r - squeeze * rng.random() * 1e-13)
                nx.append(d[0] / dist), ny.append(d[1] / dist)
    lo, hi = pos.min(axis=0) - r, pos.max(axis=0) + r
    for i in range(n):  # walls: left, right, bottom, top (normals into the box)
        for g, (ux, uy) in ((pos[i, 0] - r - lo[0], (1, 0)), (hi[0] - pos[i, 0] - r, (-1, 0)),
                            (pos[i, 1] - r - lo[1], (0, 1)), (hi[1] - pos[i, 1] - r, (0, -1))):
            if g < 0.05:
                a.append(i), b.append(-1), gap.append(g), nx.append(ux), ny.append(uy)
    vel = np.zeros((n, 3))
    vel[:, :2] = rng.normal(0.0, 1.0, (n, 2)) + [1.5, 0.5]  # towards a corner
    mass = rng.uniform(50.0, 100.0, n)
    return vel, mass, np.array(a), np.array(b), np.array(gap), np.array(nx), np.array(ny)


def _residual(v, a, b, gap, nx, ny):
    vb = np.where((b >= 0)[:, None], v[np.maximum(b, 0), :2], 0.0)
    return gap / H + ((v[a, :2] - vb) * np.stack([nx, ny], axis=1)).sum(axis=1)


def _objective(v, v0, mass):
    return 0.5 * float((mass[:, None] * (v[:, :2] - v0[:, :2]) ** 2).sum())


def _percussion(n, lam, a, b, nx, ny):
    """B_nᵀ λ (n, 2): what stationarity M (v − v') = B_nᵀ λ asks the velocity change to be."""
    out = np.zeros((n, 2))
    normal = np.stack([nx, ny], axis=1)
    np.add.at(out, a, lam[:, None] * normal)
    np.add.at(out, b[b >= 0], -(lam[b >= 0, None] * normal[b >= 0]))
    return out


def _con(a, b, gap, nx, ny):
    """The simulator's candidate dict for these rows: a pedestrian's wall contacts on segments 0, 1, …
    in turn (one contact per pedestrian and segment, as the detection makes them; at most the four
    segments of :func:`_project`)."""
    wall = np.full(a.shape[0], -1)
    for k in np.flatnonzero(b < 0):
        wall[k] = np.count_nonzero((b[:k] < 0) & (a[:k] == a[k]))
    assert wall.max() < 4
    return {"a": a, "b": b, "wall": wall, "gap": gap, "nx": nx, "ny": ny}


def _jam_cascade(**kwargs):
    """The solver cascade of the tests, with the dense projection limited to 8 rows so that every jam
    takes the large path (other constructor arguments: ``kwargs``)."""
    return SolverCascade(max_dense_projection_rows=8, **kwargs)


def _project(cascade, v, mass, con, step=0, lam_warm=None):
    """The cascade's projection of step ``step`` on the candidates ``con``, keyed as the Simulator keys
    them (the rows of ``v`` are the pedestrians; four wall segments number the jam's wall contacts)."""
    keys = contact_keys(con["a"], con["b"], con["wall"], v.shape[0], 4)
    return cascade.project(v, mass, con, H, step, keys, lam_warm)


@pytest.mark.parametrize("seed", range(4))
def test_alm_is_exact_on_degenerate_jams(seed):
    rng = np.random.default_rng(seed)
    vel, mass, a, b, gap, nx, ny = _hex_jam(8 + seed, 10, rng, squeeze=float(seed % 2))
    assert a.shape[0] > 2 * vel.shape[0]  # more contacts than degrees of freedom
    v = vel.copy()
    lam, steps, status = project_gaps_alm(v, mass, a, b, gap, nx, ny, H, np.zeros(a.shape[0]))
    assert status == STATUS_OK
    r = _residual(v, a, b, gap, nx, ny)
    assert r.min() >= -1e-9  # feasible
    assert np.all(lam >= 0.0) and np.all(lam * np.abs(r) <= 1e-7 * (1.0 + lam.max()))  # complementarity
    # stationarity: M (v − v') = B_nᵀ λ
    np.testing.assert_allclose(mass[:, None] * (v[:, :2] - vel[:, :2]), _percussion(v.shape[0], lam, a, b, nx, ny),
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
    vel, mass, a, b, gap, nx, ny = _hex_jam(3, 4, rng)
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
    vel, mass, a, b, gap, nx, ny = _hex_jam(3, 4, rng)
    v = vel.copy()
    _, _, status = project_gaps_alm(v, mass, a, b, gap, nx, ny, H, np.zeros(a.shape[0]))
    assert status != STATUS_OK
    np.testing.assert_array_equal(v, vel)
    _, path = project_gaps_large(v, mass, a, b, gap, nx, ny, H)
    assert path < 2 and _residual(v, a, b, gap, nx, ny).min() >= -1e-6  # jitter: gap/h inconsistent ~1e-7


def test_alm_warm_start_from_exact_multipliers_takes_one_step():
    rng = np.random.default_rng(7)
    vel, mass, a, b, gap, nx, ny = _hex_jam(6, 6, rng)
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


def test_simulator_large_projection_sees_only_the_touched_pedestrians():
    """SolverCascade.project hands a too-large projection to the large solvers restricted to the
    pedestrians some candidate touches: the jam's velocities equal the solver's on the jam alone, and
    the 40 pedestrians no candidate touches (numbered before, between and after the jam's) keep
    their velocities exactly."""
    rng = np.random.default_rng(7)
    vel, mass, a, b, gap, nx, ny = _hex_jam(9, 10, rng)
    n_jam, n_far = vel.shape[0], 40
    order = rng.permutation(n_jam + n_far)  # order[k]: global index of local body k
    jam_ids, far_ids = order[:n_jam], order[n_jam:]
    vel_all = np.zeros((n_jam + n_far, 3))
    vel_all[jam_ids] = vel
    vel_all[far_ids] = rng.normal(0.0, 1.0, (n_far, 3))
    mass_all = np.empty(n_jam + n_far)
    mass_all[jam_ids] = mass
    mass_all[far_ids] = rng.uniform(50.0, 100.0, n_far)
    con = _con(jam_ids[a], np.where(b >= 0, jam_ids[np.maximum(b, 0)], -1), gap, nx, ny)
    sim = _jam_cascade()
    v_sim = vel_all.copy()
    lam_sim = _project(sim, v_sim, mass_all, con)
    v_ref = vel.copy()
    lam_ref, _, status = project_gaps_alm(v_ref, mass, a, b, gap, nx, ny, H, np.zeros(a.shape[0]), 40)
    assert status == STATUS_OK and sim.n_sparse_solves == 1
    np.testing.assert_array_equal(v_sim[far_ids], vel_all[far_ids])
    np.testing.assert_allclose(v_sim[jam_ids, :2], v_ref[:, :2], atol=1e-12)
    np.testing.assert_allclose(lam_sim, lam_ref, atol=1e-9)


def _reprojection(later_kind):
    """Project a jam twice as a re-detection makes the simulator do: first without the candidates
    ``later`` (slack in the full solution, or wall contacts that bind), then with them, started from
    the first multipliers; and once from zero on all candidates. Returns the velocities and Newton
    steps of both, and how far the first solution is from the full one."""
    rng = np.random.default_rng(11)
    vel, mass, a, b, gap, nx, ny = _hex_jam(8, 10, rng)
    n = vel.shape[0]
    if later_kind == "slack":
        lam_full, _, status = project_gaps_alm(vel.copy(), mass, a, b, gap, nx, ny, H, np.zeros(a.shape[0]), 400)
        assert status == STATUS_OK
        later = rng.choice(np.flatnonzero(lam_full == 0.0), 8, replace=False)
    else:  # the right wall in front of every third pedestrian along it
        later = np.flatnonzero((b < 0) & (nx < -0.5))[::3]
    order = np.concatenate([np.setdiff1d(np.arange(a.shape[0]), later), later])
    con = _con(a[order], b[order], gap[order], nx[order], ny[order])
    con_first = {k: v[: order.shape[0] - later.shape[0]] for k, v in con.items()}
    cold, warm = _jam_cascade(), _jam_cascade()
    v_cold = vel.copy()
    _project(cold, v_cold, mass, con)
    v_first = vel.copy()
    lam_first = _project(warm, v_first, mass, con_first)
    steps_first = warm.n_alm_newton_steps
    v_warm = vel.copy()
    _project(warm, v_warm, mass, con, lam_warm=np.concatenate([lam_first, np.zeros(later.shape[0])]))
    return (v_cold, cold.n_alm_newton_steps, v_warm, warm.n_alm_newton_steps - steps_first,
            float(np.abs(v_first - v_cold).max()), warm.n_fallback_solves)


def test_reprojection_after_redetection_starts_from_the_first_multipliers():
    """Candidates a re-detection adds lie farther than the first ones and rarely bind: the projection
    repeated from the first multipliers (zeros for the new candidates) reaches the same velocities as
    from zero in one or two Newton steps (measured in a 1400-pedestrian door jam: 1-8 instead of
    40-70)."""
    v_cold, steps_cold, v_warm, steps_warm, first_off, _ = _reprojection("slack")
    np.testing.assert_allclose(v_warm, v_cold, atol=1e-9)
    assert first_off <= 1e-9
    assert steps_cold >= 8 and steps_warm <= 2, (steps_cold, steps_warm)


def test_reprojection_whose_new_candidates_bind_stays_exact():
    """New candidates that change the solution (a wall in front) can make the warm start a poor one:
    it gets ALM_WARM_NEWTON_BUDGET steps, then the projection starts from zero; exact either way."""
    from crowd_env.core.solvers.cascade import ALM_NEWTON_BUDGET, ALM_WARM_NEWTON_BUDGET

    v_cold, steps_cold, v_warm, steps_warm, first_off, fallbacks = _reprojection("wall")
    assert first_off > 0.1  # the wall matters
    np.testing.assert_allclose(v_warm, v_cold, atol=1e-9)
    assert steps_cold < ALM_NEWTON_BUDGET and fallbacks == 0
    assert steps_warm == ALM_WARM_NEWTON_BUDGET + steps_cold  # here the warm start missed, then from zero


def _jam_and_exact_projection(seed):
    """A degenerate jam of (8 + seed) × 10 disks (squeezed for odd seeds) and the augmented
    Lagrangian's exact projected velocities: ``(vel, mass, a, b, gap, nx, ny, v_exact)``."""
    rng = np.random.default_rng(seed)
    vel, mass, a, b, gap, nx, ny = _hex_jam(8 + seed, 10, rng, squeeze=float(seed % 2))
    v_exact = vel.copy()
    _, _, status = project_gaps_alm(v_exact, mass, a, b, gap, nx, ny, H, np.zeros(a.shape[0]), 400)
    assert status == STATUS_OK
    return vel, mass, a, b, gap, nx, ny, v_exact


@pytest.mark.parametrize("seed", range(4))
def test_interior_point_projection_agrees_with_the_exact_one(seed):
    """project_gaps_ipm (PIQP) on degenerate jams: feasible to its tolerance, multipliers ≥ 0 that satisfy
    stationarity M (v − v') = B_nᵀ λ, and v within 1e-6 m/s of the augmented Lagrangian's exact v."""
    vel, mass, a, b, gap, nx, ny, v_exact = _jam_and_exact_projection(seed)
    v = vel.copy()
    lam, ok = project_gaps_ipm(v, mass, a, b, gap, nx, ny, H)
    assert ok
    assert _residual(v, a, b, gap, nx, ny).min() >= -IPM_TOL_M_S
    np.testing.assert_allclose(v, v_exact, atol=1e-6)
    assert lam.min() >= 0.0
    np.testing.assert_allclose(mass[:, None] * (v[:, :2] - vel[:, :2]), _percussion(v.shape[0], lam, a, b, nx, ny),
                               atol=1e-6 * mass.max())
    np.testing.assert_array_equal(v[:, 2], vel[:, 2])  # rotation untouched


@pytest.mark.parametrize("seed", range(4))
def test_own_interior_point_projection_agrees_with_the_exact_one(seed):
    """project_gaps_interior_point (Mehrotra with dual regularisation) on degenerate jams, where the
    unregularised weights would break the Cholesky factorisation: converged, feasible to round-off,
    percussions ≥ 0 that satisfy stationarity M (v − v') = B_nᵀ z, the exact objective to 1e-9, and v
    within 1e-8 m/s of the augmented Lagrangian's exact v."""
    vel, mass, a, b, gap, nx, ny, v_exact = _jam_and_exact_projection(seed)
    v = vel.copy()
    z, iterations, status = project_gaps_interior_point(v, mass, a, b, gap, nx, ny, H)
    assert status == STATUS_OK and 5 <= iterations <= 40
    assert _residual(v, a, b, gap, nx, ny).min() >= -1e-11
    np.testing.assert_allclose(v, v_exact, rtol=0, atol=1e-8)
    assert z.min() >= 0.0
    np.testing.assert_allclose(mass[:, None] * (v[:, :2] - vel[:, :2]), _percussion(v.shape[0], z, a, b, nx, ny),
                               atol=1e-9 * mass.max())
    assert _objective(v, vel, mass) == pytest.approx(_objective(v_exact, vel, mass), rel=1e-9)
    np.testing.assert_array_equal(v[:, 2], vel[:, 2])
    # only closed contacts push: z is exactly 0 on every open gap, and positive wherever the augmented
    # Lagrangian's exact multiplier is
    slack = _residual(v, a, b, gap, nx, ny)
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
    vel, mass, a, b, gap, nx, ny, v_exact = _jam_and_exact_projection(seed)
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
        assert z.min() >= 0.0 and _residual(v, a, b, gap, nx, ny).min() >= -1e-11


def test_interior_point_projection_without_candidates():
    v = np.ones((3, 3))
    lam, ok = project_gaps_ipm(v, np.ones(3), np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0), np.zeros(0),
                               np.zeros(0), H)
    assert ok and lam.shape == (0,) and np.all(v == 1.0)


def test_simulator_hands_a_slow_augmented_lagrangian_to_the_interior_point_method():
    """A large projection whose augmented Lagrangian misses its Newton budget goes to the interior point
    method (same v to 1e-6 m/s); the next nine large projections skip the augmented Lagrangian."""
    rng = np.random.default_rng(5)
    vel, mass, a, b, gap, nx, ny = _hex_jam(9, 10, rng)
    n = vel.shape[0]
    v_exact = vel.copy()
    _, steps_exact, status = project_gaps_alm(v_exact, mass, a, b, gap, nx, ny, H, np.zeros(a.shape[0]), 400)
    assert status == STATUS_OK and steps_exact > 3
    sim = _jam_cascade(alm_newton_budget=3)
    con = _con(a, b, gap, nx, ny)
    for k in range(3):
        v = vel.copy()
        _project(sim, v, mass, con)
        np.testing.assert_allclose(v, v_exact, atol=1e-6)
        assert sim.n_ipm_projections == k + 1 and sim.n_alm_newton_steps == 3 and sim.n_fallback_solves == 0
        assert sim.n_piqp_projections == 0  # the own interior point method converged


def test_misses_in_a_row_back_off_the_augmented_lagrangian():
    """Each miss in a row doubles the number of large projections that skip the augmented Lagrangian
    (alm_skip_after_miss, up to alm_skip_max); a success from zero resets it. Every projection is exact."""
    rng = np.random.default_rng(5)
    vel, mass, a, b, gap, nx, ny = _hex_jam(9, 10, rng)
    n = vel.shape[0]
    v_exact = vel.copy()
    project_gaps_alm(v_exact, mass, a, b, gap, nx, ny, H, np.zeros(a.shape[0]), 400)
    sim = _jam_cascade(alm_newton_budget=3, alm_skip_after_miss=2, alm_skip_max=8)
    con = _con(a, b, gap, nx, ny)

    def tries(count):
        out = []
        for k in range(count):
            before = sim.n_alm_newton_steps
            v = vel.copy()
            _project(sim, v, mass, con)
            np.testing.assert_allclose(v, v_exact, atol=1e-6)
            if sim.n_alm_newton_steps > before:
                out.append(k)
        return out

    assert tries(31) == [0, 2, 6, 14, 22, 30]  # skips of 2, 4, 8, then 8 (the cap)
    sim.alm_newton_budget = 400
    assert tries(10) == [7, 8, 9]  # the next try, 8 after the last, converges, and so does every one after
    sim.alm_newton_budget = 3
    assert tries(7) == [0, 2, 6]  # the success reset the back-off
    assert sim.n_fallback_solves == 0


@pytest.mark.parametrize("seed", range(4))
def test_working_set_projection_grows_to_the_exact_one(seed):
    """project_gaps_working_set from the candidates violated at v' alone: the first answer violates
    others, they join and it solves again; the end is the exact projection (within 1e-7 m/s of the
    augmented Lagrangian's v), a KKT point with zero percussion outside the final working set. From
    all candidates it solves once."""
    vel, mass, a, b, gap, nx, ny, v_exact = _jam_and_exact_projection(seed)
    violated = _residual(vel, a, b, gap, nx, ny) < 0.0
    assert 0 < violated.sum() < a.shape[0]
    v = vel.copy()
    lam, solves, status = project_gaps_working_set(v, mass, a, b, gap, nx, ny, H, violated, max_rounds=50)
    assert status == STATUS_OK and solves >= 2
    np.testing.assert_allclose(v, v_exact, atol=1e-7)
    assert _residual(v, a, b, gap, nx, ny).min() >= -1e-9 and lam.min() >= 0.0
    assert np.all(lam[violated] >= 0.0) and np.count_nonzero(lam) < a.shape[0]  # some never joined
    np.testing.assert_allclose(mass[:, None] * (v[:, :2] - vel[:, :2]), _percussion(v.shape[0], lam, a, b, nx, ny),
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
    vel, mass, a, b, gap, nx, ny, _ = _jam_and_exact_projection(0)
    violated = _residual(vel, a, b, gap, nx, ny) < 0.0
    v = vel.copy()
    _, solves, status = project_gaps_working_set(v, mass, a, b, gap, nx, ny, H, violated, max_rounds=1)
    assert status != STATUS_OK and solves == 1
    np.testing.assert_array_equal(v, vel)
    with pytest.raises(ValueError, match="working"):
        project_gaps_working_set(v, mass, a, b, gap, nx, ny, H, violated[:-1])
    for z0 in (np.zeros(a.shape[0] - 1), np.full(a.shape[0], np.nan), np.full(a.shape[0], -1.0)):
        with pytest.raises(ValueError, match="z0"):
            project_gaps_working_set(v, mass, a, b, gap, nx, ny, H, violated, z0=z0)


def test_simulator_starts_the_interior_point_method_from_the_last_active_set(monkeypatch):
    """After a large projection, the next one (same or next step) goes to the interior point method on
    the working set (last active contacts and nearly closing candidates), started from the last
    projection's percussions (matched by contact), and is still exact; two steps later it no longer
    does."""
    vel, mass, a, b, gap, nx, ny, v_exact = _jam_and_exact_projection(1)
    n = vel.shape[0]
    starts = []

    def recording(*args, z0=None, **kwargs):
        starts.append(z0)
        return project_gaps_working_set(*args, z0=z0, **kwargs)

    monkeypatch.setattr(cascade_module, "project_gaps_working_set", recording)
    sim = _jam_cascade(alm_newton_budget=3)  # the augmented Lagrangian misses
    con = _con(a, b, gap, nx, ny)
    lam_last = None
    for call, (step, uses_working_set) in enumerate([(0, False), (0, True), (1, True), (3, False)]):
        before = sim.n_working_set_solves
        v = vel.copy()
        lam = _project(sim, v, mass, con, step)
        np.testing.assert_allclose(v, v_exact, atol=1e-7)
        assert (sim.n_working_set_solves > before) == uses_working_set, call
        if uses_working_set:  # the same candidates as last time: the start is the last percussions
            np.testing.assert_array_equal(starts[-1], lam_last)
        lam_last = lam
    assert len(starts) == 2
    assert sim.n_ipm_projections == 4 and sim.n_piqp_projections == 0 and sim.n_fallback_solves == 0


def test_envelope_factor_is_the_cholesky_factor_of_the_newton_matrix():
    """The interior point method's Newton matrix M + Σ_k w_k B_kᵀ B_k, assembled by scattering weights
    into the entries _envelope_entries precomputes and factorised in envelope storage, is L Lᵀ for the
    same matrix assembled densely from the rows B_k (with wall rows and rows left out)."""
    from crowd_env.core.solvers.large_projection import (_envelope_entries, _envelope_factor, _envelope_pattern,
                                                         _projection_dofs)

    rng = np.random.default_rng(3)
    vel, mass, a, b, gap, nx, ny = _hex_jam(6, 7, rng)
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
