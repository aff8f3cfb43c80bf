"""RL interfaces: the PettingZoo crowd environment (:mod:`crowd_env.envs.crowd_v0`), its configuration
(:mod:`crowd_env.envs.config`), its observation components and reward terms, rendering and the
single-agent Gymnasium view (:mod:`crowd_env.envs.gym_single`).

``crowd_v0.parallel_env(...)`` gives the PettingZoo ParallelEnv, ``crowd_v0.env(...)`` the AEC one.
"""
from . import crowd_v0
from .config import CrowdEnvConfig
from .crowd_v0 import CrowdParallelEnv, EnvOptionError, env, parallel_env
from .observations import OBSERVATION_FIELDS, ObservationComponent, observation_layout
from .rewards import DefaultReward, RewardTerm, TermReward

__all__ = ["crowd_v0", "CrowdParallelEnv", "CrowdEnvConfig", "EnvOptionError", "env", "parallel_env",
           "OBSERVATION_FIELDS", "observation_layout", "ObservationComponent", "DefaultReward", "RewardTerm",
           "TermReward", "CrowdSingleAgentEnv"]


def __getattr__(name):  # the Gymnasium view is imported on demand
    if name == "CrowdSingleAgentEnv":
        from .gym_single import CrowdSingleAgentEnv

        return CrowdSingleAgentEnv
    raise AttributeError(name)
