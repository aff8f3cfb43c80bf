"""Frames at a rate that is no whole number of steps (16 frames/s from h = 0.01 s, as the Jülich recordings): the
resampling recorder interpolates between the steps around each frame time; a recorded run agrees with one recorded
at every step, interpolated independently."""
from __future__ import annotations

import numpy as np
import pytest

from crowd_env.analysis.recorder import ResampledRecorder
from crowd_env.walking.presets import get_preset
from crowd_env.errors import RecorderError
from crowd_env.experiments.running.recording import record_run
from crowd_env.scenarios import make_scenario
from crowd_env.walking.agent import SocialForceAgent


def test_frames_fall_on_their_times_interpolated_between_calls():
    rec = ResampledRecorder(16.0)
    velocity = np.array([[1.0, -0.5], [0.0, 2.0]])
    for k in range(101):  # every 0.01 s for 1 s
        t = 0.01 * k
        active = np.array([True, t < 0.5])  # the second leaves within the step ending at 0.50 s
        rec.record(t, velocity * t, heading_rad=np.array([3.1 + t, -3.1 - t]), active=active)
    times = rec.frame_time_s
    np.testing.assert_allclose(times, np.arange(17) / 16.0, atol=1e-12)
    a = rec.to_arrays()
    first = a["id"] == 0
    np.testing.assert_allclose(np.column_stack([a["x"], a["y"]])[first], velocity[0] * times[:, None], atol=1e-12)
    # the heading crosses ±π the shorter way: 3.1 + t, wrapped
    np.testing.assert_allclose(np.angle(np.exp(1j * a["heading"][first])), np.angle(np.exp(1j * (3.1 + times))),
                               atol=1e-12)
    # the second is in every frame up to 0.4375 s (active at both steps around it), in none after
    assert a["time"][a["id"] == 1].max() == pytest.approx(0.4375)
    with pytest.raises(RecorderError, match="non-decreasing"):
        rec.record(0.5, velocity)
    with pytest.raises(RecorderError, match="frame_rate_per_s"):
        ResampledRecorder(0.0)


def test_a_run_recorded_at_16_per_s_is_the_run_recorded_at_every_step_interpolated():
    sc = make_scenario("juelich_corridor", entrance_width_m=1.0, exit_width_m=1.8, n_pedestrians=30, seed=0)
    params = get_preset("calibrated").params()
    r16, t16 = record_run(sc, SocialForceAgent(sc.navigation()), params, frame_rate_per_s=16.0, max_time_s=3.0,
                          line="exit", density_areas=(), lane_area=None)
    r100, t100 = record_run(sc, SocialForceAgent(sc.navigation()), params, frame_rate_per_s=100.0, max_time_s=3.0,
                            line="exit", density_areas=(), lane_area=None)
    assert t16.frame_rate_per_s == 16.0 and r16.n_steps == r100.n_steps  # recording does not change the run
    for pid in (0, 17, 29):
        a, b = t16.id == pid, t100.id == pid
        for coord in ("x_m", "y_m"):
            expected = np.interp(t16.time_s[a], t100.time_s[b], getattr(t100, coord)[b])
            np.testing.assert_allclose(getattr(t16, coord)[a], expected, atol=1e-12)
