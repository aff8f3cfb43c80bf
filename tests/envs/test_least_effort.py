"""The least-effort reward (crowd_env.envs.rewards.least_effort): its optimum speed is the preferred walking
speed √(e_s / e_w) ≈ 1.33 m/s both per metre (a walk to an exit) and per second (a walk without end), standing
costs e_s per second, and in the environment its terms add up to the reward."""
from __future__ import annotations

import math

import numpy as np
import pytest

from crowd_env.envs import crowd_v0
from crowd_env.envs.rewards import resolve_terms
from crowd_env.envs.rewards.least_effort import (COST_OF_TRANSPORT_J_KG_M, E_S_J_KG_S, E_W_J_S_KG_M2,
                                                 PREFERRED_SPEED_M_S, MetabolicEffort)
from crowd_env.errors import EnvOptionError, InputError


def _steady_walk(speed_m_s: np.ndarray, dt_s: float = 0.1) -> dict:
    """The step info of walkers at constant speeds along the geodesic (progress = v Δt), no contacts, no exit."""
    n = speed_m_s.size
    return {"progress_s": speed_m_s * dt_s, "speed_m_s": speed_m_s, "speed_before_m_s": speed_m_s,
            "contact_percussion_kg_m_s": np.zeros(n), "exited": np.zeros(n, bool), "dt_s": dt_s}


def test_the_constants_are_guy_et_al_2010s():
    assert PREFERRED_SPEED_M_S == pytest.approx(1.3304, abs=1e-4)
    assert COST_OF_TRANSPORT_J_KG_M == pytest.approx(3.3524, abs=1e-4)
    assert COST_OF_TRANSPORT_J_KG_M == pytest.approx(E_S_J_KG_S / PREFERRED_SPEED_M_S + E_W_J_S_KG_M2 * PREFERRED_SPEED_M_S)


def test_the_least_effort_optimum_is_the_preferred_speed_per_metre_and_per_second():
    reward = resolve_terms("least_effort")
    v = np.linspace(0.05, 2.5, 4901)  # 0.0005 m/s apart
    info = _steady_walk(v)
    r = reward(None, list(range(v.size)), info)
    per_second = r / info["dt_s"]
    per_metre = r / (v * info["dt_s"])
    assert v[np.argmax(per_second)] == pytest.approx(PREFERRED_SPEED_M_S, abs=1e-3)
    assert v[np.argmax(per_metre)] == pytest.approx(PREFERRED_SPEED_M_S, abs=1e-3)
    assert per_second.max() == pytest.approx(0.0, abs=1e-6) and per_metre.max() == pytest.approx(0.0, abs=1e-6)
    # what the default reward pays for instead: the faster the better, per metre and per second
    default = resolve_terms("default")(None, list(range(v.size)), info)
    assert np.all(np.diff(default / info["dt_s"]) > 0) and np.all(np.diff(default / (v * info["dt_s"])) > 0)
    # standing costs e_s per second
    still = reward(None, [0], _steady_walk(np.zeros(1)))
    assert still[0] / 0.1 == pytest.approx(-E_S_J_KG_S)


def test_the_effort_is_the_trapezoid_of_the_squared_speeds():
    info = {"speed_before_m_s": np.array([0.0, 1.0]), "speed_m_s": np.array([2.0, 1.0]), "dt_s": 0.5}
    got = MetabolicEffort().value(None, info)
    want = [-(E_S_J_KG_S + E_W_J_S_KG_M2 * 2.0) * 0.5, -(E_S_J_KG_S + E_W_J_S_KG_M2 * 1.0) * 0.5]
    np.testing.assert_allclose(got, want, rtol=1e-15)
    with pytest.raises(InputError, match="e_s_j_kg_s"):
        MetabolicEffort(e_s_j_kg_s=-1.0)


def test_the_environment_runs_the_least_effort_reward_and_reports_its_terms():
    env = crowd_v0.parallel_env(scenario_options={"n_pedestrians": 8}, reward_terms="least_effort", frame_skip=5,
                                max_steps=30, reward_terms_in_infos=True)
    obs, infos = env.reset(seed=1)
    assert all(info["reward_terms"] == [0.0] * 4 for info in infos.values())  # the same keys at reset
    speeds = {a: infos[a]["speed_m_s"] for a in env.agents}
    rng = np.random.default_rng(0)
    for _ in range(10):
        agents = list(env.agents)
        actions = {a: rng.uniform(-1.5, 1.5, 2).astype(np.float32) for a in agents}
        obs, rewards, term, trunc, infos = env.step(actions)
        for a in agents:
            parts = env.reward_terms(infos[a])
            assert tuple(parts) == ("progress", "metabolic_effort", "contact_percussion", "exit")
            assert sum(parts.values()) == pytest.approx(rewards[a], abs=1e-12)
            v0, v1 = speeds[a], infos[a]["speed_m_s"]
            want = -(E_S_J_KG_S + E_W_J_S_KG_M2 * 0.5 * (v0 ** 2 + v1 ** 2)) * env.dt_s
            assert parts["metabolic_effort"] == pytest.approx(want, rel=1e-12)
            speeds[a] = v1
        if not env.agents:
            break


def test_an_unknown_reward_name_lists_the_named_rewards():
    with pytest.raises(EnvOptionError, match="least_effort"):
        crowd_v0.parallel_env(reward_terms="least_efort")
    assert math.isclose(resolve_terms("least_effort").weights[0], COST_OF_TRANSPORT_J_KG_M)


@pytest.mark.parametrize("option", [{}, {"reward_terms_in_infos": False}])
def test_reward_terms_stay_out_of_the_infos_unless_asked_for(option):
    env = crowd_v0.parallel_env(scenario_options={"n_pedestrians": 4}, **option)
    obs, infos = env.reset(seed=0)
    assert all("reward_terms" not in i for i in infos.values())
    obs, rewards, *_, infos = env.step({a: np.zeros(2) for a in env.agents})
    assert env.reward_term_names is None and all("reward_terms" not in i for i in infos.values())
    assert env.reward_terms(infos["ped_0"]) == {}
    with pytest.raises(EnvOptionError, match="reward_terms_in_infos"):
        crowd_v0.parallel_env(reward_terms_in_infos="yes")
