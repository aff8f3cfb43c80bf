"""Vision: a density-speed relation for the calibrated agent (an addition to Kabalan et al. 2016).

The paper's walker always wants its desired speed v0 along e_d (Eq. 14); in a homogeneous crowd its
short-range social force (Eq. 16) cancels, so it walks at v0 however dense the crowd is. Real people keep a
distance that grows with their speed (single file: d ≈ 0.34 m + 1.08 s · v, Seyfried et al. 2005) and
steer into gaps. Vision adds both, after the heuristics of Moussaïd, Helbing & Theraulaz (2011, PNAS
108:6884) in the form of the collision-free speed model of Tordeux, Chraibi & Seyfried (2016):

- the *free distance* f_i(α) is how far pedestrian i can move from where it stands in direction α before
  its centre comes within κ (r_i + r_j) of another pedestrian's centre (the others where they are now) or its
  disk touches a wall, capped at the horizon H_i = l + T v0_i, beyond which nothing changes the choice.
  κ = ``vision_body_scale`` = 1 sees the others as the disks the contacts use; κ < 1 lets a walker pass a
  neighbour whose centre is off its line by more than κ (r_i + r_j): the zipper of Hoogendoorn & Daamen
  (2005), where successive lanes in a bottleneck overlap by part of a body width (the contacts still keep
  the full disks apart). With ``vision_body_scale_standing`` κ_0 > κ the reach shrinks with the walker's own
  speed, κ_i = κ_0 + (κ − κ_0) min(1, ‖u_i‖/v0_i): people sway sideways most when slow and walk narrower
  when fast (the speed-dependent body of the generalised centrifugal force model, Chraibi, Seyfried &
  Schadschneider 2010); with ``vision_anticipation`` w > 0 the others are not where they stand but move on at
  w times their current velocity while the walker walks at v0_i (w = 1: Moussaïd's own collision prediction);
- the walking direction α_i* is, among ``vision_rays`` directions spread evenly over ±``vision_half_angle_rad``
  round e_d, the one whose free walk brings i closest to a point H_i ahead along e_d (Moussaïd's
  heuristic 1): d(α)² = H² + f(α)² − 2 H f(α) cos(α − α_d); ties go to the direction closest to e_d;
- the walking speed is v_i = min(v0_i, max(0, (f_i(α*) − l)/T)) (heuristic 2; the collision-free speed
  rule), T = ``vision_time_gap_s``, l = ``vision_jam_gap_m``;
- with ``vision_door_time_gap_s`` T_d a walker keeps the time gap T_d instead of T while its way passes a door:
  on the stretch it sees, from its centre to r + H_i ahead along e_d (H_i = l + T v0_i) or to the first wall
  straight ahead if nearer (in a bend the straight line leaves the corridor), the walls' width across
  its path (:func:`~crowd_env.walking.apertures.wall_sides_m`) falls below ``vision_door_ratio`` ρ_d shoulder
  widths (ρ_d 2 r_i; 3: at most two abreast) and further on opens to half that on both sides (:func:`through_a_door`:
  a narrowing shorter than the stretch; a channel longer than it, a single-file corridor or a bend is no door). Its speed rule and
  horizon then take T_d (v_i = min(v0_i, max(0, (f − l)/T_d)), H_i = l + T_d v0_i). People keep about half the
  time gap through a door that they keep in a corridor, a channel or a ring: read through this rule, the Jülich
  corridor runs give T ≈ 0.44 s behind the 0.5 m entrance and 0.53 s through the 0.70 m exit, 0.8-1.0 s in the
  corridor and its queues, the single-file ring 1.1 s (:doc:`/validation/virtual_experiments`); and a short
  opening passes more people than a longer channel of its width (1.64 /s through the 0.70 m entrance, 1.29 /s
  through Seyfried's 0.8 m channel 2.8 m long). None (the default): T everywhere;
- with ``vision_leader_time_s`` T_a > 0 a leader pulling away lends its gap ahead: when a neighbour j ends the
  chosen free walk, f_i(α*) gains T_a max(0, u_l − u_i), u_l and u_i the leader's and the walker's velocities
  along e(α*): the gap T_a later if both keep their speeds, counted only while it opens (the velocity-difference
  term of car following: Jiang, Wu & Zhu 2001, Treiber, Hennecke & Helbing 2000). Wherever the gap is not
  opening (u_l ≤ u_i: steady following, a walker moving forward behind a standing or approaching neighbour or a
  wall) it is the rule without it, so the homogeneous corridor's distance-speed relation keeps its form; what
  changes is the start of a queue behind a leader who walks off;
- with ``vision_right_of_way`` a neighbour j farther from the exit than walker i (travel time T_j > T_i, Eq. 11)
  does not block i's rays: whoever is nearer the exit goes first and the other waits, as people give way to
  those ahead in a queue. Without it two walkers who want the same spot (beside a door narrower than two bodies,
  where the field points sideways at the door's axis) each see the other within l and both stand for good. In a
  periodic world the travel time is the uniform field's potential, which jumps at the seam; there "farther from
  the exit" is "behind along e_d" by the minimum image, −(x_j − x_i)·e_d,i > 0, the same order for that field
  (and the same reading serves a navigation without travel times, e.g. circulation round a loop).

The agent's intent then reads u_int = v_i e(α_i*) + (τ/m) Σ f_social, and its heading target θ_d = α_i*.
With T = 0 vision is off and the agent is the paper's; with one ray only the speed changes (the speed rule
of the collision-free speed model along e_d). The rule lives in the calibrated agent's intents only:
learned agents choose their own velocities, and the core's Frémond contacts are unchanged.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numba as nb
import numpy as np

from crowd_env.errors import ParameterError

from ..core.params import check_flag, check_parameter
from ..core.periodic import minimum_image_dx
from ..core.segments import ray_distances
from .apertures import FAR_M, wall_sides_m

__all__ = ["Vision", "Sight", "vision_reach_m", "vision_walk", "ray_circle_distance", "moving_circle_distance",
           "free_distances", "gives_way", "through_a_door"]


class Vision(NamedTuple):
    """The rule's parameters (module docstring; the model's ``vision_<field>`` parameters): T ``time_gap_s`` (0, the
    default: off, the paper's walking model), l ``jam_gap_m``, the fan's ``half_angle_rad`` and ``rays`` (odd: e_d
    is one of them), κ ``body_scale`` and κ_0 ``body_scale_standing`` (None: κ always), w ``anticipation``, T_a
    ``leader_time_s``, the ``right_of_way``, and the time gap in a door T_d ``door_time_gap_s`` (None: T) below
    ρ_d ``door_ratio`` shoulder widths."""

    time_gap_s: float = 0.0
    jam_gap_m: float = 0.0
    half_angle_rad: float = 0.0
    rays: int = 1
    body_scale: float = 1.0
    body_scale_standing: float | None = None
    anticipation: float = 0.0
    leader_time_s: float = 0.0
    right_of_way: bool = False
    door_time_gap_s: float | None = None
    door_ratio: float = 3.0

    def checked(self) -> "Vision":
        """This group, once checked (:class:`~crowd_env.errors.ParameterError` naming the model parameter)."""
        for name in ("time_gap_s", "jam_gap_m", "half_angle_rad", "leader_time_s"):
            check_parameter(f"vision_{name}", getattr(self, name), minimum=0.0)
        _unit("vision_body_scale (kappa)", self.body_scale, low_open=True)
        if self.body_scale_standing is not None:
            _unit("vision_body_scale_standing (kappa_0)", self.body_scale_standing, low_open=True, none=True)
        _unit("vision_anticipation", self.anticipation, low_open=False)
        if self.half_angle_rad > math.pi:
            raise ParameterError(f"vision_half_angle_rad must lie in [0, pi], got {self.half_angle_rad!r}")
        rays = self.rays
        if isinstance(rays, bool) or not isinstance(rays, (int, np.integer)) or rays < 1 or rays % 2 == 0:
            raise ParameterError(f"vision_rays must be an odd integer >= 1, got {rays!r}")
        if rays > 1 and self.half_angle_rad == 0:
            raise ParameterError(f"vision_rays = {rays} needs vision_half_angle_rad > 0 (a fan of directions); with one "
                                 "direction set vision_rays = 1")
        check_flag("vision_right_of_way", self.right_of_way)
        check_parameter("vision_door_ratio", self.door_ratio, minimum=0.0, maximum=FAR_M)
        if self.door_time_gap_s is not None:
            check_parameter("vision_door_time_gap_s", self.door_time_gap_s, positive=True)
            if self.time_gap_s <= 0:
                raise ParameterError(f"vision_door_time_gap_s = {self.door_time_gap_s!r} needs vision switched on "
                                     "(vision_time_gap_s > 0)")
        return self

    def resolved(self) -> "Vision":
        """Plain numbers for the kernels: κ_0 = κ when None, the right of way only while the rule is on (T > 0),
        T_d = T when None."""
        standing = self.body_scale if self.body_scale_standing is None else self.body_scale_standing
        door = self.time_gap_s if self.door_time_gap_s is None else self.door_time_gap_s
        return Vision(float(self.time_gap_s), float(self.jam_gap_m), float(self.half_angle_rad), int(self.rays),
                      float(self.body_scale), float(standing), float(self.anticipation), float(self.leader_time_s),
                      bool(self.time_gap_s > 0 and self.right_of_way), float(door), float(self.door_ratio))


def _unit(name: str, value, *, low_open: bool, none: bool = False) -> None:
    """``value`` must lie in (0, 1] (``low_open``) or [0, 1]; :class:`ParameterError` naming ``name`` otherwise."""
    bad = isinstance(value, bool) or not isinstance(value, (int, float, np.floating)) or not (
        (0.0 < value <= 1.0) if low_open else (0.0 <= value <= 1.0))
    if bad:
        interval = "(0, 1]" if low_open else "[0, 1]"
        raise ParameterError(f"{name} must lie in {interval}{' or be None' if none else ''}, got {value!r}")


class Sight(NamedTuple):
    """What a walker sees with (:func:`free_distances`), per walker of ``rows``: its ``horizon`` (m), its κ_i
    ``body_scale``, the speed it would walk at (``walk_speed``, for the anticipation), and for everyone the
    ``anticipation`` w and the ``right_of_way`` mode (0: everyone blocks, 1: by travel times, 2: by position along
    e_d; :func:`gives_way`)."""

    horizon: np.ndarray
    body_scale: np.ndarray
    walk_speed: np.ndarray
    anticipation: float
    right_of_way: int


@nb.njit(cache=True, inline="always")
def ray_circle_distance(ox, oy, dx, dy, cx, cy, radius):
    """Distance t ≥ 0 along the unit ray (o, d) to the first point within ``radius`` of c; 0 when o is already
    within it and the ray does not lead away from c (a touching pair blocks the way into it); inf if never."""
    wx = cx - ox
    wy = cy - oy
    along = wx * dx + wy * dy
    dist2 = wx * wx + wy * wy
    r2 = radius * radius
    if dist2 <= r2:
        return 0.0 if along > 0.0 else np.inf
    if along <= 0.0:
        return np.inf
    perp2 = dist2 - along * along
    if perp2 >= r2:
        return np.inf
    return along - np.sqrt(r2 - perp2)


@nb.njit(cache=True, inline="always")
def moving_circle_distance(qx, qy, ux, uy, dx, dy, speed, radius):
    """How far a walker starting at the origin can walk along the unit direction d at ``speed`` before a circle
    of ``radius`` about q, itself moving at velocity u, reaches its centre: speed · t for the first t ≥ 0 with
    ``‖q + (u − speed d) t‖ = radius``; 0 when already within it and closing in, inf when never."""
    cx = ux - speed * dx
    cy = uy - speed * dy
    closing = qx * cx + qy * cy
    c0 = qx * qx + qy * qy - radius * radius
    if c0 <= 0.0:
        return 0.0 if closing < 0.0 else np.inf
    a = cx * cx + cy * cy
    disc = closing * closing - a * c0
    if a == 0.0 or closing >= 0.0 or disc < 0.0:
        return np.inf
    return speed * (-closing - np.sqrt(disc)) / a


@nb.njit(cache=True, inline="always")
def _ray_capsule_distance(ox, oy, dx, dy, x0, y0, x1, y1, radius):
    """Distance along the unit ray (o, d) until a disk of ``radius`` centred on the ray touches the segment
    (x0, y0)-(x1, y1): the ray against the capsule of the segment (its two end circles and two sides)."""
    best = min(ray_circle_distance(ox, oy, dx, dy, x0, y0, radius),
               ray_circle_distance(ox, oy, dx, dy, x1, y1, radius))
    ex = x1 - x0
    ey = y1 - y0
    length = np.sqrt(ex * ex + ey * ey)
    if length == 0.0:
        return best
    nx = -ey / length
    ny = ex / length
    # signed distance of the origin from the segment's line, and its rate along the ray
    h = (ox - x0) * nx + (oy - y0) * ny
    rate = dx * nx + dy * ny
    u0 = ((ox - x0) * ex + (oy - y0) * ey) / (length * length)
    if abs(h) <= radius:  # already touching the side's line: blocked only when within the segment, moving in
        if 0.0 <= u0 <= 1.0 and h * rate < 0.0:
            return 0.0
        return best
    if h * rate >= 0.0:
        return best
    t = (abs(h) - radius) / abs(rate)
    u = ((ox + t * dx - x0) * ex + (oy + t * dy - y0) * ey) / (length * length)
    if 0.0 <= u <= 1.0 and t < best:
        best = t
    return best


@nb.njit(cache=True)
def free_distances(position, radius, velocity, index, rows, angles, neighbourhood, walls, period_m, sight,
                   travel_time_s, e_d):
    """f(α) of the pedestrians ``rows`` (rows into ``index``), one per angle in ``angles`` (len(rows), K), each
    capped at its horizon (the :class:`Sight` ``sight``, len(rows) each): the free walk before the centre comes
    within κ (r_i + r_j) of a neighbour's centre (κ: the walker's own ``sight.body_scale``; ``neighbourhood`` =
    ``(neighbours, start)``, CSR lists ``neighbours[start[k]:start[k + 1]]`` of rows into ``index``) or the disk
    touches a wall segment. With ``sight.anticipation`` w > 0 each neighbour moves on at w times its ``velocity``
    (N, 2) while the walker walks at ``sight.walk_speed`` (:func:`moving_circle_distance`); w = 0: the others stand.
    ``sight.right_of_way`` 0: everyone blocks; 1: the walkers have the right of way over neighbours farther from
    the exit by the travel times ``travel_time_s`` (len(index),); 2: over neighbours behind them along their desired
    directions ``e_d`` (len(index), 2) (:func:`gives_way`).

    Returns f (len(rows), K) and, per ray, the velocity along the ray ``u_j · e(α)`` of the neighbour that ends
    the free walk (0 when a wall ends it or nothing does before the horizon)."""
    neighbours, neighbour_start = neighbourhood
    horizon, body_scale, walk_speed = sight.horizon, sight.body_scale, sight.walk_speed
    anticipation, right_of_way = sight.anticipation, sight.right_of_way
    m = rows.shape[0]
    k_rays = angles.shape[1]
    out = np.empty((m, k_rays))
    leader = np.zeros((m, k_rays))
    by_position = right_of_way == 2
    for a in range(m):
        i = index[rows[a]]
        t_i = travel_time_s[rows[a]] if right_of_way == 1 else 0.0
        ox = position[i, 0]
        oy = position[i, 1]
        for q in range(k_rays):
            dx = np.cos(angles[a, q])
            dy = np.sin(angles[a, q])
            best = horizon[a]
            for p in range(neighbour_start[rows[a]], neighbour_start[rows[a] + 1]):
                j = index[neighbours[p]]
                qx = minimum_image_dx(position[j, 0] - ox, period_m)
                if right_of_way and gives_way(travel_time_s[neighbours[p]] if right_of_way == 1 else 0.0, t_i, qx,
                                              position[j, 1] - oy, e_d[rows[a], 0], e_d[rows[a], 1], by_position):
                    continue
                reach = body_scale[a] * (radius[i] + radius[j])
                if anticipation > 0.0:
                    t = moving_circle_distance(qx, position[j, 1] - oy, anticipation * velocity[j, 0],
                                               anticipation * velocity[j, 1], dx, dy, walk_speed[a], reach)
                else:
                    t = ray_circle_distance(ox, oy, dx, dy, ox + qx, position[j, 1], reach)
                if t < best:
                    best = t
                    leader[a, q] = velocity[j, 0] * dx + velocity[j, 1] * dy
            for s in range(walls.shape[0]):
                t = _ray_capsule_distance(ox, oy, dx, dy, walls[s, 0], walls[s, 1], walls[s, 2], walls[s, 3],
                                          radius[i])
                if t < best:
                    best = t
                    leader[a, q] = 0.0
            out[a, q] = best
    return out, leader


@nb.njit(cache=True)
def through_a_door(sides_m, narrow_m):
    """Whether a walker's stretch passes a door (``vision_door_time_gap_s``): on the lines of its stretch, in order,
    the free room to the walls on its left and right (:func:`~crowd_env.walking.apertures.wall_sides_m`, (lines, 2))
    adds up to less than ``narrow_m`` and further on opens to at least ``narrow_m``/2 on both sides. A way that only
    narrows (into a channel longer than the stretch), stays narrow (a single-file corridor) or opens on one side
    only (a bend) is no door."""
    narrowed = False
    half = 0.5 * narrow_m
    for m in range(sides_m.shape[0]):
        if sides_m[m, 0] + sides_m[m, 1] < narrow_m:
            narrowed = True
        elif narrowed and sides_m[m, 0] >= half and sides_m[m, 1] >= half:
            return True
    return False


@nb.njit(cache=True)
def gives_way(t_j, t_i, dx, dy, ex, ey, by_position):
    """Neighbour j gives way to walker i (``vision_right_of_way``): j is farther from the exit, T_j > T_i; with
    ``by_position`` (a periodic world, where T jumps at the seam, or a navigation without travel times) j is
    behind i along i's desired direction (ex, ey) by the (minimum-image) displacement (dx, dy) = x_j − x_i:
    −(dx ex + dy ey) > 0."""
    if by_position:
        return dx * ex + dy * ey < 0.0
    return t_j > t_i


@nb.njit(cache=True)
def _neighbour_lists(n, pairs):
    """CSR adjacency (``neighbours``, ``start``) of ``n`` rows from unordered ``pairs`` (P, 2)."""
    start = np.zeros(n + 1, np.int64)
    for p in range(pairs.shape[0]):
        start[pairs[p, 0] + 1] += 1
        start[pairs[p, 1] + 1] += 1
    for k in range(n):
        start[k + 1] += start[k]
    fill = start[:-1].copy()
    neighbours = np.empty(start[n], np.int64)
    for p in range(pairs.shape[0]):
        a = pairs[p, 0]
        b = pairs[p, 1]
        neighbours[fill[a]] = b
        fill[a] += 1
        neighbours[fill[b]] = a
        fill[b] += 1
    return neighbours, start


@nb.njit(cache=True)
def vision_reach_m(desired_speed, index, vision):
    """Largest horizon l + max(T, T_d) v0 over the pedestrians ``index`` (the :class:`Vision` ``vision``): pairs of
    centres closer than this + 2 r_max are all vision can see."""
    v_max = 0.0
    for k in range(index.shape[0]):
        v_max = max(v_max, desired_speed[index[k]])
    return vision.jam_gap_m + max(vision.time_gap_s, vision.door_time_gap_s) * v_max


@nb.njit(cache=True)
def vision_walk(position, radius, index, e_d, desired_speed, velocity, pairs, walls, period_m, vision, travel_time_s):
    """Walking speed (n,) and unit walking direction (n, 2) of the pedestrians ``index`` (module docstring), with the
    resolved :class:`Vision` ``vision`` (:meth:`Vision.resolved`).

    ``e_d`` (n, 2) their desired directions (Eq. 13), ``pairs`` rows into ``index`` of every pair of centres
    within 2 r_max + :func:`vision_reach_m` (more is harmless). A pedestrian without a desired direction
    (e_d = 0) gets speed 0 and direction 0. Each walker's κ_i runs from ``body_scale_standing`` κ_0 at rest to
    ``body_scale`` κ at its desired speed, linearly in its current speed ‖u_i‖ (``velocity`` (N, 2)), and is κ
    above it: κ_i = κ_0 + (κ − κ_0) min(1, ‖u_i‖ / v0_i). ``anticipation`` w: the others move on at w times their
    velocity while the walker walks at v0_i (Moussaïd et al.'s collision prediction at w = 1). ``leader_time_s``
    T_a > 0: a leader pulling away lends its gap ahead, v = (f + T_a max(0, u_l − u_i) − l)/T with u_l the
    velocity along the chosen direction of the neighbour that ends its free walk (:func:`free_distances`) and
    u_i the walker's own (a wall's u_l is 0); where the gap is not opening (u_l ≤ u_i) nothing changes.
    ``right_of_way``: the right of way (:func:`gives_way`) by the walkers' travel times ``travel_time_s`` (n,)
    (Eq. 11), or, in a periodic world or when ``travel_time_s`` is empty (a navigation without travel times), by
    their positions along e_d; off: everyone blocks. ``door_time_gap_s`` T_d ≠ T: T_d, in the speed rule and the
    horizon, for the walkers whose way ahead the walls narrow below ``door_ratio`` shoulder widths (module
    docstring)."""
    time_gap_s, jam_gap_m, half_angle_rad, n_rays = vision.time_gap_s, vision.jam_gap_m, vision.half_angle_rad, vision.rays
    body_scale, body_scale_standing = vision.body_scale, vision.body_scale_standing
    anticipation, leader_time_s = vision.anticipation, vision.leader_time_s
    n = index.shape[0]
    speed = np.zeros(n)
    direction = np.zeros((n, 2))
    if n == 0:
        return speed, direction
    neighbours, start = _neighbour_lists(n, pairs)
    rows = np.arange(n)
    mode = 0 if not vision.right_of_way else (2 if period_m > 0.0 or travel_time_s.shape[0] == 0 else 1)
    angles = np.empty((n, n_rays))
    horizon = np.empty(n)
    base = np.empty(n)
    for k in range(n):
        base[k] = np.arctan2(e_d[k, 1], e_d[k, 0])
        horizon[k] = jam_gap_m + time_gap_s * desired_speed[index[k]]
    gap_time = np.full(n, time_gap_s)
    if vision.door_time_gap_s != time_gap_s:  # T_d where the walls narrow the way ahead below ρ_d shoulder widths
        ahead = ray_distances(position[index], base.reshape(n, 1), walls, FAR_M)  # the stretch ends at a wall
        reach = np.empty(n)
        for k in range(n):
            reach[k] = min(radius[index[k]] + horizon[k], ahead[k, 0])
        sides = wall_sides_m(position, index, e_d, base, walls, period_m, reach)
        for k in range(n):
            if through_a_door(sides[k], vision.door_ratio * 2.0 * radius[index[k]]):
                gap_time[k] = vision.door_time_gap_s
                horizon[k] = jam_gap_m + gap_time[k] * desired_speed[index[k]]
    for k in range(n):
        for q in range(n_rays):
            # order: 0, +δ, −δ, +2δ, −2δ, ... so that ties go to the direction closest to e_d
            step = (q + 1) // 2
            sign = 1.0 if q % 2 == 1 else -1.0
            offset = 0.0 if q == 0 else sign * step * half_angle_rad / ((n_rays - 1) // 2)
            angles[k, q] = base[k] + offset
    scale = np.empty(n)
    for k in range(n):
        i = index[k]
        u = np.sqrt(velocity[i, 0] ** 2 + velocity[i, 1] ** 2)
        share = min(1.0, u / desired_speed[i]) if desired_speed[i] > 0.0 else 1.0
        scale[k] = body_scale_standing + (body_scale - body_scale_standing) * share
    v0 = np.empty(n)
    for k in range(n):
        v0[k] = desired_speed[index[k]]
    free, leader = free_distances(position, radius, velocity, index, rows, angles, (neighbours, start), walls, period_m,
                                  Sight(horizon, scale, v0, anticipation, mode), travel_time_s, e_d)
    for k in range(n):
        norm = e_d[k, 0] * e_d[k, 0] + e_d[k, 1] * e_d[k, 1]
        if norm == 0.0:
            continue
        h = horizon[k]
        best_q = 0
        best_d2 = np.inf
        for q in range(n_rays):
            f = free[k, q]
            d2 = h * h + f * f - 2.0 * h * f * np.cos(angles[k, q] - base[k])
            if d2 < best_d2 - 1e-12:
                best_d2 = d2
                best_q = q
        gap = free[k, best_q] - jam_gap_m
        ex = np.cos(angles[k, best_q])
        ey = np.sin(angles[k, best_q])
        if leader_time_s > 0.0 and free[k, best_q] < h:  # a leader pulling away lends T_a of its relative speed
            own = velocity[index[k], 0] * ex + velocity[index[k], 1] * ey
            gap += leader_time_s * max(0.0, leader[k, best_q] - own)
        speed[k] = min(desired_speed[index[k]], max(0.0, gap / gap_time[k]))
        direction[k, 0] = ex
        direction[k, 1] = ey
    return speed, direction
