"""Passages and flow (crowd_env.analysis.flow): crossing times of a measurement line, incremental and from a
recorded trajectory (crowd_env.analysis.recorder), and the specific flow (Eq. 22)."""
import numpy as np
import pytest

from crowd_env.analysis import (FlowError, MeasurementLine, PassageCounter, TrajectoryRecorder, line_crossings,
                                specific_flow, trajectory_crossings)

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
