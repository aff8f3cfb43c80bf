"""A native vector environment: every controlled pedestrian of K copies of ``crowd_v0`` as one batch.

:class:`CrowdVectorEnv` is a Gymnasium :class:`~gymnasium.vector.VectorEnv` of ``num_envs = K × A``
*slots* (K copies, A = ``len(possible_agents)`` agents each; slot ``c A + a`` is agent ``a`` of copy
``c``), for parameter sharing: one policy acts for all slots. Observations ``(K A, D)`` float32, actions
``(K A, 2)``, rewards, terminations and truncations ``(K A,)``, built in arrays: each step loops over the
K copies, never over agents (each copy advances through the same array core as the PettingZoo API,
:meth:`~crowd_env.envs.crowd_v0.CrowdParallelEnv._advance`). ``stable_baselines3`` trains on it through
:class:`crowd_env.envs.sb3.CrowdSB3VecEnv`; TorchRL wraps it as a Gymnasium vector environment.

Agents that leave (black death, with a mask):
    On the step its agent leaves (terminated: it reached an exit; truncated: ``max_steps``), a slot
    reports ``terminated`` / ``truncated`` with the agent's last observation in ``infos["final_obs"]``
    (mask ``infos["_final_obs"]``) and its episode return and length in ``infos["episode_return"]``
    and ``infos["episode_length"]`` (mask ``infos["episode_ended"]``). Until its copy resets, the slot is *padding*:
    observation zeros, reward 0, neither terminated nor truncated, its action ignored (any value),
    ``infos["alive"]`` False. ``infos["acted"]`` marks the slots whose action was used this step, so
    an algorithm can mask padding out instead of learning on it.
Automatic reset per copy (Gymnasium's ``AutoresetMode.SAME_STEP``):
    when the last agent of a copy ends, the copy resets in the same step: its slots return the first
    observations of the new episode, and the padding slots end their padding episode with
    ``terminated`` True (final observation zeros, ``episode_ended`` False), so no return crosses the reset.
Infos:
    a flat dict of ``(K A, …)`` arrays with the same keys after :meth:`~CrowdVectorEnv.reset` and every
    step (``alive``, ``acted``, ``copy``, ``final_obs``, ``_final_obs``, ``episode_return``,
    ``episode_length``, ``episode_ended``), so batch readers such as TorchRL's see fixed specs.
Seeding per copy:
    ``reset(seed=s)`` resets copy c with seed ``s + c`` (or ``seed=[s_0, …, s_{K−1}]``); later automatic
    resets continue each copy's stream. Copy c then gives exactly the observations, rewards and
    trajectories of ``crowd_v0.parallel_env(**options)`` reset with the same seed and fed the same
    actions (``tests/envs/test_vector.py``).
Global state:
    :meth:`CrowdVectorEnv.state` is ``(K, S)`` (:meth:`~crowd_env.envs.crowd_v0.CrowdParallelEnv.state` of
    each copy); ``slot_copy[i]`` is the copy of slot i, so ``state()[slot_copy]`` is each slot's.
"""
from __future__ import annotations

from crowd_env.errors import ActionError, EnvOptionError, EnvStateError

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from .crowd_v0 import CrowdParallelEnv, parallel_env

__all__ = ["CrowdVectorEnv", "vector_env"]


def _spaces_key(env: CrowdParallelEnv) -> tuple:
    a = env.possible_agents[0]
    return (env.observation_space(a), env.action_space(a), len(env.possible_agents), env.dt_s, env.state_space,
            env.observation_frame)


class CrowdVectorEnv(VectorEnv):
    """K copies of the crowd environment as one batch of slots (see the module docstring).

    Build it with :func:`vector_env` (K copies of the same options) or from ready environments with
    ``CrowdVectorEnv(envs)``: they must share observation, action and state spaces, agent count and
    decision interval (:class:`~crowd_env.errors.EnvOptionError` names the first difference).
    """

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP, "render_modes": ["rgb_array"]}

    def __init__(self, envs):
        envs = list(envs)
        if not envs:
            raise EnvOptionError("a vector environment needs at least one copy")
        for k, e in enumerate(envs):
            if not isinstance(e, CrowdParallelEnv):
                raise EnvOptionError(f"copy {k} is a {type(e).__name__}, not a crowd_v0 CrowdParallelEnv")
        names = ("observation space", "action space", "number of agents", "decision interval dt_s", "state space",
                 "observation_frame")
        ref = _spaces_key(envs[0])
        for k, e in enumerate(envs[1:], 1):
            key = _spaces_key(e)
            for name, a, b in zip(names, ref, key):
                if a != b:
                    raise EnvOptionError(f"copy {k} does not match copy 0: its {name} is {b}, copy 0's is {a}")
        self.envs = envs
        self.n_copies = len(envs)
        self.n_agents = len(envs[0].possible_agents)
        self.num_envs = self.n_copies * self.n_agents
        first = envs[0].possible_agents[0]
        self.single_observation_space = envs[0].observation_space(first)
        self.single_action_space = envs[0].action_space(first)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.single_state_space = envs[0].state_space
        self.render_mode = envs[0].render_mode
        self.autoreset_mode = AutoresetMode.SAME_STEP
        self.slot_copy = np.repeat(np.arange(self.n_copies), self.n_agents)
        self.slot_agent = np.tile(np.arange(self.n_agents), self.n_copies)
        # per copy: pedestrian index -> agent position (slot offset), -1 for background pedestrians
        self._position = []
        for e in envs:
            pos = np.full(e.n_pedestrians, -1, np.int64)
            pos[[e._index_of[a] for a in e.possible_agents]] = np.arange(self.n_agents)
            self._position.append(pos)
        self._dim = self.single_observation_space.shape[0]
        self._alive = np.zeros(self.num_envs, bool)
        self._return = np.zeros(self.num_envs)
        self._length = np.zeros(self.num_envs, np.int64)
        self._a_max = envs[0]._a_max_check
        self._started = False

    # ------------------------------------------------------------------ API
    def reset(self, *, seed=None, options=None):
        """Reset every copy; returns ``(observations (K A, D), infos)``. ``seed``: an int
        s (copy c gets s + c), a list of K ints or None (continue each copy's stream)."""
        if seed is None or isinstance(seed, (int, np.integer)):
            seeds = [None if seed is None else int(seed) + c for c in range(self.n_copies)]
        else:
            seeds = list(seed)
            if len(seeds) != self.n_copies:
                raise EnvOptionError(f"reset(seed=...) needs one seed per copy ({self.n_copies}), got {len(seeds)}")
        obs = np.zeros((self.num_envs, self._dim), np.float32)
        for c, (env, s) in enumerate(zip(self.envs, seeds)):
            rows, first = self._reset_copy(c, env, s, options)
            obs[rows] = first
        self._return[:] = 0.0
        self._length[:] = 0
        self._started = True
        n = self.num_envs
        return obs, self._infos(np.zeros(n, bool), np.zeros((n, self._dim), np.float32), np.zeros(n, bool),
                                np.zeros(n), np.zeros(n, np.int64), np.zeros(n, bool))

    def _infos(self, acted, final_obs, has_final, ep_r, ep_l, has_ep) -> dict:
        return {"alive": self._alive.copy(), "acted": acted, "copy": self.slot_copy.copy(), "final_obs": final_obs,
                "_final_obs": has_final, "episode_return": ep_r, "episode_length": ep_l, "episode_ended": has_ep}

    def _reset_copy(self, c: int, env: CrowdParallelEnv, seed, options=None):
        """Reset copy c; returns its slot range and first observations (A, D)."""
        o, _ = env.reset(seed=seed, options=options)
        rows = slice(c * self.n_agents, (c + 1) * self.n_agents)
        self._alive[rows] = True
        return rows, np.stack([o[a] for a in env.possible_agents])

    def _check_actions(self, actions) -> np.ndarray:
        try:
            arr = np.asarray(actions, dtype=np.float64)
        except (TypeError, ValueError):
            raise ActionError(f"actions must be a numeric ({self.num_envs}, 2) array, got {type(actions).__name__}") from None
        if arr.shape != (self.num_envs, 2):
            raise ActionError(f"actions must have shape ({self.num_envs}, 2) (one velocity intent per slot: "
                              f"{self.n_copies} copies x {self.n_agents} agents), got {arr.shape}")
        live = self._alive
        bad = live & ~np.isfinite(arr).all(axis=1)
        if bad.any():
            raise ActionError(f"non-finite action(s) in live slot(s) {np.flatnonzero(bad)[:10].tolist()}")
        out = live & (np.abs(arr) > self._a_max).any(axis=1)
        if out.any():
            i = np.flatnonzero(out)
            a = self.envs[0].action_max_m_s
            raise ActionError(f"action(s) of live slot(s) {i[:10].tolist()} outside the action space Box(-{a:g}, {a:g}) "
                              f"m/s: {arr[i[:3]].tolist()}; the environment does not clip")
        return arr

    def step(self, actions):
        """One environment step of every copy; returns ``(obs, rewards, terminations, truncations, infos)`` as
        arrays over the slots (see the module docstring for padding slots and automatic resets)."""
        if not self._started:
            raise EnvStateError("call reset() before step()")
        arr = self._check_actions(actions)
        n, A = self.num_envs, self.n_agents
        obs = np.zeros((n, self._dim), np.float32)
        rewards = np.zeros(n)
        terminated = np.zeros(n, bool)
        truncated = np.zeros(n, bool)
        final_obs = np.zeros((n, self._dim), np.float32)
        has_final = np.zeros(n, bool)
        ep_r = np.zeros(n)
        ep_l = np.zeros(n, np.int64)
        has_ep = np.zeros(n, bool)
        acted = self._alive.copy()
        for c, env in enumerate(self.envs):
            base = c * A
            slots = base + self._position[c][env._agent_index]  # the live agents' slots, in env.agents order
            o, r, te, tr, _ = env._advance(arr[slots])
            rewards[slots] = r
            self._return[slots] += r
            self._length[slots] += 1
            done = te | tr
            terminated[slots] = te
            truncated[slots] = tr
            ended = slots[done]
            final_obs[ended] = o[done]
            has_final[ended] = True
            ep_r[ended], ep_l[ended], has_ep[ended] = self._return[ended], self._length[ended], True
            self._return[ended], self._length[ended] = 0.0, 0
            self._alive[ended] = False
            kept = slots[~done]
            obs[kept] = o[~done]
            if not env.agents:  # the copy's episode is over: reset it in this step
                rows = slice(base, base + A)
                padding = np.arange(base, base + A)[~acted[rows]]
                terminated[padding] = True
                has_final[padding] = True  # final observation: zeros
                rows, first = self._reset_copy(c, env, None)
                obs[rows] = first
                self._return[rows], self._length[rows] = 0.0, 0
        return obs, rewards, terminated, truncated, self._infos(acted, final_obs, has_final, ep_r, ep_l, has_ep)

    def state(self) -> np.ndarray:
        """The global state of every copy, ``(K, S)`` float32 (index it with ``slot_copy`` for the slots)."""
        if not self._started:
            raise EnvStateError("call reset() before state()")
        return np.stack([e.state() for e in self.envs])

    def render(self):
        """The ``rgb_array`` frame of every copy (a tuple), for copies made with ``render_mode="rgb_array"``."""
        return tuple(e.render() for e in self.envs)

    def close_extras(self, **kwargs):
        for e in getattr(self, "envs", ()):  # also after a constructor that raised
            e.close()


def vector_env(copies: int = 1, **options) -> CrowdVectorEnv:
    """K = ``copies`` copies of ``crowd_v0.parallel_env(**options)`` as one :class:`CrowdVectorEnv`."""
    if isinstance(copies, (bool, np.bool_)) or not isinstance(copies, (int, np.integer)) or copies < 1:
        raise EnvOptionError(f"copies must be an integer >= 1, got {copies!r}")
    return CrowdVectorEnv([parallel_env(**options) for _ in range(int(copies))])
