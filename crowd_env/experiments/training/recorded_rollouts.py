"""Rollouts from recorded states: a learned policy driving the recorded crowd in the simulator, labelled by the
recording (the drift correction of :mod:`.human_imitation`), and the calibrated agent's actions on the recorded
states (the open-loop baseline).

**Data as Demonstrator** (Venkatraman, Hebert & Bagnell 2015, "Improving multi-step prediction of learned time
series models", AAAI; DAgger's idea for a model of a time series): a clone trained on the recorded states alone
meets, in closed loop, states the recording never visits (it lags, it presses against a body the recording's
people squeezed past) and has no answer learned for them. :func:`dad_rollouts` starts the simulator from a
recorded decision k₀ (everybody on the floor, at the recorded positions moved apart just enough for the disks not
to overlap, :func:`separated`; recorded velocities and headings), lets the policy drive every one of them for
``horizon_s`` exactly as the environment would (:func:`crowd_env.envs.drivers.observing_driver`), and labels each
decision it reaches with what brings that pedestrian back to its recording: the recorded action plus a pull
towards the recorded position,

    a = (p_rec(k+1) − p_rec(k)) / Δ + clip((p_rec(k) − p_sim(k)) / ``pull_time_s``, ``max_pull_m_s``),

in the observation's frame of the simulated state. Without drift (p_sim = p_rec) the label is the recorded action
of :mod:`.demonstrations`. That label is a velocity, the policy's action an intent, which the model's driving force
(τ = 0.5 s) and the contacts turn into a velocity: with ``intent_gain`` κ > 0 the label is instead the intent the
policy gave corrected by κ times what the realised velocity over the interval missed of that target,
i + κ (a − v_sim) (iterative learning control across the rounds: a policy whose intents realise the recorded motion
in this simulator is left as it is). The camera's edges as there, with one more allowance: people who appear in the
recording after k₀ are not simulated, so a decision at t is labelled only when the nearest appearance point is
farther than the observation's reach plus ``newcomer_speed_m_s`` × (t − t₀) (how far a newcomer can have walked in
since). Pedestrians the recording has lost (it vanished at the camera's edge, its simulated self walks on) get no
label.

**Newcomers from the spawn area** (``spawn_newcomers``): the recording never shows how people get through the
entrance from the waiting crowd behind it (the UO camera starts 0.2 m past the entrance), yet that is what limits
the flow of the five entrance runs, and what Seyfried's bottleneck is made of. With this option a rollout also
places the people who appear within twice the horizon at a point within 1 m of the scenario's spawn area (its
``spawn_area``: the waiting area) at the sites of that area nearest where they appear (at its density, the
earliest nearest; :func:`~crowd_env.scenarios.placement.place_pedestrians`), standing, turned towards e_d; each of
those who appear within the horizon is labelled, until the recording shows it, with the walk along e_d that covers
the geodesic distance to its first recorded point (the difference of the travel times T) by its recorded time (at
most ``newcomer_speed_m_s``): the one thing the recording says about it. (A straight line would run into the
barrier beside a narrow entrance: measured, it taught the crowd to press on the jambs and wedge the 0.5-0.7 m
entrances.) The appearance points then count as the vanishing ones do in the edge rule (the people
behind the entrance are simulated).

**Giving way** (``give_way_gap_m`` g, candidates measured on docs/validation/human_policy.md, off by default): of
two people who reach an opening together one goes first and the other gives way. With this option a newcomer
labelled with its walk who stands closer than 2r + g to someone ahead of it along e_d who goes first is labelled
instead stepping back along −e_d at the speed that gives that room back within ``pull_time_s`` (at most
``max_pull_m_s``). Who goes first (``give_way_to``): ``"recorded_first"``, the one the recording shows first (or
who is on the floor already), which the policy cannot see; or ``"nearer_exit"``, the one with the smaller travel
time T, which it sees with the observation component
:mod:`~crowd_env.envs.observations.neighbor_travel_time`. Where (``give_way_below_m`` w): two bodies pass abreast
through an opening at least two shoulder widths wide, and one gives way to the other only where they cannot; with
w the labels give way only in the runs whose entrance (the opening the waiting crowd passes, the scenario's
``metadata['entrance_width_m']``) is narrower than w, and are the walk in the others (None: in every run).

**The model's push** (``push_below_m_s`` u_g, off by default): the rollouts drive the crowd as ``crowd-virtual-
experiments --policy-social-force --policy-social-force-below u_g`` runs it (:class:`~crowd_env.envs.drivers.
MixedDriver`): the policy's intents plus the calibrated agent's social force (Kabalan Eq. 14, 16) for walkers slower
than u_g, so that the rounds label the states a crowd run so reaches.

:func:`calibrated_actions` gives the calibrated agent's intents (Kabalan et al. 2016, Eq. 14-16) on a recorded
state, through a read-only view of it that answers what the agent asks a simulator (:class:`RecordedView`), with
every desired speed the model's mean (1.34 m/s: the recording does not say anybody's).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import shapely
from scipy.spatial import cKDTree

from crowd_env.errors import TrainingError

from ...core.bundles import World, empty_exits
from ...core.neighbors import grid_pairs
from ...core.segments import endpoint_owners, wall_proximity
from ...core.simulator import Simulator
from ...core.state import CrowdState
from ...envs.drivers import MixedDriver, intents_and_headings, observing_driver
from ...envs.observations import to_body_frame
from ...scenarios.placement import place_pedestrians
from ...walking.agent import SocialForceAgent, desired_direction
from ...walking.model import ModelParams
from .demonstrations import Demonstrations, observation_reach_m, policy_options, recorded_state

__all__ = ["DEFAULT_DAD", "GIVE_WAY_TO", "check_rollout_options", "separated", "dad_rollouts", "RecordedView",
           "calibrated_actions"]

DEFAULT_DAD = {"horizon_s": 3.0, "start_every_s": 2.0, "pull_time_s": 1.0, "max_pull_m_s": 1.0,
               "newcomer_speed_m_s": 2.0, "intent_gain": 0.0, "spawn_newcomers": False, "give_way_gap_m": None,
               "give_way_to": "recorded_first", "give_way_below_m": None, "push_below_m_s": None}
GIVE_WAY_TO = ("recorded_first", "nearer_exit")


def separated(position_m: np.ndarray, radius_m: float, walls: np.ndarray, *, area=None, iterations: int = 2000,
              tolerance_m: float = 1e-10) -> np.ndarray:
    """``position_m`` (n, 2) moved apart until no two disks of radius ``radius_m`` overlap and none overlaps a
    wall segment of ``walls`` (S, 4): centres outside ``area`` (a shapely polygon, the walkable area; None: not
    checked) first go to the nearest point at least ``radius_m`` inside it; then each overlap is taken out by
    moving both disks apart along the line of their centres by half of it (a wall's: the disk along the wall's
    normal), all at once, until the deepest overlap is below ``tolerance_m``. Recorded people stand closer than
    two disk radii (half the decisions of the 0.70 m exit run), and a few a head's width from a wall; this is
    the least a disk crowd must move to stand where they stood. Raises :class:`TrainingError` when
    ``iterations`` do not suffice."""
    pos = np.array(position_m, dtype=np.float64)
    if area is not None and pos.size:
        inner = area.buffer(-float(radius_m))
        out = ~shapely.contains_xy(inner, pos[:, 0], pos[:, 1])
        if out.any():
            lines = shapely.shortest_line(inner, shapely.points(pos[out]))
            pos[out] = shapely.get_coordinates(shapely.get_point(lines, 0))
    n = pos.shape[0]
    index = np.arange(n, dtype=np.int64)
    radius = np.full(n, float(radius_m))
    walls = np.ascontiguousarray(walls, dtype=np.float64).reshape(-1, 4)
    owner = endpoint_owners(walls)
    margin = 1e-6  # a little past contact, so that the simulator's check (1e-9 m) holds after rounding
    for _ in range(int(iterations)):
        move = np.zeros_like(pos)
        worst = 0.0
        pairs = grid_pairs(pos, index, 2.0 * radius_m, 0.0)
        if pairs.size:
            d = pos[pairs[:, 1]] - pos[pairs[:, 0]]
            dist = np.hypot(d[:, 0], d[:, 1])
            over = 2.0 * radius_m - dist
            hit = over > 0.0
            if hit.any():
                worst = float(over[hit].max())
                u = d[hit] / np.maximum(dist[hit], 1e-12)[:, None]
                push = 0.5 * (over[hit] + margin)[:, None] * u
                np.add.at(move, pairs[hit, 0], -push)
                np.add.at(move, pairs[hit, 1], push)
        if walls.shape[0]:
            ped, _, gap, nx, ny, *_ = wall_proximity(pos, radius, index, walls, owner, np.zeros(n))
            hit = gap < 0.0
            if hit.any():
                worst = max(worst, float(-gap[hit].min()))
                np.add.at(move, ped[hit], (-gap[hit] + margin)[:, None] * np.column_stack([nx[hit], ny[hit]]))
        if worst < tolerance_m:
            return pos
        pos += move
    raise TrainingError(f"could not move {n} disks of radius {radius_m:g} m apart in {iterations} iterations "
                        f"(deepest overlap left {worst:.3g} m)")


class _Recording:
    """An observation policy that remembers the observations it acted on last (for the labels)."""

    def __init__(self, policy):
        self.policy = policy
        self.env_overrides = dict(policy.env_overrides)
        self.obs_dim = getattr(policy, "obs_dim", None)
        self.last = None

    def actions(self, observations):
        self.last = np.array(observations, dtype=np.float32)
        self.last_actions = np.asarray(self.policy.actions(observations), dtype=np.float64)
        return self.last_actions


def _label_mask(replay, rows, k: int, k0: int, pos, reach, edges: tuple, newcomer_speed_m_s: float,
                spawned: bool) -> np.ndarray:
    """Which decisions of file rows ``rows`` at ``k`` (started at ``k0``) get the recording's label (module
    docstring); with the newcomers ``spawned``, the appearance points count as the vanishing ones do."""
    mask = replay.present[k, rows] & replay.present[k + 1, rows]
    vanish, appear = edges
    if vanish is not None:
        mask &= vanish.query(pos)[0] >= reach
    if appear is not None:
        allowance = 0.0 if spawned else newcomer_speed_m_s * (replay.time_s[k] - replay.time_s[k0])
        mask &= appear.query(pos)[0] >= reach + allowance
    return mask


def check_rollout_options(**options) -> None:
    """Raise :class:`TrainingError` naming the first of the rollouts' ``options`` (:data:`DEFAULT_DAD`'s names; those
    not given are not checked) with a value :func:`dad_rollouts` cannot take: before a training's first round, not
    minutes into it."""
    def number(name, ok):
        value = options.get(name)
        if name in options and (isinstance(value, bool) or not isinstance(value, (int, float)) or not ok(value)):
            raise TrainingError(f"rollout option {name} must be {explain[name]}, got {value!r}")

    explain = {"horizon_s": "a time in s > 0", "start_every_s": "a time in s > 0", "pull_time_s": "a time in s > 0",
               "max_pull_m_s": "a speed in m/s >= 0", "newcomer_speed_m_s": "a speed in m/s > 0",
               "intent_gain": "a gain >= 0", "give_way_gap_m": "None (nobody gives way) or a gap in m >= 0",
               "give_way_below_m": "None (every run) or a width in m > 0",
               "push_below_m_s": "None (no push) or a speed in m/s > 0"}
    for name in ("horizon_s", "start_every_s", "pull_time_s", "newcomer_speed_m_s"):
        number(name, lambda v: v > 0)
    for name in ("max_pull_m_s", "intent_gain"):
        number(name, lambda v: v >= 0)
    if options.get("give_way_gap_m") is not None:
        number("give_way_gap_m", lambda v: v >= 0)
    if options.get("give_way_below_m") is not None:
        number("give_way_below_m", lambda v: v > 0)
    if options.get("push_below_m_s") is not None:
        number("push_below_m_s", lambda v: v > 0 and math.isfinite(v))
    if "give_way_to" in options and options["give_way_to"] not in GIVE_WAY_TO:
        raise TrainingError(f"rollout option give_way_to must be one of {list(GIVE_WAY_TO)}, "
                            f"got {options['give_way_to']!r}")
    if "spawn_newcomers" in options and not isinstance(options["spawn_newcomers"], bool):
        raise TrainingError(f"rollout option spawn_newcomers must be true or false, got {options['spawn_newcomers']!r}")


def dad_rollouts(replay, scenario, policy, *, params: ModelParams | None = None, options: dict | None = None,
                 starts=None, horizon_s: float = DEFAULT_DAD["horizon_s"],
                 pull_time_s: float = DEFAULT_DAD["pull_time_s"], max_pull_m_s: float = DEFAULT_DAD["max_pull_m_s"],
                 newcomer_speed_m_s: float = DEFAULT_DAD["newcomer_speed_m_s"],
                 start_every_s: float = DEFAULT_DAD["start_every_s"],
                 intent_gain: float = DEFAULT_DAD["intent_gain"],
                 spawn_newcomers: bool = DEFAULT_DAD["spawn_newcomers"],
                 give_way_gap_m: float | None = DEFAULT_DAD["give_way_gap_m"],
                 give_way_to: str = DEFAULT_DAD["give_way_to"],
                 give_way_below_m: float | None = DEFAULT_DAD["give_way_below_m"],
                 push_below_m_s: float | None = DEFAULT_DAD["push_below_m_s"]) -> Demonstrations:
    """The labelled decisions of rollouts of the observation ``policy`` from the recorded decisions ``starts``
    (indices into ``replay.time_s``; default every ``start_every_s``) of ``replay`` in ``scenario`` (module
    docstring). ``options``: the policy's (default its ``env_overrides`` over the human policy's)."""
    params = ModelParams() if params is None else params
    options = policy_options({**(options or {}), **{k: v for k, v in policy.env_overrides.items()}})
    check_rollout_options(horizon_s=horizon_s, start_every_s=start_every_s, pull_time_s=pull_time_s,
                          max_pull_m_s=max_pull_m_s, newcomer_speed_m_s=newcomer_speed_m_s, intent_gain=intent_gain,
                          give_way_gap_m=give_way_gap_m, give_way_to=give_way_to, give_way_below_m=give_way_below_m,
                          push_below_m_s=push_below_m_s)
    if starts is None:
        starts = np.arange(0, replay.time_s.size - 1, max(1, int(round(start_every_s / replay.decision_dt_s))))
    horizon = max(1, int(round(horizon_s / replay.decision_dt_s)))
    pts, appears = replay.edge_points_m, replay.edge_appears
    edges = (cKDTree(pts[~appears]) if (~appears).any() else None, cKDTree(pts[appears]) if appears.any() else None)
    spawned = bool(spawn_newcomers) and scenario.spawn_area is not None
    gives_way = give_way_gap_m is not None and _narrow_entrance(scenario, give_way_below_m)
    setting = _Setting(scenario, params, options, horizon, pull_time_s, max_pull_m_s, newcomer_speed_m_s,
                       float(intent_gain), edges, spawned, (float(give_way_gap_m), give_way_to) if gives_way else None,
                       None if push_below_m_s is None else float(push_below_m_s))
    parts = [p for k0 in starts for p in _rollout(replay, policy, int(k0), setting)]
    if not parts:
        raise TrainingError("the rollouts reached no decision with a label")
    arrays = [np.concatenate(col) for col in zip(*parts)]
    meta = {"kind": "dad", "options": options, "decision_dt_s": replay.decision_dt_s, "horizon_s": float(horizon_s),
            "pull_time_s": float(pull_time_s), "max_pull_m_s": float(max_pull_m_s), "n_starts": int(len(starts)),
            "intent_gain": float(intent_gain), "spawn_newcomers": spawned, "give_way_to": give_way_to,
            "give_way_gap_m": None if give_way_gap_m is None else float(give_way_gap_m),
            "give_way_below_m": None if give_way_below_m is None else float(give_way_below_m), "gives_way": gives_way,
            "push_below_m_s": None if push_below_m_s is None else float(push_below_m_s),
            "n_decisions": int(arrays[1].shape[0]), "n_seen": int(arrays[7].sum())}
    return Demonstrations(*arrays, meta=meta)


def _narrow_entrance(scenario, below_m: float | None) -> bool:
    """Whether the give-way labels act in ``scenario``: its entrance is narrower than ``below_m`` (None: always)."""
    if below_m is None:
        return True
    width = scenario.metadata.get("entrance_width_m")
    if width is None:
        raise TrainingError(f"rollout option give_way_below_m needs a scenario with an entrance "
                            f"(metadata['entrance_width_m']); {scenario.name!r} has none")
    return float(width) < float(below_m)


def _start_crowd(replay, scenario, k0: int, horizon: int, spawned: bool, radius: float) -> tuple:
    """``(file rows, positions, headings, velocities, arrival times, arrival points)`` of a rollout's crowd: those on
    the floor at ``k0`` as recorded (arrival NaN) and, when ``spawned``, those who appear within twice the
    horizon at a point within 1 m of the scenario's spawn area, standing at the sites of that area nearest their
    first recorded point, the earliest nearest (module docstring)."""
    rows = np.flatnonzero(replay.present[k0])
    pos, head, vel = replay.position_m[k0, rows], replay.heading_rad[k0, rows], replay.velocity_m_s[k0, rows]
    arrival, point = np.full(rows.size, np.nan), np.full((rows.size, 2), np.nan)
    if not spawned:
        return rows, pos, head, vel, arrival, point
    stop = min(k0 + 2 * horizon, replay.time_s.size - 1)
    later = replay.present[k0 + 1:stop + 1] & ~np.any(replay.present[:k0 + 1], axis=0)
    new = np.flatnonzero(later.any(axis=0))
    first = np.argmax(later[:, new], axis=0) + k0 + 1
    where = replay.position_m[first, new]
    near = shapely.distance(scenario.spawn_area, shapely.points(where)) <= 1.0
    new, first, where = new[near], first[near], where[near]
    if not new.size:
        return rows, pos, head, vel, arrival, point
    order = np.argsort(first, kind="stable")
    new, first, where = new[order], first[order], where[order]
    density = float(scenario.metadata.get("waiting_density_per_m2", 3.0))
    sites = place_pedestrians(scenario.spawn_area, new.size, radius, np.random.default_rng(k0),
                              density_per_m2=max(density, new.size / scenario.spawn_area.area),
                              toward=where.mean(axis=0))
    e_d = desired_direction(scenario.navigation(), sites, np.arange(new.size))
    return (np.r_[rows, new], np.vstack([pos, sites]), np.r_[head, np.arctan2(e_d[:, 1], e_d[:, 0])],
            np.vstack([vel, np.zeros((new.size, 2))]), np.r_[arrival, replay.time_s[first]], np.vstack([point, where]))


def _give_way_m(pos: np.ndarray, first: np.ndarray, rows: np.ndarray, e_d: np.ndarray, radius_m: float,
                gap_m: float) -> np.ndarray:
    """How far (m) each of the pedestrians ``rows`` (indices into ``pos``, heading along ``e_d``) stands inside the
    room ``gap_m`` it owes the nearest of those ahead of it along e_d who go first (a smaller ``first``: the
    recorded arrival, NaN for those on the floor from the start, before everybody; or the travel time T): 2
    ``radius_m`` + ``gap_m`` minus the distance of their centres, 0 where nobody such is that close."""
    order = np.where(np.isnan(first), -np.inf, first)
    reach = 2.0 * radius_m + gap_m
    out = np.zeros(rows.size)
    for n, (j, near) in enumerate(zip(rows, cKDTree(pos).query_ball_point(pos[rows], reach))):
        near = np.asarray([i for i in near if i != j and order[i] < order[j]], dtype=np.int64)
        ahead = near[(pos[near] - pos[j]) @ e_d[n] > 0.0] if near.size else near
        if ahead.size:
            out[n] = reach - float(np.hypot(*(pos[ahead] - pos[j]).T).min())
    return out


class _Setting(NamedTuple):
    """What every rollout of one :func:`dad_rollouts` call shares (its arguments, checked and resolved)."""

    scenario: object
    params: ModelParams
    options: dict
    horizon: int  # decisions
    pull_time_s: float
    max_pull_m_s: float
    newcomer_speed_m_s: float
    intent_gain: float
    edges: tuple  # the camera's edges: KD-trees of the vanishing and the appearing points
    spawned: bool
    give_way: tuple | None  # (gap in m, who goes first) where the labels give way
    push_below_m_s: float | None


def _targets(replay, f, k: int, k0: int, pos, arrival, point, setting: _Setting, radius_m: float) -> tuple:
    """``(world-frame targets, spawned rows labelled)`` at decision ``k`` of file rows ``f`` at ``pos`` in a rollout
    from ``k0``: the recorded action plus the pull (recorded rows), or the walk along e_d that covers the geodesic
    distance to the first recorded point (the travel times' difference) by the recorded time, at most
    ``newcomer_speed_m_s`` (newcomers not yet recorded, those arriving within the horizon: the ones behind them
    stand where they would); with ``give_way_gap_m``, a newcomer too close behind someone who goes first steps back
    (:func:`_give_way_m`, module docstring)."""
    horizon, pull_time_s, max_pull = setting.horizon, setting.pull_time_s, setting.max_pull_m_s
    newcomer_speed, give_way = setting.newcomer_speed_m_s, setting.give_way
    dt = replay.decision_dt_s
    rec = replay.present[k, f] & replay.present[k + 1, f]
    with np.errstate(invalid="ignore"):
        a_rec = (replay.position_m[k + 1, f] - replay.position_m[k, f]) / dt
        pull = (replay.position_m[k, f] - pos) / pull_time_s
    pull *= np.minimum(1.0, max_pull / np.maximum(np.hypot(pull[:, 0], pull[:, 1]), 1e-12))[:, None]
    t = replay.time_s[k]
    waiting = ~replay.present[k, f] & (arrival > t) & (arrival <= replay.time_s[k0] + horizon * dt)
    walk = np.zeros_like(pos)
    if waiting.any():  # along e_d, at the geodesic distance left over the time left
        navigation = setting.scenario.navigation()
        e_all, travel = navigation.sample(pos)  # everybody's T: the waiting ones' walk, who is nearer the exit
        e_d, left = e_all[waiting], travel[waiting]
        _, there = navigation.sample(point[waiting])
        speed = np.clip((left - there) / np.maximum(arrival[waiting] - t, dt), 0.0, newcomer_speed)
        if give_way is not None:
            gap, to = give_way
            owed = _give_way_m(pos, arrival if to == "recorded_first" else travel, np.flatnonzero(waiting), e_d,
                               radius_m, gap)
            speed = np.where(owed > 0.0, -np.minimum(owed / pull_time_s, max_pull), speed)
        walk[waiting] = e_d * speed[:, None]
    return np.where(rec[:, None], a_rec + pull, walk), waiting


def _rollout(replay, policy, k0: int, setting: _Setting) -> list:
    """The labelled decisions of one rollout from decision ``k0`` (:func:`dad_rollouts`), one part per decision."""
    scenario, params, options, horizon = setting.scenario, setting.params, setting.options, setting.horizon
    newcomer_speed, gain = setting.newcomer_speed_m_s, setting.intent_gain
    edges, spawned = setting.edges, setting.spawned
    push = setting.push_below_m_s
    radius = float(scenario.radius_m()[0]) if scenario.n_pedestrians else 0.23
    rows, pos0, head0, vel0, arrival, point = _start_crowd(replay, scenario, k0, horizon, spawned, radius)
    if not rows.size:
        return []
    state = CrowdState.create(separated(pos0, radius, scenario.geometry.walls, area=scenario.geometry.walkable_area),
                              radius_m=radius, heading_rad=head0, velocity_m_s=vel0, desired_speed_m_s=1.34)
    sim = Simulator(state, geometry=scenario.geometry, params=params)
    recording = _Recording(policy)
    navigation = scenario.navigation()
    if push is None:
        driver = observing_driver(recording, scenario, navigation=navigation, mask=np.ones(rows.size, bool),
                                  dt_s=params.dt_s, velocity_bound_m_s=20.0,
                                  travel_time_bound_s=navigation.max_travel_time_s + 1.0, what="rolled-out policy: ")
        observer = driver.observer
    else:  # the policy plus the model's push for walkers slower than push, as the virtual experiments run it
        driver = MixedDriver(recording, scenario, SocialForceAgent(navigation), np.ones(rows.size, bool),
                             dt_s=params.dt_s, social_force=True, social_force_below_m_s=push)
        observer = driver.learned.observer
    skip = int(options["frame_skip"])
    if abs(skip * params.dt_s - replay.decision_dt_s) > 1e-9:
        raise TrainingError(f"the policy decides every {skip * params.dt_s:g} s, the replay every "
                            f"{replay.decision_dt_s:g} s")
    parts = []
    for k in range(k0, min(k0 + horizon, replay.time_s.size - 1)):
        act = sim.active_index.copy()
        if not act.size:
            break
        pos, theta = state.position_m[act].copy(), state.heading_rad[act].copy()
        vel = state.velocity_m_s[act].copy()
        reach = observation_reach_m(observer, state.position_m, state.active, act)
        for _ in range(skip):
            intents, heading = intents_and_headings(driver(sim), sim.state)
            sim.step(intents, desired_heading_rad=heading)
        f = rows[act]
        target, waiting = _targets(replay, f, k, k0, pos, arrival[act], point[act], setting, radius)
        m = _label_mask(replay, f, k, k0, pos, reach, edges, newcomer_speed, spawned) | waiting
        if not m.any():
            continue
        if gain > 0.0:  # the intent that realises the target in this simulator (module docstring)
            target = gain * (target - (state.position_m[act] - pos) / replay.decision_dt_s)
        label = to_body_frame(target, np.cos(theta), np.sin(theta)) if options["observation_frame"] == "egocentric" \
            else target
        if gain > 0.0:
            label = recording.last_actions + label
        parts.append((recording.last[m], label[m], replay.ids[f[m]], np.full(m.sum(), replay.time_s[k]), pos[m],
                      vel[m], theta[m], np.ones(m.sum(), bool), np.full(m.sum(), np.nan), reach[m]))
    return parts


class RecordedView:
    """What the calibrated agent (:class:`~crowd_env.walking.agent.SocialForceAgent`) reads of a simulator, for a
    recorded crowd (:func:`~.demonstrations.recorded_state`) that no simulator would accept (people closer than two
    radii): the state, the parameters, the walls, the active rows and their neighbour pairs; read only."""

    period_m = 0.0

    def __init__(self, state: CrowdState, walls, params: ModelParams, time_s: float = 0.0):
        self.state = state
        self.params = params
        self.walls = np.ascontiguousarray(walls, dtype=np.float64).reshape(-1, 4)
        self.wall_owner = endpoint_owners(self.walls)
        self.time_s = float(time_s)
        self.active_index = np.flatnonzero(state.active)

    def world_fields(self) -> tuple:
        """The walls and no exits, as :meth:`Simulator.world_fields` gives them (a plain
        :class:`~crowd_env.core.bundles.World`)."""
        return tuple(World(self.walls, self.wall_owner, *empty_exits(), np.full(self.state.n, -1, np.int64), 0.0))

    def neighbor_pairs(self, radius_m: float) -> np.ndarray:
        """Pairs of rows into :attr:`active_index` within ``radius_m`` (as :meth:`Simulator.neighbor_pairs`)."""
        return grid_pairs(self.state.position_m, self.active_index, float(radius_m), 0.0)

    def built_pairs(self) -> tuple:
        """None built ahead (as :meth:`Simulator.built_pairs` before any): an empty list, radius −1."""
        return np.zeros((0, 2), np.int64), -1.0

    def keep_pairs(self, pairs: np.ndarray, radius_m: float) -> None:
        """Nothing to keep: a view is read once (:meth:`Simulator.keep_pairs`)."""


def calibrated_actions(replay, scenario, params: ModelParams, k: int, rows: np.ndarray) -> np.ndarray:
    """The calibrated agent's intents (len(rows), 2), world frame, of the file rows ``rows`` on the recorded
    decision ``k`` of ``replay`` (module docstring)."""
    radius = float(scenario.radius_m()[0]) if scenario.n_pedestrians else 0.23
    state = recorded_state(replay, k, radius)
    view = RecordedView(state, scenario.geometry.walls, params, time_s=float(replay.time_s[k]))
    intents, _ = intents_and_headings(SocialForceAgent(scenario.navigation())(view), state)
    return intents[rows]
