"""Run results (crowd_env.experiments.runner.RunResult): the density, speed and stationary-flow windows over
the passages."""
import numpy as np
import pytest


def test_density_windows():
    from crowd_env.experiments.runner import RunResult

    times = np.linspace(10.0, 20.0, 11)  # passages every second
    series = np.concatenate([np.full(1500, 4.0), np.full(1500, 1.0)])  # dense until t = 15 s, then thin
    r = RunResult(n_pedestrians=11, width_m=1.0, seed=0, n_steps=3000, simulated_time_s=30.0, wall_time_s=0.0,
                  n_evacuated=11, evacuation_time_s=30.0, crossing_times_s=times, flow_per_s=1.1,
                  specific_flow_per_m_s=1.1, min_gap_m=0.0, density_per_m2={"front": series})
    assert r.density_window_s("passages") == (10.0, 20.0)
    assert r.density_window_s() == (12.0, 18.0)  # the middle 60 % of the passages
    assert r.mean_density_per_m2("front", window="passages") == pytest.approx(2.5, abs=0.02)
    assert r.mean_density_per_m2("front") == pytest.approx(2.5, abs=0.02)
    assert r.mean_density_per_m2("front", fractions=(0.0, 0.5)) == pytest.approx(4.0)
    with pytest.raises(ValueError):
        r.density_window_s("nonsense")


def test_speed_and_stationary_flow_windows():
    from crowd_env.experiments.runner import RunResult

    # passages every 0.5 s for the first 8, then every 2 s (a draining tail); b = 0.8 m
    times = np.concatenate([np.arange(8) * 0.5 + 10.0, 13.5 + 2.0 * np.arange(1, 4)])
    speed = np.full(3000, 1.2)  # step j at t = (j + 1) h, h = 0.01 s
    speed[1300:] = 0.6
    speed[1150:1250] = np.nan  # nobody inside: those steps do not count
    r = RunResult(n_pedestrians=11, width_m=0.8, seed=0, n_steps=3000, simulated_time_s=30.0, wall_time_s=0.0,
                  n_evacuated=11, evacuation_time_s=30.0, crossing_times_s=times, flow_per_s=np.nan,
                  specific_flow_per_m_s=np.nan, min_gap_m=0.0, speed_m_s={"inside": speed})
    # the stationary window runs from the 2nd to the 8th passage (ranks 2 and 8 of 0..10)
    assert r.density_window_s() == (11.0, 15.5)
    assert r.stationary_specific_flow_per_m_s() == pytest.approx(6 / (4.5 * 0.8))
    assert r.stationary_specific_flow_per_m_s(fractions=(0.0, 0.5)) == pytest.approx(5 / (2.5 * 0.8))
    # in [11, 15.5] s: 100 samples of 1.2 m/s (the empty second skipped) and 250 of 0.6 m/s (± one
    # sample at each end of the window)
    assert r.mean_speed_m_s("inside") == pytest.approx((100 * 1.2 + 250 * 0.6) / 350, abs=0.005)
    assert r.mean_speed_m_s("inside", fractions=(0.0, 0.1)) == pytest.approx(1.2)
    one = RunResult(n_pedestrians=1, width_m=0.8, seed=0, n_steps=10, simulated_time_s=0.1, wall_time_s=0.0,
                    n_evacuated=1, evacuation_time_s=0.1, crossing_times_s=np.array([0.05]), flow_per_s=np.nan,
                    specific_flow_per_m_s=np.nan, min_gap_m=0.0, speed_m_s={"inside": np.ones(10)})
    assert np.isnan(one.stationary_specific_flow_per_m_s()) and np.isnan(one.mean_speed_m_s("inside"))
