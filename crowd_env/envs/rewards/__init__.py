"""Rewards of the crowd environment: named, weighted terms.

A reward function has the signature ``reward_fn(env, agent_ids, info) -> rewards``: ``agent_ids`` is
the list of agents that acted this step (live at its start), ``info`` a dict of arrays aligned with
it (see :data:`REWARD_INFO_KEYS`), and the result a sequence of ``len(agent_ids)`` finite numbers
(or a dict agent -> number). Every quantity covers the whole environment step (all ``frame_skip``
simulator steps). A reward function may also put ``info["reward_terms"]``, an (n,) structured array with one
numeric field per term (as :class:`~.base.TermReward` does; anything else there raises
:class:`~crowd_env.errors.PolicyError`). With the environment option ``reward_terms_in_infos=True``, the
environment hands each agent its row, a list of floats in the order of ``env.reward_term_names``, in its info
under ``"reward_terms"``.

The default reward (:class:`DefaultReward`) is a :class:`~.base.TermReward` of four terms
(:mod:`.terms`): ``progress``, ``contact_percussion``, ``time`` and ``exit``, summed in that order. The
least-effort reward (``reward_terms="least_effort"``, :mod:`.least_effort`) prices walking in metabolic
energy. The
environment's ``reward_terms`` option names the terms of a :class:`~.base.TermReward`
(:func:`resolve_terms`: names of :data:`REWARD_TERMS`, ``"module:Class"`` import paths, term objects, or a
dict of them to weights); a new term subclasses :class:`~.base.RewardTerm` in a module of its own.
"""
from __future__ import annotations

import dataclasses
import importlib
from dataclasses import dataclass

import numpy as np

from crowd_env.errors import EnvOptionError, InputError

from ...core.checks import check_number
from .base import RewardTerm, TermReward
from .least_effort import LEAST_EFFORT_TERMS, MetabolicEffort
from .terms import ContactPercussion, ExitBonus, Progress, TimeCost

__all__ = ["DefaultReward", "REWARD_INFO_KEYS", "RewardTerm", "TermReward", "REWARD_TERMS", "DEFAULT_TERMS",
           "REWARDS", "resolve_terms"]

# The built-in terms by name, and the default reward's, in order.
REWARD_TERMS = {t.name: t for t in (Progress, ContactPercussion, TimeCost, ExitBonus, MetabolicEffort)}
DEFAULT_TERMS = ("progress", "contact_percussion", "time", "exit")
# Whole rewards by name (``reward_terms="least_effort"``): term -> weight.
REWARDS = {"default": {name: REWARD_TERMS[name].weight for name in DEFAULT_TERMS},
           "least_effort": LEAST_EFFORT_TERMS}
OPTION = "reward_terms"

REWARD_INFO_KEYS = {
    "agent_index": "(n,) int: pedestrian index of each agent (agent 'ped_i' has index i)",
    "progress_s": "(n,) T_before − T_after: decrease of the travel time to the nearest exit, s of travel at the "
                  "field's speed (1 m/s: m along the geodesic)",
    "travel_time_before_s": "(n,) T at the start of the step",
    "travel_time_s": "(n,) T at the end of the step (0 once in an exit)",
    "contact_percussion_kg_m_s": "(n,) sum of |normal percussion| over all contacts of the agent this step, kg m/s",
    "n_contacts": "(n,) number of contacts with a non-zero percussion (each simulator step counted)",
    "speed_m_s": "(n,) speed at the end of the step, m/s",
    "speed_before_m_s": "(n,) speed at the start of the step, m/s",
    "exited": "(n,) bool: the agent left through an exit this step",
    "dt_s": "float: simulated duration of the step (frame_skip × dt)",
}


@dataclass(frozen=True)
class DefaultReward(TermReward):
    """r = progress_weight × (T_before − T_after) − collision_weight × P − time_cost_per_s × Δt
    (+ exit_bonus on the step the agent leaves): the terms ``progress``, ``contact_percussion``, ``time``
    and ``exit`` of :mod:`.terms` with these weights, summed in that order: the :class:`~.base.TermReward` of
    them (a frozen dataclass of the four weights).

    P is the sum of the normal percussions (kg m/s) the agent received in contacts this step
    (impacts and the non-penetration projection), T the eikonal travel time in s, Δt the step's
    simulated duration. With the defaults, a typical impact in a dense crowd (~20 kg m/s) costs about
    0.2 s of travel, standing still costs 0.1 per simulated second and walking at 1.34 m/s along the
    geodesic earns about 1.24 per second. Summed over an episode, the progress term telescopes to
    T_start − T_end (the exit bonus and time cost make leaving early pay).
    """

    progress_weight: float = 1.0
    collision_weight: float = 0.01
    time_cost_per_s: float = 0.1
    exit_bonus: float = 1.0

    def __post_init__(self):
        for name in ("progress_weight", "collision_weight", "time_cost_per_s", "exit_bonus"):
            check_number(f"DefaultReward.{name}", getattr(self, name), error=InputError)
        terms = (Progress(float(self.progress_weight)), ContactPercussion(float(self.collision_weight)),
                 TimeCost(float(self.time_cost_per_s)), ExitBonus(float(self.exit_bonus)))
        self.__dict__.update(self._lay_out(terms))  # the TermReward of the four terms (frozen: set apart)


def _term(item, weight=None):
    """One entry of the option as a term object (None when it names none)."""
    if isinstance(item, str):
        if item in REWARD_TERMS:
            item = REWARD_TERMS[item]
        elif ":" in item:
            module, _, attr = item.partition(":")
            try:
                item = getattr(importlib.import_module(module), attr)
            except (ImportError, AttributeError) as exc:
                raise EnvOptionError(f"{OPTION}: cannot import {module!r}:{attr!r} ({exc})") from None
        else:
            return None
    try:
        if isinstance(item, type) and issubclass(item, RewardTerm):
            item = item() if weight is None else item(weight=weight)
        elif isinstance(item, RewardTerm) and weight is not None:
            item = dataclasses.replace(item, weight=weight)
    except InputError as exc:
        raise EnvOptionError(f"{OPTION}: {exc}") from None
    return item if isinstance(item, RewardTerm) else None


def resolve_terms(terms) -> TermReward:
    """The :class:`~.base.TermReward` of the ``reward_terms`` option: the name of a whole reward (:data:`REWARDS`:
    ``"default"``, ``"least_effort"``), a sequence of names of
    :data:`REWARD_TERMS`, ``"module:Class"`` paths or :class:`~.base.RewardTerm` objects (or classes), each
    with its default weight, or a dict of them to weights. Raises :class:`~crowd_env.errors.EnvOptionError`
    naming the option for anything else and for two terms of one name."""
    if isinstance(terms, str) and terms in REWARDS:
        terms = REWARDS[terms]
    if isinstance(terms, dict):
        pairs = list(terms.items())
    elif isinstance(terms, (str, RewardTerm)) or not hasattr(terms, "__iter__"):
        raise EnvOptionError(f"{OPTION} must be a sequence of term names or objects, a dict of them to weights, or "
                             f"the name of a reward ({sorted(REWARDS)}), got {terms!r}")
    else:
        pairs = [(t, None) for t in terms]
    out = []
    for item, weight in pairs:
        term = _term(item, weight)
        if term is None:
            raise EnvOptionError(f"{OPTION}: unknown term {item!r}; known: {sorted(REWARD_TERMS)}, a 'module:Class' "
                                 "import path or a RewardTerm object")
        out.append(term)
    names = [t.name for t in out]
    twice = sorted({n for n in names if names.count(n) > 1})
    if not out or twice or not all(names):
        raise EnvOptionError(f"{OPTION} needs one or more named terms, each once; got {names}")
    return TermReward(out)
