"""The one interface of environment policies (the evaluation harness, the scripts, :mod:`baselines.trained`).

An *environment policy* maps the parallel environment and its observations to one action per live agent::

    policy.reset(env, seed)                      # before each episode (optional state, RNG)
    actions = policy.act(env, observations)      # dict agent -> (2,) velocity intent in m/s
"""
from __future__ import annotations

import numpy as np

__all__ = ["EnvPolicy", "stack_observations"]


def stack_observations(env, observations) -> np.ndarray:
    """(n_live, D) array of the observations of ``env.agents``, in that order."""
    agents = env.agents
    if not agents:
        return np.zeros((0,) + env.observation_space(env.possible_agents[0]).shape, np.float32)
    return np.stack([observations[a] for a in agents])


class EnvPolicy:
    """Base class: override :meth:`act` (and :meth:`reset` for state)."""

    name = "policy"
    env_overrides: dict = {}

    def reset(self, env, seed=None) -> None:
        pass

    def act(self, env, observations) -> dict:
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"
