"""The calibrated walking agent of Kabalan et al. (2016): eikonal direction plus social force, as a velocity intent.

Each pedestrian's intent is

    u_int = ‖u_d‖ e_d + (τ/m) Σ f_social,

so that the core's driving force m (u_int − u)/τ equals the paper's driving force (Eq. 14) plus
Helbing's social repulsion (Eq. 16) exactly: with every pedestrian on this agent the simulator runs the
paper's model. e_d comes from the eikonal field (Eq. 11-13, :mod:`crowd_env.walking.navigation`); the
desired heading θ_d of the heading spring-damper (Eq. 15) is the angle of e_d. The environment's
default background policy and the experiments use it; ``baselines.social_force`` names it for users.

The agent's parameters are :class:`WalkingParams`, a named tuple of small frozen groups, each checked beside the
kernel that reads it: :class:`~crowd_env.walking.social_force.SocialForce` and
:class:`~crowd_env.walking.social_force.WallForce` (Eq. 16), :class:`~crowd_env.walking.vision.Vision`,
:class:`~crowd_env.walking.time_to_collision.TimeToCollision`, the agent's own :class:`Intent` and
:class:`~crowd_env.walking.give_way.GiveWay` and :class:`~crowd_env.walking.shoulder_turn.ShoulderTurn`. A model's
``<group>_<field>`` parameter (``social_strength_n``, ``vision_time_gap_s``, ...) is the field of its group
(:class:`crowd_env.walking.model.ModelParams` pairs them with the core's physics). The kernels take the
resolved bundle (:meth:`WalkingParams.resolved`, plain numbers) beside the core's :class:`~crowd_env.core.bundles.Bodies`
and :class:`~crowd_env.core.bundles.World`, and return named results (:class:`Intents`, :class:`Decision`). One body
serves both paths: :meth:`SocialForceAgent.__call__` (a simulator stepped from Python) and :func:`decide` (compiled
rollouts) call the same :func:`pair_radius_m` and :func:`baseline_intents`.
"""
from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np

from ..core.angles import direction_angles_rad
from ..core.bundles import Bodies, World
from ..core.neighbors import grid_pairs
from ..core.params import check_parameter
from .give_way import GiveWay, give_way
from .shoulder_turn import ShoulderTurn, shoulder_turn, shoulder_turn_reach_m
from .navigation import DestinationNavigation, NavigationField, sample_bilinear
from .social_force import SocialForce, WallForce, social_repulsion, total_social_forces
from .time_to_collision import TimeToCollision, total_ttc_accelerations
from .vision import Vision, vision_reach_m, vision_walk

# agent_step's status: the intents are ready, or a pedestrian's e_d is undefined (outside the grid, not
# finite, or unreachable): the caller must take the Python path, which raises naming it.
AGENT_OK = 0
AGENT_BAD_DIRECTION = 1


class Intent(NamedTuple):
    """The calibrated agent's own numbers (the model's ``intent_<field>`` parameters): what shapes its intent beyond
    the social force, vision and the time to collision, read by :func:`baseline_intents`. The paper's model has none;
    docs/architecture/layers.md adds one (a cap on the intent's speed) as the worked example of a new walking-model
    parameter. Each is a finite number >= 0."""

    def checked(self) -> "Intent":
        """This group, once checked (:class:`~crowd_env.errors.ParameterError` naming the model parameter)."""
        for name, value in zip(self._fields, self):
            check_parameter(f"intent_{name}", value, minimum=0.0)
        return self

    def resolved(self) -> "Intent":
        """Plain numbers for the kernels."""
        return type(self)(*(float(value) for value in self))


class WalkingParams(NamedTuple):
    """The calibrated agent's parameters, one frozen group each, defaults the paper's model (Kabalan's validation
    point, no wall term of its own, vision, time to collision, giving way and turning the shoulders off). The model's parameter ``<group>_<field>``
    (``social_strength_n``, ``wall_social_range_m``, ``vision_rays``, ``ttc_horizon_s``, ...) is ``field`` of the
    group ``group`` (:class:`crowd_env.walking.model.ModelParams`)."""

    social: SocialForce = SocialForce()
    wall_social: WallForce = WallForce()
    vision: Vision = Vision()
    ttc: TimeToCollision = TimeToCollision()
    intent: Intent = Intent()
    give_way: GiveWay = GiveWay()
    shoulder_turn: ShoulderTurn = ShoulderTurn()

    def checked(self) -> "WalkingParams":
        """These parameters, once every group is checked beside its kernel (:class:`~crowd_env.errors.ParameterError`
        naming the model parameter)."""
        for group in self:
            group.checked()
        return self

    def resolved(self) -> "WalkingParams":
        """The bundle the kernels take: plain numbers, the walls' A and B where None the pedestrians', vision's κ_0
        and right of way resolved (:meth:`Vision.resolved <crowd_env.walking.vision.Vision.resolved>`)."""
        return WalkingParams(self.social.resolved(), self.wall_social.resolved(self.social), self.vision.resolved(),
                             self.ttc.resolved(), self.intent.resolved(), self.give_way.resolved(),
                             self.shoulder_turn.resolved())


DEFAULT_WALKING = WalkingParams().resolved()


def walking_bundle(params) -> WalkingParams:
    """The resolved :class:`WalkingParams` of a simulator's parameters: a
    :class:`~crowd_env.walking.model.ModelParams`' own (``params.walking_bundle``, resolved once), or the defaults,
    the paper's walking model, for the core's :class:`~crowd_env.core.params.PhysicsParams` alone."""
    bundle = getattr(params, "walking_bundle", None)
    return DEFAULT_WALKING if bundle is None else bundle


def plain_walking(walking: WalkingParams) -> tuple:
    """A resolved bundle as nested plain tuples, the form a call from Python passes (numba's dispatcher types a plain
    tuple about 2 µs faster than a named one); :func:`named_walking` names it again in compiled code."""
    return tuple(tuple(group) for group in walking)


@nb.njit(cache=True, inline="always")
def named_walking(plain):
    """:func:`plain_walking`'s tuples as the :class:`WalkingParams` they came from (in compiled code)."""
    return WalkingParams(SocialForce(*plain[0]), WallForce(*plain[1]), Vision(*plain[2]), TimeToCollision(*plain[3]),
                         Intent(*plain[4]), GiveWay(*plain[5]), ShoulderTurn(*plain[6]))


class Intents(NamedTuple):
    """What :func:`baseline_intents` decides: the velocity intents u_int (N, 2) of Eq. 14 (zero for inactive rows)
    and the desired headings θ_d (N,) of Eq. 15 (the current heading for inactive rows)."""

    intents_m_s: np.ndarray
    desired_heading_rad: np.ndarray


class Decision(NamedTuple):
    """What :func:`agent_step` decides: its ``status`` (:data:`AGENT_OK`, or :data:`AGENT_BAD_DIRECTION`: the
    caller takes the Python path, which raises naming the pedestrian), the :class:`Intents`' two arrays, and the
    neighbour ``pairs`` it built with their radius ``pair_radius_m`` (−1: none built), which the step may reuse."""

    status: int
    intents_m_s: np.ndarray
    desired_heading_rad: np.ndarray
    pairs: np.ndarray
    pair_radius_m: float


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


@nb.njit(cache=True, inline="always")
def baseline_intents(bodies, world, index, e_d, travel_time_s, pairs, walking, time_s):
    """u_int = ‖u_d‖ e_d + (τ/m) Σ f_social (Eq. 14, 16) and θ_d = angle of e_d, in one compiled call (with
    vision: u_int = v e(α*) + (τ/m) Σ f_social and θ_d = α*; with the time-to-collision interaction, + τ Σ f_ttc/m):
    the :class:`Intents` of the pedestrians ``index`` of ``bodies`` (:class:`~crowd_env.core.bundles.Bodies`) in
    ``world`` (:class:`~crowd_env.core.bundles.World`) under the resolved :class:`WalkingParams` ``walking``.

    ``e_d`` (n, 2) their desired directions (Eq. 13), ``pairs`` rows into ``index`` within :func:`pair_radius_m`.
    The forces are :func:`~crowd_env.walking.social_force.total_social_forces` (``walking.social`` on). With
    vision (``walking.vision.time_gap_s`` > 0) the speed and direction of the driving term are
    :func:`~crowd_env.walking.vision.vision_walk`'s and θ_d is the walking direction's angle; with its right of way
    or giving way ``travel_time_s`` (n,) are the walkers' travel times T (Eq. 11), else unused. With
    ``walking.ttc.strength_m2_s2`` > 0 the time-to-collision interaction of
    :mod:`crowd_env.walking.time_to_collision`; with ``walking.give_way.share`` > 0 the intent's push into a touched
    walker ahead taken out (:mod:`crowd_env.walking.give_way`); with ``walking.shoulder_turn.critical_ratio`` > 0
    θ_d turned at a narrow aperture (:mod:`crowd_env.walking.shoulder_turn`). Pedestrians whose
    premovement time has not come at ``time_s`` stand still (:func:`hold_waiting`).
    """
    position, radius, heading, velocity = bodies.position_m, bodies.radius_m, bodies.heading_rad, bodies.velocity_m_s
    tau, mass = bodies.tau_s, bodies.mass_kg
    n = index.shape[0]
    intents = np.zeros((position.shape[0], 2))
    theta_d = heading.copy()
    force = np.zeros((n, 2))
    if walking.social.forces and n:
        pos = np.empty((n, 2))
        rad = np.empty(n)
        for k in range(n):
            pos[k, 0] = position[index[k], 0]
            pos[k, 1] = position[index[k], 1]
            rad[k] = radius[index[k]]
        total_social_forces(pos, rad, e_d, pairs, np.arange(n), world.walls, world.wall_owner, walking.social,
                            walking.wall_social, force, world.period_m)
    if walking.vision.time_gap_s > 0.0:  # the walking speed and direction of vision instead of ‖u_d‖ and e_d
        speed, walk = vision_walk(position, radius, index, e_d, bodies.desired_speed_m_s, velocity, pairs,
                                  world.walls, world.period_m, walking.vision, travel_time_s)
    else:
        speed = np.empty(n)
        desired_speed = bodies.desired_speed_m_s
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
    if walking.shoulder_turn.critical_ratio > 0.0:  # the shoulders turned at a narrow aperture ahead
        shoulder_turn(theta_d, heading, position, radius, index, walk, pairs, world.walls, world.period_m,
                      walking.shoulder_turn)
    if walking.ttc.strength_m2_s2 > 0.0 and n:  # + τ_i Σ f_ttc / m_i
        accel = total_ttc_accelerations(position, velocity, radius, index, pairs, world.period_m, walking.ttc)
        for k in range(n):
            i = index[k]
            intents[i, 0] += tau[i] * accel[k, 0]
            intents[i, 1] += tau[i] * accel[k, 1]
    if walking.give_way.share > 0.0:  # the part pushing into a touched walker ahead taken out
        give_way(intents, position, radius, index, travel_time_s, pairs, world.period_m, walking.give_way)
    hold_waiting(intents, theta_d, heading, bodies.premovement_s, time_s, index)
    return Intents(intents, theta_d)


@nb.njit(cache=True)
def pair_reach_m(desired_speed, index, walking):
    """How far beyond 2 r_max the agent under ``walking`` needs its neighbour pairs: the social cut-off, vision's
    horizon (:func:`~crowd_env.walking.vision.vision_reach_m`), the time-to-collision range, the give-way gap, the
    largest of them; −1 when it needs none."""
    reach = walking.social.cutoff_m if walking.social.forces else -1.0
    if walking.vision.time_gap_s > 0.0:
        reach = max(reach, vision_reach_m(desired_speed, index, walking.vision))
    if walking.ttc.strength_m2_s2 > 0.0:
        reach = max(reach, walking.ttc.range_m)
    if walking.give_way.share > 0.0:
        reach = max(reach, walking.give_way.gap_m)
    return reach


@nb.njit(cache=True, inline="always")
def pair_radius_m(bodies, index, walking):
    """The centre distance within which the agent needs the pairs of the pedestrians ``index``: 2 r_max +
    :func:`pair_reach_m`; −1 when it needs none."""
    reach = pair_reach_m(bodies.desired_speed_m_s, index, walking)
    r_max = 0.0
    radius = bodies.radius_m
    for k in range(index.shape[0]):
        r_max = max(r_max, radius[index[k]])
    if walking.shoulder_turn.critical_ratio > 0.0:  # its reach follows the body (shoulder_turn_reach_m)
        reach = max(reach, shoulder_turn_reach_m(r_max, walking.shoulder_turn))
    if reach < 0.0:
        return -1.0
    return 2.0 * r_max + reach


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
def sample_directions(position, index, navigation):
    """e_d (Eq. 13) of the pedestrians ``index``, each from its own field of the :class:`CompiledNavigation`
    ``navigation``, by the same bilinear kernel as :meth:`NavigationField.sample` (point by point: the same bits).
    Returns ``(e_d (n, 2), T (n,), ok)``: the travel times T of the same samples, and ``ok`` False when a point is
    outside the grid or not finite, or has no direction (unreachable)."""
    origin_m, resolution_m, travel_time, direction, field_of = navigation
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


@nb.njit(cache=True, inline="always")
def decide_with(bodies, world, index, e_d, travel_time_s, built_pairs, built_radius_m, walking, time_s):
    """The decision of :class:`SocialForceAgent` once e_d and T are known: the neighbour pairs within
    :func:`pair_radius_m` (``built_pairs``, the pairs within ``built_radius_m`` already built this step, when they
    reach that far: a superset, as ``Simulator.neighbor_pairs`` reuses them; else built by the same
    :func:`~crowd_env.core.neighbors.grid_pairs`), then :func:`baseline_intents`. Returns an ``AGENT_OK``
    :class:`Decision` whose ``pairs`` lie within its ``pair_radius_m`` (−1: none needed). The one body of
    :func:`agent_step` and of the Python agent's call (:func:`python_decide`)."""
    radius = pair_radius_m(bodies, index, walking)
    if radius < 0.0:
        pairs = np.zeros((0, 2), np.int64)
    elif radius > built_radius_m:
        pairs = grid_pairs(bodies.position_m, index, radius, world.period_m)
    else:
        pairs = built_pairs
        radius = built_radius_m
    chosen = baseline_intents(bodies, world, index, e_d, travel_time_s, pairs, walking, time_s)
    return Decision(AGENT_OK, chosen.intents_m_s, chosen.desired_heading_rad, pairs, radius)


@nb.njit(cache=True)
def python_decide(bodies, world, index, e_d, travel_time_s, built_pairs, built_radius_m, walking, time_s):
    """:func:`decide_with` called from Python (one compiled call per decision), the bundles as plain tuples
    (:meth:`CrowdState.array_fields <crowd_env.core.state.CrowdState.array_fields>`, ``tuple(Simulator.world)``,
    :func:`plain_walking`). Returns the :class:`Decision`'s last four fields as a plain tuple."""
    d = decide_with(Bodies(*bodies), World(*world), index, e_d, travel_time_s, built_pairs, built_radius_m,
                    named_walking(walking), time_s)
    return d.intents_m_s, d.desired_heading_rad, d.pairs, d.pair_radius_m


@nb.njit(cache=True)
def agent_step(bodies, world, index, navigation, walking, time_s):
    """One decision of :class:`SocialForceAgent` in compiled code, exactly as its ``__call__``: e_d from the
    :class:`CompiledNavigation` ``navigation`` (:func:`sample_directions`), then :func:`decide_with` with no pairs
    built yet (those it builds, the ones ``Simulator.neighbor_pairs`` would build, the step may reuse) under the
    resolved :class:`WalkingParams` ``walking``. Returns a :class:`Decision`."""
    e_d, times, ok = sample_directions(bodies.position_m, index, navigation)
    if not ok:
        return Decision(AGENT_BAD_DIRECTION, np.zeros((bodies.position_m.shape[0], 2)), bodies.heading_rad.copy(),
                        np.zeros((0, 2), np.int64), -1.0)
    return decide_with(bodies, world, index, e_d, times, np.zeros((0, 2), np.int64), -1.0, walking, time_s)


class CompiledAgent(NamedTuple):
    """:class:`SocialForceAgent` for compiled code (:func:`decide`): its :class:`CompiledNavigation` and the resolved
    :class:`WalkingParams` it decides with. Built by :func:`compiled_agent`."""

    navigation: CompiledNavigation
    walking: WalkingParams


def compiled_agent(navigation: CompiledNavigation, params) -> CompiledAgent:
    """The :class:`CompiledAgent` of a compiled ``navigation`` (:meth:`SocialForceAgent.compiled`) under a
    simulator's ``params`` (:func:`walking_bundle`)."""
    return CompiledAgent(navigation, walking_bundle(params))


@nb.njit(cache=True, inline="always")
def decide(agent, bodies, world, index, time_s):
    """:func:`agent_step` of the :class:`CompiledAgent` ``agent`` for the pedestrians ``index`` of ``bodies`` in
    ``world`` (:mod:`crowd_env.core.bundles`) at ``time_s``: a :class:`Decision`."""
    return agent_step(bodies, world, index, agent.navigation, agent.walking, time_s)


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


def facing_headings_rad(navigation, position_m: np.ndarray, radius_m: np.ndarray, heading_rad: np.ndarray,
                        index: np.ndarray, walls: np.ndarray, rule: ShoulderTurn, *, floor: np.ndarray | None = None,
                        period_m: float = 0.0) -> np.ndarray:
    """θ_d (m,) of the pedestrians ``index`` facing their desired directions: the angle of e_d (Eq. 13, from
    ``navigation``), their shoulders turned at a narrow aperture ahead along e_d by the resolved
    :class:`~crowd_env.walking.shoulder_turn.ShoulderTurn` ``rule`` (off at ``critical_ratio`` 0), as the
    calibrated agent turns its own (:func:`baseline_intents`, walking along e_d). The heading target of a learned
    policy that walks where it wants and faces e_d (the environment's ``heading_target="desired_direction"``).
    ``floor``: the rows of everybody on the floor, whose bodies narrow the apertures (default ``index``); only those
    of ``index`` on the floor turn. ``heading_rad`` (N,): the current headings (the way a body turns); ``walls``
    (S, 4)."""
    index = np.asarray(index, np.int64)
    if rule.critical_ratio <= 0.0:  # the paper's model: e_d's angle, nothing more to compute
        return direction_angles_rad(desired_direction(navigation, position_m, index))
    floor = index if floor is None else np.asarray(floor, np.int64)
    on_floor = np.isin(index, floor)
    if not on_floor.any():
        return direction_angles_rad(desired_direction(navigation, position_m, index))
    walk = desired_direction(navigation, position_m, floor)  # everybody's e_d once: the walkers' and their neighbours'
    theta = np.array(heading_rad, dtype=np.float64, copy=True)
    theta[floor] = direction_angles_rad(walk)
    r_max = float(np.max(radius_m[floor]))
    pairs = grid_pairs(position_m, floor, 2.0 * r_max + shoulder_turn_reach_m(r_max, rule), period_m)
    shoulder_turn(theta, np.asarray(heading_rad, np.float64), position_m, radius_m, floor, walk, pairs, walls,
                  period_m, rule)
    off = index[~on_floor]  # off the floor: e_d's angle, unturned
    if off.size:
        theta[off] = direction_angles_rad(desired_direction(navigation, position_m, off))
    return theta[index]


def facing_headings(navigation, sim, index: np.ndarray) -> np.ndarray:
    """:func:`facing_headings_rad` in a :class:`~crowd_env.core.simulator.Simulator` ``sim``: its active pedestrians
    on the floor, its walls and periodicity, and the shoulder turn of its model (``sim.params``; off for the paper's
    model and for the core's physics alone)."""
    st = sim.state
    return facing_headings_rad(navigation, st.position_m, st.radius_m, st.heading_rad, index, sim.walls,
                               walking_bundle(sim.params).shoulder_turn, floor=sim.active_index,
                               period_m=sim.period_m)


class SocialForceAgent:
    """Policy object: ``agent(sim) -> (intents (N, 2), desired_heading (N,))`` for a :class:`Simulator`.

    ``navigation``: an object with ``direction(points) -> (n, 2)`` (a
    :class:`~crowd_env.walking.navigation.NavigationField`), or, when its ``per_pedestrian`` attribute is
    true, ``direction(points, index)`` (a :class:`~crowd_env.walking.navigation.DestinationNavigation`:
    each pedestrian follows the field of its own destination exit; a navigation with an ``update(sim)``
    method, e.g. :class:`~crowd_env.walking.route_choice.QuickestExitNavigation`, is updated once per
    decision). The walking parameters (the social force, vision, ...) are the simulator's
    (:func:`walking_bundle` of ``sim.params``: a :class:`~crowd_env.walking.model.ModelParams`' own, the paper's
    for the core's physics alone). A call decides as :func:`agent_step` does, with the same
    :func:`pair_radius_m` and :func:`baseline_intents` (:func:`decide_with`, one compiled call): e_d from the
    navigation object, the pairs those the simulator built earlier in the step when they reach far enough
    (``sim.built_pairs()``), else built in that call and kept for the step (``sim.keep_pairs``).
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
        walking = walking_bundle(sim.params)
        idx = sim.active_index
        pos = st.position_m[idx]
        radius = st.radius_m[idx]
        pairs = sim.neighbor_pairs(2.0 * float(radius.max()) + walking.social.cutoff_m) if idx.size \
            else np.zeros((0, 2), np.int64)
        return social_repulsion(pos, radius, e_d, pairs, sim.walls, sim.wall_owner, walking.social,
                                walking.wall_social, period_m=sim.period_m)

    def compiled(self, n_pedestrians: int) -> CompiledNavigation | None:
        """The agent's navigation for :func:`agent_step` (None: this agent has no compiled form, e.g. a
        subclass that changes how it decides, or a navigation compiled code cannot sample)."""
        cls = type(self)
        if cls.__call__ is not SocialForceAgent.__call__ or cls.desired_direction is not SocialForceAgent.desired_direction:
            return None
        return compile_navigation(self.navigation, n_pedestrians)

    def _walking(self, params) -> tuple:
        """``(resolved WalkingParams, its plain tuples)`` of the simulator's ``params``, kept while they stay the same
        object."""
        kept = self.__dict__.get("_walking_kept")
        if kept is None or kept[0] is not params:
            walking = walking_bundle(params)
            kept = self._walking_kept = (params, walking, plain_walking(walking))
        return kept[1], kept[2]

    def __call__(self, sim):
        st = sim.state
        idx = sim.active_index
        if idx.size == 0:
            return np.zeros((st.n, 2)), st.heading_rad.copy()
        update = getattr(self.navigation, "update", None)  # a navigation that changes with the crowd
        if update is not None:
            update(sim)
        walking, plain = self._walking(sim.params)
        e_d = self.desired_direction(sim, idx)
        times = np.asarray(travel_time(self.navigation, st.position_m, idx), np.float64) \
            if walking.vision.right_of_way or walking.give_way.share > 0.0 else _NO_TIMES
        built_pairs, built_radius_m = sim.built_pairs()
        intents, theta_d, pairs, radius = python_decide(st.array_fields(), sim.world_fields(), idx, e_d, times,
                                                        built_pairs, built_radius_m, plain, float(sim.time_s))
        if radius > built_radius_m:
            sim.keep_pairs(pairs, radius)
        return intents, theta_d


_NO_TIMES = np.zeros(0)
