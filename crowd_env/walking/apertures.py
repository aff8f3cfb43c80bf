"""Apertures: how wide the free space across a walker's path is over the stretch ahead of it.

Two walking rules read it: turning the shoulders at a narrow passage (:mod:`crowd_env.walking.shoulder_turn`, walls
and neighbours, the stretch the body is about to enter) and vision's time gap in a door
(:mod:`crowd_env.walking.vision`, walls only, the stretch the walker sees). The aperture A of a walker at x walking
along the unit direction e is the narrowest free width across e over the lines across e through x + s e,
0 ≤ s ≤ reach (every :data:`LINE_STEP_M` at most): on each line, the distance from its centre to the nearest wall
(a ray cast) or neighbour's disk on the left of e plus the same on the right. A line whose centre a neighbour's disk
covers is no aperture (someone straight ahead is followed, not passed) and is left out. Widths beyond 2 :data:`FAR_M`
are not told apart. In a periodic corridor the displacements to neighbours are taken to the nearest image along x
and the lines' centres are brought into the periodic cell, whose walls they see.
"""
from __future__ import annotations

import numba as nb
import numpy as np

from ..core.angles import direction_angles_rad
from ..core.periodic import minimum_image_dx, wrap_x
from ..core.segments import ray_distances

__all__ = ["FAR_M", "LINE_STEP_M", "apertures_m", "apertures_along", "wall_sides_m"]

FAR_M = 5.0  # apertures beyond 2 FAR_M are not told apart
LINE_STEP_M = 0.05  # the lines across the path are at most this far apart


@nb.njit(cache=True)
def apertures_m(position, radius, index, walk, pairs, walls, period_m, lookahead_m):
    """The aperture A (m; module docstring) of each pedestrian of ``index`` walking along the unit directions ``walk``
    (n, 2), over the stretch from its centre to the point r + ``lookahead_m`` ahead of it, to the walls ``walls``
    (S, 4) and the disks of its neighbours ``pairs`` (rows into ``index``); ``period_m``: the periodicity along x
    (0: none). Also ``(left, right)``, the two sides at that narrowest line."""
    n = index.shape[0]
    reach = np.empty(n)
    for k in range(n):
        reach[k] = radius[index[k]] + lookahead_m
    return apertures_along(position, radius, index, walk, direction_angles_rad(walk), pairs, walls, period_m, reach)


@nb.njit(cache=True)
def apertures_along(position, radius, index, walk, walk_angle, pairs, walls, period_m, reach_m):
    """:func:`apertures_m` with the walking directions' angles ``walk_angle`` (n,) given and each walker's stretch
    ``reach_m`` (n,): its lines lie at s from 0 to ``reach_m[k]``, ``ceil(max reach / LINE_STEP_M) + 1`` of them,
    evenly spaced on each walker's stretch."""
    n = index.shape[0]
    aperture = np.full(n, 2.0 * FAR_M)
    best_left = np.full(n, FAR_M)
    best_right = np.full(n, FAR_M)
    blocked = np.zeros(n, np.bool_)
    n_lines = line_count(reach_m)
    q = np.empty((n, 2))
    angles = _across(walk_angle)
    for m in range(n_lines):
        _line_centres(position, index, walk, reach_m, m, n_lines, period_m, q)
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
def wall_sides_m(position, index, walk, walk_angle, walls, period_m, reach_m):
    """The free room to the walls on either side of the path on each line of each walker's stretch
    (:func:`apertures_along`'s lines, walls only): (n, :func:`line_count`, 2) distances from each line's centre to the
    nearest wall on the left of e and on the right (each at most :data:`FAR_M`), the lines in order from the walker's
    centre outwards; their sum is the walls' width across the path."""
    n = index.shape[0]
    n_lines = line_count(reach_m)
    sides = np.empty((n, n_lines, 2))
    q = np.empty((n, 2))
    angles = _across(walk_angle)
    for m in range(n_lines):
        _line_centres(position, index, walk, reach_m, m, n_lines, period_m, q)
        side = ray_distances(q, angles, walls, FAR_M)
        for k in range(n):
            sides[k, m, 0] = side[k, 0]
            sides[k, m, 1] = side[k, 1]
    return sides


@nb.njit(cache=True)
def line_count(reach_m):
    """How many lines across the path the stretches ``reach_m`` (n,) get: ``ceil(max reach / LINE_STEP_M) + 1``."""
    n_lines = 1
    for k in range(reach_m.shape[0]):
        n_lines = max(n_lines, int(np.ceil(reach_m[k] / LINE_STEP_M)) + 1)
    return n_lines


@nb.njit(cache=True, inline="always")
def _across(walk_angle):
    """The angles (n, 2) of the rays across the path: to the left of e, to the right."""
    angles = np.empty((walk_angle.shape[0], 2))
    for k in range(walk_angle.shape[0]):
        angles[k, 0] = walk_angle[k] + 0.5 * np.pi
        angles[k, 1] = walk_angle[k] - 0.5 * np.pi
    return angles


@nb.njit(cache=True, inline="always")
def _line_centres(position, index, walk, reach_m, m, n_lines, period_m, q):
    """Centres ``q`` (n, 2) of the lines number ``m`` of ``n_lines``, evenly spaced on each walker's stretch, brought
    into the periodic cell [0, ``period_m``) along x (a periodic strip's walls are the cell's)."""
    for k in range(index.shape[0]):
        i = index[k]
        s = reach_m[k] * m / max(n_lines - 1, 1)
        q[k, 0] = wrap_x(position[i, 0] + s * walk[k, 0], period_m)
        q[k, 1] = position[i, 1] + s * walk[k, 1]
