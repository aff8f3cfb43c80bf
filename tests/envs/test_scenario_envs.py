"""The scenario families beyond the bottleneck as environments: their Gymnasium ids pass check_env, and the
PettingZoo parallel API holds on the bidirectional corridor and with hand-holding groups."""
import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import parallel_api_test

import crowd_env  # noqa: F401  (registers the gymnasium ids)
from crowd_env.envs import crowd_v0


SMALL_OPTIONS = {"crowd_env/CorridorBidirectional-v0": {"n_per_direction": 3},
                 "crowd_env/RoomPillar-v0": {"n_pedestrians": 6},
                 "crowd_env/Corner90-v0": {"n_pedestrians": 6},
                 "crowd_env/BottleneckGroups-v0": {"n_pedestrians": 12, "n_pairs": 2, "n_triples": 1},
                 "crowd_env/Custom-v0": None}


@pytest.mark.parametrize("env_id", sorted(SMALL_OPTIONS))
def test_gymnasium_make_and_check_env_new_ids(env_id):
    assert env_id in gymnasium.registry
    kwargs = {"max_steps": 5}
    if SMALL_OPTIONS[env_id] is not None:
        kwargs["scenario_options"] = SMALL_OPTIONS[env_id]
    env = gymnasium.make(env_id, **kwargs)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # gymnasium's advice on non-normalised Boxes
        check_env(env.unwrapped, skip_render_check=True)
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    obs, r, term, trunc, _ = env.step(env.action_space.sample())
    assert env.observation_space.contains(obs) and np.isfinite(r)
    env.close()


def test_parallel_api_on_the_bidirectional_corridor():
    env = crowd_v0.parallel_env(scenario="corridor_bidirectional", scenario_options={"n_per_direction": 4},
                                frame_skip=5, max_steps=40)
    parallel_api_test(env, num_cycles=60)
    env = crowd_v0.parallel_env(scenario="bottleneck_groups", controlled=3, frame_skip=5, max_steps=10,
                                scenario_options={"n_pedestrians": 12, "n_pairs": 2, "n_triples": 1})
    parallel_api_test(env, num_cycles=10)
