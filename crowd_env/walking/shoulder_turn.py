"""Turning the shoulders at a narrow passage (Warren & Whang 1987), an addition to Kabalan et al. 2016.

People walking through an aperture narrower than about 1.3 times their shoulder width turn their shoulders, and turn
them further the narrower it is (Warren & Whang 1987, "Visual guidance of walking through apertures: body-scaled
information for affordances", J. Exp. Psychol. Hum. Percept. Perform. 13:371-383: the critical ratio A/S = 1.30).
In the paper's model the desired heading θ_d of the heading spring-damper (Eq. 15) is the walking direction's angle,
so a walker always faces where it goes. With a body narrower front to back than across the shoulders
(:mod:`crowd_env.core.body`, ``body_depth_m`` > 0) a turned body takes less room across its path; with the paper's
disk turning changes nothing but the heading.

The rule: the aperture A is the narrowest free width across the walking direction e over the stretch the body is in
or about to enter, from its centre x to the point x + (r + L) e just ahead of it (L ``lookahead_m``): on each line
across e through x + s e, 0 ≤ s ≤ r + L, the distance from the line's centre to the nearest wall (a ray cast) or
neighbour's disk on the left of e plus the same on the right, the smallest over the lines (a line whose centre a
neighbour covers is left out: someone straight ahead is followed, not passed). When A < ρ S (ρ ``critical_ratio``, S = 2 r the shoulder width) the walker turns
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

from ..core.angles import direction_angles_rad, wrap_angle_scalar
from ..core.params import check_parameter
from ..core.periodic import minimum_image_dx
from ..core.segments import ray_distances

__all__ = ["ShoulderTurn", "apertures_m", "shoulder_turn", "shoulder_turn_reach_m"]

FAR_M = 5.0  # apertures beyond this are not told apart (no turn is ever needed there)
LINE_STEP_M = 0.05  # the lines across the path are at most this far apart


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
def apertures_m(position, radius, index, walk, pairs, walls, period_m, lookahead_m):
    """The aperture A (m; module docstring) of each pedestrian of ``index`` walking along the unit directions ``walk``
    (n, 2): the narrowest free width across its path over the stretch it is in or about to enter, the lines across e
    through x + s e for s from 0 to r + L (every :data:`LINE_STEP_M` at most), to the walls ``walls`` (S, 4) and the
    disks of its neighbours ``pairs`` (rows into ``index``); at most 2 :data:`FAR_M`. A line whose centre a
    neighbour's disk covers is no aperture (someone straight ahead is followed, not passed: no turn for it) and is
    left out. Also ``(left, right)``, the two sides at that narrowest line."""
    return _apertures(position, radius, index, walk, direction_angles_rad(walk), pairs, walls, period_m, lookahead_m)


@nb.njit(cache=True)
def _apertures(position, radius, index, walk, walk_angle, pairs, walls, period_m, lookahead_m):
    """:func:`apertures_m` with the walking directions' angles ``walk_angle`` (n,) given."""
    n = index.shape[0]
    aperture = np.full(n, 2.0 * FAR_M)
    best_left = np.full(n, FAR_M)
    best_right = np.full(n, FAR_M)
    blocked = np.zeros(n, np.bool_)
    n_lines = 1
    for k in range(n):
        n_lines = max(n_lines, int(np.ceil((radius[index[k]] + lookahead_m) / LINE_STEP_M)) + 1)
    q = np.empty((n, 2))
    angles = np.empty((n, 2))
    for k in range(n):
        angles[k, 0] = walk_angle[k] + 0.5 * np.pi  # left of e
        angles[k, 1] = walk_angle[k] - 0.5 * np.pi
    for m in range(n_lines):
        for k in range(n):
            i = index[k]
            s = (radius[i] + lookahead_m) * m / max(n_lines - 1, 1)
            q[k, 0] = position[i, 0] + s * walk[k, 0]
            q[k, 1] = position[i, 1] + s * walk[k, 1]
        side = ray_distances(q, angles, walls, FAR_M)
        left = side[:, 0].copy()
        right = side[:, 1].copy()
        blocked[:] = False
        for p in range(pairs.shape[0]):
            for w in range(2):
                a = pairs[p, w]
                j = index[pairs[p, 1 - w]]
                dx = minimum_image_dx(position[j, 0] - q[a, 0], period_m)
                dy = position[j, 1] - q[a, 1]
                along = dx * walk[a, 0] + dy * walk[a, 1]
                rj = radius[j]
                if abs(along) >= rj:
                    continue  # j's disk does not reach this line
                across = -dx * walk[a, 1] + dy * walk[a, 0]  # + on the left of e
                half = np.sqrt(rj * rj - along * along)
                if abs(across) < half:  # j's disk covers the line's centre: no gap to pass there, one to follow
                    blocked[a] = True
                elif across > 0.0:
                    left[a] = min(left[a], across - half)
                else:
                    right[a] = min(right[a], -across - half)
        for k in range(n):
            if not blocked[k] and left[k] + right[k] < aperture[k]:
                aperture[k] = left[k] + right[k]
                best_left[k] = left[k]
                best_right[k] = right[k]
    return aperture, best_left, best_right


@nb.njit(cache=True)
def shoulder_turn(theta_d, heading, position, radius, index, walk, pairs, walls, period_m, rule):
    """Apply the rule (module docstring) to the desired headings ``theta_d`` (N,) in place, for the pedestrians
    ``index`` walking along ``walk`` (n, 2, unit) with current headings ``heading`` (N,), under the resolved
    :class:`ShoulderTurn` ``rule``. Returns how many turn."""
    if rule.critical_ratio <= 0.0 or index.shape[0] == 0:
        return 0
    walk_angle = direction_angles_rad(walk)
    aperture, _, _ = _apertures(position, radius, index, walk, walk_angle, pairs, walls, period_m, rule.lookahead_m)
    turned = 0
    for k in range(index.shape[0]):
        i = index[k]
        span = rule.critical_ratio * 2.0 * radius[i]
        if aperture[k] >= span:
            continue
        phi = np.arccos(aperture[k] / span)
        sign = 1.0 if wrap_angle_scalar(heading[i] - walk_angle[k]) >= 0.0 else -1.0
        theta_d[i] = wrap_angle_scalar(theta_d[i] + sign * phi)
        turned += 1
    return turned
