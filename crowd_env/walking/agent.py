"""The calibrated walking agent of Kabalan et al. (2016): eikonal direction plus social force, as a velocity intent.

Each pedestrian's intent is

    u_int = ‖u_d‖ e_d + (τ/m) Σ f_social,

so that the core's driving force m (u_int − u)/τ equals the paper's driving force (Eq. 14) plus
Helbing's social repulsion (Eq. 16) exactly: with every pedestrian on this agent the simulator runs the
paper's model. e_d comes from the eikonal field (Eq. 11-13, :mod:`crowd_env.walking.navigation`); the
desired heading θ_d of the heading spring-damper (Eq. 15) is the angle of e_d. The environment's
default background policy and the experiments use it; ``baselines.social_force`` names it for users.
"""
from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np

from ..core.angles import direction_angles_rad
from ..core.neighbors import grid_pairs
from .navigation import DestinationNavigation, NavigationField, sample_bilinear
from .social_force import social_repulsion, total_social_forces
from .time_to_collision import total_ttc_accelerations
from .vision import vision_reach_m, vision_walk

# agent_step's status: the intents are ready, or a pedestrian's e_d is undefined (outside the grid, not
# finite, or unreachable): the caller must take the Python path, which raises naming it.
AGENT_OK = 0
AGENT_BAD_DIRECTION = 1


@nb.njit(cache=True)
def hold_waiting(intents, theta_d, heading, premovement_s, time_s, index):
    """Hold the pedestrians ``index`` whose premovement time has not come (``time_s < premovement_s[i]``,
    RiMEA's premovement) still: zero intent, θ_d = their heading, so the driving force brakes them to rest
    and the heading spring stays relaxed (contacts may still push them). Returns how many wait."""
    waiting = 0
    for k in range(index.shape[0]):
        i = index[k]
        if time_s < premovement_s[i]:
            intents[i, 0] = 0.0
            intents[i, 1] = 0.0
            theta_d[i] = heading[i]
            waiting += 1
    return waiting


@nb.njit(cache=True)
def baseline_intents(position, radius, index, e_d, desired_speed, tau, mass, heading, velocity, pairs, walls,
                     wall_owner, social, strength_n, range_m, anisotropy, cutoff_m, wall_strength_n, wall_range_m, premovement_s,
                     time_s, vision, ttc, travel_time_s, period_m=0.0):
    """u_int = ‖u_d‖ e_d + (τ/m) Σ f_social (Eq. 14, 16) and θ_d = angle of e_d, in one compiled call (with
    vision: u_int = v e(α*) + (τ/m) Σ f_social and θ_d = α*; with the time-to-collision interaction, + τ Σ f_ttc/m).

    ``index`` (n,) active pedestrians, ``e_d`` (n, 2) their desired directions (Eq. 13), ``pairs``
    rows into ``index``. Returns full (N, 2) intents (zero for inactive rows) and (N,) desired
    headings (the current heading for inactive rows). The forces are :func:`social_repulsion`'s
    compiled core, :func:`~crowd_env.walking.social_force.total_social_forces`. Pedestrians whose
    premovement time has not come at ``time_s`` stand still (:func:`hold_waiting`). ``vision``
    ``(T, l, half-angle, rays, κ, κ_0, w, T_a)`` (:func:`vision_parameters`): with T > 0 the speed and direction of the
    driving term are :func:`~crowd_env.walking.vision.vision_walk`'s (``pairs`` must then reach 2 r_max +
    :func:`~crowd_env.walking.vision.vision_reach_m`), and θ_d is the walking direction's angle; with its right of
    way (``vision[8]`` > 0) ``travel_time_s`` (n,) are the walkers' travel times T (Eq. 11), else unused. ``ttc``
    ``(k, τ0, range, cap)`` (:func:`ttc_parameters`): with k > 0 the time-to-collision interaction of
    :mod:`crowd_env.walking.time_to_collision` over ``pairs`` within the range (``pairs`` must reach it).
    ``period_m``: the simulation's periodicity along x (``Simulator.period_m``; 0: none).
    """
    n = index.shape[0]
    intents = np.zeros((position.shape[0], 2))
    theta_d = heading.copy()
    force = np.zeros((n, 2))
    if social and n:
        pos = np.empty((n, 2))
        rad = np.empty(n)
        for k in range(n):
            pos[k, 0] = position[index[k], 0]
            pos[k, 1] = position[index[k], 1]
            rad[k] = radius[index[k]]
        total_social_forces(pos, rad, e_d, pairs, np.arange(n), walls, wall_owner, strength_n, range_m, anisotropy,
                            cutoff_m, wall_strength_n, wall_range_m, force, period_m)
    if vision[0] > 0.0:  # the walking speed and direction of vision instead of ‖u_d‖ and e_d
        speed, walk = vision_walk(position, radius, index, e_d, desired_speed, velocity, pairs, walls, period_m,
                                  vision[0], vision[1], vision[2], vision[3], vision[4], vision[5], vision[6],
                                  vision[7], vision[8], travel_time_s)
    else:
        speed = np.empty(n)
        for k in range(n):
            speed[k] = desired_speed[index[k]]
        walk = e_d
    angles = direction_angles_rad(walk)
    for k in range(n):
        i = index[k]
        scale = tau[i] / mass[i]
        intents[i, 0] = speed[k] * walk[k, 0] + scale * force[k, 0]
        intents[i, 1] = speed[k] * walk[k, 1] + scale * force[k, 1]
        theta_d[i] = angles[k]
    if ttc[0] > 0.0 and n:  # + τ_i Σ f_ttc / m_i
        accel = total_ttc_accelerations(position, velocity, radius, index, pairs, period_m, ttc[0], ttc[1], ttc[2],
                                        ttc[3])
        for k in range(n):
            i = index[k]
            intents[i, 0] += tau[i] * accel[k, 0]
            intents[i, 1] += tau[i] * accel[k, 1]
    hold_waiting(intents, theta_d, heading, premovement_s, time_s, index)
    return intents, theta_d


class CompiledNavigation(NamedTuple):
    """A navigation as arrays for compiled code: F fields on one grid (``origin_m`` (2,), ``resolution_m``,
    ``travel_time_s`` (F, nx, ny), ``direction`` (F, nx, ny, 2)) and the field of each pedestrian
    ``field_of`` (N,)."""

    origin_m: np.ndarray
    resolution_m: float
    travel_time_s: np.ndarray
    direction: np.ndarray
    field_of: np.ndarray


def compile_navigation(navigation, n_pedestrians: int) -> CompiledNavigation | None:
    """``navigation`` as a :class:`CompiledNavigation`, or None when compiled code cannot sample it the
    way its ``direction`` does (a rigidly moved field, a user's own object, destination fields on
    different grids): callers then keep the Python path."""
    if type(navigation) is NavigationField:
        fields, field_of = [navigation], np.zeros(n_pedestrians, np.int64)
    elif type(navigation) is DestinationNavigation and navigation.destination.shape[0] == n_pedestrians:
        keys = sorted(navigation.fields)
        fields = [navigation.fields[k] for k in keys]
        field_of = np.searchsorted(np.asarray(keys), navigation.destination).astype(np.int64)
    else:
        return None
    first = fields[0]
    if any(f.shape != first.shape or f.resolution_m != first.resolution_m
           or not np.array_equal(f.origin_m, first.origin_m) for f in fields):
        return None
    return CompiledNavigation(np.array([float(first.origin_m[0]), float(first.origin_m[1])]), float(first.resolution_m),
                              np.ascontiguousarray(np.stack([f.travel_time_s_grid for f in fields])),
                              np.ascontiguousarray(np.stack([f.direction_grid for f in fields])), field_of)


@nb.njit(cache=True)
def sample_directions(position, index, origin_m, resolution_m, travel_time, direction, field_of):
    """e_d (Eq. 13) of the pedestrians ``index``, each from its own field, by the same bilinear kernel as
    :meth:`NavigationField.sample` (point by point: the same bits). Returns ``(e_d (n, 2), ok)``; ``ok``
    is False when a point is outside the grid or not finite, or has no direction (unreachable). Also returns the
    travel times T (n,) of the same samples: ``(e_d, T, ok)``."""
    n = index.shape[0]
    e_d = np.empty((n, 2))
    times = np.empty(n)
    ok = True
    for f in range(travel_time.shape[0]):
        count = 0
        for k in range(n):
            if field_of[index[k]] == f:
                count += 1
        if count == 0:
            continue
        rows = np.empty(count, np.int64)
        pts = np.empty((count, 2))
        count = 0
        for k in range(n):
            if field_of[index[k]] == f:
                rows[count] = k
                pts[count, 0] = position[index[k], 0]
                pts[count, 1] = position[index[k], 1]
                count += 1
        out_dir = np.empty((count, 2))
        out_time = np.empty(count)
        if sample_bilinear(pts, origin_m[0], origin_m[1], resolution_m, travel_time[f], direction[f], out_dir,
                            out_time) >= 0:
            ok = False
        for q in range(count):
            e_d[rows[q], 0] = out_dir[q, 0]
            e_d[rows[q], 1] = out_dir[q, 1]
            times[rows[q]] = out_time[q]
    for k in range(n):
        if not (np.isfinite(e_d[k, 0]) and np.isfinite(e_d[k, 1])):
            ok = False
    return e_d, times, ok


@nb.njit(cache=True)
def pair_reach_m(desired_speed, index, social, cutoff_m, vision, ttc):
    """How far beyond 2 r_max the agent needs its neighbour pairs: the social cut-off, vision's horizon
    (:func:`~crowd_env.walking.vision.vision_reach_m`), the time-to-collision range, the largest of them; −1 when
    it needs none."""
    reach = cutoff_m if social else -1.0
    if vision[0] > 0.0:
        reach = max(reach, vision_reach_m(desired_speed, index, vision[0], vision[1]))
    if ttc[0] > 0.0:
        reach = max(reach, ttc[2])
    return reach


def ttc_parameters(params) -> tuple:
    """``(k, τ0, range, cap)`` of :class:`~crowd_env.core.params.ModelParams` ``params`` for the kernels (the
    time-to-collision interaction, :mod:`crowd_env.walking.time_to_collision`; k = 0: off)."""
    return (float(params.ttc_strength_m2_s2), float(params.ttc_horizon_s), float(params.ttc_range_m),
            float(params.ttc_max_accel_m_s2))


def vision_parameters(params) -> tuple:
    """``(T, l, half-angle, rays, κ, κ_0, w, T_a, right of way)`` of :class:`~crowd_env.core.params.ModelParams`
    ``params`` for the kernels (κ_0 = κ when ``vision_body_scale_standing`` is None; w the anticipation, T_a the
    leader time, the right of way 1.0 or 0.0)."""
    standing = params.vision_body_scale if params.vision_body_scale_standing is None \
        else params.vision_body_scale_standing
    return (float(params.vision_time_gap_s), float(params.vision_jam_gap_m), float(params.vision_half_angle_rad),
            int(params.vision_rays), float(params.vision_body_scale), float(standing),
            float(params.vision_anticipation), float(params.vision_leader_time_s),
            1.0 if params.vision_time_gap_s > 0 and params.vision_right_of_way else 0.0)


@nb.njit(cache=True)
def agent_step(position, radius, index, origin_m, resolution_m, travel_time, direction, field_of, desired_speed, tau,
               mass, heading, velocity, walls, wall_owner, social, strength_n, range_m, anisotropy, cutoff_m,
               wall_strength_n, wall_range_m, premovement_s, time_s, vision, ttc, period_m=0.0):
    """One decision of :class:`SocialForceAgent` in compiled code, exactly as its ``__call__``: e_d from the
    fields (:func:`sample_directions`), the neighbour pairs within 2 r_max + cut-off (the ones
    ``Simulator.neighbor_pairs`` would build, which the step may reuse) and :func:`baseline_intents`.
    Returns ``(status, intents, θ_d, pairs, pair_radius_m)``, ``pair_radius_m`` −1 when no pairs were built."""
    n = index.shape[0]
    no_pairs = np.zeros((0, 2), np.int64)
    e_d, times, ok = sample_directions(position, index, origin_m, resolution_m, travel_time, direction, field_of)
    if not ok:
        return AGENT_BAD_DIRECTION, np.zeros((position.shape[0], 2)), heading.copy(), no_pairs, -1.0
    pairs = no_pairs
    pair_radius = -1.0
    reach = pair_reach_m(desired_speed, index, social, cutoff_m, vision, ttc)
    if reach >= 0.0:
        r_max = 0.0
        for k in range(n):
            r_max = max(r_max, radius[index[k]])
        pair_radius = 2.0 * r_max + reach
        pairs = grid_pairs(position, index, pair_radius, period_m)
    intents, theta_d = baseline_intents(position, radius, index, e_d, desired_speed, tau, mass, heading, velocity,
                                        pairs, walls, wall_owner, social, strength_n, range_m, anisotropy, cutoff_m, wall_strength_n,
                                        wall_range_m, premovement_s, time_s, vision, ttc, times, period_m)
    return AGENT_OK, intents, theta_d, pairs, pair_radius


class CompiledAgent(NamedTuple):
    """:class:`SocialForceAgent` for compiled code (:func:`decide`): its navigation and the parameters of
    :class:`~crowd_env.core.params.ModelParams` it reads (Eq. 16's A, B, λ and cut-off, the walls' A and B,
    :func:`vision_parameters`, :func:`ttc_parameters`). Built by :func:`compiled_agent`."""

    navigation: CompiledNavigation
    social: bool
    strength_n: float
    range_m: float
    anisotropy: float
    cutoff_m: float
    wall_strength_n: float
    wall_range_m: float
    vision: tuple
    ttc: tuple


def compiled_agent(navigation: CompiledNavigation, params) -> CompiledAgent:
    """The :class:`CompiledAgent` of a compiled ``navigation`` (:meth:`SocialForceAgent.compiled`) under
    ``params``."""
    return CompiledAgent(navigation, bool(params.social_forces), float(params.social_strength_n),
                         float(params.social_range_m), float(params.social_anisotropy), float(params.social_cutoff_m),
                         float(params.wall_strength_n), float(params.wall_range_m), vision_parameters(params),
                         ttc_parameters(params))


@nb.njit(cache=True, inline="always")
def decide(agent, bodies, world, index, time_s):
    """:func:`agent_step` of the :class:`CompiledAgent` ``agent`` for the pedestrians ``index`` of ``bodies`` in
    ``world`` (:mod:`crowd_env.core.bundles`) at ``time_s``: ``(status, intents, θ_d, pairs, pair_radius_m)``."""
    nav = agent.navigation
    return agent_step(bodies.position_m, bodies.radius_m, index, nav.origin_m, nav.resolution_m, nav.travel_time_s,
                      nav.direction, nav.field_of, bodies.desired_speed_m_s, bodies.tau_s, bodies.mass_kg,
                      bodies.heading_rad, bodies.velocity_m_s, world.walls, world.wall_owner, agent.social,
                      agent.strength_n, agent.range_m, agent.anisotropy, agent.cutoff_m, agent.wall_strength_n,
                      agent.wall_range_m, bodies.premovement_s, time_s, agent.vision, agent.ttc, world.period_m)


def travel_time(navigation, position_m: np.ndarray, index: np.ndarray) -> np.ndarray:
    """T (Eq. 11), (m,), of pedestrians ``index`` at ``position_m[index]`` from ``navigation``, as
    :func:`desired_direction` reads e_d: its ``travel_time(points)``, or ``travel_time(points, index)`` for a
    per-pedestrian navigation; an empty array for a navigation without ``travel_time`` (vision's right of way
    then reads positions along e_d, :func:`~crowd_env.walking.vision.gives_way`)."""
    sample = getattr(navigation, "travel_time", None)
    return np.zeros(0) if sample is None else _read_navigation(navigation, sample, position_m, index)


def _read_navigation(navigation, read, position_m: np.ndarray, index: np.ndarray):
    """``read`` (a method of ``navigation``) at ``position_m[index]``: ``read(points, index)`` when the
    navigation's ``per_pedestrian`` attribute is true (each pedestrian's own destination), else ``read(points)``."""
    if getattr(navigation, "per_pedestrian", False):
        return read(position_m[index], index)
    return read(position_m[index])


def desired_direction(navigation, position_m: np.ndarray, index: np.ndarray) -> np.ndarray:
    """e_d (Eq. 13), (m, 2), of pedestrians ``index`` at ``position_m[index]`` from ``navigation``: its
    ``direction(points)``, or ``direction(points, index)`` when its ``per_pedestrian`` attribute is true
    (each pedestrian's own destination)."""
    return _read_navigation(navigation, navigation.direction, position_m, index)


class SocialForceAgent:
    """Policy object: ``agent(sim) -> (intents (N, 2), desired_heading (N,))`` for a :class:`Simulator`.

    ``navigation``: an object with ``direction(points) -> (n, 2)`` (a
    :class:`~crowd_env.walking.navigation.NavigationField`), or, when its ``per_pedestrian`` attribute is
    true, ``direction(points, index)`` (a :class:`~crowd_env.walking.navigation.DestinationNavigation`:
    each pedestrian follows the field of its own destination exit; a navigation with an ``update(sim)``
    method, e.g. :class:`~crowd_env.walking.route_choice.QuickestExitNavigation`, is updated once per
    decision). Social parameters (A, B, λ,
    cut-off, on/off) are read from the simulator's :class:`~crowd_env.core.params.ModelParams`.
    """

    def __init__(self, navigation):
        self.navigation = navigation

    def desired_direction(self, sim, index=None) -> np.ndarray:
        """e_d (Eq. 13) at the positions of pedestrians ``index`` (default: the active ones)."""
        idx = sim.active_index if index is None else index
        return desired_direction(self.navigation, sim.state.position_m, idx)

    def social_force(self, sim, e_d: np.ndarray) -> np.ndarray:
        """Σ f_social (N) on every active pedestrian, from pedestrians and walls (Eq. 16); compact rows."""
        st = sim.state
        p = sim.params
        idx = sim.active_index
        pos = st.position_m[idx]
        radius = st.radius_m[idx]
        pairs = sim.neighbor_pairs(2.0 * float(radius.max()) + p.social_cutoff_m) if idx.size else np.zeros((0, 2), np.int64)
        return social_repulsion(pos, radius, e_d, pairs, sim.walls, sim.wall_owner, p, period_m=sim.period_m)

    def compiled(self, n_pedestrians: int) -> CompiledNavigation | None:
        """The agent's navigation for :func:`agent_step` (None: this agent has no compiled form, e.g. a
        subclass that changes how it decides, or a navigation compiled code cannot sample)."""
        cls = type(self)
        if cls.__call__ is not SocialForceAgent.__call__ or cls.desired_direction is not SocialForceAgent.desired_direction:
            return None
        return compile_navigation(self.navigation, n_pedestrians)

    def __call__(self, sim):
        st = sim.state
        p = sim.params
        idx = sim.active_index
        if idx.size == 0:
            return np.zeros((st.n, 2)), st.heading_rad.copy()
        update = getattr(self.navigation, "update", None)  # a navigation that changes with the crowd
        if update is not None:
            update(sim)
        e_d = self.desired_direction(sim, idx)
        vision = vision_parameters(p)
        ttc = ttc_parameters(p)
        times = travel_time(self.navigation, st.position_m, idx) if vision[8] > 0.0 else np.zeros(0)
        reach = pair_reach_m(st.desired_speed_m_s, idx, bool(p.social_forces), float(p.social_cutoff_m), vision, ttc)
        pairs = sim.neighbor_pairs(2.0 * float(st.radius_m[idx].max()) + reach) if reach >= 0.0 \
            else np.zeros((0, 2), np.int64)
        return baseline_intents(st.position_m, st.radius_m, idx, e_d, st.desired_speed_m_s, st.tau_s, st.mass_kg,
                                st.heading_rad, st.velocity_m_s, pairs, sim.walls, sim.wall_owner, p.social_forces,
                                float(p.social_strength_n), float(p.social_range_m), float(p.social_anisotropy),
                                float(p.social_cutoff_m), float(p.wall_strength_n), float(p.wall_range_m),
                                st.premovement_s, float(sim.time_s), vision, ttc, np.asarray(times, np.float64),
                                sim.period_m)
