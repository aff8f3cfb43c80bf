"""Policies for the crowd environment with one interface, used by the evaluation harness and scripts.

An *environment policy* maps the parallel environment and its observations to one action per live
agent::

    policy.reset(env, seed)                      # before each episode (optional state, RNG)
    actions = policy.act(env, observations)      # dict agent -> (2,) velocity intent in m/s

``env_overrides`` (a dict) names environment options the policy needs (the calibrated baseline needs a
larger action bound, since its intents include the social force); the harness applies them. Build any
of them with :func:`as_policy` from a name (``"baseline"``, ``"random"``, ``"zero"``), a saved SB3
model path (``.zip``), an SB3 model object, or a callable.
"""
from __future__ import annotations

import os

import numpy as np

from .policy import EnvPolicy, stack_observations
from .trained import file_policy, list_trained

__all__ = ["EnvPolicy", "CalibratedPolicy", "RandomPolicy", "ZeroIntentPolicy", "SB3Policy", "CallablePolicy",
           "as_policy", "stack_observations"]


class CalibratedPolicy(EnvPolicy):
    """The calibrated eikonal + social-force agent (:class:`baselines.social_force.SocialForceAgent`)
    driving the controlled pedestrians: with every pedestrian controlled, the environment then runs the
    paper's model exactly (bitwise the same trajectories as the plain simulator). For that
    :attr:`env_overrides` asks for ``heading_target="desired_direction"``, decisions every simulator
    step (``frame_skip=1``; the model recomputes its intents every step) and an action bound of 50 m/s,
    which its intents (they include the social force) never reach."""

    name = "baseline"
    env_overrides = {"action_max_m_s": 50.0, "heading_target": "desired_direction", "frame_skip": 1}

    def __init__(self):
        self._agent = None
        self._nav = None

    def reset(self, env, seed=None) -> None:
        if self._agent is None or self._nav is not env.navigation:
            from .social_force import SocialForceAgent

            self._agent = SocialForceAgent(env.navigation)
            self._nav = env.navigation

    def act(self, env, observations) -> dict:
        if self._agent is None or self._nav is not env.navigation:
            self.reset(env)
        if not env.agents:
            return {}
        intents, _ = self._agent(env.sim)
        index = [int(a[4:]) for a in env.agents]
        return dict(zip(env.agents, intents[index]))


class RandomPolicy(EnvPolicy):
    """Uniform random intents in the action Box, from its own seeded RNG (one draw for all agents)."""

    name = "random"

    def __init__(self, seed=None):
        self._rng = np.random.default_rng(seed)

    def reset(self, env, seed=None) -> None:
        if seed is not None:
            self._rng = np.random.default_rng(seed + 1_000_003)

    def act(self, env, observations) -> dict:
        agents = env.agents
        if not agents:
            return {}
        space = env.action_space(agents[0])
        a = self._rng.uniform(space.low, space.high, size=(len(agents), 2)).astype(np.float32)
        return dict(zip(agents, a))


class ZeroIntentPolicy(EnvPolicy):
    """Intent 0 for everybody (pedestrians brake and stand: a lower bound for any policy)."""

    name = "zero"

    def act(self, env, observations) -> dict:
        z = np.zeros((len(env.agents), 2), np.float32)
        return dict(zip(env.agents, z))


class SB3Policy(EnvPolicy):
    """A Stable-Baselines3 model (or the path of a saved one) shared by all agents; one batched
    ``predict`` per step. The observation space must match the environment's (raises otherwise).

    A saved SB3 model (``.zip``) holds pickles, which run code when ``PPO.load`` reads them: load only models
    from sources you trust, and share a policy as a policy file (``.npz``: ``crowd-convert-policy``)."""

    def __init__(self, model, deterministic: bool = True, name: str | None = None):
        if isinstance(model, (str, os.PathLike)):
            path = os.fspath(model)
            if not os.path.exists(path) and not os.path.exists(path + ".zip"):  # SB3 would name path + ".zip"
                from crowd_env.errors import MissingFileError

                raise MissingFileError(f"no saved SB3 model: {path!r} does not exist"
                                       + ("" if path.endswith(".zip") else f" (nor {path + '.zip'!r})")
                                       + f" (looked in {os.path.dirname(os.path.abspath(path))})")
            from stable_baselines3 import PPO

            try:
                model = PPO.load(path, device="cpu")  # SB3's pickles: a model the user chose to trust (docstring)
            except Exception as exc:
                raise ValueError(f"cannot load an SB3 PPO model from {path!r}: {exc}") from exc
            self.name = name or os.path.splitext(os.path.basename(path))[0]
        else:
            if not hasattr(model, "predict"):
                raise TypeError(f"SB3Policy needs a model with predict(), got {type(model).__name__}")
            self.name = name or type(model).__name__
        self.model = model
        self.deterministic = bool(deterministic)

    def reset(self, env, seed=None) -> None:
        want = self.model.observation_space.shape
        have = env.observation_space(env.possible_agents[0]).shape
        if tuple(want) != tuple(have):
            raise ValueError(f"model {self.name!r} expects observations of shape {want}, the environment gives {have} "
                             "(use the same n_neighbors / n_rays as in training)")

    def act(self, env, observations) -> dict:
        if not env.agents:
            return {}
        obs = stack_observations(env, observations)
        actions, _ = self.model.predict(obs, deterministic=self.deterministic)
        space = env.action_space(env.agents[0])
        # SB3 clips Box actions to the model's own space; clip again to the env's bound (policy side).
        actions = np.clip(np.asarray(actions, dtype=np.float32).reshape(len(env.agents), 2), space.low, space.high)
        return dict(zip(env.agents, actions))


class CallablePolicy(EnvPolicy):
    """Wrap ``fn(obs (n, D) float32) -> actions (n, 2)`` (batched, in ``env.agents`` order)."""

    def __init__(self, fn, name: str | None = None):
        if not callable(fn):
            raise TypeError(f"CallablePolicy needs a callable, got {fn!r}")
        self.fn = fn
        self.name = name or getattr(fn, "__name__", "callable")

    def act(self, env, observations) -> dict:
        if not env.agents:
            return {}
        actions = np.asarray(self.fn(stack_observations(env, observations)))
        if actions.shape != (len(env.agents), 2):
            raise ValueError(f"policy {self.name!r} returned actions of shape {actions.shape}, expected "
                             f"({len(env.agents)}, 2)")
        return dict(zip(env.agents, actions))


_NAMED = {"baseline": CalibratedPolicy, "calibrated": CalibratedPolicy, "social_force": CalibratedPolicy,
          "random": RandomPolicy, "zero": ZeroIntentPolicy}


def as_policy(spec, name: str | None = None) -> EnvPolicy:
    """An :class:`EnvPolicy` from a name (``baseline``, ``random``, ``zero`` or a shipped trained policy:
    ``baselines.trained.list_trained()``), a policy file (``.npz``), a saved model (SB3 ``.zip``; ``crowd-train-mappo``'s ``policy.pt`` or its
    run folder; ``crowd-train-rllib``'s run folder), an SB3 model, a policy or a callable.

    Policy files and ``policy.pt`` are read as data only (nothing in them runs); an SB3 ``.zip`` and an RLlib run
    folder hold pickles, which run code when loaded: load those only from sources you trust."""
    if isinstance(spec, EnvPolicy):
        if name:
            spec.name = name
        return spec
    if isinstance(spec, (str, os.PathLike)):
        s = os.fspath(spec)
        if s in _NAMED:
            p = _NAMED[s]()
            if name:
                p.name = name
            return p
        p = file_policy(s, name=name)
        if p is not None:
            return p
        if s.endswith(".pt") or os.path.exists(os.path.join(s, "policy.pt")):
            from crowd_env.experiments.training.marl import load_policy  # crowd-train-mappo (MAPPO / IPPO)

            return load_policy(s, name=name)
        if os.path.exists(os.path.join(s, "policy.json")):
            from crowd_env.experiments.training.rllib import load_policy as load_rllib  # crowd-train-rllib

            return load_rllib(s, name=name)
        if s.endswith(".zip") or os.path.exists(s) or os.path.exists(s + ".zip"):
            return SB3Policy(s, name=name)
        raise ValueError(f"unknown policy {s!r}: give one of {sorted(_NAMED) + list_trained()}, a policy file (.npz), a saved model (SB3 .zip, a "
                         "crowd-train-mappo policy.pt or run folder, a crowd-train-rllib run folder) or a callable")
    if hasattr(spec, "predict") and hasattr(spec, "observation_space"):
        return SB3Policy(spec, name=name)
    if hasattr(spec, "act") and callable(spec.act):
        return spec
    if callable(spec):
        return CallablePolicy(spec, name=name)
    raise TypeError(f"cannot make a policy from {type(spec).__name__}")
