"""Helbing's social repulsion with anisotropy (Kabalan et al. 2016, Eq. 16), between pedestrians and from walls.

After Helbing, Farkas & Vicsek (2000), the force on pedestrian i from pedestrian j is

    f_ij = A exp((R_ij - d_ij) / B) · w_i(φ_ij) · n_ji,   w_i(φ) = λ + (1 - λ)(1 + cos φ) / 2,

with R_ij = r_i + r_j, d_ij the centre distance, n_ji the unit vector from j to i and φ_ij the angle
between i's desired direction e_d,i (Eq. 13) and the direction from i to j: a neighbour straight ahead
counts fully, one straight behind with weight λ (λ = 1 is isotropic). The force on j uses j's own
weight, so Newton's third law holds only for λ = 1. Forces act at the centre (no torque).

A candidate beyond the paper (off by default): with ``lateral_range_scale`` s < 1 the range depends on the
bearing as well, B(φ) = B √(cos²φ + s² sin²φ): B for a neighbour ahead or behind, s B for one beside (an
ellipse of ranges along e_d, in the spirit of the elliptical specification of Johansson, Helbing & Shukla
2007). The recordings of the Jülich corridor runs show people coming closer beside each other than ahead
(:func:`crowd_env.analysis.corridor_runs.neighbour_spacing`); one range B holds them apart alike in both.

Walls: the paper defines Eq. 16 between pedestrians only (its walls act through the Frémond collisions
alone); the wall term here is Helbing, Farkas & Vicsek's (2000), with R = r_i, d the distance to the
wall's closest point, n the wall's normal into the pedestrian, and its own strength and range
(:class:`WallForce`, the model's ``wall_social_strength_n`` and ``wall_social_range_m``; ``wall_social_strength_n
= 0`` is the paper-literal model). The parameters come in two small frozen groups checked here, :class:`SocialForce`
and :class:`WallForce` (:class:`crowd_env.walking.agent.WalkingParams` holds them with the agent's others).

Neighbour pairs come from the simulator's cell grid (:mod:`crowd_env.core.neighbors`), pedestrian/wall
pairs from :func:`crowd_env.core.segments.wall_proximity`; pairs whose surface gap exceeds ``cutoff_m``
contribute nothing. The simulator itself never calls this module: the calibrated agent
(:mod:`crowd_env.walking.agent`) adds these forces to its velocity intent. In a periodic simulation
(``period_m`` L > 0) the displacement between two pedestrians is taken to its nearest image along x
(:func:`~crowd_env.core.periodic.minimum_image_dx`); walls are not periodic.
"""
from __future__ import annotations

from crowd_env.errors import InputError, ParameterError

from typing import NamedTuple

import numba as nb
import numpy as np

from ..core.params import check_flag, check_parameter
from ..core.periodic import minimum_image_dx
from ..core.segments import as_segments, closest_point_on_segment, wall_proximity

_TINY_M = 1e-12  # centre distances below this have no defined direction: the pair is skipped


class SocialForce(NamedTuple):
    """Eq. 16 between pedestrians (the model's ``social_<field>`` parameters): ``forces`` on or off, A
    ``strength_n``, B ``range_m``, λ ``anisotropy`` (1 = isotropic; Eq. 16 states 0 < λ < 1), pairs interacting while
    their surface gap is below ``cutoff_m`` (walls too), and s ``lateral_range_scale`` (0 < s ≤ 1; 1, the default, is
    Eq. 16: the range does not depend on the bearing). Defaults: Kabalan's validation point (Section 4.1.3)."""

    forces: bool = True
    strength_n: float = 790.0
    range_m: float = 0.08
    anisotropy: float = 1.0
    cutoff_m: float = 1.0
    lateral_range_scale: float = 1.0  # s: the range beside a walker is s B (module docstring); 1: Eq. 16's

    def checked(self) -> "SocialForce":
        """This group, once its values are checked (:class:`~crowd_env.errors.ParameterError` naming the model
        parameter)."""
        check_flag("social_forces", self.forces)
        check_parameter("social_strength_n", self.strength_n, minimum=0.0)
        check_parameter("social_range_m", self.range_m, positive=True)
        if isinstance(self.anisotropy, bool) or not isinstance(self.anisotropy, (int, float, np.floating)) \
                or not 0.0 <= self.anisotropy <= 1.0:
            raise ParameterError(f"social_anisotropy (lambda) must lie in [0, 1], got {self.anisotropy!r}")
        check_parameter("social_cutoff_m", self.cutoff_m, positive=True)
        check_parameter("social_lateral_range_scale", self.lateral_range_scale, positive=True)
        if self.lateral_range_scale > 1.0:
            raise ParameterError(f"social_lateral_range_scale (s) must lie in (0, 1], got {self.lateral_range_scale!r}")
        return self

    def resolved(self) -> "SocialForce":
        """Plain numbers for the kernels (one numba type whatever was given)."""
        return SocialForce(bool(self.forces), float(self.strength_n), float(self.range_m), float(self.anisotropy),
                           float(self.cutoff_m), float(self.lateral_range_scale))


class WallForce(NamedTuple):
    """Helbing's wall repulsion (the model's ``wall_social_<field>`` parameters): A ``strength_n`` and B ``range_m``
    for walls, None for the pedestrians' own (:class:`SocialForce`); ``strength_n = 0`` is the paper-literal model
    (walls act through the Frémond contacts alone). λ and the cut-off are the pedestrians'."""

    strength_n: float | None = None
    range_m: float | None = None

    def checked(self) -> "WallForce":
        """This group, once checked (each a non-negative finite number or None; the range > 0)."""
        for name, value in (("wall_social_strength_n", self.strength_n), ("wall_social_range_m", self.range_m)):
            if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float, np.integer,
                                                                                       np.floating))
                                      or not np.isfinite(value) or value < 0 or (name.endswith("_m") and value == 0)):
                raise ParameterError(f"{name} must be a positive finite number or None, got {value!r}")
        return self

    def resolved(self, social: SocialForce) -> "WallForce":
        """Plain numbers for the kernels: None takes the pedestrians' A or B (``social``)."""
        return WallForce(float(social.strength_n if self.strength_n is None else self.strength_n),
                         float(social.range_m if self.range_m is None else self.range_m))


@nb.njit(cache=True, inline="always")
def _cos_bearing(ex, ey, ux, uy):
    """cos φ, φ between the desired direction e and the unit vector u; 0 for a zero desired direction."""
    norm = np.sqrt(ex * ex + ey * ey)
    cos_phi = 0.0
    if norm > 0.0:
        cos_phi = (ex * ux + ey * uy) / norm
        if cos_phi > 1.0:
            cos_phi = 1.0
        elif cos_phi < -1.0:
            cos_phi = -1.0
    return cos_phi


@nb.njit(cache=True, inline="always")
def _anisotropy_weight(ex, ey, ux, uy, anisotropy):
    """w = λ + (1 - λ)(1 + cos φ)/2 (Eq. 16), φ between desired direction e and unit vector u.

    A zero desired direction gives cos φ = 0 (weight (1 + λ)/2).
    """
    return anisotropy + (1.0 - anisotropy) * 0.5 * (1.0 + _cos_bearing(ex, ey, ux, uy))


@nb.njit(cache=True, inline="always")
def _bearing_range_m(ex, ey, ux, uy, range_m, lateral_scale):
    """B(φ) = B √(cos²φ + s² sin²φ): B ahead and behind, s B beside (φ between the desired direction e and u)."""
    c = _cos_bearing(ex, ey, ux, uy)
    return range_m * np.sqrt(c * c + lateral_scale * lateral_scale * (1.0 - c * c))


@nb.njit(cache=True)
def social_forces(position, radius, desired_direction, pairs, strength_n, range_m, anisotropy, cutoff_m, out,
                  period_m=0.0, lateral_range_scale=1.0):
    """Accumulate pedestrian-pedestrian repulsion (Eq. 16) into ``out`` (N, 2), in newtons.

    ``pairs`` (P, 2) int: unordered index pairs (i, j); each contributes f_ij to i and f_ji to j.
    Pairs with surface gap d_ij - R_ij > ``cutoff_m`` or coincident centres are skipped. ``period_m`` L > 0:
    x is periodic (nearest images). ``lateral_range_scale`` s < 1: each walker sees the other with the range
    B(φ) = B √(cos²φ + s² sin²φ) (module docstring).
    """
    for p in range(pairs.shape[0]):
        i = pairs[p, 0]
        j = pairs[p, 1]
        dx = minimum_image_dx(position[i, 0] - position[j, 0], period_m)  # from j to i
        dy = position[i, 1] - position[j, 1]
        d = np.sqrt(dx * dx + dy * dy)
        gap = d - radius[i] - radius[j]
        if gap > cutoff_m or d < _TINY_M:
            continue
        nx = dx / d  # n_ji: unit vector from j to i
        ny = dy / d
        # i sees j in direction -n_ji; j sees i in direction +n_ji.
        wi = _anisotropy_weight(desired_direction[i, 0], desired_direction[i, 1], -nx, -ny, anisotropy)
        wj = _anisotropy_weight(desired_direction[j, 0], desired_direction[j, 1], nx, ny, anisotropy)
        if lateral_range_scale == 1.0:  # Eq. 16: one range, one magnitude for both
            mag_i = mag_j = strength_n * np.exp(-gap / range_m)
        else:
            mag_i = strength_n * np.exp(-gap / _bearing_range_m(desired_direction[i, 0], desired_direction[i, 1], -nx,
                                                                -ny, range_m, lateral_range_scale))
            mag_j = strength_n * np.exp(-gap / _bearing_range_m(desired_direction[j, 0], desired_direction[j, 1], nx,
                                                                ny, range_m, lateral_range_scale))
        out[i, 0] += mag_i * wi * nx
        out[i, 1] += mag_i * wi * ny
        out[j, 0] -= mag_j * wj * nx
        out[j, 1] -= mag_j * wj * ny
    return out


@nb.njit(cache=True)
def wall_social_forces(desired_direction, index, ped, gap, normal_x, normal_y, strength_n, range_m, anisotropy,
                       cutoff_m, out):
    """Accumulate wall repulsion (Eq. 16 with R = r_i) into ``out`` (N, 2), in newtons.

    ``ped, gap, normal_x, normal_y`` are the first, third, fourth and fifth outputs of
    :func:`~crowd_env.core.segments.wall_proximity` (rows into ``index``, surface gap, unit normal
    from the wall into the pedestrian); ``index`` maps rows to pedestrians. The direction from the
    pedestrian to the wall's closest point is -normal, so closest points are not needed.
    """
    for k in range(ped.shape[0]):
        if gap[k] > cutoff_m:
            continue
        i = index[ped[k]]
        nx = normal_x[k]
        ny = normal_y[k]
        w = _anisotropy_weight(desired_direction[i, 0], desired_direction[i, 1], -nx, -ny, anisotropy)
        mag = strength_n * np.exp(-gap[k] / range_m) * w
        out[i, 0] += mag * nx
        out[i, 1] += mag * ny
    return out


@nb.njit(cache=True)
def wall_forces_within(position, radius, desired_direction, index, segments, owner, strength_n, range_m, anisotropy,
                       cutoff_m, out):
    """Compiled core of :func:`wall_repulsion`: wall neighbours of pedestrians ``index`` within
    ``cutoff_m`` (:func:`wall_proximity`) and their repulsion (:func:`wall_social_forces`) into ``out``."""
    if segments.shape[0] == 0:
        return out
    ped, _seg, gap, nx, ny, _cx, _cy = wall_proximity(position, radius, index, segments, owner,
                                                      np.full(index.shape[0], cutoff_m))
    return wall_social_forces(desired_direction, index, ped, gap, nx, ny, strength_n, range_m, anisotropy, cutoff_m,
                              out)


@nb.njit(cache=True)
def total_social_forces(position, radius, desired_direction, pairs, index, segments, owner, social, wall, out,
                        period_m=0.0):
    """Compiled core of :func:`social_repulsion` (Eq. 16 between the ``pairs`` and from the walls near
    pedestrians ``index``) with the :class:`SocialForce` ``social`` and the resolved :class:`WallForce` ``wall``
    (:meth:`WallForce.resolved`), accumulated into ``out``; also called from other compiled code. ``period_m``:
    the periodicity along x of the pedestrians' displacements (0: none)."""
    social_forces(position, radius, desired_direction, pairs, social.strength_n, social.range_m, social.anisotropy,
                  social.cutoff_m, out, period_m, social.lateral_range_scale)
    return wall_forces_within(position, radius, desired_direction, index, segments, owner, wall.strength_n,
                              wall.range_m, social.anisotropy, social.cutoff_m, out)


def wall_repulsion(position, radius, desired_direction, segments, owner, strength_n, range_m, anisotropy,
                   cutoff_m, out, index=None):
    """Query :func:`wall_proximity` within ``cutoff_m`` and accumulate wall repulsion into ``out``.

    ``index`` (int array) restricts to those pedestrians (e.g. the active ones); default all.
    ``owner`` comes from :func:`~crowd_env.core.segments.endpoint_owners` (shared corners once).
    """
    index = np.arange(position.shape[0], dtype=np.int64) if index is None else \
        np.ascontiguousarray(index, dtype=np.int64)
    return wall_forces_within(position, radius, desired_direction, index, segments, owner, float(strength_n),
                              float(range_m), float(anisotropy), float(cutoff_m), out)


def social_repulsion(position, radius, desired_direction, pairs, segments, owner, social: SocialForce,
                     wall: WallForce = WallForce(), index=None, out=None, period_m: float = 0.0):
    """Total social force (N, 2) in newtons from pedestrians and walls: the :class:`SocialForce` ``social`` between
    pedestrians (A, B, λ and the cut-off for both) and the :class:`WallForce` ``wall`` for walls (None fields: the
    pedestrians' A, B). ``pairs`` must only hold pedestrians that should interact (e.g. active ones); ``index``
    restricts wall queries. ``period_m``: the periodicity along x (``Simulator.period_m``; 0: none).
    """
    n = position.shape[0]
    if out is None:
        out = np.zeros((n, 2))
    elif out.shape != (n, 2):
        raise InputError(f"out must have shape {(n, 2)}, got {out.shape}")
    if isinstance(pairs, (set, frozenset)):  # cKDTree.query_pairs' default output
        pairs = sorted(pairs)
    pairs = np.ascontiguousarray(pairs, dtype=np.int64).reshape(-1, 2)
    if pairs.size and (pairs.min() < 0 or pairs.max() >= n):
        raise InputError(f"neighbour pairs index pedestrians outside 0..{n - 1}")
    index = np.arange(n, dtype=np.int64) if index is None else np.ascontiguousarray(index, dtype=np.int64)
    social = social.checked().resolved()
    return total_social_forces(position, radius, desired_direction, pairs, index, segments, owner, social,
                               wall.checked().resolved(social), out, float(period_m))


def social_forces_dense_reference(position, radius, desired_direction, segments, strength_n, range_m, anisotropy,
                                  cutoff_m, wall_strength_n=None, wall_range_m=None, corner_tol_m=1e-9,
                                  lateral_range_scale=1.0):
    """Slow dense reference of Eq. 16 for tests: all N² pairs and all walls, plain loops.

    Independent of the kernels' pair lists; walls follow the convention of
    :func:`~crowd_env.core.segments.endpoint_owners`: a closest point at a segment endpoint shared
    with other segments counts only when it is also their closest point, and then once.
    """
    position = np.asarray(position, dtype=np.float64)
    n = position.shape[0]
    segments = as_segments(segments)
    wall_strength_n = strength_n if wall_strength_n is None else wall_strength_n
    wall_range_m = range_m if wall_range_m is None else wall_range_m
    lam = anisotropy
    force = np.zeros((n, 2))

    def cos_bearing(i, u):
        e = desired_direction[i]
        ne = np.linalg.norm(e)
        return 0.0 if ne == 0 else float(np.clip(e @ u / ne, -1.0, 1.0))

    def weight(i, u):
        return lam + (1.0 - lam) * (1.0 + cos_bearing(i, u)) / 2.0

    def pair_range(i, u):
        if lateral_range_scale == 1.0:
            return range_m
        c = cos_bearing(i, u)
        return range_m * np.sqrt(c ** 2 + lateral_range_scale ** 2 * (1.0 - c ** 2))

    for i in range(n):
        for j in range(n):
            if i == j:
                continue
            diff = position[i] - position[j]
            d = np.linalg.norm(diff)
            if d < _TINY_M or d - radius[i] - radius[j] > cutoff_m:
                continue
            n_ji = diff / d
            force[i] += strength_n * np.exp((radius[i] + radius[j] - d) / pair_range(i, -n_ji)) * weight(i, -n_ji) \
                * n_ji
        for k in range(segments.shape[0]):
            cx, cy, t = closest_point_on_segment(position[i, 0], position[i, 1], *segments[k])
            c = np.array([cx, cy])
            if t in (0.0, 1.0):
                # Other segments sharing this vertex: skip it unless it is the closest point of every
                # one of them, and then count it once (lowest index).
                skip = False
                for k2 in range(segments.shape[0]):
                    ends = segments[k2].reshape(2, 2)
                    shared = np.all(np.abs(ends - c) <= corner_tol_m, axis=1)
                    if k2 == k or not shared.any():
                        continue
                    t2 = closest_point_on_segment(position[i, 0], position[i, 1], *segments[k2])[2]
                    if t2 != (1.0 if shared[1] else 0.0) or k2 < k:
                        skip = True
                if skip:
                    continue
            diff = position[i] - c
            d = np.linalg.norm(diff)
            if d < _TINY_M or d - radius[i] > cutoff_m:
                continue
            normal = diff / d
            force[i] += wall_strength_n * np.exp((radius[i] - d) / wall_range_m) * weight(i, -normal) * normal
    return force


__all__ = [
    "SocialForce",
    "WallForce",
    "social_forces",
    "wall_social_forces",
    "wall_repulsion",
    "wall_forces_within",
    "social_repulsion",
    "total_social_forces",
    "social_forces_dense_reference",
]
