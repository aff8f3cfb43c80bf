"""Analysis: passages and specific flow (Eq. 22), density, lanes, calibration errors (Eq. 23-24)."""
import numpy as np
import pytest

from crowd_env.analysis import (PUBLISHED_SPECIFIC_FLOW_N60_PER_M_S, RESIDUAL_NORM_BY_GROUP, CalibrationError,
                                ExperimentTable, FlowError, MeasurementLine, PassageCounter, TrajectoryRecorder,
                                density_in_area, density_time_series, detect_lanes, epsilon_j, epsilon_total,
                                in_range_check, lateral_histogram, line_crossings, linear_fit,
                                linear_fit_residual_norm, seyfried_2009, specific_flow, stationary_mean,
                                trajectory_crossings)


# --- passages -----------------------------------------------------------------------------------------

def _linear_walkers():
    """Straight constant-velocity walkers; line x = 2 for y in [-1, 1], counted towards +x."""
    x0 = np.array([[0.0, 0.0], [1.0, 0.5], [0.3, -0.9], [0.0, 1.5], [3.0, 0.0], [1.9, 0.2]])
    vel = np.array([[1.3, 0.0], [0.7, 0.1], [1.1, 0.05], [1.0, 0.0], [-1.0, 0.0], [0.0, 0.0]])
    # Expected: 0, 1, 2 cross; 3 passes outside the segment; 4 crosses backwards; 5 stands still.
    t_cross = {k: (2.0 - x0[k, 0]) / vel[k, 0] for k in (0, 1, 2)}
    return x0, vel, t_cross


def test_crossing_time_exact_for_linear_motion():
    x0, vel, t_cross = _linear_walkers()
    line = MeasurementLine((2.0, -1.0), (2.0, 1.0))
    np.testing.assert_allclose(line.normal, [1.0, 0.0])
    counter = PassageCounter(line)
    dt, ids = 0.1, np.arange(100, 106)
    for step in range(40):
        t0, t1 = step * dt, (step + 1) * dt
        counter.update(x0 + vel * t0, x0 + vel * t1, t0, t1, ids)
    got = dict(zip(counter.ids.tolist(), counter.times_s.tolist()))
    assert sorted(got) == [100, 101, 102]
    for k, t in t_cross.items():
        assert got[100 + k] == pytest.approx(t, abs=1e-12)


def test_crossing_direction_and_single_step():
    line = MeasurementLine((0.0, 0.0), (0.0, 2.0), direction=(-1.0, 0.0))  # count towards -x
    who, t = line_crossings([[1.0, 1.0], [-1.0, 1.0]], [[-1.0, 1.0], [1.0, 1.0]], 2.0, 3.0, line)
    assert who.tolist() == [0] and t[0] == pytest.approx(2.5)
    with pytest.raises(FlowError, match="parallel"):
        MeasurementLine((0.0, 0.0), (0.0, 2.0), direction=(0.0, 1.0))
    with pytest.raises(FlowError, match="zero length"):
        MeasurementLine((1.0, 1.0), (1.0, 1.0))


def test_batch_crossings_match_incremental_on_recorded_trajectory():
    x0, vel, t_cross = _linear_walkers()
    rec = TrajectoryRecorder(chunk_rows=7)  # many chunk boundaries
    dt = 0.1
    active = np.ones(6, dtype=bool)
    for step in range(41):
        active[4] = step < 20  # pedestrian 4 leaves halfway
        rec.record(step * dt, x0 + vel * step * dt, heading_rad=np.zeros(6), active=active, ids=np.arange(6) + 10)
    arr = rec.to_arrays()
    assert arr["x"].shape[0] == 6 * 41 - 21 and rec.n_frames == 41
    assert set(arr) >= {"frame", "id", "x", "y", "heading"}
    who, t = trajectory_crossings(arr["frame"], arr["id"], arr["x"], arr["y"], rec.frame_time_s,
                                  MeasurementLine((2.0, -1.0), (2.0, 1.0)))
    want = sorted((tc, 10 + k) for k, tc in t_cross.items())
    assert who.tolist() == [k for _, k in want]
    np.testing.assert_allclose(t, [tc for tc, _ in want], atol=1e-12)
    full = rec.to_arrays(active_only=False)
    assert full["x"].shape[0] == 6 * 41 and not full["active"].all()


def test_specific_flow_formula():
    times = np.linspace(3.0, 13.0, 21)
    res = specific_flow(times[::-1], width_m=0.8)
    assert res.n == 21 and res.dt_s == pytest.approx(10.0)
    assert res.flow_per_s == pytest.approx(21 / 10.0)  # N / Δt, not (N - 1) / Δt
    assert res.specific_flow_per_m_s == pytest.approx(21 / 10.0 / 0.8)
    assert specific_flow(times, 1.0, n=60).flow_per_s == pytest.approx(6.0)
    with pytest.raises(FlowError):
        specific_flow([1.0], 1.0)


def test_shipped_table_and_residual_norms():
    t = seyfried_2009()
    assert "Seyfried" in t.source and len(t) == 5 and set(t.n_pedestrians.tolist()) == {60}
    np.testing.assert_allclose(t.flow_per_s, 60 / t.dt_s, rtol=1e-8)
    np.testing.assert_allclose(t.specific_flow_per_m_s, t.flow_per_s / t.width_m, rtol=1e-8)
    np.testing.assert_allclose(np.round(t.specific_flow_per_m_s, 2), PUBLISHED_SPECIFIC_FLOW_N60_PER_M_S, atol=1e-9)
    # Kabalan Table 3 (0.098) is reproduced by J = b * (published two-decimal J_s): 0.0978.
    published_flow = t.width_m * np.asarray(PUBLISHED_SPECIFIC_FLOW_N60_PER_M_S)
    assert linear_fit_residual_norm(t.width_m, published_flow) == pytest.approx(0.0978, abs=1e-3)
    assert linear_fit_residual_norm(t.width_m, published_flow) == pytest.approx(RESIDUAL_NORM_BY_GROUP[60], abs=1e-3)
    # The full-precision flows N / Δt give 0.0997 (still within 2e-3 of Table 3).
    fit = linear_fit(t.width_m, t.flow_per_s)
    assert fit.residual_norm == pytest.approx(0.0997, abs=1e-3)
    assert fit.slope == pytest.approx(2.60, abs=0.01)


# --- density ------------------------------------------------------------------------------------------

def test_density_on_grid():
    g = np.arange(0.25, 4.0, 0.5)  # 8 x 8 grid, no point on the box boundary
    xx, yy = np.meshgrid(g, g)
    pts = np.c_[xx.ravel(), yy.ravel()]
    box = (1.0, 1.0, 3.0, 3.0)  # 4 x 4 points inside, area 4 m²
    assert density_in_area(pts, box) == pytest.approx(16 / 4.0)
    frame = np.r_[np.zeros(64, int), np.ones(64, int)]
    x = np.r_[pts[:, 0], pts[:, 0] + 10.0]
    y = np.r_[pts[:, 1], pts[:, 1]]
    rho = density_time_series(frame, x, y, [[1, 1], [3, 1], [3, 3], [1, 3]], n_frames=3)
    np.testing.assert_allclose(rho, [4.0, 0.0, 0.0])


def test_stationary_mean():
    t = np.arange(0.0, 100.0, 1.0)
    v = np.zeros_like(t)
    v[10:90] = 2.0
    v[10:20] = np.linspace(0, 2, 10)  # filling transient
    assert stationary_mean(v, t) == pytest.approx(2.0)
    assert stationary_mean(v, t, t_start_s=20.0, t_end_s=80.0) == pytest.approx(2.0)


# --- lanes --------------------------------------------------------------------------------------------

def _channel_samples(rng, centres, n=20000, half_width=0.4):
    y = rng.normal(rng.choice(centres, n), 0.06)
    y = y[np.abs(y) < half_width]
    return rng.uniform(0.0, 2.8, y.size), y


@pytest.mark.parametrize("centres,expected", [((0.0,), 1), ((-0.2, 0.2), 2), ((-0.35, 0.15), 2)])
def test_lanes_unimodal_vs_bimodal(centres, expected):
    rng = np.random.default_rng(7)
    x, y = _channel_samples(rng, centres)
    hist = lateral_histogram(x, y, (0.0, -0.4, 2.8, 0.4))
    assert hist.centers_m.size == 80 and np.diff(hist.centers_m) == pytest.approx(0.01)
    assert hist.probability.sum() == pytest.approx(1.0)
    lanes = detect_lanes(hist.centers_m, hist.probability)
    assert lanes.n_lanes == expected
    np.testing.assert_allclose(lanes.peak_positions_m, centres, atol=0.03)


# --- calibration --------------------------------------------------------------------------------------

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


def test_force_balance_jam_density():
    """Eq. 14 at rest = Eq. 16 head on: d = 2r + B ln(Aτ/(m‖u_d‖)); hexagonal packing 2/(√3 d²)."""
    from crowd_env.analysis import DensityError, force_balance_jam_density_per_m2, hexagonal_density_per_m2

    assert hexagonal_density_per_m2(0.46) == pytest.approx(5.4570, abs=1e-4)  # densest packing, r = 0.23 m
    assert hexagonal_density_per_m2(1.0) == pytest.approx(2.0 / np.sqrt(3.0))
    d = 0.46 + 0.08 * np.log(790.0 * 0.5 / (83.0 * 1.34))
    assert force_balance_jam_density_per_m2(790.0, 0.08) == pytest.approx(2.0 / (np.sqrt(3.0) * d * d), rel=1e-12)
    assert force_balance_jam_density_per_m2(790.0, 0.08) == pytest.approx(3.66, abs=0.01)
    assert force_balance_jam_density_per_m2(1150.0, 0.2) == pytest.approx(1.86, abs=0.01)
    # repulsion at contact weaker than the drive (A < m‖u_d‖/τ = 222 N): the jam packs the disks
    assert force_balance_jam_density_per_m2(100.0, 0.08) == pytest.approx(hexagonal_density_per_m2(0.46))
    # broadcasting over A and B; density falls as A or B grows
    rho = force_balance_jam_density_per_m2(np.array([400.0, 790.0, 1500.0]), 0.08)
    assert rho.shape == (3,) and np.all(np.diff(rho) < 0)
    for bad in ((0.0, 0.08), (790.0, np.nan), (790.0, -0.1)):
        with pytest.raises(DensityError, match="must be finite and > 0"):
            force_balance_jam_density_per_m2(*bad)
    with pytest.raises(DensityError, match="spacing_m"):
        hexagonal_density_per_m2(0.0)
