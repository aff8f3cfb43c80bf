"""Compiled rollouts (crowd_env.experiments.running.rollout): a run rolled out in compiled chunks is the run stepped
from Python, to the last bit: on the calibrated bottleneck, with hand-holding groups, with per-pedestrian
destinations, on a jam that hands steps to the staged path and the solver cascade mid-run, with trajectory
recording and with the stall rule firing."""
import dataclasses

import numpy as np
import pytest

from crowd_env.walking import ModelParams
from crowd_env.walking.presets import DEFAULT_PRESET, get_preset
from crowd_env.experiments.running.recording import record_run
from crowd_env.experiments.running.runner import run_scenario
from crowd_env.scenarios import make_scenario
from crowd_env.walking.agent import SocialForceAgent
from crowd_env.walking.navigation import RigidlyMovedNavigation
from tests.conftest import DATA

STATE_FIELDS = ("position_m", "velocity_m_s", "heading_rad", "angular_velocity_rad_s", "active")


def _run(scenario, params, compiled, state=None, **kw):
    """run_scenario with the calibrated agent; returns (result, final state, the simulator)."""
    state = scenario.make_state() if state is None else state
    seen = {}
    result = run_scenario(scenario, SocialForceAgent(scenario.navigation()), params, state=state, compiled=compiled,
                          progress=lambda sim: seen.update(sim=sim), **kw)
    return result, state, seen["sim"]


def _assert_same_run(a, b):
    """Every field of two RunResults equal to the bit (nan equal to nan), wall time aside."""
    for f in dataclasses.fields(a):
        if f.name == "wall_time_s":
            continue
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, dict):
            assert x.keys() == y.keys(), f.name
            for k in x:
                np.testing.assert_array_equal(x[k], y[k], err_msg=f"{f.name}[{k}]")
        else:
            np.testing.assert_array_equal(x, y, err_msg=f.name)


def _assert_same_state(s, t):
    for name in STATE_FIELDS:
        np.testing.assert_array_equal(getattr(s, name), getattr(t, name), err_msg=name)


def test_calibrated_bottleneck_rollout_equals_stepping():
    """The calibrated preset at b = 1.0 m, N = 60 to the end: flows, densities, speeds, lateral positions,
    the smallest gap and the final state bitwise equal, with chunks that end mid-run."""
    scenario = make_scenario("seyfried_bottleneck", width_m=1.0, n_pedestrians=60, seed=1)
    params = get_preset(DEFAULT_PRESET).params()
    a, sa, sim_a = _run(scenario, params, True, chunk_steps=700)
    b, sb, sim_b = _run(scenario, params, False)
    assert a.complete and a.n_passed == 60 and a.n_steps > 1000
    # Every step compiled: re-detections (a push along a queue) included.
    assert sim_a.n_staged_steps == sim_b.n_staged_steps == 0
    assert sim_a.n_redetections == sim_b.n_redetections > 0
    _assert_same_run(a, b)
    _assert_same_state(sa, sb)


def test_groups_and_destinations_rollout_equals_stepping():
    """Hand links (K_v, Eq. 2) and per-pedestrian destination fields (two exits, opposite flows)."""
    params = get_preset(DEFAULT_PRESET).params()
    groups = make_scenario("bottleneck_groups", width_m=1.0, n_pedestrians=30, seed=0)
    assert groups.make_state().links.shape[0] > 0
    a, sa, _ = _run(groups, params, True, max_time_s=8.0)
    b, sb, _ = _run(groups, params, False, max_time_s=8.0)
    _assert_same_run(a, b)
    _assert_same_state(sa, sb)
    corridor = make_scenario("corridor_bidirectional", n_per_direction=12, seed=0, length_m=7.0, spawn_depth_m=2.0)
    assert SocialForceAgent(corridor.navigation()).compiled(corridor.n_pedestrians) is not None
    a, sa, _ = _run(corridor, params, True, max_time_s=8.0, line=None)
    b, sb, _ = _run(corridor, params, False, max_time_s=8.0, line=None)
    _assert_same_run(a, b)
    _assert_same_state(sa, sb)
    assert a.n_evacuated > 0


def test_jam_hands_steps_to_the_staged_path_and_back():
    """The paper preset's jam at the entrance (b = 1.0 m, N = 180, seed 2, from step 620), pushed without
    social repulsion: projections beyond the dense solver send steps to the staged path and the cascade's
    sparse solvers; the rollout hands them over and resumes. Both runs agree to the bit."""
    params = ModelParams(social_forces=False)
    scenario = make_scenario("seyfried_bottleneck", width_m=1.0, n_pedestrians=180, seed=2, corridor_width_m=7.0,
                             channel_length_m=4.0, navigation_clearance_m=0.0)
    saved = np.load(DATA / "seyfried_b1.0_n180_seed2_step620.npz")

    def state():
        s = scenario.make_state()
        for name in STATE_FIELDS:
            getattr(s, name)[...] = saved[name]
        return s

    a, sa, sim_a = _run(scenario, params, True, state=state(), max_time_s=1.5)
    b, sb, sim_b = _run(scenario, params, False, state=state(), max_time_s=1.5)
    assert sim_a.step_count == sim_b.step_count == 150
    assert 0 < sim_a.n_staged_steps < 150  # hand-offs, and compiled steps between them
    assert sim_a.n_sparse_solves == sim_b.n_sparse_solves == sim_a.n_staged_steps
    assert sim_a.n_redetections == sim_b.n_redetections > 0
    _assert_same_run(a, b)
    _assert_same_state(sa, sb)


def test_stall_and_recording_in_the_rollout():
    """The stall rule fires at the same step either way (a 0.5 s window and a 10 m/s threshold: it fires at
    the first 0.5 s without a passage), and trajectories recorded at 25 fps are the same frames."""
    scenario = make_scenario("seyfried_bottleneck", width_m=1.0, n_pedestrians=20, seed=0)
    params = get_preset(DEFAULT_PRESET).params()
    kw = dict(max_time_s=30.0, stall_window_s=0.5, stall_speed_m_s=10.0)  # "slower than 10 m/s" after 0.5 s
    a, _, _ = _run(scenario, params, True, **kw)
    b, _, _ = _run(scenario, params, False, **kw)
    assert a.stalled and b.stalled and a.stall_time_s == b.stall_time_s
    _assert_same_run(a, b)
    ra, ta = record_run(scenario, SocialForceAgent(scenario.navigation()), params, max_time_s=3.0, compiled=True)
    rb, tb = record_run(scenario, SocialForceAgent(scenario.navigation()), params, max_time_s=3.0, compiled=False)
    _assert_same_run(ra, rb)
    assert ta.frame_rate_per_s == tb.frame_rate_per_s
    for key in ("frame", "id", "x_m", "y_m", "heading_rad"):
        np.testing.assert_array_equal(getattr(ta, key), getattr(tb, key), err_msg=key)
    assert ta.frame.max() == 75  # 3 s at 25 fps


def test_rollout_falls_back_where_it_has_no_compiled_form():
    """A rigidly moved field and a subclass that decides differently run step by step (same figures as
    compiled=False); a bad chunk size or recording rate is refused naming it."""
    scenario = make_scenario("seyfried_bottleneck", width_m=1.0, n_pedestrians=10, seed=0)
    nav = scenario.navigation()
    assert SocialForceAgent(RigidlyMovedNavigation(nav, 0.0)).compiled(10) is None

    class Slower(SocialForceAgent):
        def __call__(self, sim):
            intents, heading = super().__call__(sim)
            return 0.5 * intents, heading

    assert Slower(nav).compiled(10) is None
    assert SocialForceAgent(nav).compiled(10) is not None
    for bad in (0, 2.5, "10", True):  # a fraction of a step is refused, not rounded down
        with pytest.raises(ValueError, match="chunk_steps must be an integer >= 1"):
            run_scenario(scenario, SocialForceAgent(nav), chunk_steps=bad)
        with pytest.raises(ValueError, match="record_every must be an integer >= 1"):
            run_scenario(scenario, SocialForceAgent(nav), record_every=bad)
    for bad in (0.0, -1.0, float("nan"), float("inf"), "60"):  # no run of zero or negative length passes as complete
        with pytest.raises(ValueError, match="max_time_s must be a positive finite number"):
            run_scenario(scenario, SocialForceAgent(nav), max_time_s=bad)
