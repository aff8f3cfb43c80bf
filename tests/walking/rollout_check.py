"""One check the walking tests share: the compiled rollout and Python stepping run the same walk to the last bit."""
import numpy as np


def assert_rollout_equals_stepping(params, *, n_pedestrians=20, seed=3, max_time_s=4.0, scenario=None,
                                   reference=None):
    """Record the Seyfried bottleneck (b = 1.0 m; or the ``scenario``) with ``params`` both ways, assert equal
    trajectories to the last bit and that they differ from the default preset's (or the ``reference`` parameters':
    the option acts), and return the trajectories."""
    from crowd_env.walking.presets import get_preset
    from crowd_env.experiments.running.recording import record_run
    from crowd_env.scenarios import make_scenario
    from crowd_env.walking.agent import SocialForceAgent

    sc = scenario if scenario is not None else make_scenario("seyfried_bottleneck", width_m=1.0,
                                                             n_pedestrians=n_pedestrians, seed=seed)
    ra, ta = record_run(sc, SocialForceAgent(sc.navigation()), params, max_time_s=max_time_s, compiled=True)
    rb, tb = record_run(sc, SocialForceAgent(sc.navigation()), params, max_time_s=max_time_s, compiled=False)
    assert ra.n_steps == rb.n_steps == round(max_time_s / params.dt_s)
    for key in ("frame", "id", "x_m", "y_m", "heading_rad"):
        np.testing.assert_array_equal(getattr(ta, key), getattr(tb, key), err_msg=key)
    _, tc = record_run(sc, SocialForceAgent(sc.navigation()),
                       get_preset("calibrated").params() if reference is None else reference, max_time_s=max_time_s)
    assert not np.array_equal(tc.x_m, ta.x_m)
    return ta
