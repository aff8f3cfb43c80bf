"""Run results (crowd_env.experiments.running.runner.RunResult): the density, speed and stationary-flow windows over
the passages."""
import numpy as np
import pytest


def test_density_windows():
    from crowd_env.experiments.running.runner import RunResult

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
    from crowd_env.experiments.running.runner import RunResult

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


# ---------------------------------------------------------------- issue 37, item 9: steps and buffers
def _small_bottleneck():
    from crowd_env.scenarios import make_scenario

    return make_scenario("seyfried_bottleneck", n_pedestrians=10, seed=1)


@pytest.mark.parametrize("dt_s, count", [(1e-9, "300,000,000,000"), (1e-6, "300,000,000")])
def test_run_needing_more_steps_than_the_limit_is_refused_with_the_count(dt_s, count):
    """dt_s = 1e-9 tried to allocate 4.37 TiB (series sized by max_time / dt); 1e-6 ran for ever."""
    from crowd_env.walking import ModelParams
    from crowd_env.errors import InputError
    from crowd_env.experiments.running.runner import run_scenario
    from crowd_env.walking.agent import SocialForceAgent

    sc = _small_bottleneck()
    with pytest.raises(InputError, match=rf"max_time_s = 300 s at dt_s = {dt_s:g} s needs up to {count} steps, more "
                                         rf"than step_limit = 10,000,000 .*MAX_RUN_STEPS.*pass a larger step_limit"):
        run_scenario(sc, SocialForceAgent(sc.navigation()), ModelParams(dt_s=dt_s), max_time_s=300.0)
    with pytest.raises(InputError, match=r"needs up to 10 steps, more than step_limit = 5"):
        run_scenario(sc, SocialForceAgent(sc.navigation()), ModelParams(), max_time_s=0.1, step_limit=5)


def test_series_grow_with_the_steps_run_not_with_max_time():
    """A run allowed 1e5 s (1e7 steps: 320 MB of density and speed series at once before) that ends after
    about 20 s holds only what it used, and gives the same record as with series that start tiny."""
    import tracemalloc

    import crowd_env.experiments.running.runner as runner
    from crowd_env.walking import ModelParams
    from crowd_env.walking.agent import SocialForceAgent

    sc = _small_bottleneck()

    def run(**kw):
        return runner.run_scenario(sc, SocialForceAgent(sc.navigation()), ModelParams(), **kw)

    run(max_time_s=1.0)  # compile first: tracemalloc below sees the run's arrays only
    tracemalloc.start()
    try:
        long = run(max_time_s=1e5)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert long.complete and long.n_steps < 5000
    assert peak < 30e6, f"peak {peak / 1e6:.1f} MB"
    old = runner.SERIES_START_ROWS
    runner.SERIES_START_ROWS = 3  # grow many times, in the compiled chunks and in Python steps
    try:
        for compiled in (True, False):
            small = run(max_time_s=1e5, compiled=compiled, chunk_steps=257)
            assert small.n_steps == long.n_steps
            np.testing.assert_array_equal(small.crossing_times_s, long.crossing_times_s)
            for name in long.density_per_m2:
                np.testing.assert_array_equal(small.density_per_m2[name], long.density_per_m2[name])
                np.testing.assert_array_equal(small.speed_m_s[name], long.speed_m_s[name])
                assert long.density_per_m2[name].shape == (long.n_steps,)
            np.testing.assert_array_equal(small.lateral_positions_m, long.lateral_positions_m)
    finally:
        runner.SERIES_START_ROWS = old


