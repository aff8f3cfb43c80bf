"""Reward terms and their weighted sum.

A term (:class:`RewardTerm`) gives, per agent, its value per unit weight (positive: rewarded; a penalty is a
negative value, e.g. −P for the contact percussion P); :class:`TermReward` sums ``weight × value`` over its
terms in their order, r = c_1 + c_2 + … (each c_t = w_t v_t), and reports each agent's c_t in its info under
``"reward_terms"``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from crowd_env.errors import InputError

from ...core.checks import check_number

__all__ = ["RewardTerm", "TermReward"]


@dataclass(frozen=True)
class RewardTerm:
    """One named part of the reward. Subclass it (a frozen dataclass), set ``name`` and implement
    :meth:`value`; ``weight`` scales it (the term adds ``weight × value`` to each agent's reward)."""

    weight: float = 1.0

    name = ""

    def __post_init__(self):
        check_number(f"{type(self).__name__}.weight", self.weight, error=InputError)

    def value(self, env, info: dict):
        """Per-agent value (n,) per unit weight (or a number, the same for every agent) from the step's
        ``info`` arrays (:data:`~crowd_env.envs.rewards.REWARD_INFO_KEYS`, aligned with the agents)."""
        raise NotImplementedError(f"{type(self).__name__}.value")


class TermReward:
    """``reward_fn(env, agent_ids, info)`` that sums its ``terms`` (:class:`RewardTerm` objects, names unique):
    r = Σ_t w_t v_t, added in the terms' order. Also writes ``info["reward_terms"]``: the contributions
    w_t v_t as an (n,) structured array with one float64 field per term (``info["reward_terms"]["progress"]``:
    (n,)); with ``reward_terms_in_infos=True`` the environment hands each agent its row as a list of floats
    in the order of the names (``infos[agent]["reward_terms"]``; ``env.reward_terms(infos[agent])["progress"]``)."""

    def __init__(self, terms):
        self.terms = tuple(terms)
        names = [t.name for t in self.terms]
        if not self.terms or len(set(names)) != len(names) or not all(names):
            raise InputError(f"a TermReward needs one or more terms with distinct names, got {names}")
        self.names = tuple(names)
        self.weights = np.array([float(t.weight) for t in self.terms])
        self.dtype = np.dtype([(name, np.float64) for name in names])

    def __call__(self, env, agent_ids, info) -> np.ndarray:
        n = len(agent_ids)
        values = np.empty((len(self.terms), n))
        for row, term in zip(values, self.terms):
            row[:] = term.value(env, info)
        terms = np.empty(n, self.dtype)
        total = _weighted_sum(values, self.weights, terms.view(np.float64).reshape(n, len(self.terms)))
        info["reward_terms"] = terms
        return total

    def __repr__(self) -> str:
        return f"TermReward({list(self.terms)!r})"

    def __eq__(self, other) -> bool:
        return type(other) is type(self) and other.terms == self.terms

    __hash__ = None


@nb.njit(cache=True)
def _weighted_sum(values, weights, parts):
    """The sums over t of the contributions c_t = w_t v_t (written to ``parts`` (n, T)), added in order from
    c_0 (not from 0, which would turn a total of −0.0 into 0.0)."""
    total = np.empty(values.shape[1])
    for a in range(values.shape[1]):
        s = weights[0] * values[0, a]
        parts[a, 0] = s
        for t in range(1, values.shape[0]):
            c = weights[t] * values[t, a]
            parts[a, t] = c
            s = s + c
        total[a] = s
    return total
