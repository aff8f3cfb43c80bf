"""Learned background pedestrians (crowd_env.envs.background) and background policies by name.

Two implementations of the same thing: pedestrians driven in the background by an observation policy
must move exactly as the same pedestrians do when they are the environment's agents acting with that
policy (observations, decision interval, egocentric frame, heading). Then: the decision interval is the
policy's own, names and policy files load through the entry point, and bad policies are named.
"""
from __future__ import annotations

import numpy as np
import pytest

from baselines.trained import FilePolicy
from crowd_env.envs import crowd_v0
from crowd_env.envs.observations import observation_size
from crowd_env.errors import EnvOptionError, EnvStateError, PolicyError
from crowd_env.envs.policy_files import MLPPolicyFile, save_policy_file
from crowd_env.scenarios import make_scenario

SCENARIO = {"scenario": "seyfried_bottleneck", "scenario_options": {"width_m": 1.0, "n_pedestrians": 12}}


def _policy_file(tmp_path, frame="world", frame_skip=5, seed=0, scale=1.0) -> str:
    """A random 2-layer tanh MLP whose actions (TanhNormal's mean, inside Box(-2.5, 2.5)) depend on the
    observation, saved as a policy file trained with ``frame`` and ``frame_skip``."""
    rng = np.random.default_rng(seed)
    d = observation_size(6, 8, frame)
    w = [rng.normal(0, 0.3, (d, 16)), rng.normal(0, 0.5, (16, 4))]
    b = [np.zeros(16), np.array([0.8, 0.0, 0.0, 0.0])]
    pf = MLPPolicyFile(w, b, "tanh", "tanh_box", np.full(2, -2.5 * scale), np.full(2, 2.5 * scale), np.zeros(d),
                       np.full(d, 2.0), env_config={"observation_frame": frame, "frame_skip": frame_skip,
                                                    "action_max_m_s": 2.5})
    return save_policy_file(pf, str(tmp_path / f"p_{frame}_{frame_skip}_{scale}.npz"))


def _positions(env, policy, steps=30, seed=4):
    obs, _ = env.reset(seed=seed)
    policy.reset(env)
    out = [env.sim.state.position_m.copy()]
    for _ in range(steps):
        if not env.agents:
            break
        obs, *_ = env.step(policy.act(env, obs))
        out.append(env.sim.state.position_m.copy())
    return np.array(out)


@pytest.mark.parametrize("frame", ["world", "egocentric"])
def test_background_pedestrians_move_as_the_same_policy_s_agents(tmp_path, frame):
    policy = FilePolicy(_policy_file(tmp_path, frame))
    all_agents = crowd_v0.parallel_env(**SCENARIO, controlled="all", **policy.env_overrides)
    one_agent = crowd_v0.parallel_env(**SCENARIO, controlled=[0], background_policy=policy, **policy.env_overrides)
    a = _positions(all_agents, policy)
    b = _positions(one_agent, policy)
    assert a.shape == b.shape and a.shape[0] == 31
    moved = np.abs(a[-1] - a[0]).max()
    assert moved > 0.5  # the policy walks them somewhere
    np.testing.assert_allclose(b, a, rtol=0, atol=1e-9)


def test_a_learned_background_differs_from_the_calibrated_one(tmp_path):
    """The option is not ignored: the same crowd with the calibrated background moves otherwise."""
    policy = FilePolicy(_policy_file(tmp_path))
    learned = crowd_v0.parallel_env(**SCENARIO, controlled=[0], background_policy=policy, **policy.env_overrides)
    calibrated = crowd_v0.parallel_env(**SCENARIO, controlled=[0], **policy.env_overrides)
    assert np.abs(_positions(learned, policy, 10) - _positions(calibrated, policy, 10)).max() > 0.05


class _Counting:
    """An observation policy that walks east and counts its calls (decisions)."""

    def __init__(self, frame_skip):
        self.env_overrides = {"frame_skip": frame_skip}
        self.calls = []

    def actions(self, observations):
        self.calls.append(observations.shape[0])
        return np.tile([1.0, 0.0], (observations.shape[0], 1))


def test_the_background_decides_at_its_own_interval():
    pol = _Counting(frame_skip=4)
    env = crowd_v0.parallel_env(**SCENARIO, controlled=[0], background_policy=pol, frame_skip=1)
    env.reset(seed=0)
    for _ in range(12):
        env.step({"ped_0": np.zeros(2)})
    assert pol.calls == [11, 11, 11]  # steps 0, 4, 8: the 11 background pedestrians at once
    env.reset(seed=1)  # a new episode decides at once
    env.step({"ped_0": np.zeros(2)})
    assert len(pol.calls) == 4


def test_names_and_files_load_through_the_entry_point(tmp_path):
    path = _policy_file(tmp_path)
    by_object = crowd_v0.parallel_env(**SCENARIO, controlled=[0], background_policy=FilePolicy(path), frame_skip=5)
    by_path = crowd_v0.parallel_env(**SCENARIO, controlled=[0], background_policy=path, frame_skip=5)
    zero = FilePolicy(path)
    np.testing.assert_array_equal(_positions(by_path, zero, 8), _positions(by_object, zero, 8))
    default = crowd_v0.parallel_env(**SCENARIO, controlled=[0], frame_skip=5)
    named = crowd_v0.parallel_env(**SCENARIO, controlled=[0], background_policy="calibrated", frame_skip=5)
    np.testing.assert_array_equal(_positions(named, zero, 8), _positions(default, zero, 8))


def test_unknown_names_and_bad_policies_are_named(tmp_path):
    with pytest.raises(EnvOptionError, match="unknown background policy 'no_such_policy'.*shipped"):
        crowd_v0.parallel_env(**SCENARIO, controlled=[0], background_policy="no_such_policy")
    with pytest.raises(EnvOptionError, match="background_policy must be"):
        crowd_v0.parallel_env(**SCENARIO, controlled=[0], background_policy=3)
    world = FilePolicy(_policy_file(tmp_path, "world"))
    world.env_overrides["observation_frame"] = "egocentric"  # its options no longer give its input size
    with pytest.raises(PolicyError, match="expects observations of size"):
        crowd_v0.parallel_env(**SCENARIO, controlled=[0], background_policy=world)
    for key, bad, what in (("n_rays", -1, "n_rays must be an integer >= 0"),
                           ("heading_target", "sideways", "heading_target must be 'intent' or 'desired_direction'"),
                           ("observation_frame", "polar", "observation_frame must be one of")):
        odd = FilePolicy(_policy_file(tmp_path))
        odd.env_overrides[key] = bad  # checked as the environment checks its own options
        with pytest.raises(EnvOptionError, match=f"background policy: {what}"):
            crowd_v0.parallel_env(**SCENARIO, controlled=[0], background_policy=odd)
    wide = FilePolicy(_policy_file(tmp_path, scale=10.0))  # acts in Box(-25, 25) but claims a_max 2.5
    env = crowd_v0.parallel_env(**SCENARIO, controlled=[0], background_policy=wide, frame_skip=5)
    env.reset(seed=0)
    with pytest.raises(PolicyError, match="outside its Box.*nothing is clipped"):
        for _ in range(5):
            env.step({"ped_0": np.zeros(2)})


def test_per_pedestrian_destinations_and_desired_direction_heading(tmp_path):
    """A scenario with per-pedestrian exits and heading_target='desired_direction': the background's θ_d
    is the angle of each one's own e_d, as for an agent."""
    sc = make_scenario("rimea_10_escape_routes", seed=0)
    assert sc.destination is not None and len(set(sc.destination.tolist())) > 1
    d = observation_size(6, 8, "world")
    rng = np.random.default_rng(0)
    pf = MLPPolicyFile([rng.normal(0, 0.3, (d, 4))], [np.zeros(4)], "tanh", "tanh_box", np.full(2, -2.5),
                       np.full(2, 2.5), np.zeros(d), np.ones(d),
                       env_config={"heading_target": "desired_direction", "frame_skip": 2})
    policy = FilePolicy(save_policy_file(pf, str(tmp_path / "dd.npz")))
    a = _positions(crowd_v0.parallel_env(scenario=sc, controlled="all", **policy.env_overrides), policy, 10)
    b = _positions(crowd_v0.parallel_env(scenario=sc, controlled=[0], background_policy=policy,
                                         **policy.env_overrides), policy, 10)
    np.testing.assert_allclose(b, a, rtol=0, atol=1e-9)



def test_background_pedestrians_turn_their_shoulders_as_the_same_policys_agents(tmp_path):
    """In a model that turns the shoulders (the preset ``shoulders``: bodies of three circles, ρ = 1.3), with
    heading_target='desired_direction': the background's θ_d is turned at a narrow aperture as an agent's is, and
    both move alike; the turn is exercised (some heading target departs from e_d's angle)."""
    from crowd_env.walking.agent import desired_direction, facing_headings

    d = observation_size(6, 8, "egocentric")
    rng = np.random.default_rng(1)
    pf = MLPPolicyFile([rng.normal(0, 0.3, (d, 4))], [np.array([0.8, 0.0, 0.0, 0.0])], "tanh", "tanh_box",
                       np.full(2, -2.5), np.full(2, 2.5), np.zeros(d), np.full(d, 2.0),
                       env_config={"heading_target": "desired_direction", "observation_frame": "egocentric",
                                   "frame_skip": 5})
    policy = FilePolicy(save_policy_file(pf, str(tmp_path / "turn.npz")))
    scenario = {"scenario": "seyfried_bottleneck", "scenario_options": {"width_m": 0.5, "n_pedestrians": 12}}
    env = crowd_v0.parallel_env(**scenario, preset="shoulders", controlled="all", **policy.env_overrides)
    a = _positions(env, policy, 40)
    sim = env.sim
    idx = sim.active_index
    plain = np.arctan2(*desired_direction(env.navigation, sim.state.position_m, idx)[:, ::-1].T)
    assert np.abs(np.angle(np.exp(1j * (facing_headings(env.navigation, sim, idx) - plain)))).max() > 0.1
    b = _positions(crowd_v0.parallel_env(**scenario, preset="shoulders", controlled=[0], background_policy=policy,
                                         **policy.env_overrides), policy, 40)
    np.testing.assert_allclose(b, a, rtol=0, atol=1e-9)

def test_crowd_evaluate_takes_a_background_policy(tmp_path, capsys):
    from crowd_env.cli.evaluate import main

    path = _policy_file(tmp_path)
    args = ["--policies", "baseline", "--scenario-option", "n_pedestrians=6", "--controlled", "2", "--seeds", "0",
            "--max-time", "2", "--out", str(tmp_path / "eval")]
    assert main(args + ["--background", path]) == 0
    assert (tmp_path / "eval" / "results.csv").exists()
    with pytest.raises(SystemExit, match="unknown background policy 'nobody'"):
        main(args + ["--background", "nobody"])


def test_step_background_moves_the_crowd_on_after_the_agents_only():
    env = crowd_v0.parallel_env(**SCENARIO, controlled=[0], frame_skip=10, max_steps=400)
    with pytest.raises(EnvStateError, match="reset"):
        env.step_background()
    env.reset(seed=0)
    with pytest.raises(EnvStateError, match="1 agent.*live"):
        env.step_background()
    while env.agents:
        env.step({"ped_0": np.array([2.0, 0.0])})
    on_floor = int(env.sim.state.active.sum())
    t = env.sim.time_s
    assert on_floor > 0 and env.step_background() and env.sim.time_s == pytest.approx(t + 0.1)
    steps = 1
    while env.step_background():
        steps += 1
    assert not env.sim.state.active.any()  # the calibrated crowd has left
    end = env.sim.time_s  # the last step stops at the last exit
    assert t + 0.1 * (steps - 1) < end <= t + 0.1 * steps + 1e-9
    assert not env.step_background() and env.sim.time_s == end



def test_a_shipped_clone_walks_a_crowd_out_as_its_background():
    """The shipped behaviour clone of the calibrated model, by name as the background of a 20-person
    bottleneck crowd, walks everybody out without overlap at the calibrated crowd's flow (the shipped PPO
    policy there gives less than half of it)."""
    from baselines.reference_policies import as_policy
    from baselines.trained import list_trained
    from crowd_env.experiments.running.evaluation import ScenarioSpec, run_episode

    assert "bottleneck_bc" in list_trained()
    spec = ScenarioSpec("seyfried_bottleneck", {"width_m": 1.0, "n_pedestrians": 20})
    runs = {bg: run_episode(as_policy("baseline"), spec, 5, env_options={"controlled": [0], "background_policy": bg},
                            max_time_s=60.0) for bg in ("bottleneck_bc", "calibrated")}
    for m in runs.values():
        assert m.complete and m.n_evacuated == 20 and m.min_gap_m > -1e-3
    clone, model = runs["bottleneck_bc"].specific_flow_per_m_s, runs["calibrated"].specific_flow_per_m_s
    assert abs(clone - model) < 0.10 * model


class _WalkAlongDesiredDirection:
    """An observation policy that walks along e_d at 1 m/s (its observation is e_d in the body frame), facing e_d."""

    env_overrides = {"observation_frame": "egocentric", "heading_target": "desired_direction",
                     "observation_components": ["desired_direction"], "frame_skip": 10, "action_max_m_s": 2.5}

    def actions(self, obs):
        return obs[:, :2] / np.maximum(np.hypot(obs[:, 0], obs[:, 1]), 1e-12)[:, None]


@pytest.mark.parametrize("ratio", [0.0, 1.3])
def test_a_policy_facing_e_d_turns_its_shoulders_through_a_gap_as_the_models_walkers_do(ratio):
    """A body of three circles driven by an observation policy (heading_target="desired_direction") towards a 0.40 m
    gap, narrower than its shoulders: facing e_d it stops at the gap's corners; in a model that turns the shoulders
    (ρ = 1.3) its heading target turns as the calibrated agent's does (tests/walking/test_shoulder_turn.py) and it
    goes through, turned by more than 45°."""
    import math
    from types import SimpleNamespace

    from crowd_env.core import CrowdState, Simulator
    from crowd_env.envs.drivers import intents_and_headings, observing_driver
    from crowd_env.walking import ModelParams
    from tests.walking.scenes import gap_world

    geometry, navigation = gap_world(0.20)
    params = ModelParams(body_depth_m=0.25, shoulder_turn_critical_ratio=ratio)
    sim = Simulator(CrowdState.create(np.array([[0.0, 0.0]]), radius_m=0.23, desired_speed_m_s=1.0),
                    geometry=geometry, params=params)
    driver = observing_driver(_WalkAlongDesiredDirection(), SimpleNamespace(geometry=geometry), navigation=navigation,
                              mask=np.ones(1, bool), dt_s=params.dt_s, velocity_bound_m_s=20.0,
                              travel_time_bound_s=100.0)
    crossing = None
    for _ in range(800):
        intents, heading = intents_and_headings(driver(sim), sim.state)
        sim.step(intents, desired_heading_rad=heading)
        assert sim.min_gap_m() > -1e-3
        x = sim.state.position_m[0, 0] if sim.state.active[0] else np.inf
        if crossing is None and x >= 1.05:
            crossing = abs(math.remainder(sim.state.heading_rad[0], 2 * math.pi))
    if ratio == 0.0:
        assert x < 1.0 and crossing is None  # stuck before the gap
    else:
        assert x > 1.1 and crossing > math.radians(45)
