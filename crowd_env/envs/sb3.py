"""Stable-Baselines3 view of the native vector environment: ``PPO("MlpPolicy", CrowdSB3VecEnv(...))``.

:class:`CrowdSB3VecEnv` is an SB3 :class:`~stable_baselines3.common.vec_env.VecEnv` over the slots of a
:class:`~crowd_env.envs.vector.CrowdVectorEnv` (one slot per controlled pedestrian of K copies, one
policy for all). SB3's conventions: ``dones = terminated | truncated``; on a done slot the returned
observation is the next episode's first (zeros for a slot that turns into padding: see the vector
environment's docstring), ``infos[i]["terminal_observation"]`` the last one and
``infos[i]["TimeLimit.truncated"]`` true for a truncation; ``infos[i]["episode"] = {"r", "l", "t"}``
for every agent episode that ended (not for padding), which SB3's logger reads as ``ep_rew_mean`` (no
``VecMonitor`` needed: it would count the padding episodes too). ``seed(s)`` seeds copy c with s + c
at the next reset. SB3 wants one info dict per slot, so that list is the one per-slot Python loop of a
step. Needs ``stable_baselines3`` (the ``train`` extra).
"""
from __future__ import annotations

import time

import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv

from crowd_env.errors import EnvOptionError

from .vector import CrowdVectorEnv, vector_env

__all__ = ["CrowdSB3VecEnv", "sb3_vec_env"]


class CrowdSB3VecEnv(VecEnv):
    """SB3 vector environment over ``vector``'s slots (see the module docstring)."""

    def __init__(self, vector: CrowdVectorEnv):
        if not isinstance(vector, CrowdVectorEnv):
            raise EnvOptionError(f"CrowdSB3VecEnv wraps a CrowdVectorEnv, got {type(vector).__name__}")
        self.vector = vector
        self.render_mode = vector.render_mode
        super().__init__(vector.num_envs, vector.single_observation_space, vector.single_action_space)
        self._actions = None
        self._t0 = time.perf_counter()

    def reset(self):
        seed = self._seeds[0]
        obs, _ = self.vector.reset(seed=seed)
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions) -> None:
        self._actions = actions

    def step_wait(self):
        obs, rewards, terminated, truncated, infos = self.vector.step(self._actions)
        dones = terminated | truncated
        out = [{} for _ in range(self.num_envs)]
        final = infos["final_obs"]
        episode = infos["episode_ended"]
        elapsed = round(time.perf_counter() - self._t0, 6)
        for i in np.flatnonzero(dones).tolist():
            info = out[i]
            info["terminal_observation"] = final[i]
            info["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
            if episode[i]:
                info["episode"] = {"r": float(infos["episode_return"][i]), "l": int(infos["episode_length"][i]),
                                   "t": elapsed}
        return obs, rewards.astype(np.float32), dones, out

    def close(self) -> None:
        self.vector.close()

    def get_images(self):
        return list(self.vector.render())

    def _indices(self, indices):
        if indices is None:
            return range(self.num_envs)
        if isinstance(indices, int):
            return [indices]
        return indices

    def _copies(self, indices) -> list:
        return sorted({int(self.vector.slot_copy[i]) for i in self._indices(indices)})

    def get_attr(self, attr_name, indices=None):
        """The attribute of the copy each slot belongs to (``render_mode`` and the like), in whichever process
        holds the copy."""
        slots = list(self._indices(indices))
        copies = self._copies(slots)
        values = dict(zip(copies, self.vector.call_copies(attr_name, copies=copies)))
        return [values[int(self.vector.slot_copy[i])] for i in slots]

    def set_attr(self, attr_name, value, indices=None) -> None:
        self.vector.set_attr(attr_name, [value] * len(self._copies(indices)), copies=self._copies(indices))

    def env_method(self, method_name, *method_args, indices=None, **method_kwargs):
        """The method of the copy each slot belongs to, called once per slot (as SB3 expects)."""
        slots = list(self._indices(indices))
        copies = [int(self.vector.slot_copy[i]) for i in slots]
        return list(self.vector.call_copies(method_name, *method_args, copies=copies, **method_kwargs))

    def env_is_wrapped(self, wrapper_class, indices=None):
        return [False for _ in self._indices(indices)]


def sb3_vec_env(copies: int = 1, *, seed: int | None = None, **options) -> CrowdSB3VecEnv:
    """``copies`` copies of ``crowd_v0.parallel_env(**options)`` for SB3; ``seed``: copy c gets seed + c;
    ``workers`` and ``start_method`` (in ``options``) as in :func:`~crowd_env.envs.vector.vector_env`."""
    vec = CrowdSB3VecEnv(vector_env(copies, **options))
    if seed is not None:
        vec.seed(seed)
    return vec
