"""Observation frames and the global state of crowd_v0.

Egocentric: a rigidly moved copy of a scenario (``Scenario.moved``: rotated by any angle and shifted)
gives the same observations and state, and the same body-frame actions give the same trajectories
moved along. World: the observations of the moved copy are the moved observations (so the two frames
really differ). The global state: PettingZoo's state test, fixed shape and dtype while agents leave,
determinism under seeding, and its blocks against the simulator's own arrays.
"""
from __future__ import annotations

import numpy as np
import pytest
from pettingzoo.test.state_test import test_state as pz_state_test
from pettingzoo.test.state_test import test_state_space as pz_state_space_test

from crowd_env.envs import crowd_v0
from crowd_env.envs.observations import EGOCENTRIC_OBSERVATION_FIELDS, OBSERVATION_FIELDS, observation_size
from crowd_env.envs.state import PEDESTRIAN_STATE_FIELDS, scenario_frame, state_size
from crowd_env.errors import EnvOptionError, EnvStateError
from crowd_env.scenarios import make_scenario


def _scenario(n=12):
    return make_scenario("seyfried_bottleneck", width_m=1.0, n_pedestrians=n, seed=0)


def _rollout(scenario, frame, steps=40, controlled="all", seed=3):
    """Same seeded random actions (in the action frame) for every call; positions, observations, states."""
    env = crowd_v0.parallel_env(scenario=scenario, frame_skip=5, observation_frame=frame, controlled=controlled)
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(1)
    pos, ob, st = [env.sim.state.position_m.copy()], [np.stack([obs[a] for a in env.possible_agents])], [env.state()]
    for _ in range(steps):
        if not env.agents:
            break
        draws = rng.uniform(-1.0, 1.5, size=(len(env.possible_agents), 2))
        actions = {a: draws[k] for k, a in enumerate(env.possible_agents) if a in env.agents}
        obs, *_ = env.step(actions)
        pos.append(env.sim.state.position_m.copy())
        ob.append(np.stack([obs[a] for a in env.agents]) if env.agents else np.zeros((0, ob[0].shape[1])))
        st.append(env.state())
    return pos, ob, st, env


def _rotation(phi):
    c, s = np.cos(phi), np.sin(phi)
    return np.array([[c, -s], [s, c]])


@pytest.mark.parametrize("phi", [0.7, np.pi / 2, np.pi, -2.3])
@pytest.mark.parametrize("controlled", ["all", 0.5])
def test_egocentric_frame_is_invariant_under_rigid_motions(phi, controlled):
    shift = np.array([3.0, -2.0])
    scenario = _scenario()
    p0, o0, s0, _ = _rollout(scenario, "egocentric", controlled=controlled)
    p1, o1, s1, _ = _rollout(scenario.moved(phi, shift), "egocentric", controlled=controlled)
    assert len(p0) == len(p1) > 30
    rot = _rotation(phi)
    for a, b in zip(p0, p1):  # the trajectories, moved along (solver round-off grows over 200 sub-steps)
        np.testing.assert_allclose(a @ rot.T + shift, b, rtol=0, atol=1e-8)
    for a, b in zip(o0, o1):  # float32 observations: equal to their rounding
        assert a.shape == b.shape
        np.testing.assert_allclose(a, b, rtol=0, atol=2e-5)
    for a, b in zip(s0, s1):
        np.testing.assert_allclose(a, b, rtol=0, atol=5e-5)


def test_world_frame_observations_turn_with_the_scenario():
    phi = 0.7
    scenario = _scenario()
    _, o0, _, env = _rollout(scenario, "world", steps=1)
    _, o1, _, _ = _rollout(scenario.moved(phi, (3.0, -2.0)), "world", steps=1)
    L = env.observation_layout
    rot = _rotation(phi)
    for field in ("velocity", "desired_direction"):
        np.testing.assert_allclose(o0[0][:, L[field]] @ rot.T, o1[0][:, L[field]], atol=2e-5)
    assert np.abs(o0[0][:, L["desired_direction"]] - o1[0][:, L["desired_direction"]]).max() > 0.1
    np.testing.assert_allclose(o0[0][:, L["wall_rays"]], o1[0][:, L["wall_rays"]], atol=2e-5)


def test_egocentric_layout_and_body_frame_values():
    env = crowd_v0.parallel_env(scenario=_scenario(6), observation_frame="egocentric", n_neighbors=3, n_rays=4)
    obs, _ = env.reset(seed=0)
    assert env.observation_space(env.possible_agents[0]).shape == (observation_size(3, 4, "egocentric"),) == (24,)
    assert [f.name for f in EGOCENTRIC_OBSERVATION_FIELDS] == [f.name for f in OBSERVATION_FIELDS if f.name != "heading"]
    L = env.observation_layout
    st = env.sim.state
    for k, a in enumerate(env.possible_agents):
        th = st.heading_rad[k]
        forward, left = np.array([np.cos(th), np.sin(th)]), np.array([-np.sin(th), np.cos(th)])
        e_d = env.navigation.direction(st.position_m[k:k + 1])[0]
        np.testing.assert_allclose(obs[a][L["desired_direction"]], [e_d @ forward, e_d @ left], atol=1e-6)
        rel = obs[a][L["neighbors"]].reshape(3, 4)
        mask = obs[a][L["neighbor_mask"]]
        for slot in np.flatnonzero(mask):
            d = rel[slot, :2]
            # the neighbour at body-frame offset d is at world offset forward*d_x + left*d_y
            j = np.argmin(np.linalg.norm(st.position_m - (st.position_m[k] + forward * d[0] + left * d[1]), axis=1))
            assert j != k and np.linalg.norm(st.position_m[j] - st.position_m[k]) == pytest.approx(np.hypot(*d), abs=1e-5)


def test_egocentric_action_is_forward_and_left_of_the_heading():
    """A pure 'forward' or 'left' intent moves a lone pedestrian along its heading or to its left, whichever
    way it faces (from rest, 0.2 s at τ = 0.5 s: about 3.7 cm for 1 m/s)."""
    scenario = make_scenario("seyfried_bottleneck", width_m=1.0, n_pedestrians=1, seed=0)
    for phi in (0.0, 2.0):
        for action, axis in (([1.0, 0.0], 0), ([0.0, 1.0], 1)):
            env = crowd_v0.parallel_env(scenario=scenario.moved(phi), observation_frame="egocentric", frame_skip=20,
                                        params={"social_forces": False})
            env.reset(seed=0)
            th = env.sim.state.heading_rad[0]
            frame = np.array([[np.cos(th), np.sin(th)], [-np.sin(th), np.cos(th)]])  # forward, left
            p0 = env.sim.state.position_m[0].copy()
            env.step({env.possible_agents[0]: np.array(action)})
            d = frame @ (env.sim.state.position_m[0] - p0)
            assert d[axis] > 0.03 and abs(d[1 - axis]) < 0.1 * d[axis]


def test_unknown_frame_is_refused_by_name():
    with pytest.raises(EnvOptionError, match="observation_frame must be one of \\['world', 'egocentric'\\]"):
        crowd_v0.parallel_env(scenario=_scenario(4), observation_frame="body")


# ------------------------------------------------------------------ the global state
@pytest.mark.parametrize("frame", ["world", "egocentric"])
def test_pettingzoo_state_tests(frame):
    env = crowd_v0.env(scenario=_scenario(6), frame_skip=10, observation_frame=frame, max_steps=30)
    pz_state_space_test(env)
    pz_state_test(env, num_cycles=30)


def test_state_keeps_its_shape_while_agents_leave_and_zeroes_those_gone():
    env = crowd_v0.parallel_env(scenario=_scenario(8), frame_skip=10, controlled=0.5)
    env.reset(seed=2)
    n, e = 8, len(env.geometry.exits)
    assert env.state_space.shape == (state_size(n, e),) == (11 * n + 1 + 2 * e,)
    left = set()
    while env.agents:
        actions = {a: np.clip(env.navigation.direction(env.sim.state.position_m[[int(a[4:])]])[0] * 1.3, -2.5, 2.5)
                   for a in env.agents}
        env.step(actions)
        s = env.state()
        assert s.dtype == np.float32 and s.shape == env.state_space.shape and env.state_space.contains(s)
        ped = s[env.state_layout["pedestrians"]].reshape(n, len(PEDESTRIAN_STATE_FIELDS))
        active = env.sim.state.active
        np.testing.assert_array_equal(ped[:, 0], active.astype(np.float32))
        np.testing.assert_array_equal(ped[:, 1], env.controlled_mask.astype(np.float32))
        assert not ped[~active][:, [0] + list(range(2, 11))].any()
        np.testing.assert_allclose(ped[active, 2:4], env.sim.state.position_m[active], atol=1e-5)
        np.testing.assert_allclose(ped[active, 4:6], env.sim.state.velocity_m_s[active], atol=1e-5)
        left |= set(np.flatnonzero(~active).tolist())
    assert len(left) >= 2  # some pedestrians left during the episode
    assert s[env.state_layout["episode_fraction"]][0] == pytest.approx(env._steps / env.max_steps)


def test_state_is_seeded_and_refused_before_reset():
    env = crowd_v0.parallel_env(scenario="seyfried_bottleneck", scenario_options={"width_m": 1.0, "n_pedestrians": 6})
    with pytest.raises(EnvStateError, match="reset\\(\\) before state\\(\\)"):
        env.state()
    states = []
    for seed in (5, 5, 6):
        env.reset(seed=seed)
        states.append(env.state())
    np.testing.assert_array_equal(states[0], states[1])
    assert not np.array_equal(states[0], states[2])  # another seed, other start positions


def test_scenario_frame_points_from_the_centroid_to_the_first_exit():
    g = _scenario(4).geometry
    origin, c, s = scenario_frame(g)
    exit_centre = np.array(g.exits[0].centroid.coords[0])
    d = exit_centre - origin
    assert np.hypot(c, s) == pytest.approx(1.0)
    assert c * d[1] - s * d[0] == pytest.approx(0.0, abs=1e-9) and np.dot([c, s], d) > 0
    env = crowd_v0.parallel_env(scenario=_scenario(4), observation_frame="egocentric")
    env.reset(seed=0)
    exits = env.state()[env.state_layout["exits"]].reshape(-1, 2)
    np.testing.assert_allclose(exits[0], [np.hypot(*d), 0.0], atol=1e-5)  # the first exit lies on the +x axis
