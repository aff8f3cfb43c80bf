"""The built-in reward terms: the four of :class:`~crowd_env.envs.rewards.DefaultReward`.

Each gives its value per unit weight per agent from the step's info arrays
(:data:`~crowd_env.envs.rewards.REWARD_INFO_KEYS`); the weighted sum of the four, in this order, is the
default reward. Each names its ``kind``: the value, described here, is computed for all of them in one compiled
loop (:func:`~crowd_env.envs.rewards.base._sum_terms`).
"""
from __future__ import annotations

from dataclasses import dataclass

from .base import CONTACT_PERCUSSION, EXIT, PROGRESS, TIME, RewardTerm

__all__ = ["Progress", "ContactPercussion", "TimeCost", "ExitBonus"]


@dataclass(frozen=True)
class Progress(RewardTerm):
    """``progress``: T_before − T_after, the decrease of the travel time along the eikonal field (s of travel at
    the field's speed; 1 m/s: m along the geodesic). Over an episode it telescopes to T_start − T_end."""

    weight: float = 1.0
    name = "progress"
    kind = PROGRESS


@dataclass(frozen=True)
class ContactPercussion(RewardTerm):
    """``contact_percussion``: −P, P the sum of the normal percussions (kg m/s) the agent received in contacts
    this step (impacts and the non-penetration projection); weight 0.01: a typical impact in a dense crowd
    (~20 kg m/s) costs about 0.2 s of travel."""

    weight: float = 0.01
    name = "contact_percussion"
    kind = CONTACT_PERCUSSION


@dataclass(frozen=True)
class TimeCost(RewardTerm):
    """``time``: −Δt, the step's simulated duration in s (the weight is a cost per simulated second)."""

    weight: float = 0.1
    name = "time"
    kind = TIME


@dataclass(frozen=True)
class ExitBonus(RewardTerm):
    """``exit``: 1 on the step the agent leaves through an exit, else 0."""

    weight: float = 1.0
    name = "exit"
    kind = EXIT
