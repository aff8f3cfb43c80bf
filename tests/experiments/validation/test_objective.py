"""The calibration's multi-target objective (crowd_env.experiments.validation.calibration.objective) on constructed records. (The
presets on reduced cases of the targets: tests/experiments/validation/test_presets.py.)"""
import numpy as np
import pytest

from crowd_env.experiments.validation.calibration.errors import CalibrationError
from crowd_env.analysis.experiment import seyfried_2009
from crowd_env.experiments.validation.calibration.objective import (CAPACITY_RANGE, FAILED_POINT_OBJECTIVE, TargetWeights, band_miss,
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


# --- the fundamental diagram's terms (issue 36, item 4) ----------------------------------------------------

def _fd_records(corridor_shift=0.0, single_shift=0.0, corridor_speeds=None, a=0.34, b=1.08, seeds=(0, 1)):
    """Sweep records at every scored bin: the bin's speed + shift (or ``corridor_speeds``), seeds scattering
    ±0.01 around; a single file on the line d = a + b v."""
    from crowd_env.experiments.validation.calibration.objective import corridor_fd_bins, single_file_bins

    out = []
    for setup, bins, shift in (("corridor", corridor_fd_bins(), corridor_shift),
                               ("single_file", single_file_bins(), single_shift)):
        for k, (rho, v) in enumerate(bins):
            if setup == "corridor" and corridor_speeds is not None:
                v, shift = corridor_speeds[k], 0.0
            for j, s in enumerate(seeds):
                r = {"setup": setup, "density": float(rho), "seed": s, "n_pedestrians": 20, "complete": True,
                     "stalled": False, "speed_m_s": v + shift + 0.01 * (1 if j % 2 else -1)}
                if setup == "single_file":
                    speeds = np.linspace(0.1, 1.2, 12)
                    r.update(headway_samples_m=(a + b * speeds).tolist(), speed_samples_m_s=speeds.tolist())
                out.append(r)
    return out


def test_a_model_on_every_bin_scores_zero_and_bottleneck_only_leaves_the_fd_terms_unscored():
    from crowd_env.experiments.validation.calibration.objective import FD_TERMS

    e = target_error(_records() + _fd_records())
    assert not e.failed and e.unscored == () and e.objective == pytest.approx(0.0, abs=1e-12)
    assert all(e.terms[k] == pytest.approx(0.0, abs=1e-12) for k in FD_TERMS)
    assert e.figures["headway_a_m"] == pytest.approx(0.34) and e.figures["headway_b_s"] == pytest.approx(1.08)
    e = target_error(_records())
    assert e.unscored == FD_TERMS and all(e.terms[k] == 0.0 for k in FD_TERMS)
    with pytest.raises(CalibrationError, match="need runs of its sweep"):
        target_error(_records(), fd=True)
    assert target_error(_records() + _fd_records(corridor_shift=1.0), fd=False).objective == pytest.approx(0.0)
    # within the ±0.10 m/s band: no miss
    assert target_error(_records() + _fd_records(corridor_shift=0.085, single_shift=-0.085)).objective == \
        pytest.approx(0.0, abs=1e-12)


def test_a_miss_of_0_2_m_s_costs_its_squared_relative_excess():
    from crowd_env.experiments.validation.calibration.objective import corridor_fd_bins, single_file_bins

    e = target_error(_records() + _fd_records(corridor_shift=0.2, single_shift=-0.2))
    v_c, v_s = corridor_fd_bins()[:, 1], single_file_bins()[:, 1]
    assert e.terms["corridor_fd"] == pytest.approx(np.mean((0.1 / v_c) ** 2))
    assert e.terms["single_file"] == pytest.approx(np.mean((0.1 / v_s) ** 2))
    assert e.terms["corridor_monotone"] == pytest.approx(0.0, abs=1e-12)  # the shifted bins still fall
    assert e.objective == pytest.approx(e.terms["corridor_fd"] + e.terms["single_file"])
    w = TargetWeights(corridor_fd=2.0, single_file=0.0)
    assert target_error(_records() + _fd_records(corridor_shift=0.2, single_shift=-0.2), weights=w).objective == \
        pytest.approx(2.0 * e.terms["corridor_fd"])


def test_speed_rising_with_density_is_penalised():
    from crowd_env.experiments.validation.calibration.objective import corridor_fd_bins

    bins = corridor_fd_bins()
    speeds = bins[:, 1].copy()
    speeds[-2] -= 0.09  # 3.101 /m²: 0.245 and 3.364 /m²: 0.423, both inside the band, rising by 0.178
    speeds[-1] += 0.09
    e = target_error(_records() + _fd_records(corridor_speeds=speeds))
    rise = speeds[-1] - speeds[-2]
    assert e.terms["corridor_fd"] == pytest.approx(0.0, abs=1e-12)
    assert e.terms["corridor_monotone"] == pytest.approx((rise / bins[-1, 1]) ** 2 / (len(bins) - 1))
    assert e.objective == pytest.approx(e.terms["corridor_monotone"])


def test_a_headway_fit_outside_its_band_is_penalised():
    from crowd_env.experiments.validation.calibration.objective import HEADWAY_A_RANGE_M, HEADWAY_B_RANGE_S, UNDEFINED_FIT_MISS

    e = target_error(_records() + _fd_records(a=0.5, b=1.5))
    expected = 0.5 * ((0.5 / HEADWAY_A_RANGE_M[1] - 1) ** 2 + (1.5 / HEADWAY_B_RANGE_S[1] - 1) ** 2)
    assert e.terms["headway_fit"] == pytest.approx(expected)
    assert target_error(_records() + _fd_records(a=0.2, b=1.0)).terms["headway_fit"] == \
        pytest.approx(0.5 * (0.2 / 0.28 - 1) ** 2)
    assert target_error(_records() + _fd_records(a=0.30, b=1.2)).terms["headway_fit"] == 0.0  # inside both bands
    standing = _fd_records()
    for r in standing:
        if r["setup"] == "single_file":
            r["speed_samples_m_s"] = [0.0] * len(r["speed_samples_m_s"])  # nobody moves: no fit
    assert target_error(_records() + standing).terms["headway_fit"] == pytest.approx(UNDEFINED_FIT_MISS ** 2)


def test_a_stalled_bottleneck_run_still_fails_the_point_and_sweep_errors_are_named():
    recs = _records()
    recs[3] = dict(recs[3], n_evacuated=recs[3]["n_pedestrians"] - 5, stalled=True)
    fd = _fd_records()
    e = target_error(recs + fd)
    assert e.failed and e.n_incomplete == 1 and e.objective == pytest.approx(FAILED_POINT_OBJECTIVE + 1 / len(recs + fd))
    with pytest.raises(CalibrationError, match="no shipped bin"):
        target_error(_records() + [dict(fd[0], density=1.0)] + fd[1:])
    with pytest.raises(CalibrationError, match="every set-up"):
        target_error(_records() + [r for r in fd if r["setup"] == "corridor"])
    with pytest.raises(CalibrationError, match="headway samples"):
        target_error(_records() + [{k: v for k, v in r.items() if k != "headway_samples_m"} for r in fd])
    with pytest.raises(CalibrationError, match="no bottleneck run"):
        target_error(fd)


# --- the fundamental diagram's rows of the acceptance table (crowd-calibrate targets --fd) ------------------

def test_fd_table_passes_the_experiments_own_bins_with_target_tables_keys():
    from crowd_env.experiments.validation.calibration.objective import fd_table, target_table

    rows = fd_table(_records() + _fd_records())
    bottleneck = target_table([dict(r, min_gap_m=0.0) for r in _records()])
    assert [list(r) for r in rows] == [list(bottleneck[0])] * 5  # target_table's keys, in its order
    assert all(r["passed"] for r in rows), rows
    by = {r["target"]: r for r in rows}
    assert by["corridor 1.8 m: speed at the bins 0.394-3.364 /m²"]["figure"].startswith("13 of 13,")
    assert by["corridor 1.8 m: peak of the specific flow ρ·v"]["figure"] == "1.61 1/(m s) at 1.629 /m²"
    # the bins' own rise (0.011 m/s from 0.394 to 0.628 /m²) is allowed, as in corridor_monotone
    assert by["corridor 1.8 m: speed never rising with density"]["figure"] == "+0.011 m/s at 0.394-0.628 /m²"
    assert by["single file: speed at the bins 0.658-1.847 /m"]["figure"].startswith("6 of 6,")
    assert by["single file: headway d = a + b v"]["figure"] == "a = 0.34 m, b = 1.08 s"
    # within the ±0.10 m/s band everywhere: still every row passed
    assert all(r["passed"] for r in fd_table(_records() + _fd_records(corridor_shift=0.085, single_shift=-0.085)))
    with pytest.raises(CalibrationError, match="every set-up"):
        fd_table(_records())


def test_fd_table_names_a_bin_off_by_0_2_m_s_a_rise_and_a_peak_outside_its_band():
    from crowd_env.experiments.validation.calibration.objective import corridor_fd_bins, fd_table

    bins = corridor_fd_bins()
    off = bins[:, 1].copy()
    off[5] -= 0.2  # 1.629 /m²
    speed_row = fd_table(_records() + _fd_records(corridor_speeds=off))[0]
    assert not speed_row["passed"] and speed_row["figure"] == "12 of 13, worst -0.20 m/s at 1.629 /m²"
    single = fd_table(_records() + _fd_records(single_shift=0.2))[3]
    assert not single["passed"] and single["figure"].startswith("0 of 6, worst +0.20 m/s at ")
    rising = bins[:, 1].copy()
    rising[-2] -= 0.09  # inside the speed band, but 3.101 -> 3.364 /m² now rises by 0.178 m/s
    rising[-1] += 0.09
    rows = fd_table(_records() + _fd_records(corridor_speeds=rising))
    assert rows[0]["passed"] and not rows[2]["passed"]
    assert rows[2]["figure"] == "+0.178 m/s at 3.101-3.364 /m²"
    # the peak moved to 2.105 /m² (outside 1.4-2.0), every speed still within ±0.10 m/s and falling
    peak = bins[:, 1].copy()
    peak[4:7] -= 0.09  # 1.375, 1.629, 1.873 /m²
    peak[7] += 0.09  # 2.105 /m²: 0.724 m/s, 1.52 1/(m s)
    rows = fd_table(_records() + _fd_records(corridor_speeds=peak))
    assert rows[0]["passed"] and rows[2]["passed"] and not rows[1]["passed"]
    assert rows[1]["figure"] == f"{2.105 * (0.634 + 0.09):.2f} 1/(m s) at 2.105 /m²"


def test_fd_table_gives_back_the_single_files_headway_line_or_says_why_there_is_none():
    from crowd_env.experiments.validation.calibration.objective import fd_table

    row = fd_table(_records() + _fd_records(a=0.30, b=1.2))[4]
    assert row["passed"] and row["figure"] == "a = 0.30 m, b = 1.20 s"
    row = fd_table(_records() + _fd_records(a=0.5, b=1.5))[4]
    assert not row["passed"] and row["figure"] == "a = 0.50 m, b = 1.50 s"
    standing = _fd_records()
    for r in standing:
        if r["setup"] == "single_file":
            r["speed_samples_m_s"] = [0.0] * len(r["speed_samples_m_s"])
    row = fd_table(_records() + standing)[4]
    assert not row["passed"] and row["figure"] == "no fit: 0 sample(s) above 0.05 m/s"
