"""Giving way at contact: a walker does not push into the one ahead whom it touches, an addition to Kabalan et al. 2016.

In the paper's model every walker's intent points along e_d whatever is in front of it (Eq. 14, 16): in a queue
behind a narrow door each one pushes the one ahead, the pushes add up along the queue, and at a door narrower
than two bodies two walkers pressed side by side into the opening hold each other against its edges (an arch
that nobody lets go, :doc:`/validation/virtual_experiments`). People at such doors take turns: the one who is
behind lets the other go first.

The rule: walker i gives way to a neighbour j whom it touches or nearly touches (surface gap d_ij − r_i − r_j
below ``gap_m``) and who is nearer the destination (travel time T_j < T_i, Eq. 11: "ahead" along the eikonal
field, which breaks the tie between two walkers side by side in a door as the field does): the part of i's intent
pushing towards j is taken out, a share ``share`` of it,

    u_int,i ← u_int,i − share · max(0, u_int,i · n_ij) n_ij,    n_ij = (x_j − x_i)/‖x_j − x_i‖,

one neighbour after the other in the order of the pairs. The part along the contact's tangent stays, so a walker
held behind another may still step aside; the one ahead is not changed by the one behind. Nothing changes for
walkers who touch nobody, so free flow is the paper's model; the core's contacts still keep the bodies apart
(Eq. 4-8) and a walker pushed from behind is still pushed.

Constants (:class:`GiveWay`, the model's ``give_way_<field>`` parameters): ``share`` ∈ [0, 1] (0, the default,
switches the rule off: the paper's model), ``gap_m`` ≥ 0 the surface gap at which a walker counts as touching.
Pairs are those the agent builds (within :func:`~crowd_env.walking.agent.pair_radius_m`); a periodic corridor's
displacements are taken to the nearest image along x.
"""
from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np

from ..core.params import check_parameter
from ..core.periodic import minimum_image_dx

__all__ = ["GiveWay", "give_way"]


class GiveWay(NamedTuple):
    """The rule's constants (module docstring; the model's ``give_way_<field>`` parameters)."""

    share: float = 0.0
    gap_m: float = 0.05

    def checked(self) -> "GiveWay":
        """This group, once checked (:class:`~crowd_env.errors.ParameterError` naming the model parameter)."""
        check_parameter("give_way_share", self.share, minimum=0.0, maximum=1.0)
        check_parameter("give_way_gap_m", self.gap_m, minimum=0.0)
        return self

    def resolved(self) -> "GiveWay":
        """Plain numbers for the kernels."""
        return GiveWay(*(float(value) for value in self))


@nb.njit(cache=True)
def give_way(intents, position, radius, index, travel_time_s, pairs, period_m, rule):
    """Apply the rule (module docstring) to ``intents`` (N, 2) in place, for the pedestrians ``index`` with travel
    times ``travel_time_s`` (n,) and neighbour ``pairs`` (rows into ``index``), under the resolved :class:`GiveWay`
    ``rule``; ``period_m``: the periodicity along x (0: none). Returns how many times an intent was changed."""
    changed = 0
    if rule.share <= 0.0:
        return changed
    for p in range(pairs.shape[0]):
        a = pairs[p, 0]
        b = pairs[p, 1]
        if travel_time_s[a] == travel_time_s[b]:
            continue
        behind, ahead = (a, b) if travel_time_s[b] < travel_time_s[a] else (b, a)
        i = index[behind]
        j = index[ahead]
        dx = minimum_image_dx(position[j, 0] - position[i, 0], period_m)
        dy = position[j, 1] - position[i, 1]
        d = np.sqrt(dx * dx + dy * dy)
        if d == 0.0 or d - radius[i] - radius[j] >= rule.gap_m:
            continue
        nx = dx / d
        ny = dy / d
        push = intents[i, 0] * nx + intents[i, 1] * ny
        if push > 0.0:
            intents[i, 0] -= rule.share * push * nx
            intents[i, 1] -= rule.share * push * ny
            changed += 1
    return changed
