"""The solver cascade (crowd_env.core.solvers.cascade.SolverCascade) on degenerate jammed packings too large
for the dense projection: the large solvers see only the touched pedestrians, a re-detection's projection
starts from the first multipliers, a slow augmented Lagrangian hands over to the interior point method and
backs off, and the interior point method starts from the last active set. (The cascade's choices on small
problems: tests/core/test_cascade.py.)"""
import numpy as np

from crowd_env.core.solvers import cascade as cascade_module
from crowd_env.core.solvers.cascade import SolverCascade
from crowd_env.core.solvers.graph import contact_keys
from crowd_env.core.solvers.large_projection import project_gaps_alm, project_gaps_working_set
from crowd_env.core.solvers.status import STATUS_OK
from tests.core.conftest import H, hex_jam, jam_and_exact_projection


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
    keys = contact_keys(con["a"], con["b"], con["wall"], np.zeros_like(con["a"]), v.shape[0], 4)
    return cascade.project(v, mass, con, H, step, keys, lam_warm)


def test_simulator_large_projection_sees_only_the_touched_pedestrians():
    """SolverCascade.project hands a too-large projection to the large solvers restricted to the
    pedestrians some candidate touches: the jam's velocities equal the solver's on the jam alone, and
    the 40 pedestrians no candidate touches (numbered before, between and after the jam's) keep
    their velocities exactly."""
    rng = np.random.default_rng(7)
    vel, mass, a, b, gap, nx, ny = hex_jam(9, 10, rng)
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
    vel, mass, a, b, gap, nx, ny = hex_jam(8, 10, rng)
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


def test_simulator_hands_a_slow_augmented_lagrangian_to_the_interior_point_method():
    """A large projection whose augmented Lagrangian misses its Newton budget goes to the interior point
    method (same v to 1e-6 m/s); the next nine large projections skip the augmented Lagrangian."""
    rng = np.random.default_rng(5)
    vel, mass, a, b, gap, nx, ny = hex_jam(9, 10, rng)
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
    vel, mass, a, b, gap, nx, ny = hex_jam(9, 10, rng)
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


def test_simulator_starts_the_interior_point_method_from_the_last_active_set(monkeypatch):
    """After a large projection, the next one (same or next step) goes to the interior point method on
    the working set (last active contacts and nearly closing candidates), started from the last
    projection's percussions (matched by contact), and is still exact; two steps later it no longer
    does."""
    vel, mass, a, b, gap, nx, ny, v_exact = jam_and_exact_projection(1)
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
