"""Who drives a run's crowd: the calibrated agent, or a learned policy for all or some of the pedestrians.

A run task of the bottleneck or the fundamental-diagram sweep (:func:`crowd_env.experiments.validation.bottleneck.
run_one`, :func:`crowd_env.experiments.validation.fundamental_diagram.run_fd_one`) may carry ``"policy"``:
``{"name": spec, "learned_fraction": f}``, ``spec`` a shipped trained policy's name, a policy file (``.npz``) or an
import path ``"module:attribute"`` of an observation policy (``actions(observations)`` and ``env_overrides``, as
:mod:`crowd_env.envs.background` defines it), ``f`` in (0, 1] the fraction of the pedestrians it drives (evenly
spread over the indices, as the environment's ``controlled`` option picks them; 1: all), and with ``"social_force":
true`` the model's social force added to its intents, with ``"social_force_below_m_s": u_g`` only to those nearly
standing (:class:`~crowd_env.envs.drivers.MixedDriver`). Without it the calibrated
agent (Kabalan et al. 2016, Eq. 14-16) drives everybody, the runs are the calibration's own, and the compiled
rollout runs them.
"""
from __future__ import annotations

import math

import numpy as np

from crowd_env.errors import PolicyError

from ...envs.background import CALIBRATED_NAMES, is_observation_policy, load_named_background
from ...envs.config import select_controlled
from ...envs.drivers import MixedDriver, check_social_force_gate
from ...walking.agent import SocialForceAgent
from .evaluation import import_object

__all__ = ["policy_entry", "load_scored_policy", "crowd_policy"]


def policy_entry(name: str, learned_fraction: float = 1.0, *, social_force: bool = False,
                 social_force_below_m_s: float | None = None) -> dict | None:
    """The ``"policy"`` entry of a task for ``name`` driving ``learned_fraction`` of the crowd (None for the
    calibrated agent driving everybody), with the model's social force added to its intents when ``social_force``
    (only to those slower than ``social_force_below_m_s``, when given); checks the fraction, the gate and that the
    policy loads, naming what is wrong."""
    if not isinstance(learned_fraction, (int, float)) or not math.isfinite(learned_fraction) \
            or not 0.0 < learned_fraction <= 1.0:
        raise PolicyError(f"learned_fraction must lie in (0, 1], got {learned_fraction!r}")
    below = check_social_force_gate(social_force, social_force_below_m_s)
    if name in CALIBRATED_NAMES:
        if social_force:
            raise PolicyError("social_force adds the model's social force to a learned policy's intents; the "
                              "calibrated agent has it already")
        return None
    load_scored_policy(name)
    entry = {"name": str(name), "learned_fraction": float(learned_fraction)}
    if social_force:  # absent otherwise: the tasks (and their stored runs) of a plain policy stay as they were
        entry["social_force"] = True
    if below is not None:
        entry["social_force_below_m_s"] = below
    return entry


def load_scored_policy(name: str):
    """The observation policy ``name`` names (a shipped trained policy, a ``.npz`` file, ``"module:attribute"``)."""
    if ":" in str(name) and not str(name).endswith(".npz"):
        policy = import_object(name)
        if isinstance(policy, type):
            policy = policy()
    else:
        policy = load_named_background(name)
    if policy is None or not is_observation_policy(policy):
        raise PolicyError(f"{name!r} is no observation policy (actions(observations) and env_overrides): the scored "
                          "policies are shipped trained policies, policy files (.npz) or such objects by import path")
    return policy


def crowd_policy(task: dict, scenario, params):
    """The runner's ``policy(sim)`` of ``task`` on ``scenario`` with ``params`` (module docstring)."""
    agent = SocialForceAgent(scenario.navigation())
    entry = task.get("policy")
    if not entry:
        return agent
    n = scenario.n_pedestrians
    mask = np.zeros(n, bool)
    fraction = float(entry.get("learned_fraction", 1.0))
    mask[select_controlled("all" if fraction == 1.0 else fraction, n)] = True
    return MixedDriver(load_scored_policy(entry["name"]), scenario, agent, mask, dt_s=params.dt_s,
                       social_force=bool(entry.get("social_force", False)),
                       social_force_below_m_s=entry.get("social_force_below_m_s"))
