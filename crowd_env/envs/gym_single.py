"""Single-agent Gymnasium view: one learner among a crowd driven by the background policy.

The learner is one pedestrian (``learner``, default ``"ped_0"``) of a :class:`CrowdParallelEnv`
with ``controlled=[learner]``; every other pedestrian follows the background policy (the calibrated
social-force agent by default). Observation and action spaces are the learner's; the episode
terminates when the learner leaves through an exit and is truncated at ``max_steps``. All other
options go to :class:`~crowd_env.envs.crowd_v0.CrowdParallelEnv` (``controlled`` is fixed here; ``max_cycles``
is taken for ``max_steps``); an unknown one raises :class:`~crowd_env.errors.UnknownOptionError`, a
``TypeError`` in Python's wording, so TorchRL's ``GymEnv`` drops its ``frameskip`` argument on it as for any
Gymnasium environment.
"""
from __future__ import annotations

from crowd_env.errors import EnvStateError

import gymnasium

from ..core.checks import check_seed
from .config import resolve_options
from .crowd_v0 import CrowdParallelEnv, EnvOptionError

__all__ = ["CrowdSingleAgentEnv"]


class CrowdSingleAgentEnv(gymnasium.Env):
    """``gymnasium.Env`` with the spaces of one pedestrian; see the module docstring."""

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 10}

    def __init__(self, learner="ped_0", render_mode=None, **options):
        if "controlled" in options:
            raise EnvOptionError("the single-agent view controls exactly one pedestrian: pass learner=..., not "
                                 "controlled=...")
        options = resolve_options(options, "CrowdSingleAgentEnv", "CrowdSingleAgentEnv.__init__")
        self.parallel = CrowdParallelEnv(controlled=[learner], render_mode=render_mode, **options)
        self.learner = self.parallel.possible_agents[0]
        self.observation_space = self.parallel.observation_space(self.learner)
        self.action_space = self.parallel.action_space(self.learner)
        self.render_mode = render_mode
        self.metadata = {**type(self).metadata, "render_fps": self.parallel.metadata["render_fps"]}

    def reset(self, *, seed=None, options=None):
        seed = check_seed("seed", seed, error=EnvOptionError)
        super().reset(seed=seed)
        inner = seed if seed is not None else int(self.np_random.integers(0, 2**31 - 1))
        obs, infos = self.parallel.reset(seed=inner, options=options)
        return obs[self.learner], infos[self.learner]

    def step(self, action):
        """One step of the learner (the other pedestrians act by their policy): ``(observation, reward,
        terminated, truncated, info)`` of the learner, as in :meth:`gymnasium.Env.step`."""
        a = self.learner
        self.parallel.require_reset("step")
        if a not in self.parallel.agents:
            raise EnvStateError("the episode is over (the learner left or was truncated): call reset()")
        obs, rewards, terminations, truncations, infos = self.parallel.step({a: action})
        return obs[a], rewards[a], terminations[a], truncations[a], infos[a]

    def render(self):
        return self.parallel.render()

    def close(self):
        self.parallel.close()
