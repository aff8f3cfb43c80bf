"""Turning the shoulders at a narrow passage (Warren & Whang 1987), an addition to Kabalan et al. 2016.

People walking through an aperture narrower than about 1.3 times their shoulder width turn their shoulders, and turn
them further the narrower it is (Warren & Whang 1987, "Visual guidance of walking through apertures: body-scaled
information for affordances", J. Exp. Psychol. Hum. Percept. Perform. 13:371-383: the critical ratio A/S = 1.30).
In the paper's model the desired heading θ_d of the heading spring-damper (Eq. 15) is the walking direction's angle,
so a walker always faces where it goes. With a body narrower front to back than across the shoulders
(:mod:`crowd_env.core.body`, ``body_depth_m`` > 0) a turned body takes less room across its path; with the paper's
disk turning changes nothing but the heading.

The rule: the aperture A is the narrowest free width across the walking direction e, to the walls and the
neighbours' disks, over the stretch the body is in or about to enter, from its centre x to the point x + (r + L) e
just ahead of it (L ``lookahead_m``; :func:`~crowd_env.walking.apertures.apertures_m`: someone straight ahead is
followed, not passed). When A < ρ S (ρ ``critical_ratio``, S = 2 r the shoulder width) the walker turns
its shoulders by

    φ = arccos(A / (ρ S)),

so that its shoulders' span across the path, S cos φ, is A/ρ: no turn at A = ρ S, 40° at A = S with ρ = 1.3, 90°
when nothing is free. θ_d ← θ_d ± φ, turning the way the body is already turned (+ when it faces e exactly); the
heading spring-damper (Eq. 15) and the contacts then turn the body. The walking direction and the intent do not
change.

Constants (:class:`ShoulderTurn`, the model's ``shoulder_turn_<field>`` parameters): ``critical_ratio`` ρ ≥ 0 (0, the
default, switches the rule off: the paper's model; Warren & Whang's 1.3), ``lookahead_m`` L ≥ 0 (0.3 m, about half a
step ahead of the body's front; a choice, its effect measured in :doc:`/validation/virtual_experiments`). Neighbours
are the agent's pairs (:func:`~crowd_env.walking.agent.pair_radius_m` reaches them); a periodic corridor's
displacements are taken to the nearest image along x.
"""
from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np

from ..core.angles import wrap_angle_scalar
from ..core.params import check_parameter
from .apertures import FAR_M, apertures_m

__all__ = ["ShoulderTurn", "shoulder_turn", "shoulder_turn_reach_m"]

class ShoulderTurn(NamedTuple):
    """The rule's constants (module docstring; the model's ``shoulder_turn_<field>`` parameters)."""

    critical_ratio: float = 0.0
    lookahead_m: float = 0.3

    def checked(self) -> "ShoulderTurn":
        """This group, once checked (:class:`~crowd_env.errors.ParameterError` naming the model parameter)."""
        check_parameter("shoulder_turn_critical_ratio", self.critical_ratio, minimum=0.0, maximum=FAR_M)
        check_parameter("shoulder_turn_lookahead_m", self.lookahead_m, minimum=0.0, maximum=FAR_M)
        return self

    def resolved(self) -> "ShoulderTurn":
        """Plain numbers for the kernels."""
        return ShoulderTurn(*(float(value) for value in self))


@nb.njit(cache=True)
def shoulder_turn_reach_m(r_max, rule):
    """How far beyond 2 r_max a neighbour can narrow the aperture of a walker (0 with the rule off): a disk that
    reaches a line across the path within ρ S of its centre has its centre within (r + L + r) + (ρ 2r + r) of the
    walker's."""
    if rule.critical_ratio <= 0.0:
        return 0.0
    return rule.lookahead_m + (2.0 * rule.critical_ratio + 1.0) * r_max


@nb.njit(cache=True)
def shoulder_turn(theta_d, heading, position, radius, index, walk, pairs, walls, period_m, rule):
    """Apply the rule (module docstring) to the desired headings ``theta_d`` (N,) in place, for the pedestrians
    ``index`` walking along ``walk`` (n, 2, unit) with current headings ``heading`` (N,), under the resolved
    :class:`ShoulderTurn` ``rule``. Returns how many turn."""
    if rule.critical_ratio <= 0.0 or index.shape[0] == 0:
        return 0
    aperture, _, _ = apertures_m(position, radius, index, walk, pairs, walls, period_m, rule.lookahead_m)
    turned = 0
    for k in range(index.shape[0]):
        i = index[k]
        span = rule.critical_ratio * 2.0 * radius[i]
        if aperture[k] >= span:
            continue
        phi = np.arccos(aperture[k] / span)
        walk_angle = np.arctan2(walk[k, 1], walk[k, 0])  # as direction_angles_rad computes it
        sign = 1.0 if wrap_angle_scalar(heading[i] - walk_angle) >= 0.0 else -1.0
        theta_d[i] = wrap_angle_scalar(theta_d[i] + sign * phi)
        turned += 1
    return turned
