"""A user's reward term, in a module of its own: ``tests/envs/test_components.py`` names it in the
environment's options as ``"tests.envs.user_reward_term:ContactCount"``; nothing else is edited to add it."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from crowd_env.envs.rewards import RewardTerm


@dataclass(frozen=True)
class ContactCount(RewardTerm):
    """−(number of contacts this step): a penalty per contact, whatever its percussion."""

    weight: float = 0.05
    name = "contact_count"

    def value(self, env, info):
        return -info["n_contacts"]


def blas_threads_reward(env, agent_ids, info):
    """A reward_fn that pays each agent the number of BLAS threads of the process that steps it (for the test
    that the vector environment's worker processes run one)."""
    from threadpoolctl import threadpool_info

    n = max(lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas")
    return np.full(len(agent_ids), float(n))
