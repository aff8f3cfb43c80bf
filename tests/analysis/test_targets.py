"""The calibration's multi-target objective (crowd_env.analysis.targets) on constructed records. (The
presets on reduced cases of the targets: tests/experiments/test_presets.py.)"""
import numpy as np
import pytest

from crowd_env.analysis.calibration import CalibrationError
from crowd_env.analysis.experiment import seyfried_2009
from crowd_env.analysis.targets import (CAPACITY_RANGE, FAILED_POINT_OBJECTIVE, TargetWeights, band_miss,
                                        required_cases, target_error)

WIDTHS = (0.8, 0.9, 1.0, 1.1, 1.2)


def _records(js60_factor=1.0, js_small=2.0, speed=1.1, rho_in=1.6, rho_front=5.0, stat_ratio=1.0, seeds=(0, 1)):
    """Records of every required case whose seed means hit the given figures (two seeds: ±0.01 around)."""
    ref = seyfried_2009()
    out = []
    for b, n in required_cases(WIDTHS):
        if n == 60:
            js = float(ref.specific_flow_per_m_s[ref.lookup(b, 60)[0]]) * js60_factor
        else:
            js = js_small
        stat = 1.9 * (stat_ratio if n == 120 else 1.0)
        for k, s in enumerate(seeds):
            d = 0.01 * (1 if k % 2 else -1)  # seeds scatter symmetrically: the mean is the figure
            out.append({"width_m": b, "n_pedestrians": n, "seed": s, "n_evacuated": n,
                        "specific_flow_per_m_s": js + d, "stationary_specific_flow_per_m_s": stat + d,
                        "speed_inside_m_s": speed + d, "density_inside_per_m2": rho_in + d,
                        "density_front_per_m2": rho_front + d})
    return out


def test_band_miss_is_the_relative_distance_outside():
    assert np.allclose(band_miss([0.9, 1.0, 1.5, 2.0, 2.2], 1.0, 2.0), [-0.1, 0.0, 0.0, 0.0, 0.1])


def test_records_on_every_target_score_zero():
    e = target_error(_records())
    assert not e.failed and e.objective == pytest.approx(0.0, abs=1e-12)
    assert set(e.terms) == set(TargetWeights().as_dict())
    assert e.capacity_ratio[1.0] == pytest.approx(1.0)


def test_each_term_is_its_squared_relative_miss():
    assert target_error(_records(js60_factor=1.05)).terms["epsilon_60"] == pytest.approx(0.05 ** 2, rel=1e-3)
    # N = 20/40 at 1.6 against the band's low end 1.77, and N = 60 above them at most widths
    e = target_error(_records(js_small=1.6))
    assert e.terms["small_groups"] == pytest.approx((1.6 / 1.77 - 1) ** 2)
    js60 = seyfried_2009().specific_flow_per_m_s
    assert e.terms["ordering"] == pytest.approx(np.mean(np.clip(js60 / 1.6 - 1, 0, None) ** 2))
    assert target_error(_records(speed=1.5)).terms["speed_inside"] == pytest.approx((1.5 / 1.22 - 1) ** 2)
    assert target_error(_records(rho_in=1.0)).terms["density_inside"] == pytest.approx((1.0 / 1.42 - 1) ** 2)
    assert target_error(_records(rho_front=3.0)).terms["density_front"] == pytest.approx((3.0 / 4.0 - 1) ** 2)
    e = target_error(_records(stat_ratio=1.3))
    assert e.capacity_ratio[1.2] == pytest.approx(1.3, rel=1e-2)
    assert e.terms["capacity"] == pytest.approx((e.capacity_ratio[1.0] / CAPACITY_RANGE[1] - 1) ** 2, rel=0.05)
    assert e.objective == pytest.approx(sum(e.terms.values()))


def test_weights_scale_their_terms():
    e1 = target_error(_records(speed=1.5))
    e2 = target_error(_records(speed=1.5), weights=TargetWeights(speed_inside=3.0))
    assert e2.objective == pytest.approx(3.0 * e1.objective)
    with pytest.raises(CalibrationError, match="weight capacity"):
        TargetWeights(capacity=-1.0)


def test_an_incomplete_run_fails_the_point():
    recs = _records()
    recs[3] = dict(recs[3], n_evacuated=recs[3]["n_pedestrians"] - 5, stalled=True)
    e = target_error(recs)
    assert e.failed and e.n_incomplete == 1 and e.n_stalled == 1
    assert e.objective == pytest.approx(FAILED_POINT_OBJECTIVE + 1 / len(recs))
    assert e.objective > target_error(_records(js60_factor=2.0, speed=3.0)).objective


def test_missing_cases_and_figures_are_named():
    recs = [r for r in _records() if r["n_pedestrians"] != 120]
    with pytest.raises(CalibrationError, match="b = 1 m, N = 120"):
        target_error(recs)
    with pytest.raises(CalibrationError, match="no N = 60"):
        target_error([r for r in _records() if r["n_pedestrians"] != 60])
    with pytest.raises(CalibrationError, match="capacity widths"):
        required_cases((0.8, 0.9))
