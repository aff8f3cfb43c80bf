"""The time step (crowd_env.core.timestep; issue 37, item 9): a dt_s beyond the explicit update's stability
limit is refused naming the limit, one above the safe step warns with its reason, and both bounds are what
the dynamics do (the refused steps diverge, the contact criterion is the gap a sliding pair opens)."""
import math
import warnings

import numpy as np
import pytest

import crowd_env.core.simulator as simulator_module
from crowd_env.core import CrowdState, ParameterError, Simulator
from crowd_env.walking import ModelParams
from crowd_env.core.timestep import (PAPER_TIME_STEP_S, TimeStepWarning, check_time_step, safe_time_step_s,
                                     stability_limit_s)
from crowd_env.scenarios import make_scenario


def _one(**kw):
    return CrowdState.create([[0.0, 0.0]], desired_speed_m_s=1.34, **kw)


def _unchecked(state, params, monkeypatch):
    """A Simulator built without the time-step check, to watch what a refused step would do."""
    monkeypatch.setattr(simulator_module, "check_time_step", lambda *a: None)
    return Simulator(state, params=params)


def test_default_crowd_at_the_papers_step_is_neither_refused_nor_warned():
    state = make_scenario("seyfried_bottleneck", n_pedestrians=20, seed=0).make_state()
    with warnings.catch_warnings():
        warnings.simplefilter("error", TimeStepWarning)
        check_time_step(state, ModelParams(dt_s=PAPER_TIME_STEP_S))
    safe, _ = safe_time_step_s(state, ModelParams())
    limit, _ = stability_limit_s(state, ModelParams())
    assert PAPER_TIME_STEP_S < safe < 0.02 and 0.5 < limit < 0.6


def test_step_of_one_second_is_refused_naming_the_heading_limit():
    """The issue's dt_s = 1.0, which "ran without a word": the heading update diverges there."""
    sc = make_scenario("seyfried_bottleneck", n_pedestrians=10, seed=0)
    with pytest.raises(ParameterError, match=r"dt_s = 1 s is beyond the stability limit 0\.5489 s for pedestrian 0 "
                                             r"\(k = 5 N m/rad, c = 6\.626 N m s/rad, I = 2\.195 kg m\^2; the explicit "
                                             r"heading update of Eq\. 15 is unstable where h\^2 k \+ 2 h c > 4 I\)"):
        sc.make_simulator(params=ModelParams(dt_s=1.0))
    with pytest.raises(ParameterError, match=r"dt_s = 1\.5 s is beyond the stability limit 2 tau = 1 s of pedestrian "
                                             r"0 \(the explicit driving relaxation of Eq\. 14"):
        sc.make_simulator(params=ModelParams(dt_s=1.5, rotation=False))


@pytest.mark.parametrize("factor", [0.98, 1.02, 1.0 / 0.5489])
def test_heading_settles_below_the_limit_only(factor, monkeypatch):
    """Below h^2 k + 2 h c = 4 I the heading turns to theta_d; just beyond it, it spins for ever; at h = 1 s
    (beyond 2 I / c) omega grows geometrically towards overflow."""
    state = _one(tau_s=1e12)
    params = ModelParams(social_forces=False)
    limit, _ = stability_limit_s(state, params)
    sim = _unchecked(state, params.replace(dt_s=factor * limit), monkeypatch)
    omega, theta = [], []
    for _ in range(400):
        sim.step(np.zeros((1, 2)), desired_heading_rad=np.array([1.0]))
        omega.append(abs(float(state.angular_velocity_rad_s[0])))
        theta.append(float(state.heading_rad[0]))
    late = max(omega[-50:])
    if factor < 1.0:
        assert late < 1e-6 and abs(theta[-1] - 1.0) < 1e-6
    elif factor * limit < 2 * state.inertia_kg_m2[0] / state.heading_damping[0]:
        assert late > 1.0 and max(abs(t - 1.0) for t in theta[-50:]) > 1.0  # never settles
    else:
        assert late > 1e50


@pytest.mark.parametrize("factor, diverges", [(0.99, False), (1.01, True)])
def test_driving_relaxation_diverges_exactly_beyond_two_tau(factor, diverges, monkeypatch):
    state = _one(tau_s=0.5)
    params = ModelParams(social_forces=False, rotation=False)
    limit, why = stability_limit_s(state, params)
    assert limit == 1.0 and why.startswith("2 tau")
    sim = _unchecked(state, params.replace(dt_s=factor * limit), monkeypatch)
    for _ in range(600):
        sim.step(np.array([[1.0, 0.0]]))
    speed = float(np.hypot(*state.velocity_m_s[0]))
    assert (speed > 100.0) is diverges and (speed < 2.1) is not diverges, speed


def test_safe_step_warns_with_its_reason_and_the_contact_criterion_is_the_gap_a_sliding_pair_opens():
    """Two touching pedestrians, one sliding past the other at v0: after one step they are (h v0)^2 / (4 r)
    apart; at the safe step that is exactly the contact tolerance, beyond it the contact is lost."""
    r, v0, eps = 0.23, 1.5, ModelParams().contact_tolerance_m
    state = CrowdState.create([[0.0, 0.0], [2 * r, 0.0]], radius_m=r, desired_speed_m_s=[0.0, v0], tau_s=1e12,
                              velocity_m_s=[[0.0, 0.0], [0.0, v0]])
    params = ModelParams(social_forces=False, rotation=False)
    safe, why = safe_time_step_s(state, params)
    assert safe == pytest.approx(math.sqrt(4 * eps * r) / v0) and why.startswith("sqrt(2 eps (2 r)) / v0")
    with warnings.catch_warnings():
        warnings.simplefilter("error", TimeStepWarning)
        sim = Simulator(state.copy(), params=params.replace(dt_s=safe))
    sim.step(sim.state.velocity_m_s.copy())
    gap = float(np.hypot(*(sim.state.position_m[1] - sim.state.position_m[0]))) - 2 * r
    assert gap == pytest.approx(math.hypot(2 * r, safe * v0) - 2 * r, rel=1e-9)  # slid along, not pushed apart
    assert gap == pytest.approx(eps, rel=2e-3)  # (h v0)^2 / (4 r) = eps at the safe step, to second order
    with pytest.warns(TimeStepWarning, match=r"dt_s = 0\.03 s is above this crowd's safe time step sqrt\(2 eps "
                                             r"\(2 r\)\) / v0 = 0\.02022 s \(a walker at v0 = 1\.5 m/s"):
        Simulator(state.copy(), params=params.replace(dt_s=0.03))


def test_a_step_below_the_smallest_is_refused_by_the_simulator_and_the_environment_at_construction():
    """Regression (issue 52): parallel_env(params={"dt_s": 1e-9}) was accepted silently (600 decisions of 10 steps
    covered 6 µs and nobody moved) where the runner refuses the same step."""
    from crowd_env.envs import crowd_v0
    from crowd_env.errors import EnvOptionError
    from crowd_env.core.timestep import MIN_TIME_STEP_S

    assert MIN_TIME_STEP_S == PAPER_TIME_STEP_S / 100
    state = _one()
    with pytest.raises(ParameterError, match=r"dt_s = 1e-09 s is below the smallest time step crowd_env takes, "
                                             r"0.0001 s .*1,000,000,000 steps"):
        Simulator(state.copy(), params=ModelParams(dt_s=1e-9))
    with pytest.raises(EnvOptionError, match=r"params dt_s = 1e-09 s is below the smallest time step"):
        crowd_v0.parallel_env(params={"dt_s": 1e-9}, max_cycles=600, frame_skip=10)
    with pytest.raises(EnvOptionError, match=r"params dt_s = 5e-05 s is below"):
        crowd_v0.parallel_env(params=ModelParams(dt_s=5e-5))
    Simulator(state.copy(), params=ModelParams(dt_s=MIN_TIME_STEP_S))  # the smallest step itself is taken
    env = crowd_v0.parallel_env(params={"dt_s": MIN_TIME_STEP_S}, scenario_options={"n_pedestrians": 4})
    env.reset(seed=0)
    env.close()
