"""The solver cascade (crowd_env.core.solvers.cascade) on its own: which method it picks for a small and
a too-large problem, the back-off of the augmented Lagrangian after misses, missing optional solvers,
the impact path and its counters."""
import numpy as np
import pytest

from crowd_env.core.solvers import cascade as cascade_module
from crowd_env.core.solvers.cascade import SolverCascade
from crowd_env.core.solvers.dense_projection import PROJECTION_TOL_M_S, project_gaps
from crowd_env.core.solvers.graph import contact_keys, gap_residuals
from crowd_env.core.solvers.impact import solve_rows
from crowd_env.core.solvers.reference import random_cluster
from crowd_env.core.solvers.status import STATUS_MAX_ITER, STATUS_OK
from crowd_env.errors import SimulationError

H = 0.01


def _chain(n, gap_m=1e-3, speed_m_s=1.0):
    """n disks (r = 0.25 m, 80 kg) on the x axis ``gap_m`` apart, the left half walking right and the
    right half left at ``speed_m_s``: every neighbour pair a candidate (normal from b = i to a = i + 1),
    all closing within the step. Returns (vel (n, 3), mass, con)."""
    vel = np.zeros((n, 3))
    vel[:, 0] = np.where(np.arange(n) < n / 2, speed_m_s, -speed_m_s)
    con = {"a": np.arange(1, n, dtype=np.int64), "b": np.arange(n - 1, dtype=np.int64),
           "wall": np.full(n - 1, -1, np.int64), "gap": np.full(n - 1, gap_m), "nx": np.ones(n - 1),
           "ny": np.zeros(n - 1)}
    return vel, np.full(n, 80.0), con


def _keys(vel, con):
    return contact_keys(con["a"], con["b"], con["wall"], np.zeros_like(con["a"]), vel.shape[0], 1)


def _dense(vel, mass, con):
    """The exact projection by the dense solver with no size limit."""
    v = vel.copy()
    lam, _, status = project_gaps(v, mass, con["a"], con["b"], con["gap"], con["nx"], con["ny"], H,
                                  PROJECTION_TOL_M_S, 10_000)
    assert status == STATUS_OK
    return v, lam


def test_small_projection_stays_dense_and_needs_no_keys():
    vel, mass, con = _chain(8)
    v_exact, lam_exact = _dense(vel, mass, con)
    cascade = SolverCascade()
    calls = []
    v = vel.copy()
    lam = cascade.project(v, mass, con, H, 0, lambda: calls.append(1) or _keys(vel, con))
    assert np.array_equal(v, v_exact) and np.array_equal(lam, lam_exact)  # the same dense solve, bit for bit
    assert cascade.n_sparse_solves == 0 and calls == []  # keys are only asked for by a large projection
    assert cascade.dense_only(0) and cascade.dense_only(1)


def test_too_large_projection_goes_large_and_keeps_the_next_step_off_the_dense_path():
    vel, mass, con = _chain(8)
    v_exact, _ = _dense(vel, mass, con)
    cascade = SolverCascade(max_dense_projection_rows=2)
    calls = []
    v = vel.copy()
    lam = cascade.project(v, mass, con, H, 5, lambda: calls.append(1) or _keys(vel, con))
    np.testing.assert_allclose(v, v_exact, atol=1e-9)
    assert gap_residuals(v, con["gap"] / H, con["a"], con["b"], con["nx"], con["ny"]).min() >= -1e-9
    assert lam.min() >= 0.0 and calls == [1]
    assert cascade.n_sparse_solves == 1 and cascade.n_alm_newton_steps > 0 and cascade.n_fallback_solves == 0
    # this step and the next skip the dense path (the fused step waits too), the one after may use it
    assert not cascade.dense_only(5) and not cascade.dense_only(6) and cascade.dense_only(7)
    small_vel, small_mass, small_con = _chain(2)
    cascade.project(small_vel.copy(), small_mass, small_con, H, 6, _keys(small_vel, small_con))
    assert cascade.n_sparse_solves == 2  # even one contact goes the large way right after a large projection
    cascade.project(small_vel.copy(), small_mass, small_con, H, 8, _keys(small_vel, small_con))
    assert cascade.n_sparse_solves == 2


def _count_tries(cascade, counter, count, step, vel, mass, con, v_exact):
    """Run ``count`` large projections of the chain (10 steps apart: no working set from an earlier one),
    each exact; return those (0-based) in which ``cascade.<counter>`` rose, i.e. the method was tried."""
    out = []
    for k in range(count):
        before = getattr(cascade, counter)
        v = vel.copy()
        step[0] += 10
        cascade.project(v, mass, con, H, step[0], _keys(vel, con))
        np.testing.assert_allclose(v, v_exact, atol=1e-8)
        if getattr(cascade, counter) > before:
            out.append(k)
    return out


def test_augmented_lagrangian_backs_off_after_misses_and_resets_after_a_success(monkeypatch):
    """A miss from zero (forced here) has the augmented Lagrangian tried again alm_skip_after_miss large
    projections later, twice as many after each further miss, up to alm_skip_max; the interior point method
    serves those between, exactly. A success from zero resets the back-off."""
    vel, mass, con = _chain(10)
    v_exact, _ = _dense(vel, mass, con)
    real_alm = cascade_module.project_gaps_alm
    fail = [True]

    def alm(*args):
        if fail[0]:
            return np.zeros(con["a"].shape[0]), 1, STATUS_MAX_ITER
        return real_alm(*args)

    monkeypatch.setattr(cascade_module, "project_gaps_alm", alm)
    cascade = SolverCascade(max_dense_projection_rows=2, alm_skip_after_miss=2, alm_skip_max=4)
    step = [0]

    def tries(count):
        return _count_tries(cascade, "n_alm_newton_steps", count, step, vel, mass, con, v_exact)

    assert tries(11) == [0, 2, 6, 10]  # tried again 2, then 4 (the cap) projections later
    assert cascade.n_ipm_projections == 11 and cascade.n_working_set_solves == 0
    fail[0] = False
    assert tries(6) == [3, 4, 5]  # the next try converges, and so does every one after
    fail[0] = True
    assert tries(4) == [0, 2]  # the success reset the back-off
    assert cascade.n_piqp_projections == 0 and cascade.n_fallback_solves == 0


def _interior_point_fails(monkeypatch):
    monkeypatch.setattr(cascade_module, "project_gaps_interior_point",
                        lambda vel, mass, c_a, *args, **kwargs: (np.zeros(c_a.shape[0]), 60, STATUS_MAX_ITER))


def test_interior_point_backs_off_to_piqp_after_misses_and_resets_after_a_success(monkeypatch):
    """With PIQP installed, a miss of the interior point method (forced here) has it tried first again
    ipm_skip_after_miss large projections later (PIQP first in between), twice as many after each further
    miss, up to ipm_skip_max, as the augmented Lagrangian's back-off; a success resets it. Every
    projection stays exact; nothing reaches the last resorts."""
    pytest.importorskip("piqp")
    vel, mass, con = _chain(10)
    v_exact, _ = _dense(vel, mass, con)
    real_ipm = cascade_module.project_gaps_interior_point
    fail = [True]

    def ipm(vel, mass, c_a, *args, **kwargs):
        if fail[0]:
            return np.zeros(c_a.shape[0]), 60, STATUS_MAX_ITER
        return real_ipm(vel, mass, c_a, *args, **kwargs)

    monkeypatch.setattr(cascade_module, "project_gaps_interior_point", ipm)
    cascade = SolverCascade(max_dense_projection_rows=2, alm_newton_budget=0, ipm_skip_after_miss=2,
                            ipm_skip_max=4)
    step = [0]

    def tries(count):
        return _count_tries(cascade, "n_ipm_projections", count, step, vel, mass, con, v_exact)

    assert tries(11) == [0, 2, 6, 10]  # tried again 2, then 4 (the cap) projections later, as the ALM is
    assert cascade.n_piqp_projections == 11 and cascade.n_fallback_solves == 0
    fail[0] = False
    assert tries(6) == [3, 4, 5]  # the back-off runs out, the next try converges, and so does every one after
    assert cascade.n_piqp_projections == 11 + 3
    fail[0] = True
    assert tries(4) == [0, 2]  # the success reset the back-off to 2
    assert cascade.n_fallback_solves == 0


def test_piqp_miss_while_the_interior_point_method_is_skipped_tries_it_before_the_last_resorts(monkeypatch):
    pytest.importorskip("piqp")
    vel, mass, con = _chain(10)
    v_exact, _ = _dense(vel, mass, con)
    cascade = SolverCascade(max_dense_projection_rows=2, alm_newton_budget=0)
    cascade._skip_ipm = 3  # as after a miss
    monkeypatch.setattr(cascade_module, "project_gaps_ipm", lambda vel, mass, c_a, *args: (np.zeros(c_a.shape[0]), False))
    v = vel.copy()
    cascade.project(v, mass, con, H, 0, _keys(vel, con))
    np.testing.assert_allclose(v, v_exact, atol=1e-8)
    assert cascade.n_piqp_projections == 1 and cascade.n_ipm_projections == 1 and cascade.n_fallback_solves == 0
    assert cascade._skip_ipm == 2


def test_a_cascade_pickled_before_the_interior_point_back_off_existed_loads_with_its_defaults():
    """Checkpoints of long runs pickle the cascade; one written by an earlier version lacks the back-off."""
    import pickle

    old = SolverCascade()
    for name in ("ipm_skip_after_miss", "ipm_skip_max", "_skip_ipm", "_ipm_backoff"):
        del old.__dict__[name]
    old.n_piqp_projections = 616
    back = pickle.loads(pickle.dumps(old))
    assert (back.ipm_skip_after_miss, back.ipm_skip_max, back._skip_ipm, back._ipm_backoff) == (
        cascade_module.IPM_SKIP_AFTER_MISS, cascade_module.IPM_SKIP_MAX, 0, cascade_module.IPM_SKIP_AFTER_MISS)
    assert back.n_piqp_projections == 616
    custom = pickle.loads(pickle.dumps(SolverCascade(ipm_skip_max=7)))
    assert custom.ipm_skip_max == 7  # what was pickled wins over the defaults


def test_missing_piqp_is_skipped_and_counted_and_the_answer_stays_exact(monkeypatch):
    vel, mass, con = _chain(8)
    v_exact, _ = _dense(vel, mass, con)
    _interior_point_fails(monkeypatch)
    for solvers, skipped, piqp in (({"piqp", "clarabel"}, 0, 1), ({"clarabel"}, 1, 0), ((), 1, 0)):
        cascade = SolverCascade(max_dense_projection_rows=2, alm_newton_budget=0, external_solvers=solvers)
        v = vel.copy()
        cascade.project(v, mass, con, H, 0, _keys(vel, con))
        np.testing.assert_allclose(v, v_exact, atol=1e-8)
        assert cascade.n_skipped_solvers == skipped and cascade.n_piqp_projections == piqp, solvers
        assert cascade.n_fallback_solves == 1 - piqp  # PIQP converges here; without it the last resorts serve


def test_missing_clarabel_where_it_is_the_last_method_raises(monkeypatch):
    """Where sparse pivoting cannot certify a projection or an impact and Clarabel is not available, the
    cascade raises SimulationError naming it, and leaves the velocities alone."""
    vel, mass, con = _chain(8)
    _interior_point_fails(monkeypatch)
    monkeypatch.setattr(cascade_module, "project_gaps_sparse",
                        lambda vel, mass, c_a, *args, **kwargs: (np.zeros(c_a.shape[0]), STATUS_MAX_ITER))
    cascade = SolverCascade(max_dense_projection_rows=2, alm_newton_budget=0, external_solvers=())
    v = vel.copy()
    with pytest.raises(SimulationError, match="Clarabel"):
        cascade.project(v, mass, con, H, 0, _keys(vel, con))
    assert np.array_equal(v, vel)
    cl = random_cluster(6, np.random.default_rng(0))
    monkeypatch.setattr(cascade_module, "solve_rows_sparse",
                        lambda mass_diag, *rows: (None, None, STATUS_MAX_ITER))
    with pytest.raises(SimulationError, match="Clarabel"):
        cascade.solve_impact_cluster(cl["mass_diag"], *cl["rows"], cl["v_minus"], np.zeros_like(cl["v_minus"]))
    # with Clarabel it takes over
    with_clarabel = SolverCascade(external_solvers={"clarabel"})
    v_qp, _ = with_clarabel.solve_impact_cluster(cl["mass_diag"], *cl["rows"], cl["v_minus"],
                                                 np.zeros_like(cl["v_minus"]))
    v_dense, _, status = solve_rows(cl["mass_diag"], *cl["rows"], cl["v_minus"], np.zeros_like(cl["v_minus"]))
    assert status == STATUS_OK
    np.testing.assert_allclose(v_qp, v_dense, atol=1e-5)
    assert with_clarabel.n_sparse_solves == 1 and with_clarabel.n_fallback_solves == 1


def test_impact_clusters_by_sparse_pivoting_or_the_reference():
    cl = random_cluster(10, np.random.default_rng(1))
    args = (cl["mass_diag"], *cl["rows"], cl["v_minus"], np.zeros_like(cl["v_minus"]))
    v_dense, _, status = solve_rows(*args)
    assert status == STATUS_OK
    cascade = SolverCascade(max_dense_rows=3, max_dense_bodies=2)
    assert cascade.impact_limits() == (3, 2) and cascade.dense_only(0)
    v_sparse, _ = cascade.solve_impact_cluster(*args)
    np.testing.assert_allclose(v_sparse, v_dense, atol=1e-9)
    assert cascade.n_sparse_solves == 1 and cascade.n_fallback_solves == 0
    reference = SolverCascade(reference=True)
    assert reference.impact_limits() == (-1, reference.max_dense_bodies)  # every cluster to the reference
    assert not reference.dense_only(0)  # so no step may run the dense solvers alone
    v_ref, _ = reference.solve_impact_cluster(*args)
    np.testing.assert_allclose(v_ref, v_dense, atol=1e-5)
    assert reference.n_sparse_solves == 0 and reference.n_fallback_solves == 0
