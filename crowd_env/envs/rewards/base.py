"""Reward terms and their weighted sum.

A term (:class:`RewardTerm`) gives, per agent, its value per unit weight (positive: rewarded; a penalty is a
negative value, e.g. −P for the contact percussion P); :class:`TermReward` sums ``weight × value`` over its
terms in their order, r = c_1 + c_2 + … (each c_t = w_t v_t), and reports each agent's c_t in its info under
``"reward_terms"``.
"""
from __future__ import annotations

import dataclasses
import operator
from dataclasses import dataclass

import numba as nb
import numpy as np

from crowd_env.errors import InputError, NotFoundError

from ...core.checks import check_number

__all__ = ["RewardTerm", "TermReward"]


# What a term's value is, for the terms of this package: each built-in term names its kind, and one compiled loop
# (_sum_terms) computes every kind's value where the step's info holds it; GIVEN: a term's own value(), from Python.
GIVEN, PROGRESS, CONTACT_PERCUSSION, TIME, EXIT, METABOLIC_EFFORT = range(6)
# The info each kind reads (the keys of REWARD_INFO_KEYS).
_READS = {PROGRESS: ("progress_s",), CONTACT_PERCUSSION: ("contact_percussion_kg_m_s",), TIME: ("dt_s",),
          EXIT: ("exited",), METABOLIC_EFFORT: ("speed_before_m_s", "speed_m_s", "dt_s")}


@dataclass(frozen=True)
class RewardTerm:
    """One named part of the reward. Subclass it (a frozen dataclass), set ``name`` and implement
    :meth:`value`; ``weight`` scales it (the term adds ``weight × value`` to each agent's reward).

    The built-in terms implement no :meth:`value` of their own: each names its ``kind`` (and its ``constants``),
    and :func:`_sum_terms` computes the value of every kind, in compiled code, for :meth:`value` and for
    :class:`TermReward` alike."""

    weight: float = 1.0

    name = ""
    kind = GIVEN

    def __post_init__(self):
        check_number(f"{type(self).__name__}.weight", self.weight, error=InputError)

    @property
    def constants(self) -> tuple:
        """The numbers a built-in kind's value needs besides the info (two, unused ones 0)."""
        return 0.0, 0.0

    def value(self, env, info: dict):
        """Per-agent value (n,) per unit weight (or a number, the same for every agent) from the step's
        ``info`` arrays (:data:`~crowd_env.envs.rewards.REWARD_INFO_KEYS`, aligned with the agents)."""
        if self.kind == GIVEN:
            raise NotImplementedError(f"{type(self).__name__}.value")
        arrays = [info[key] for key in _READS[self.kind] if key != "dt_s"]
        info = dict(info)
        TermReward((dataclasses.replace(self, weight=1.0),))(env, [None] * (len(arrays[0]) if arrays else 1), info)
        values = info["reward_terms"][self.name]
        return values if arrays else float(values[0])  # a value of the step alone (the time): one number


def _kind(term) -> int:
    """The compiled kind of ``term``: its class's, unless a subclass computes its own :meth:`RewardTerm.value`."""
    return term.kind if type(term).value is RewardTerm.value else GIVEN


class TermReward:
    """``reward_fn(env, agent_ids, info)`` that sums its ``terms`` (:class:`RewardTerm` objects, names unique):
    r = Σ_t w_t v_t, added in the terms' order. Also writes ``info["reward_terms"]``: the contributions
    w_t v_t as an (n,) structured array with one float64 field per term (``info["reward_terms"]["progress"]``:
    (n,)); with ``reward_terms_in_infos=True`` the environment hands each agent its row as a list of floats
    in the order of the names (``infos[agent]["reward_terms"]``; ``env.reward_terms(infos[agent])["progress"]``).

    One compiled call (:func:`_sum_terms`) computes the built-in terms' values and the sum; the values of
    terms of other modules (their own :meth:`RewardTerm.value`) are computed from Python first."""

    def __init__(self, terms):
        self.__dict__.update(self._lay_out(terms))

    @staticmethod
    def _lay_out(terms) -> dict:
        """The attributes of a TermReward of ``terms`` (its subclass :class:`~crowd_env.envs.rewards.DefaultReward`,
        a frozen dataclass, takes them too)."""
        terms = tuple(terms)
        names = tuple(t.name for t in terms)
        if not terms or len(set(names)) != len(names) or not all(names):
            raise InputError(f"a TermReward needs one or more terms with distinct names, got {list(names)}")
        weights = np.array([float(t.weight) for t in terms])
        kinds = [_kind(t) for t in terms]
        rows = np.cumsum([k == GIVEN for k in kinds]) - 1
        # per term: its kind, its row of the given values, its weight and its kind's two constants
        table = np.array([(k, r, w, *t.constants) for k, r, w, t in zip(kinds, rows, weights, terms)], np.float64)
        return {"terms": terms, "names": names, "weights": weights,
                "dtype": np.dtype([(name, np.float64) for name in names]),
                "_given": tuple(t for t, k in zip(terms, kinds) if k == GIVEN),  # values from Python, in order
                "_table": table}

    def __call__(self, env, agent_ids, info) -> np.ndarray:
        n = len(agent_ids)
        given = _NO_VALUES
        if self._given:
            given = np.empty((len(self._given), n))
            for row, term in zip(given, self._given):
                row[:] = term.value(env, info)
        terms = np.empty(n, self.dtype)
        out = np.empty(n)  # made here: numba hands an array back to Python for 0.3 µs
        try:
            read = _read_info(info)  # what the environment gives (one C call)
        except KeyError:  # an info of some keys only: those that a term reads must be there
            read = tuple(info.get(key, np.nan if key == "dt_s" else _NO_ARRAY) for key in _INFO_READ)
        missing = _sum_terms(self._table, *read, given, np.ndarray((n, len(self.terms)), np.float64, terms), out)
        if missing >= 0:
            key = next(key for key in _READS[missing] if key not in info)
            raise NotFoundError(f"the step's info has no {key!r}, which the reward term(s) "
                                f"{[t.name for t in self.terms if _kind(t) == missing]} read")
        info["reward_terms"] = terms
        return out

    def __repr__(self) -> str:
        return f"TermReward({list(self.terms)!r})"

    def __eq__(self, other) -> bool:
        return type(other) is type(self) and other.terms == self.terms

    __hash__ = None


_NO_VALUES = np.zeros((0, 0))
_NO_ARRAY = np.zeros(0)
_INFO_READ = ("progress_s", "contact_percussion_kg_m_s", "exited", "speed_before_m_s", "speed_m_s", "dt_s")
_read_info = operator.itemgetter(*_INFO_READ)  # the info the kinds read, in the order _sum_terms takes it


@nb.njit(cache=True)
def _sum_terms(table, progress, percussion, exited, speed_before, speed, dt_s, given, parts, out):
    """The contributions c_t = w_t v_t of the terms into ``parts`` (n, T) and their sums into ``out`` (n,), added in
    order from c_0 (not from 0, which would turn a total of −0.0 into 0.0). ``table`` (T, 5): each term's kind, its
    row of ``given`` (G, n: the values of GIVEN terms), its weight w_t and its kind's two constants. The values:
    ``progress`` v = T_before − T_after, ``contact_percussion`` v = −P, ``time`` v = −Δt, ``exit`` v = 1 on
    leaving, else 0, ``metabolic_effort`` v = −(e_s + e_w v̄²) Δt with v̄² = (v_start² + v_end²)/2 and (e_s, e_w)
    its constants. Returns −1, or the first kind whose input the step's info lacks (nothing written then)."""
    n = out.shape[0]
    for t in range(table.shape[0]):
        kind = int(table[t, 0])
        if (kind == PROGRESS and progress.shape[0] < n) or (kind == CONTACT_PERCUSSION and percussion.shape[0] < n) \
                or (kind == EXIT and exited.shape[0] < n) or ((kind == TIME or kind == METABOLIC_EFFORT) and np.isnan(dt_s)) \
                or (kind == METABOLIC_EFFORT and min(speed_before.shape[0], speed.shape[0]) < n):
            return kind
    for a in range(n):
        s = 0.0
        for t in range(table.shape[0]):
            kind = int(table[t, 0])
            if kind == PROGRESS:
                v = progress[a]
            elif kind == CONTACT_PERCUSSION:
                v = -percussion[a]
            elif kind == TIME:
                v = -dt_s
            elif kind == EXIT:
                v = 1.0 if exited[a] else 0.0
            elif kind == METABOLIC_EFFORT:
                v2 = 0.5 * (speed_before[a] ** 2 + speed[a] ** 2)
                v = -(table[t, 3] + table[t, 4] * v2) * dt_s
            else:
                v = given[int(table[t, 1]), a]
            c = table[t, 2] * v
            parts[a, t] = c
            s = c if t == 0 else s + c
        out[a] = s
    return -1
