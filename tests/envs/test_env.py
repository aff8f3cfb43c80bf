"""The PettingZoo environment, its Gymnasium single-agent view and registration."""
import subprocess
import sys
import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test, render_test, seed_test
from shapely.geometry import Polygon

import crowd_env  # noqa: F401  (registers the gymnasium ids)
from crowd_env.core import Simulator
from crowd_env.envs import OBSERVATION_FIELDS, crowd_v0
from crowd_env.envs.crowd_v0 import EnvOptionError
from crowd_env.errors import ActionError, EnvStateError, PolicyError
from crowd_env.envs.gym_single import CrowdSingleAgentEnv
from crowd_env.envs.observations import observation_layout, observation_size
from crowd_env.scenarios import Scenario, make_scenario
from tests.conftest import room_geometry

SMALL = {"scenario_options": {"n_pedestrians": 12}, "frame_skip": 5, "max_steps": 40}


def small_env(**kw):
    return crowd_v0.parallel_env(**{**SMALL, **kw})


def walk_actions(env, obs, speed=1.3):
    """Walk along the observed desired direction."""
    ed = env.observation_layout["desired_direction"]
    return {a: obs[a][ed] * np.float32(speed) for a in env.agents}


def room_scenario(n=1, positions=None, heading=0.0):
    """A 6 m x 4 m room with an exit at the right end of the floor (x in [5.5, 6])."""
    geom = room_geometry()
    pos = np.array(positions if positions is not None else [[1.0 + 1.0 * i, 2.0] for i in range(n)])
    return Scenario(geometry=geom, position_m=pos, heading_rad=np.full(len(pos), heading), name="room")


# ---------------------------------------------------------------- PettingZoo conformance
def test_parallel_api():
    parallel_api_test(small_env(), num_cycles=60)


def test_aec_api():
    api_test(crowd_v0.env(**SMALL), num_cycles=30)


def test_render_api_and_image():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # human mode on a headless machine falls back
        render_test(lambda render_mode=None: crowd_v0.env(render_mode=render_mode, **SMALL))
    env = small_env(render_mode="rgb_array", controlled=4)
    env.reset(seed=0)
    img = env.render()
    assert img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] == 3 and img.shape[0] > 50
    # learned pedestrians in blue, background ones in grey
    blue = (img[..., 2] > 150) & (img[..., 0] < 80)
    grey = (np.abs(img[..., 0].astype(int) - 166) < 6) & (np.abs(img[..., 2].astype(int) - 166) < 6)
    assert blue.sum() > 20 and grey.sum() > 20
    env.close()


def test_human_render_headless_does_not_crash():
    env = small_env(render_mode="human")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        env.reset(seed=0)
        assert env.render() is None
        env.step({a: np.zeros(2, np.float32) for a in env.agents})
    env.close()


def test_seed_tests():
    seed_test(lambda: crowd_v0.env(**SMALL), num_cycles=10)
    parallel_seed_test(lambda: small_env(), num_cycles=10)


# ---------------------------------------------------------------- determinism
def _rollout(seed, steps=120, action_seed=5):
    env = crowd_v0.parallel_env(scenario_options={"n_pedestrians": 15}, frame_skip=1, max_steps=1000)
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(action_seed)
    frames = [np.stack([obs[a] for a in env.possible_agents])]
    rewards = []
    for _ in range(steps):
        acts = {a: rng.uniform(-1.5, 1.5, 2).astype(np.float32) + 0.8 * obs[a][4:6] for a in env.agents}
        obs, rew, term, trunc, info = env.step(acts)
        frames.append(np.stack([obs[a] for a in sorted(obs, key=lambda s: int(s[4:]))]))
        rewards.append(np.array([rew[a] for a in sorted(rew, key=lambda s: int(s[4:]))]))
    return frames, rewards


def test_determinism_bitwise_same_seed_and_actions():
    f1, r1 = _rollout(seed=11)
    f2, r2 = _rollout(seed=11)
    assert len(f1) == 121
    for a, b in zip(f1, f2):
        assert a.dtype == np.float32 and a.tobytes() == b.tobytes()
    for a, b in zip(r1, r2):
        assert a.tobytes() == b.tobytes()
    f3, _ = _rollout(seed=12)
    assert any(a.tobytes() != b.tobytes() for a, b in zip(f1, f3))


def test_reset_without_seed_continues_stream_and_reseed_scenario():
    env = crowd_v0.parallel_env(scenario_options={"n_pedestrians": 10}, max_steps=5)
    assert env.reseed_scenario  # auto: on for a named scenario with a free seed
    assert not crowd_v0.parallel_env(scenario_options={"n_pedestrians": 10, "seed": 1}).reseed_scenario
    env.reset(seed=3)
    p1 = np.array(list(env.positions_m.values()))
    env.reset(seed=3)
    assert np.array_equal(p1, np.array(list(env.positions_m.values())))
    env.reset()
    assert not np.array_equal(p1, np.array(list(env.positions_m.values())))
    with pytest.raises(EnvOptionError, match="reseed_scenario"):
        crowd_v0.parallel_env(scenario=room_scenario(), reseed_scenario=True)


# ---------------------------------------------------------------- the key equivalence
@pytest.mark.parametrize("heading_target", ["desired_direction", "intent"])
def test_equivalence_all_controlled_with_baseline_intents(heading_target):
    """Feeding the calibrated agent's intents as actions of an all-controlled env reproduces the plain
    simulator with every pedestrian on the baseline (bitwise: positions, velocities, and headings when
    the desired heading is e_d as in the baseline); a single controlled pedestrian among a background
    crowd too."""
    from baselines.social_force import SocialForceAgent

    opts = {"n_pedestrians": 20, "seed": 3}
    seed = 7
    env = crowd_v0.parallel_env(scenario_options=opts, controlled="all", action_max_m_s=100.0,
                                heading_target=heading_target, max_steps=10_000)
    env.reset(seed=seed)
    agent = SocialForceAgent(env.navigation)
    one = crowd_v0.parallel_env(scenario_options=opts, controlled=["ped_5"], action_max_m_s=100.0,
                                heading_target=heading_target, max_steps=10_000)
    one.reset(seed=seed)
    agent_one = SocialForceAgent(one.navigation)
    sc = make_scenario("seyfried_bottleneck", **opts)
    sim = Simulator(sc.make_state(np.random.default_rng(seed)), geometry=sc.geometry, params=env.params)
    ref = SocialForceAgent(sc.navigation())
    n_contacts = 0
    for _ in range(650):
        intents, _ = agent(env.sim)
        _, _, _, _, infos = env.step({a: intents[int(a[4:])] for a in env.agents})
        n_contacts += sum(i["n_contacts"] for i in infos.values())
        if one.agents:
            intents_one, _ = agent_one(one.sim)
            one.step({"ped_5": intents_one[5]})
        ri, rh = ref(sim)
        sim.step(ri, desired_heading_rad=rh)
        a, b = env.sim.state, sim.state
        assert np.array_equal(a.position_m, b.position_m)
        assert np.array_equal(a.velocity_m_s, b.velocity_m_s)
        assert np.array_equal(a.active, b.active)
        if heading_target == "desired_direction":
            assert np.array_equal(a.heading_rad, b.heading_rad)
            assert np.array_equal(a.angular_velocity_rad_s, b.angular_velocity_rad_s)
        if one.agents:
            assert np.array_equal(one.sim.state.position_m, b.position_m)
            assert np.array_equal(one.sim.state.velocity_m_s, b.velocity_m_s)
    assert n_contacts > 0, "the comparison should include contacts"
    assert (~sim.state.active).sum() >= 3, "the comparison should include exits"


# ---------------------------------------------------------------- agents, termination, truncation
def test_exit_terminates_and_removes_agent_then_empty_step():
    env = crowd_v0.parallel_env(scenario=room_scenario(2), frame_skip=10, max_steps=200)
    obs, _ = env.reset(seed=0)
    assert env.agents == ["ped_0", "ped_1"]
    seen_term = set()
    while env.agents:
        live = list(env.agents)
        obs, rew, term, trunc, info = env.step(walk_actions(env, obs, 2.0))
        assert set(obs) == set(rew) == set(term) == set(trunc) == set(info) == set(live)
        for a in live:
            if term[a]:
                seen_term.add(a)
                assert a not in env.agents and not trunc[a]
                assert info[a]["travel_time_s"] < 0.1 and rew[a] > 0.5  # exit bonus
    assert seen_term == {"ped_0", "ped_1"}
    assert env.step({}) == ({}, {}, {}, {}, {})
    with pytest.raises(ValueError, match="no live agent"):
        env.step({"ped_0": np.zeros(2)})


def test_truncation_at_max_steps():
    env = small_env(max_steps=3)
    obs, _ = env.reset(seed=0)
    for k in range(3):
        obs, rew, term, trunc, info = env.step({a: np.zeros(2, np.float32) for a in env.agents})
    assert all(trunc.values()) and not any(term.values()) and env.agents == []
    assert env.step({}) == ({}, {}, {}, {}, {})


def test_controlled_selection_and_background():
    env = small_env(controlled=3)
    assert env.possible_agents == ["ped_0", "ped_6", "ped_11"]
    assert len(small_env(controlled=0.5).possible_agents) == 6
    env = small_env(controlled=["ped_2", 7])
    assert env.possible_agents == ["ped_2", "ped_7"]
    obs, _ = env.reset(seed=1)
    before = {k: v.copy() for k, v in env.positions_m.items()}
    for _ in range(5):
        obs, *_ = env.step({a: np.zeros(2, np.float32) for a in env.agents})
    after = env.positions_m
    moved = {k for k in before if np.linalg.norm(after[k] - before[k]) > 1e-3}
    assert "ped_0" in moved  # background pedestrians walk (calibrated agent)
    assert set(env.controlled_mask.nonzero()[0]) == {2, 7}


def test_custom_background_policy_and_scenario_object():
    calls = []

    def stand_still(sim):
        calls.append(sim.step_count)
        return np.zeros((sim.state.n, 2))

    env = crowd_v0.parallel_env(scenario=room_scenario(3), controlled=["ped_0"], background_policy=stand_still,
                                frame_skip=2, max_steps=5)
    obs, _ = env.reset(seed=0)
    p0 = env.positions_m
    obs, *_ = env.step({"ped_0": np.array([1.0, 0.0])})
    assert calls == [0, 1]
    p1 = env.positions_m
    assert p1["ped_0"][0] > p0["ped_0"][0] and np.allclose(p1["ped_2"], p0["ped_2"])
    assert env.time_s == pytest.approx(0.02) and env.dt_s == pytest.approx(0.02)


def test_import_does_not_import_baselines():
    code = ("import sys, crowd_env, crowd_env.envs.crowd_v0 as m; "
            "e = m.parallel_env(scenario_options={'n_pedestrians': 5}); "
            "assert 'baselines' not in sys.modules, 'baselines imported at load'; "
            "e.reset(seed=0); assert 'baselines' not in sys.modules; "
            "e2 = m.parallel_env(scenario_options={'n_pedestrians': 5}, controlled=2); e2.reset(seed=0); "
            "assert 'baselines' not in sys.modules; "
            "assert type(e2._background_policy).__module__ == 'crowd_env.walking.agent'")
    subprocess.run([sys.executable, "-c", code], check=True)


# ---------------------------------------------------------------- observations
def test_observation_fields_layout_and_space():
    env = small_env(n_neighbors=4, n_rays=6)
    layout = env.observation_layout
    assert list(layout) == [f.name for f in OBSERVATION_FIELDS]
    assert observation_size(4, 6) == 7 + 5 * 4 + 6 == env.observation_space("ped_0").shape[0]
    assert layout == observation_layout(4, 6)
    for a in env.possible_agents:
        assert env.observation_space(a) is env.observation_space(a)
        assert env.action_space(a) is env.action_space(a)
    sp = env.action_space("ped_0")
    assert sp.shape == (2,) and sp.dtype == np.float32 and sp.high[0] == np.float32(2.5) and sp.low[0] == -2.5
    obs, _ = env.reset(seed=0)
    for _ in range(10):
        obs, *_ = env.step(walk_actions(env, obs))
    for a, o in obs.items():
        assert o.dtype == np.float32 and env.observation_space(a).contains(o)


def test_observation_contents():
    env = crowd_v0.parallel_env(scenario_options={"n_pedestrians": 20}, n_neighbors=5, n_rays=4, neighbor_radius_m=3.0)
    obs, infos = env.reset(seed=2)
    for _ in range(30):
        obs, _, _, _, infos = env.step(walk_actions(env, obs))
    L = env.observation_layout
    st = env.sim.state
    nav_dir, nav_t = env.navigation.sample(st.position_m)
    active = np.flatnonzero(st.active)
    for a, o in obs.items():
        i = int(a[4:])
        np.testing.assert_array_equal(o[L["velocity"]], st.velocity_m_s[i].astype(np.float32))
        np.testing.assert_allclose(o[L["heading"]], [np.cos(st.heading_rad[i]), np.sin(st.heading_rad[i])], atol=1e-6)
        np.testing.assert_allclose(o[L["desired_direction"]], nav_dir[i], atol=1e-6)
        assert o[L["travel_time"]][0] == pytest.approx(nav_t[i], rel=1e-6) == pytest.approx(infos[a]["travel_time_s"])
        # neighbours: the nearest others within the radius, nearest first
        others = active[active != i]
        d = np.linalg.norm(st.position_m[others] - st.position_m[i], axis=1)
        order = others[np.argsort(d)][: 5]
        order = order[np.linalg.norm(st.position_m[order] - st.position_m[i], axis=1) < 3.0]
        mask = o[L["neighbor_mask"]]
        assert mask.sum() == len(order) and np.all(mask[: len(order)] == 1)
        rel = o[L["neighbors"]].reshape(5, 4)
        np.testing.assert_allclose(rel[: len(order), :2], st.position_m[order] - st.position_m[i], atol=1e-5)
        np.testing.assert_allclose(rel[: len(order), 2:], st.velocity_m_s[order] - st.velocity_m_s[i], atol=1e-5)
        assert np.all(rel[len(order):] == 0)
        assert infos[a]["speed_m_s"] == pytest.approx(np.linalg.norm(st.velocity_m_s[i]))


def test_wall_rays_relative_to_heading():
    # one pedestrian at (1, 2) heading +y (pi/2) in a 6 x 4 room: ray 0 (ahead) hits y = 4 at 2 m,
    # ray 1 (left, -x) hits x = 0 at 1 m, ray 2 (behind) 2 m, ray 3 (right, +x) is open to the exit -> 4.5 m
    env = crowd_v0.parallel_env(scenario=room_scenario(positions=[[1.0, 2.0]], heading=np.pi / 2), n_rays=4,
                                ray_range_m=10.0, n_neighbors=2)
    obs, _ = env.reset(seed=0)
    o = obs["ped_0"]
    np.testing.assert_allclose(o[env.observation_layout["wall_rays"]], [2.0, 1.0, 2.0, 10.0], atol=1e-6)
    assert np.all(o[env.observation_layout["neighbor_mask"]] == 0)


# ---------------------------------------------------------------- rewards and infos
def test_collision_percussion_in_infos_and_reward():
    captured = {}

    def reward_fn(env, agent_ids, info):
        captured.update({k: np.copy(v) for k, v in info.items()})
        return {a: 0.0 for a in agent_ids}

    # two pedestrians walking into each other head-on
    env = crowd_v0.parallel_env(scenario=room_scenario(positions=[[2.0, 2.0], [3.0, 2.0]]), frame_skip=10,
                                max_steps=20, reward_fn=reward_fn)
    env.reset(seed=0)
    total, contacts = 0.0, 0
    for _ in range(8):
        _, rew, _, _, info = env.step({"ped_0": np.array([2.0, 0.0]), "ped_1": np.array([-2.0, 0.0])})
        total += info["ped_0"]["contact_percussion_kg_m_s"]
        contacts += info["ped_0"]["n_contacts"]
        assert rew == {"ped_0": 0.0, "ped_1": 0.0}
        assert info["ped_0"]["contact_percussion_kg_m_s"] == pytest.approx(info["ped_1"]["contact_percussion_kg_m_s"])
        assert info["ped_0"]["n_contacts"] == info["ped_1"]["n_contacts"]
    assert total > 10.0 and contacts > 0
    assert set(captured) >= {"progress_s", "contact_percussion_kg_m_s", "n_contacts", "travel_time_s", "speed_m_s",
                             "exited", "dt_s", "agent_index"}
    # default reward = progress - 0.01 * percussion - 0.1 * dt (+ 1 on exit)
    env = crowd_v0.parallel_env(scenario=room_scenario(positions=[[2.0, 2.0], [3.0, 2.0]]), frame_skip=10, max_steps=20)
    _, infos = env.reset(seed=0)
    t0 = {a: infos[a]["travel_time_s"] for a in env.agents}
    for _ in range(4):
        _, rew, _, _, info = env.step({"ped_0": np.array([2.0, 0.0]), "ped_1": np.array([-2.0, 0.0])})
        for a in rew:
            expect = t0[a] - info[a]["travel_time_s"] - 0.01 * info[a]["contact_percussion_kg_m_s"] - 0.1 * 0.1
            assert rew[a] == pytest.approx(expect)
            t0[a] = info[a]["travel_time_s"]


# ---------------------------------------------------------------- bad inputs
@pytest.mark.parametrize("bad, match", [
    (np.array([3.0, 0.0]), "outside the action space"),
    (np.array([np.nan, 0.0]), "non-finite"),
    (np.array([1.0, 0.0, 0.0]), "shape"),
    ("fast", "not numeric"),
])
def test_bad_actions_raise(bad, match):
    env = small_env()
    env.reset(seed=0)
    acts = {a: np.zeros(2) for a in env.agents}
    acts["ped_3"] = bad
    with pytest.raises(ValueError, match=match):
        env.step(acts)


def test_complex_and_non_finite_actions_are_named_beside_their_agents():
    """Regression (issue 52): a complex action was cast to real with only numpy's ComplexWarning; the NaN error
    named 4 agents but showed 3 values; step() of the Gymnasium view before reset() said 'the episode is over'."""
    import warnings

    env = small_env(controlled=["ped_0", "ped_1", "ped_2", "ped_3"])
    env.reset(seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # numpy's ComplexWarning would be an error here: none is raised
        with pytest.raises(ActionError, match=r"^complex action\(s\) of \['ped_1'\]: a velocity intent is two real"):
            env.step({a: (np.array([0.5 + 1j, 0.0]) if a == "ped_1" else np.zeros(2)) for a in env.agents})
    with pytest.raises(ActionError, match=r"^non-finite action\(s\) for ped_0 \[nan, 0.0\], ped_1 \[nan, 0.0\], "
                                          r"ped_2 \[nan, 0.0\], ped_3 \[nan, 0.0\]$"):
        env.step({a: np.array([np.nan, 0.0]) for a in env.agents})
    many = small_env()
    many.reset(seed=0)
    with pytest.raises(ActionError, match=r"ped_4 \[9.0, 0.0\] \(12 in all\) outside the action space"):
        many.step({a: np.array([9.0, 0.0]) for a in many.agents})
    with pytest.raises(EnvStateError, match=r"^call reset\(\) before step\(\)$"):
        CrowdSingleAgentEnv(scenario_options={"n_pedestrians": 4}).step(np.zeros(2))


def test_action_bound_is_inclusive_and_exact():
    env = small_env(action_max_m_s=2.3, controlled=2)
    env.reset(seed=0)
    high = env.action_space("ped_0").high
    env.step({"ped_0": np.array([2.3, -2.3]), "ped_11": high})  # float64 a_max and float32 high both pass
    with pytest.raises(ValueError, match="outside the action space"):
        env.step({"ped_0": np.array([np.nextafter(2.3, 3.0), 0.0]), "ped_11": high})


def test_bad_agent_ids_raise():
    env = small_env(controlled=["ped_0", "ped_1"])
    env.reset(seed=0)
    with pytest.raises(ValueError, match="unknown agent"):
        env.step({"ped_0": np.zeros(2), "ped_1": np.zeros(2), "ped_9": np.zeros(2)})
    with pytest.raises(ValueError, match="missing action"):
        env.step({"ped_0": np.zeros(2)})
    with pytest.raises(ValueError, match="dict"):
        env.step([np.zeros(2), np.zeros(2)])
    with pytest.raises(ValueError, match="unknown agent"):
        env.observation_space("ped_5")


def test_bad_options_raise():
    with pytest.raises(EnvOptionError, match="unknown option.*'n_agents'"):
        crowd_v0.parallel_env(n_agents=3)
    with pytest.raises(ValueError, match="unknown option.*'people'"):
        crowd_v0.parallel_env(scenario_options={"people": 3})
    with pytest.raises(ValueError, match="unknown scenario"):
        crowd_v0.parallel_env(scenario="nowhere")
    with pytest.raises(EnvOptionError, match="scenario_options"):
        crowd_v0.parallel_env(scenario=room_scenario(), scenario_options={"n_pedestrians": 3})
    for controlled, match in ((0, "controlled"), (13, "has 12"), (1.5, "fraction"), (["ped_99"], "unknown pedestrian"),
                              (["ped_1", 1], "duplicate"), ([], "no pedestrian"), ("some", "controlled"),
                              (True, "controlled")):
        with pytest.raises(EnvOptionError, match=match):
            small_env(controlled=controlled)
    for kw in ({"frame_skip": 0}, {"max_steps": -1}, {"action_max_m_s": np.inf}, {"n_neighbors": 1.5},
               {"render_mode": "ansi"}, {"heading_target": "up"}, {"reward_fn": 3}, {"params": "fast"},
               {"background_policy": "social"}):
        with pytest.raises(EnvOptionError):
            small_env(**kw)
    with pytest.raises(ValueError, match="unknown model parameter"):
        small_env(params={"dt": 0.1})


def test_bad_reward_fn_output_raises():
    env = small_env(reward_fn=lambda env, ids, info: np.zeros(len(ids) + 1))
    env.reset(seed=0)
    with pytest.raises(ValueError, match="one per agent"):
        env.step({a: np.zeros(2) for a in env.agents})


def _terms_writer(make):
    """A reward_fn that returns zeros and puts ``make(n)`` in info["reward_terms"]."""
    def reward_fn(env, ids, info):
        info["reward_terms"] = make(len(ids))
        return np.zeros(len(ids))
    return reward_fn


@pytest.mark.parametrize("make, match", [
    (lambda n: {"progress": np.zeros(n)}, r"put a dict in info\['reward_terms'\]; info\['reward_terms'\] must be an"),
    (lambda n: np.zeros((n, 2)), r"put a ndarray in info\['reward_terms'\]"),
    (lambda n: np.zeros(n + 1, [("progress", float)]), r"shape \(\d+,\) in info\['reward_terms'\].*one row per agent"),
    (lambda n: np.zeros(n, [("progress", float), ("why", "U4")]), r"field\(s\) \['why'\] are not numbers"),
])
def test_a_reward_fns_bad_terms_raise_naming_them(make, match):
    env = small_env(reward_fn=_terms_writer(make))
    env.reset(seed=0)
    with pytest.raises(PolicyError, match=match):
        env.step({a: np.zeros(2) for a in env.agents})


def test_a_reward_fns_own_terms_reach_each_agents_info():
    """Integer fields are numbers too: each agent gets its row as floats, under the reward's field names."""
    terms_of = lambda n: np.array([(i, 0.5 * i) for i in range(n)], [("count", np.int64), ("half", np.float64)])
    env = small_env(reward_fn=_terms_writer(terms_of), reward_terms_in_infos=True)
    env.reset(seed=0)
    *_, infos = env.step({a: np.zeros(2) for a in env.agents})
    for i, a in enumerate(infos):
        assert infos[a]["reward_terms"] == [float(i), 0.5 * i]
        assert env.reward_terms(infos[a]) == {"count": float(i), "half": 0.5 * i}


# ---------------------------------------------------------------- inspection, pickling
def test_inspection_properties():
    env = small_env(controlled=2)
    env.reset(seed=0)
    st = env.sim.state
    pos = env.positions_m
    assert list(pos) == [f"ped_{i}" for i in range(12)]  # every pedestrian on the floor, controlled or not
    np.testing.assert_array_equal(pos["ped_4"], st.position_m[4])
    pos["ped_4"][0] = 1e9  # copies: the simulation is not touched
    assert st.position_m[4, 0] != 1e9
    assert env.radii_m["ped_0"] == pytest.approx(0.23)
    assert env.headings_rad["ped_3"] == pytest.approx(st.heading_rad[3])
    np.testing.assert_array_equal(env.velocities_m_s["ped_5"], st.velocity_m_s[5])
    assert isinstance(env.walkable_area, Polygon) and env.walkable_area.area > 10


def test_env_pickles():
    """SuperSuit copies environments with cloudpickle (core Geometry holds mappingproxies, which the
    standard pickle refuses)."""
    cloudpickle = pytest.importorskip("cloudpickle")
    env = small_env(render_mode="rgb_array")
    env.reset(seed=0)
    env.render()
    clone = cloudpickle.loads(cloudpickle.dumps(env))
    a = env.step({x: np.ones(2) for x in env.agents})[0]
    b = clone.step({x: np.ones(2) for x in clone.agents})[0]
    assert all(np.array_equal(a[k], b[k]) for k in a)


# ---------------------------------------------------------------- Gymnasium
def test_single_agent_view_passes_check_env():
    env = CrowdSingleAgentEnv(learner="ped_3", scenario_options={"n_pedestrians": 12}, frame_skip=10, max_steps=30)
    check_env(env, skip_render_check=True)
    obs, info = env.reset(seed=4)
    assert env.observation_space.contains(obs)
    done = False
    n = 0
    while not done:
        obs, r, term, trunc, info = env.step(np.array([1.0, 0.0], np.float32))
        n += 1
        done = term or trunc
    assert n <= 30
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(2, np.float32))
    with pytest.raises(EnvOptionError):
        CrowdSingleAgentEnv(controlled="all")
    with pytest.raises(EnvOptionError, match="unknown option"):
        CrowdSingleAgentEnv(speed=3)


def test_single_agent_terminates_when_learner_exits():
    env = CrowdSingleAgentEnv(scenario=room_scenario(2), frame_skip=10, max_steps=100)
    env.reset(seed=0)
    term = trunc = False
    while not (term or trunc):
        _, r, term, trunc, info = env.step(np.array([2.0, 0.0], np.float32))
    assert term and not trunc


def test_gymnasium_make_every_registered_id():
    ids = [k for k in gymnasium.registry if k.startswith("crowd_env/")]
    assert "crowd_env/Bottleneck-v0" in ids and len(ids) >= 2
    for env_id in ids:
        env = gymnasium.make(env_id)
        obs, _ = env.reset(seed=0)
        assert env.observation_space.contains(obs)
        obs, r, term, trunc, info = env.step(env.action_space.sample())
        assert env.observation_space.contains(obs) and np.isfinite(r)
        env.close()
    env = gymnasium.make("crowd_env/BottleneckSmall-v0", scenario_options={"n_pedestrians": 8}, max_steps=3)
    check_env(env.unwrapped, skip_render_check=True)
    env = gymnasium.make("crowd_env/BottleneckSmall-v0", render_mode="rgb_array")
    env.reset(seed=0)
    assert env.render().shape[2] == 3


def test_registration_is_lazy_and_complete():
    code = ("import sys, crowd_env; assert 'gymnasium' not in sys.modules; import gymnasium; "
            "assert 'crowd_env/Bottleneck-v0' in gymnasium.registry")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_render_shows_the_contact_percussions_of_the_last_step():
    """env.render() draws the percussions of the last environment step's sub-steps (crowd_env.envs.rendering)."""
    env = crowd_v0.parallel_env(scenario="seyfried_bottleneck", scenario_options={"width_m": 0.8, "n_pedestrians": 20},
                                frame_skip=5, render_mode="rgb_array")
    obs, _ = env.reset(seed=0)
    ed = env.observation_layout["desired_direction"]
    env.render()
    for _ in range(200):
        obs, _, _, _, infos = env.step({a: np.clip(2.4 * obs[a][ed], -2.5, 2.5) for a in env.agents})
        if sum(i["contact_percussion_kg_m_s"] for i in infos.values()) > 5.0:
            break
    else:
        pytest.fail("no contact in 200 steps of a crowd pushing into a 0.8 m bottleneck")
    with_contacts = env.render()
    without = env._renderer.draw(env.sim.state, env.sim.time_s, len(env.agents))  # same state, no percussions
    assert with_contacts.shape == without.shape
    assert (np.abs(with_contacts.astype(int) - without.astype(int)).sum(axis=2) > 60).sum() > 20
    np.testing.assert_array_equal(env.render(), with_contacts)  # the same step, the same frame
    env.reset(seed=1)
    np.testing.assert_array_equal(env.render()[:5], env._renderer.draw(env.sim.state, env.sim.time_s, 20)[:5])


@pytest.mark.parametrize("seed", ["abc", 1.5, -1, True])
def test_reset_refuses_a_bad_seed_naming_it(seed):
    """Issue 37, item 8: ``reset(seed="abc" / 1.5 / -1)`` raised numpy's messages, which do not name the seed."""
    from crowd_env.envs.vector import vector_env

    env = small_env()
    with pytest.raises(EnvOptionError, match=r"^seed must be None or an integer >= 0, got "):
        env.reset(seed=seed)
    single = CrowdSingleAgentEnv(scenario_options={"n_pedestrians": 12}, frame_skip=10, max_steps=30)
    with pytest.raises(EnvOptionError, match=r"^seed must be None or an integer >= 0, got "):
        single.reset(seed=seed)
    vec = vector_env(2, **SMALL)
    try:
        with pytest.raises(EnvOptionError, match=r"^seed must be None or an integer >= 0, got "):
            vec.reset(seed=seed)
        with pytest.raises(EnvOptionError, match=r"^seed\[1\] must be None or an integer >= 0, got "):
            vec.reset(seed=[0, seed])
    finally:
        vec.close()
    obs, _ = env.reset(seed=np.int64(7))  # a NumPy integer is a seed
    assert obs


def test_action_max_beyond_the_cores_bound_on_intents_is_refused_when_made():
    """An action's norm (up to a_max √2) must stay within crowd_env.core.step.MAX_INPUT_SPEED_M_S, which
    Simulator.step enforces (issue 37, item 6): the environment says so when made, not at its first step."""
    from crowd_env.core.step import MAX_INPUT_SPEED_M_S

    limit = MAX_INPUT_SPEED_M_S / np.sqrt(2.0)
    small_env(action_max_m_s=0.999 * limit)
    with pytest.raises(EnvOptionError, match=r"action_max_m_s must be at most 707\.107 m/s .*MAX_INPUT_SPEED_M_S"):
        small_env(action_max_m_s=1.001 * limit)


def test_render_after_several_steps_draws_only_the_last_steps_contacts():
    """Regression (issue 37): contacts summed over every step since the previous render() were drawn between
    the current positions, lines of 3-4 m across the room. A frame shows the last environment step's
    contacts only, between pedestrians that touch (or a pedestrian and a wall), and render() twice shows the
    same frame."""
    from crowd_env.envs.rendering import contact_segments

    env = crowd_v0.parallel_env(scenario="seyfried_bottleneck", scenario_options={"width_m": 0.8, "n_pedestrians": 20},
                                frame_skip=5, render_mode="rgb_array")
    obs, _ = env.reset(seed=0)
    ed = env.observation_layout["desired_direction"]
    env.render()
    pushed = 0
    for _ in range(200):  # no render() meanwhile: many steps of contacts
        obs, _, _, _, infos = env.step({a: np.clip(2.4 * obs[a][ed], -2.5, 2.5) for a in env.agents})
        pushed += sum(i["contact_percussion_kg_m_s"] > 0 for i in infos.values()) > 0
        if pushed >= 40 and sum(i["contact_percussion_kg_m_s"] for i in infos.values()) > 5.0:
            break
    else:
        pytest.fail("not enough contact in 200 steps of a crowd pushing into a 0.8 m bottleneck")
    st = env.sim.state
    contacts = env._percussions.peek()
    assert len(contacts[0]) > 0
    segs, _ = contact_segments(st.position_m, st.active, env.geometry.walls, contacts)
    lengths = np.hypot(*(segs[:, 1] - segs[:, 0]).T)
    assert lengths.max() < 2.0 * st.radius_m.max() + 0.05  # touching now (within one step's travel), not 3-4 m
    first = env.render()
    np.testing.assert_array_equal(env.render(), first)


def test_unknown_options_are_type_errors_in_pythons_wording():
    from crowd_env.errors import UnknownOptionError

    for make in (crowd_v0.parallel_env, crowd_v0.env, CrowdSingleAgentEnv):
        with pytest.raises(UnknownOptionError, match=r"unexpected keyword argument 'frameskip'") as info:
            make(frameskip=4)
        assert isinstance(info.value, TypeError) and isinstance(info.value, EnvOptionError)
        assert "unknown option(s) ['frameskip']" in str(info.value)


def test_torchrl_gym_env_makes_the_registered_ids():
    """Regression (issue 37): TorchRL passes frameskip and drops it only on Python's standard TypeError."""
    torchrl_envs = pytest.importorskip("torchrl.envs")
    env = torchrl_envs.GymEnv("crowd_env/BottleneckSmall-v0", frame_skip=2, scenario_options={"n_pedestrians": 6})
    td = env.rollout(3)
    assert td["next", "observation"].shape == (3, env.observation_spec["observation"].shape[-1])
    env.close()


def test_registered_ids_have_a_time_limit_and_the_native_vector_entry_point():
    """Regression (issue 37): spec.max_episode_steps was None and make_vec(vector_entry_point) failed."""
    spec = gymnasium.spec("crowd_env/BottleneckSmall-v0")
    assert spec.max_episode_steps == spec.kwargs["max_steps"] == 600
    from crowd_env.envs.vector import CrowdVectorEnv

    vec = gymnasium.make_vec("crowd_env/BottleneckSmall-v0", num_envs=3, vectorization_mode="vector_entry_point",
                             scenario_options={"n_pedestrians": 6}, max_steps=4)
    assert isinstance(vec, CrowdVectorEnv) and vec.num_envs == 3 and vec.spec.id == "crowd_env/BottleneckSmall-v0"
    obs, _ = vec.reset(seed=5)
    single = gymnasium.make("crowd_env/BottleneckSmall-v0", scenario_options={"n_pedestrians": 6}, max_steps=4)
    for c in range(3):  # slot c is the learner of copy c, seeded seed + c as gymnasium's vector envs do
        np.testing.assert_array_equal(obs[c], single.reset(seed=5 + c)[0])
    for t in range(4):
        obs, rewards, terminated, truncated, infos = vec.step(np.zeros((3, 2), np.float32))
    assert truncated.all() and not terminated.any()  # max_steps=4, as the single view
    vec.close()
    # gymnasium's time limit caps max_steps (the smaller one truncates), as TimeLimit does for make()
    vec = gymnasium.make_vec("crowd_env/BottleneckSmall-v0", num_envs=2, scenario_options={"n_pedestrians": 6},
                             max_episode_steps=2)
    assert isinstance(vec, CrowdVectorEnv) and vec.get_attr("max_steps") == (2, 2)
    vec.close()
    sync = gymnasium.make_vec("crowd_env/BottleneckSmall-v0", num_envs=2, vectorization_mode="sync",
                              scenario_options={"n_pedestrians": 6})
    assert isinstance(sync, gymnasium.vector.SyncVectorEnv)
    sync.close()


def test_max_cycles_is_pettingzoos_name_of_max_steps():
    """Regression (issue 37): PettingZoo's max_cycles was an unknown option."""
    options = {k: v for k, v in SMALL.items() if k != "max_steps"}
    env = crowd_v0.parallel_env(max_cycles=3, **options)
    assert env.max_steps == env.max_cycles == 3
    obs, _ = env.reset(seed=0)
    for _ in range(3):
        assert env.agents
        obs, _, term, trunc, _ = env.step({a: np.zeros(2, np.float32) for a in env.agents})
    assert not env.agents and all(trunc.values()) and not any(term.values())
    parallel_api_test(env, num_cycles=7)  # PettingZoo's test sets env.max_cycles itself
    assert env.max_steps == 7
    aec = crowd_v0.env(max_cycles=3, **options)
    assert aec.unwrapped.max_steps == 3
    api_test(aec, num_cycles=10)
    assert CrowdSingleAgentEnv(max_cycles=5, scenario_options={"n_pedestrians": 6}).parallel.max_steps == 5
    with pytest.raises(EnvOptionError, match="max_steps or its PettingZoo name max_cycles, not both"):
        crowd_v0.parallel_env(max_cycles=3, max_steps=4)
