"""The shape of a pedestrian's body: the paper's disk, or three circles across the shoulders (an addition).

Kabalan et al. (2016) give every pedestrian a rigid disk of radius r (Section 2.1): 0.46 m across in every
direction, where a person is about 0.46 m across the shoulders and 0.25-0.3 m from chest to back. A disk cannot
pass a gap narrower than 2 r however it turns; people pass such gaps turned, one shoulder first, and stand closer
beside each other than two disks can (the recorded corridor runs, :doc:`/validation/virtual_experiments`).

With a body depth D > 0 (``PhysicsParams.body_depth_m``) the body is three circles of radius D/2 whose centres lie
on the shoulder axis, perpendicular to the heading θ: one at the centre and two at ±(r − D/2), so that the body is
2 r across the shoulders and D from chest to back, and lies inside the paper's disk of radius r (every placement
that keeps the disks apart keeps these bodies apart too). It is the three-circle body of Thompson & Marchant
(1995, SIMULEX) and Langston, Masling & Asmar (2006). The body stays one rigid body with the paper's three degrees
of freedom (x, y, θ), mass and moment of inertia: a contact on a shoulder circle acts at a lever arm from the
centre, so a push on one shoulder turns the body (the θ coefficients of the normal rows of B,
:func:`~crowd_env.core.contacts.build_rows`). D = 0 is the paper's disk, computed exactly as before.

Each function here is the one place its quantity is computed: :func:`circle_count`, :func:`circle` (offset and
radius of circle s), :func:`arm_m` (the largest distance of a circle's centre from the body's centre, which the
contact margins need for a turning body), :func:`arm_cross` (an arm's lever about a contact direction, the θ
coefficient of a contact row), :func:`body_gaps` (the surface gap of two bodies, for checks) and
:func:`body_circles` (every circle of a crowd).
"""
from __future__ import annotations

import numba as nb
import numpy as np

from crowd_env.errors import ParameterError

from .periodic import minimum_image_dx


@nb.njit(cache=True, inline="always")
def circle_count(depth_m):
    """How many circles make a body of depth ``depth_m``: 1 (the paper's disk, D = 0) or 3."""
    return 1 if depth_m <= 0.0 else 3


@nb.njit(cache=True, inline="always")
def circle(heading_rad, radius_m, depth_m, s):
    """Circle ``s`` (0: the centre; 1, 2: the left and right shoulder) of a body of radius r, depth D and heading θ:
    ``(ox, oy, rc)``, the offset of its centre from the body's centre (m, world frame) and its radius (m).
    D = 0: the disk itself, (0, 0, r)."""
    if depth_m <= 0.0:
        return 0.0, 0.0, radius_m
    rc = 0.5 * depth_m
    if s == 0:
        return 0.0, 0.0, rc
    arm = radius_m - rc if s == 1 else rc - radius_m
    return -arm * np.sin(heading_rad), arm * np.cos(heading_rad), rc


@nb.njit(cache=True, inline="always")
def arm_m(radius_m, depth_m):
    """The distance of the shoulder circles' centres from the body's centre, r − D/2 (0 for the disk): a body
    turning at ω moves a circle's centre by at most abs(ω) (r − D/2) per second."""
    return 0.0 if depth_m <= 0.0 else radius_m - 0.5 * depth_m


@nb.njit(cache=True, inline="always")
def arm_cross(arm, c, x, y):
    """a × (x, y) = a_x y − a_y x for the arm ``arm[c]`` (a circle's centre from its body's centre) and a direction
    (x, y): the lever of a contact along that direction about the body's centre (0 for the disk, whose arm is 0)."""
    return arm[c, 0] * y - arm[c, 1] * x


def check_body_depth(depth_m: float, radius_m: np.ndarray) -> None:
    """Refuse a body depth D the bodies of radii ``radius_m`` cannot have: 0 (the disk) or 0 < D < 2 r_min (at
    D = 2 r the three circles would coincide; use 0). Raises :class:`~crowd_env.errors.ParameterError`."""
    if depth_m == 0.0 or radius_m.shape[0] == 0:
        return
    r_min = float(np.min(radius_m))
    if not depth_m < 2.0 * r_min:
        raise ParameterError(f"body_depth_m = {depth_m:g} m must be below the smallest body's width 2 r = "
                             f"{2.0 * r_min:g} m (0: the paper's disk)")


@nb.njit(cache=True)
def body_gaps(position, heading, radius, depth_m, pairs, period_m=0.0):
    """The surface gap (m; negative: overlap) of each body pair ``pairs`` (P, 2) (rows into the arrays): the
    smallest gap between a circle of one and a circle of the other (the disk's d − r_i − r_j when D = 0);
    nearest images along x with ``period_m``."""
    k = circle_count(depth_m)
    out = np.empty(pairs.shape[0])
    for p in range(pairs.shape[0]):
        i = pairs[p, 0]
        j = pairs[p, 1]
        best = np.inf
        for sa in range(k):
            oax, oay, ra = circle(heading[i], radius[i], depth_m, sa)
            for sb in range(k):
                obx, oby, rb = circle(heading[j], radius[j], depth_m, sb)
                dx = minimum_image_dx(position[i, 0] + oax - position[j, 0] - obx, period_m)
                dy = position[i, 1] + oay - position[j, 1] - oby
                best = min(best, np.sqrt(dx * dx + dy * dy) - ra - rb)
        out[p] = best
    return out


@nb.njit(cache=True)
def body_circles(position, heading, radius, index, depth_m):
    """The circles of the bodies ``index``: ``(centre (nK, 2), radius (nK,), arm (nK, 2))``, circle s of row k at row
    k K + s (K = :func:`circle_count`), ``arm`` its centre's offset from the body's centre. With D = 0 the rows are
    the bodies' own centres and radii, copied."""
    k = circle_count(depth_m)
    n = index.shape[0]
    centre = np.empty((n * k, 2))
    rad = np.empty(n * k)
    arm = np.zeros((n * k, 2))
    for a in range(n):
        i = index[a]
        for s in range(k):
            ox, oy, rc = circle(heading[i], radius[i], depth_m, s)
            centre[a * k + s, 0] = position[i, 0] + ox
            centre[a * k + s, 1] = position[i, 1] + oy
            rad[a * k + s] = rc
            arm[a * k + s, 0] = ox
            arm[a * k + s, 1] = oy
    return centre, rad, arm
