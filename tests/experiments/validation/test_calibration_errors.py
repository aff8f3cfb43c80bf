"""The calibration's error measures (crowd_env.experiments.validation.calibration.errors): ε_J and ε_T (Kabalan Eq. 23-24), the
experiment's range check, the error of one point from per-run flows, grid axes, and the valley of minima of
the Fig. 10 surface with its exponential fit. (Runs, grids and the optimiser:
tests/experiments/validation/test_calibration.py.)"""
import numpy as np
import pytest

from crowd_env.analysis import ExperimentTable, seyfried_2009
from crowd_env.experiments.validation.calibration.errors import epsilon_j, epsilon_total, in_range_check
from crowd_env.experiments.validation.calibration.errors import (PAPER_VALLEY_FIT, CalibrationError, best_grid_point, check_grid_values,
                                            fit_exponential_valley, grid_axis, point_error, valley_of_minima)
from tests.conftest import exp_js


def test_epsilon_zero_for_experiment_and_hand_computation():
    t = seyfried_2009()
    assert epsilon_total(t.width_m, 60, t.specific_flow_per_m_s) == 0.0
    factors = np.array([1.1, 0.9, 1.0, 1.2, 1.0])
    model = t.specific_flow_per_m_s * factors
    hand = np.mean((factors - 1.0) ** 2)  # (0.01 + 0.01 + 0 + 0.04 + 0) / 5 = 0.012
    assert epsilon_total(t.width_m, 60, model) == pytest.approx(0.012, rel=1e-12)
    assert epsilon_j(t.width_m, model, 60) == pytest.approx(hand, rel=1e-12)


def test_epsilon_errors_and_other_reference():
    t = seyfried_2009()
    with pytest.raises(CalibrationError, match="b = 0.8 m, N = 20"):
        epsilon_total([0.8], [20], [1.8])  # no N = 20 point in the shipped table
    with pytest.raises(CalibrationError, match="no model run"):
        epsilon_total(t.width_m[:3], 60, t.specific_flow_per_m_s[:3])
    assert epsilon_total(t.width_m[:3], 60, t.specific_flow_per_m_s[:3], require_all_rows=False) == 0.0
    ref = ExperimentTable.from_arrays([0.8, 0.9, 0.8, 0.9], [20, 20, 40, 40], [2.0, 2.0, 1.9, 2.2])
    eps = epsilon_total([0.8, 0.9, 0.8, 0.9], [20, 20, 40, 40], [2.2, 2.0, 1.9, 1.1], reference=ref)
    assert eps == pytest.approx((0.01 + 0 + 0 + 0.25) / 4)
    assert epsilon_j([0.8, 0.9], [2.2, 2.0], 20, reference=ref) == pytest.approx(0.005)


def test_in_range_check():
    res = in_range_check([1.8, 2.0, 2.31, 1.7, 2.5])
    assert res.inside.tolist() == [True, True, True, False, False] and not res.all_inside
    assert res.max_excess_per_m_s == pytest.approx(0.19)
    assert in_range_check([1.77, 2.0]).all_inside


def test_point_error_equals_hand_computation_from_per_run_flows():
    b = np.array([0.8, 0.8, 1.0, 1.0, 1.2, 1.2, 0.8, 1.0, 1.2, 0.8])
    n = np.array([60, 60, 60, 60, 60, 60, 20, 20, 20, 40])
    js = np.array([1.5, 1.7, 2.0, np.nan, 1.9, 2.1, 2.5, 2.0, 1.5, 1.8])
    e = point_error(b, n, js, range_weight=2.0)
    # hand: mean over seeds per (b, N) (undefined J_s counts 0), then Eq. 23-24 over the N = 60 rows
    terms = [(1.6 / exp_js(0.8) - 1) ** 2, (1.0 / exp_js(1.0) - 1) ** 2, (2.0 / exp_js(1.2) - 1) ** 2]
    assert e.epsilon_total == pytest.approx(np.mean(terms), rel=1e-12)
    assert e.epsilon_by_group == {60: pytest.approx(np.mean(terms), rel=1e-12)}
    # N = 20 / 40: 2.5 above 2.31, 1.5 below 1.77, 2.0 and 1.8 inside
    penalty = np.mean([(2.5 / 2.31 - 1) ** 2, 0.0, (1.5 / 1.77 - 1) ** 2, 0.0])
    assert e.range_penalty == pytest.approx(penalty, rel=1e-12)
    assert not e.range_all_inside
    assert e.objective == pytest.approx(np.mean(terms) + 2.0 * penalty, rel=1e-12)
    assert (e.n_runs, e.n_undefined) == (10, 1)


def test_point_error_bad_input():
    with pytest.raises(CalibrationError, match="no model run has an experimental counterpart"):
        point_error([1.0], [20], [2.0])
    with pytest.raises(CalibrationError, match="equal lengths"):
        point_error([1.0, 0.8], [60], [2.0])
    with pytest.raises(CalibrationError, match="range_weight"):
        point_error([1.0], [60], [2.0], range_weight=-1)
    for b, n in [([1.0, 0.85], [60, 60]), ([1.0, 1.0], [60, 30])]:  # neither a reference value nor a known range
        with pytest.raises(CalibrationError, match="without experimental counterpart or known range"):
            point_error(b, n, [2.0, 2.0])


def test_grid_axes_like_the_paper_and_bad_grids():
    a = grid_axis(10, 1000, 20, "A")
    assert a.size == 20 and a[0] == 10 and a[-1] == 1000 and np.allclose(np.diff(a), 990 / 19)
    assert np.allclose(grid_axis(10, 1000, 3, "A", "log"), [10, 100, 1000])
    for args, msg in [((10, 1000, 0, "A"), "integer >= 1"), ((0, 1000, 4, "A"), "> 0"),
                      ((0.2, 0.01, 4, "B"), "low < high"), ((0.01, 0.2, 1, "B"), "size 1"),
                      ((-0.1, 0.2, 4, "B"), "> 0"), ((10, 100, 4, "A", "cubic"), "spacing")]:
        with pytest.raises(CalibrationError, match=msg):
            grid_axis(*args)
    for values, msg in [([], "empty"), ([10, -5], "> 0"), ([0.1, 0.05], "increasing"), ([1, 1], "increasing"),
                        ([1, np.nan], "finite")]:
        with pytest.raises(CalibrationError, match=msg):
            check_grid_values(values, "A")


def synthetic_surface(a, b, coef=1501.0, rate=-7.98):
    """ε quadratic in ln A around the paper's valley A = 1501 exp(-7.98 B), rising with B."""
    return (np.log(a)[:, None] - np.log(coef * np.exp(rate * b))[None, :]) ** 2 + 0.1 * b[None, :]


def test_valley_fit_recovers_known_coefficients_from_a_synthetic_surface():
    a = np.geomspace(20, 3000, 9)
    b = np.linspace(0.03, 0.3, 7)
    eps = synthetic_surface(a, b)
    valley = valley_of_minima(a, b, eps)
    assert not valley.at_edge.any()
    fit = fit_exponential_valley(valley.social_range_m, valley.social_strength_n)
    assert fit.coefficient_n == pytest.approx(1501.0, rel=1e-9)
    assert fit.rate_per_m == pytest.approx(-7.98, rel=1e-9)
    assert fit.residual_norm_log < 1e-9 and fit.n_points == 7
    assert np.allclose(fit(b), PAPER_VALLEY_FIT(b))
    # without sub-grid refinement the minima are grid values: the fit is only approximate
    coarse = valley_of_minima(a, b, eps, refine=False)
    assert set(coarse.social_strength_n) <= set(a)
    assert fit_exponential_valley(coarse.social_range_m, coarse.social_strength_n).rate_per_m != pytest.approx(-7.98, rel=1e-6)
    # missing points (nan) are skipped; the best point is the grid argmin
    eps[3, 2] = np.nan
    i, j = np.unravel_index(np.nanargmin(eps), eps.shape)
    assert best_grid_point(a, b, eps) == (a[i], b[j], eps[i, j])
    with pytest.raises(CalibrationError, match="shape"):
        valley_of_minima(a, b, eps.T)
    with pytest.raises(CalibrationError, match="2 distinct B"):
        fit_exponential_valley([0.1, 0.1], [100, 200])
