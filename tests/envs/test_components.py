"""Observations as components, rewards as terms, the environment's configuration as one dataclass.

The default observation, its bounds and the default reward are bitwise those of the environment before
the split (``tests/data/observation_reference.npz``, :mod:`tests.envs.observation_reference`); the
per-term rewards in the infos add up to the reward to the bit; a component and a term of a user's own
module (``tests/envs/user_component.py``, ``tests/envs/user_reward_term.py``) work by being named in the
options; bad options raise errors that name the option.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from crowd_env.envs import CrowdEnvConfig, crowd_v0
from crowd_env.envs.config import ENV_OPTIONS, make_config
from crowd_env.envs.observations import (COMPONENTS, DEFAULT_COMPONENTS, EGOCENTRIC_OBSERVATION_FIELDS,
                                         OBSERVATION_FIELDS, ObservationComponent, ObservationField,
                                         observation_layout)
from crowd_env.envs.observations.free_distance import FreeDistance
from crowd_env.envs.observations.local_density import LocalDensity
from crowd_env.envs.rewards import DEFAULT_TERMS, DefaultReward, TermReward, resolve_terms
from crowd_env.envs.rewards.terms import Progress, TimeCost
from crowd_env.errors import EnvOptionError, UnknownOptionError
from tests.envs.observation_reference import CASES, PATH, rollout
from tests.envs.test_env import room_scenario
from tests.envs.user_component import VelocityError

SMALL = {"scenario_options": {"n_pedestrians": 12}, "frame_skip": 5, "max_steps": 40}
USER_COMPONENT = "tests.envs.user_component:VelocityError"
USER_TERM = "tests.envs.user_reward_term:ContactCount"


def _bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a).view(np.uint8)


# ---------------------------------------------------------------- the default, bitwise as before
@pytest.mark.parametrize("case", sorted(CASES))
def test_default_observation_rewards_and_bounds_are_bitwise_the_frozen_ones(case):
    ref = np.load(PATH)
    got = rollout(*CASES[case])
    for key, value in got.items():
        want = ref[f"{case}/{key}"]
        assert value.dtype == want.dtype and value.shape == want.shape, key
        np.testing.assert_array_equal(_bits(value), _bits(want), err_msg=f"{case}/{key}")


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_fused_default_pass_equals_the_components_one_by_one(case, monkeypatch):
    """The built-in components in one compiled call (ObservationBuilder: _observe, _write_builtins) and each
    component's own ``write`` in turn give the same bits, in every frozen case."""
    from crowd_env.envs.observations.assembler import ObservationBuilder

    env = crowd_v0.parallel_env(**CASES[case][0])
    assert env._observer._fused is not None  # the default takes the fused pass
    fused = rollout(*CASES[case])
    monkeypatch.setattr(ObservationBuilder, "_compiled_table", lambda self: None)
    one_by_one = rollout(*CASES[case])
    assert fused.keys() == one_by_one.keys()
    for key in fused:
        np.testing.assert_array_equal(_bits(fused[key]), _bits(one_by_one[key]), err_msg=f"{case}/{key}")


@pytest.mark.parametrize("frame", ["world", "egocentric"])
def test_every_built_in_component_takes_the_one_compiled_pass_with_the_bits_of_its_own_write(frame, monkeypatch):
    """Any list of built-in components, a user's among them or not, is written by the one compiled pass
    (_write_builtins: every class of COMPONENTS has its kind there, so a new built-in cannot fall back to a call
    of its own unnoticed) with the bits of each component's own ``write``."""
    from crowd_env.envs.observations.assembler import _KINDS, ObservationBuilder

    assert set(COMPONENTS.values()) <= set(_KINDS)
    every = [*reversed(list(COMPONENTS)), LocalDensity(radius_m=1.7, max_count=5)]
    every.remove("local_density")
    options = dict(SMALL, scenario_options={"n_pedestrians": 12, "width_m": 1.0}, observation_frame=frame,
                   n_neighbors=3, n_rays=5)

    def run(components):
        env = crowd_v0.parallel_env(**options, observation_components=components)
        obs, _ = env.reset(seed=2)
        rows = [np.stack(list(obs.values()))]
        for _ in range(6):
            obs, *_ = env.step({a: np.array([1.0, 0.3]) for a in env.agents})
            rows.append(np.stack(list(obs.values())))
        return env, np.concatenate(rows)

    for components in (every, [every[0], USER_COMPONENT, *every[1:]]):
        env, compiled = run(components)
        assert env._observer._fused is not None  # the built-ins in the compiled pass, the user's alone from Python
        assert [type(write.__self__) for write, _, _ in env._observer._writers] == [VelocityError] * (len(components) > 8)
        with monkeypatch.context() as m:
            m.setattr(ObservationBuilder, "_compiled_table", lambda self: None)
            one_by_one = run(components)[1]
        np.testing.assert_array_equal(_bits(compiled), _bits(one_by_one))


def test_every_built_in_reward_term_is_computed_in_the_compiled_sum():
    """Each term of REWARD_TERMS names a kind that the one compiled sum computes (none left to a value() of its
    own); a subclass that computes its own value() is summed with it."""
    from crowd_env.envs.rewards import REWARD_TERMS
    from crowd_env.envs.rewards.base import GIVEN, _kind

    assert all(_kind(term()) != GIVEN for term in REWARD_TERMS.values())

    class Halved(Progress):
        def value(self, env, info):
            return 0.5 * info["progress_s"]

    assert _kind(Halved()) == GIVEN
    info = {"progress_s": np.array([0.25, -1.0]), "dt_s": 0.1}
    got = TermReward([Halved(2.0), TimeCost()])(None, [0, 1], info)
    np.testing.assert_array_equal(got, 2.0 * (0.5 * info["progress_s"]) + 0.1 * -0.1)
    with pytest.raises(KeyError, match="progress_s"):
        TermReward([Progress()])(None, [0, 1], {"dt_s": 0.1})


def test_default_fields_and_layout_are_unchanged():
    assert [f.name for f in OBSERVATION_FIELDS] == ["velocity", "heading", "desired_direction", "travel_time",
                                                   "neighbors", "neighbor_mask", "wall_rays"]
    ego = [f.name for f in EGOCENTRIC_OBSERVATION_FIELDS]
    assert ego == [f.name for f in OBSERVATION_FIELDS if f.name != "heading"]
    assert observation_layout(6, 8)["wall_rays"] == slice(37, 45)
    assert observation_layout(6, 8, "egocentric")["neighbors"] == slice(5, 29)
    # naming the defaults is the default; the heading drops out of the egocentric frame by itself
    assert observation_layout(3, 4, "egocentric", DEFAULT_COMPONENTS) == observation_layout(3, 4, "egocentric")


def test_default_reward_is_the_old_formula_to_the_bit_for_any_weights():
    rng = np.random.default_rng(0)
    n = 500
    info = {"progress_s": rng.normal(0, 0.2, n), "exited": rng.random(n) < 0.1, "dt_s": 0.1,
            "contact_percussion_kg_m_s": rng.exponential(5.0, n) * (rng.random(n) < 0.5)}
    info["progress_s"][:3] = [0.0, -0.0, 1e-300]
    for w in ((1.0, 0.01, 0.1, 1.0), (2.5, 0.3, 0.07, -4.0), (0.0, 0.0, 0.0, 0.0)):
        old = w[0] * info["progress_s"] - w[1] * info["contact_percussion_kg_m_s"] - w[2] * info["dt_s"] \
            + w[3] * info["exited"].astype(float)
        reward = DefaultReward(*w)
        got = reward(None, [None] * n, dict(info))
        np.testing.assert_array_equal(_bits(got), _bits(old))
        # the generic sum of the same terms gives the same bits and the same per-term contributions
        terms_info = dict(info)
        generic = TermReward(reward.terms)(None, [None] * n, terms_info)
        np.testing.assert_array_equal(_bits(generic), _bits(old))
        parts = dict(info)
        reward(None, [None] * n, parts)
        np.testing.assert_array_equal(_bits(parts["reward_terms"]), _bits(terms_info["reward_terms"]))


def test_reward_terms_in_the_infos_add_up_to_the_reward_to_the_bit():
    env = crowd_v0.parallel_env(scenario_options={"n_pedestrians": 8, "width_m": 1.2}, frame_skip=10,
                                heading_target="desired_direction", reward_terms_in_infos=True)
    obs, _ = env.reset(seed=3)
    ed = env.observation_layout["desired_direction"]
    exits = 0
    for _ in range(70):
        if not env.agents:
            break
        obs, rew, term, _, infos = env.step({a: 1.3 * obs[a][ed].astype(float) for a in env.agents})
        for a, r in rew.items():
            assert env.reward_term_names == DEFAULT_TERMS and all(type(x) is float for x in infos[a]["reward_terms"])
            t = env.reward_terms(infos[a])
            assert t["progress"] + t["contact_percussion"] + t["time"] + t["exit"] == r
            assert t["exit"] == (1.0 if term[a] else 0.0)
            exits += term[a]
    assert exits >= 3


def test_naming_the_default_terms_gives_the_default_rewards():
    def run(**kw):
        env = crowd_v0.parallel_env(**SMALL, **kw)
        obs, _ = env.reset(seed=1)
        out = []
        for _ in range(8):
            _, rew, *_ = env.step({a: np.array([1.0, 0.2]) for a in env.agents})
            out.append(np.array(list(rew.values())))
        return np.concatenate(out)

    np.testing.assert_array_equal(_bits(run()), _bits(run(reward_terms=list(DEFAULT_TERMS))))
    doubled = run(reward_terms={"progress": 2.0, "contact_percussion": 0.01, "time": 0.1, "exit": 1.0})
    assert not np.array_equal(doubled, run())


# ---------------------------------------------------------------- a user's component and term
def test_a_user_component_and_term_of_their_own_modules_named_in_the_options():
    env = crowd_v0.parallel_env(**SMALL, observation_components=[*DEFAULT_COMPONENTS, USER_COMPONENT],
                                reward_terms=["progress", "time", USER_TERM], reward_terms_in_infos=True)
    L = env.observation_layout
    assert list(L)[-2:] == ["velocity_error", "velocity_error_norm"] and L["velocity_error_norm"].stop == 48
    space = env.observation_space("ped_0")
    assert space.shape == (48,) and space.low[45] < 0 and space.low[47] == 0.0
    obs, _ = env.reset(seed=0)
    for _ in range(5):
        obs, rew, _, _, infos = env.step({a: np.array([0.8, 0.1]) for a in env.agents})
    st = env.sim.state
    for a, o in obs.items():
        i = int(a[4:])
        e_d, _ = env.navigation.sample(st.position_m[i:i + 1])
        want = 1.34 * e_d[0] - st.velocity_m_s[i]
        np.testing.assert_allclose(o[L["velocity_error"]], want, rtol=1e-6, atol=1e-6)
        assert o[L["velocity_error_norm"]][0] == pytest.approx(np.hypot(*want), rel=1e-6)
        assert space.contains(o)
        assert env.reward_term_names == ("progress", "time", "contact_count")
        t = env.reward_terms(infos[a])
        assert t["contact_count"] == -0.05 * infos[a]["n_contacts"]
        assert t["progress"] + t["time"] + t["contact_count"] == rew[a]


def test_a_user_component_follows_the_egocentric_frame():
    env = crowd_v0.parallel_env(**SMALL, observation_frame="egocentric",
                                observation_components=["velocity", USER_COMPONENT])
    assert list(env.observation_layout) == ["velocity", "velocity_error", "velocity_error_norm"]
    obs, _ = env.reset(seed=0)
    obs, *_ = env.step({a: np.array([0.5, 0.0]) for a in env.agents})
    st = env.sim.state
    for a, o in obs.items():
        i = int(a[4:])
        c, s = np.cos(st.heading_rad[i]), np.sin(st.heading_rad[i])
        e_d, _ = env.navigation.sample(st.position_m[i:i + 1])
        w = 1.34 * e_d[0] - st.velocity_m_s[i]
        np.testing.assert_allclose(o[2:4], [c * w[0] + s * w[1], c * w[1] - s * w[0]], rtol=1e-6, atol=1e-6)


def test_a_component_object_and_class_are_accepted():
    class Speed(ObservationComponent):
        name = "speed"
        fields = (ObservationField("speed", "1", "own speed, m/s"),)

        def bounds(self, spec):
            return 0.0, spec.velocity_bound_m_s

        def compute(self, ctx, out):
            out[:, 0] = ctx.speed_m_s

    for spec in (Speed, Speed()):
        env = crowd_v0.parallel_env(**SMALL, observation_components=["travel_time", spec])
        obs, infos = env.reset(seed=0)
        assert env.observation_space("ped_0").high[1] == np.float32(env.velocity_bound_m_s)
        assert all(o[1] == np.float32(infos[a]["speed_m_s"]) for a, o in obs.items())


# ---------------------------------------------------------------- the new built-in components
def test_free_distance_and_local_density():
    # one pedestrian at (1, 2) facing +y in the 6 m x 4 m room, a second 2 m ahead of it at (1, 4 - 0.5)
    scenario = room_scenario(positions=[[1.0, 2.0], [1.0, 3.5]], heading=np.pi / 2)
    env = crowd_v0.parallel_env(scenario=scenario, observation_components=["free_distance", "local_density"],
                                n_neighbors=2, ray_range_m=10.0)
    L = env.observation_layout
    assert L == {"free_distance": slice(0, 1), "local_density": slice(1, 2)}
    space = env.observation_space("ped_0")
    assert space.high[0] == 10.0 and space.high[1] == np.float32(33 / np.pi)
    obs, _ = env.reset(seed=0)
    r = scenario.make_state(rng=np.random.default_rng(0)).radius_m
    assert obs["ped_0"][0] == pytest.approx(1.5 - r[0] - r[1], abs=1e-6)  # the other's disc ahead
    assert obs["ped_1"][0] == pytest.approx(0.5 - r[1], abs=1e-6)  # the wall at y = 4 ahead
    assert obs["ped_0"][1] == pytest.approx(1 / np.pi, rel=1e-6)  # alone within 1 m
    dense = crowd_v0.parallel_env(scenario=scenario, observation_components=[LocalDensity(radius_m=2.0)])
    obs, _ = dense.reset(seed=0)
    assert obs["ped_0"][0] == pytest.approx(2 / (4 * np.pi), rel=1e-6)  # both within 2 m
    assert FreeDistance().uses_neighbors and set(COMPONENTS) >= {"free_distance", "local_density"}


# ---------------------------------------------------------------- errors that name the option
@pytest.mark.parametrize("value, match", [
    (["velocity", "nowhere"], r"observation_components: unknown component 'nowhere'; known: \["),
    (["tests.envs.user_component:Missing"], "observation_components: cannot import"),
    (["no_such_module_xyz:Thing"], "observation_components: cannot import"),
    ("velocity", "observation_components must be a sequence"),
    (["velocity", "velocity"], r"observation_components: the field\(s\) \['velocity'\] appear twice"),
    ([3], "observation_components: unknown component 3"),
])
def test_bad_observation_components_name_the_option(value, match):
    with pytest.raises(EnvOptionError, match=match):
        crowd_v0.parallel_env(**SMALL, observation_components=value)


def test_bounds_that_do_not_fit_name_the_option():
    class Bad(ObservationComponent):
        name = "bad"
        fields = (ObservationField("bad", "2", "two entries"),)

        def bounds(self, spec):
            return np.zeros(3), np.ones(3)

    with pytest.raises(EnvOptionError, match="observation_components: Bad.bounds"):
        crowd_v0.parallel_env(**SMALL, observation_components=[Bad()])


@pytest.mark.parametrize("kw, match", [
    ({"reward_terms": ["progress", "speed"]}, r"reward_terms: unknown term 'speed'; known: \["),
    ({"reward_terms": ["progress", "progress"]}, "reward_terms needs one or more named terms, each once"),
    ({"reward_terms": []}, "reward_terms needs one or more"),
    ({"reward_terms": "progress"}, "reward_terms must be a sequence"),
    ({"reward_terms": {"progress": "a lot"}}, "reward_terms: Progress.weight"),
    ({"reward_terms": ["tests.envs.user_reward_term:Nope"]}, "reward_terms: cannot import"),
    ({"reward_terms": ["time"], "reward_fn": DefaultReward()}, "give reward_fn or reward_terms, not both"),
])
def test_bad_reward_terms_name_the_option(kw, match):
    with pytest.raises(EnvOptionError, match=match):
        crowd_v0.parallel_env(**SMALL, **kw)


# ---------------------------------------------------------------- the configuration
def test_the_configuration_is_one_checked_dataclass():
    config = CrowdEnvConfig(scenario_options={"n_pedestrians": 12}, frame_skip=np.int64(5), max_steps=40,
                            neighbor_radius_m=3)
    assert config.frame_skip == 5 and type(config.frame_skip) is int and config.neighbor_radius_m == 3.0
    assert set(ENV_OPTIONS) == {f.name for f in dataclasses.fields(CrowdEnvConfig)}
    assert {"observation_components", "reward_terms"} <= set(ENV_OPTIONS)
    env = crowd_v0.CrowdParallelEnv(config)
    assert env.config is config and env.frame_skip == 5 and env.max_steps == 40
    same = crowd_v0.parallel_env(**SMALL, neighbor_radius_m=3)
    assert same.config == config
    a, b = env.reset(seed=4)[0], same.reset(seed=4)[0]
    assert all(np.array_equal(a[k], b[k]) for k in a)
    over = crowd_v0.CrowdParallelEnv(config, n_rays=2)  # keywords over a configuration
    assert over.config == dataclasses.replace(config, n_rays=2) and over.n_rays == 2
    assert make_config(None, {"max_cycles": 7}).max_steps == 7
    with pytest.raises(EnvOptionError, match="n_rays"):
        dataclasses.replace(config, n_rays=-1)
    with pytest.raises(UnknownOptionError, match="'n_agents'"):
        crowd_v0.CrowdParallelEnv(config, n_agents=3)
    with pytest.raises(EnvOptionError, match="config must be a CrowdEnvConfig"):
        crowd_v0.CrowdParallelEnv({"n_rays": 3})


@pytest.mark.parametrize("kw, match", [
    ({"controlled": 0}, "controlled"), ({"controlled": ["ped_1", 1]}, "duplicate"),
    ({"controlled": []}, "no pedestrian"),
    ({"frame_skip": 0}, "frame_skip"), ({"max_steps": 0}, "max_steps"), ({"render_mode": "ansi"}, "render_mode"),
    ({"heading_target": "up"}, "heading_target"), ({"observation_frame": "polar"}, "observation_frame"),
    ({"reward_fn": 3}, "reward_fn"), ({"params": "fast"}, "params"), ({"reseed_scenario": "yes"}, "reseed_scenario"),
    ({"scenario": 3}, "scenario"), ({"scenario_options": [1]}, "scenario_options"),
    ({"background_policy": 3.5}, "background_policy"), ({"action_max_m_s": 1e4}, "action_max_m_s"),
])
def test_the_configuration_refuses_bad_options_naming_them(kw, match):
    with pytest.raises(EnvOptionError, match=match):
        CrowdEnvConfig(**kw)


def test_a_term_reward_pickles_and_compares():
    cloudpickle = pytest.importorskip("cloudpickle")
    reward = resolve_terms({"progress": 2.0, USER_TERM: 0.5})
    assert reward == TermReward([Progress(2.0), reward.terms[1]]) and reward.names == ("progress", "contact_count")
    assert cloudpickle.loads(cloudpickle.dumps(reward)) == reward
