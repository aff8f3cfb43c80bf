"""JuPedSim as a backend of the RiMEA suite: the same scenario, the same people, JuPedSim's models.

:func:`runner` gives, for the backend names ``"jupedsim_cfsm"`` and ``"jupedsim_sfm"``, a function with
:func:`~crowd_env.experiments.validation.rimea.base.run_crowd_env`'s signature, ``run(scenario, *, seed, max_time_s)
-> BackendRun``, that runs a :class:`~crowd_env.scenarios.Scenario` in JuPedSim (a benchmark extra:
``pip install -e '.[bench]'``; crowd_env itself never imports it, this module imports it inside its
functions). :func:`build_simulation` builds the JuPedSim simulation alone (``benchmarks/compare_jupedsim.py``
uses it).

What is carried over, and how:

* **Geometry** (:func:`jupedsim_geometry`): JuPedSim's walkable area is the scenario's walkable area
  (holes are obstacles) united with its exit polygons (``geometry.navigable_area``), so agents can walk
  into the exits; each exit polygon is a JuPedSim exit stage. An exit drawn as a strip against the
  boundary too thin for a disk centre to enter with JuPedSim's wall behind it (RiMEA 12's 0.2 m goal
  strips) gets open space behind that stretch of boundary, where crowd_env has no wall either. A
  pedestrian has *left* when its centre lies in the exit it walks to (crowd_env's rule: its centre crossed
  the door); JuPedSim removes such an agent one or two iterations later, and the recording counts it as
  gone from the frame where either happened.
* **People**: ``scenario.make_state(rng=np.random.default_rng(seed))``, as crowd_env's run draws them:
  the same start positions, radii, desired speeds (drawn ones included), masses and premovement times.
  JuPedSim refuses an agent whose distance to a wall equals its radius (the scenarios let disks touch the
  walls), so its agents are ``RADIUS_SHRINK_M`` = 1 µm thinner; the gaps are measured with these radii.
* **Destinations**: a pedestrian with a destination exit k (``scenario.destination[i] = k``) gets the
  journey to exit k. One without (``destination`` None or -1) gets the journey to the exit with the
  smallest eikonal travel time from its start (one :class:`~crowd_env.walking.navigation.NavigationField`
  per exit, with the scenario's resolution, clearance and wall slowdown; with one exit, that one). The
  choice is made once, at the start: JuPedSim has no dynamic route choice here (crowd_env's pedestrians
  without a destination follow the field to the nearest exit all along and may leave by any exit, and with
  ``route_choice="quickest"``, RiMEA test 11, re-choose the exit as the crowd queues; JuPedSim's agents
  all keep the nearest one).
* **Premovement**: an agent stands (desired speed 0) until its premovement time, then gets its desired
  speed: at the first iteration whose start time t = k dt has t >= premovement (crowd_env's rule,
  :func:`~crowd_env.walking.agent.hold_waiting`), changed through ``sim.agent(id).model`` during the run.
  In the social force model a standing agent's social and wall repulsion (its agent and obstacle scale)
  are 0 as well, as crowd_env's waiting pedestrians ignore their social forces (the repulsion alone
  would make it drift, 0.25 m in 3 s beside a wall); body contact forces still push it, and the others
  still avoid it. In the collision-free speed model an agent of desired speed 0 does not move at all.
* **Scenarios without exits** (a prebuilt ``navigation_field`` that is not an eikonal field to the
  geometry's exits, e.g. a ring where the agents circulate): JuPedSim cannot run them from the exits, and
  :func:`build_simulation` raises :class:`~crowd_env.errors.InputError`, unless the test provides its own
  JuPedSim set-up as the hook below.
* **Hook, cyclic waypoints**: when ``scenario.metadata`` has ``"jupedsim_waypoints"`` (a list of at least
  two (x, y) points in the walkable area), every agent walks a cyclic journey of JuPedSim waypoint stages
  w_0 -> w_1 -> ... -> w_{m-1} -> w_0 (fixed transitions), each reached within
  ``metadata["jupedsim_waypoint_distance_m"]`` (default ``WAYPOINT_DISTANCE_M`` = 1 m). Each agent starts
  towards the waypoint at the end of the closed polyline's segment nearest to its start (the one ahead on
  a ring whose waypoints run in the walking direction). The exits are then unused: nobody leaves, and
  such a run ends at ``max_time_s``, incomplete (as a ring runs in crowd_env).
* **JuPedSim stopping**: JuPedSim raises when a model pushes an agent out of its walkable area (its social
  force model can push one through a wall beside a crowded door). The run then ends there, incomplete,
  with a :class:`RuntimeWarning`; its last frame holds the agents where JuPedSim left them, so the one
  outside shows in ``outside_m`` (and fails the suite's condition) instead of being lost.

Models and parameters (JuPedSim 1.4; its defaults except where said):

* ``jupedsim_cfsm``: ``CollisionFreeSpeedModel`` (Tordeux et al. 2016) with its defaults: neighbour
  repulsion strength 8, range 0.1 m; geometry repulsion strength 5, range 0.02 m; agent time gap 1 s.
  Per agent: position, radius, desired speed.
* ``jupedsim_sfm``: ``SocialForceModel`` (Helbing et al. 2000) with its defaults: body force 120000 kg/s²,
  friction 240000 kg/(m s); agent reaction time 0.5 s, agent and obstacle scale 2000 N, force distance
  0.08 m. Per agent: position, radius, desired speed, mass (the state's), orientation (the state's
  heading) and initial velocity (the state's).
* Time step ``DT_S`` = 0.01 s (JuPedSim's default, crowd_env's h); trajectories every
  1 / ``FRAME_RATE_PER_S`` s.

The :class:`~crowd_env.experiments.validation.rimea.base.BackendRun`: trajectories at the frame rate (ids = scenario
indices, heading = the agent's orientation); ``exit_time_s`` = the time of the first frame a pedestrian is
no longer recorded (the same reading as crowd_env's runs, :func:`~.base.exit_times_s`; a run ends on a frame),
nan for those still inside; ``min_gap_m`` =
the smallest gap over the recorded frames, between two disks (centre distance minus radii) or a disk and a
wall (distance minus radius), as crowd_env's runs measure it (they do so every step);
``outside_m`` from the frames (:func:`~.base.outside_distance_m`); ``complete``: everybody left before
``max_time_s``; ``wall_time_s``: the whole run, set-up included.
"""
from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass

import numpy as np
import shapely
from scipy.spatial import cKDTree

from crowd_env.errors import InputError, MissingDependencyError, NotFoundError

from ....analysis.trajectories import Trajectories, steps_per_frame
from ....core.checks import check_number
from ....walking.navigation import DestinationNavigation, NavigationField, RigidlyMovedNavigation
from .base import FRAME_RATE_PER_S, BackendRun, exit_times_s, outside_distance_m

__all__ = ["runner", "run_jupedsim", "build_simulation", "JupedsimSetup", "choose_exits", "jupedsim_geometry",
           "frame_min_gap_m", "MODELS", "DT_S", "RADIUS_SHRINK_M", "EXIT_CLEARANCE_M", "WAYPOINT_DISTANCE_M",
           "INSTALL_HINT"]

MODELS = {"jupedsim_cfsm": "cfsm", "jupedsim_sfm": "sfm"}  # backend name -> model
DT_S = 0.01
RADIUS_SHRINK_M = 1e-6  # JuPedSim refuses an agent touching a wall: its agents are this much thinner
EXIT_CLEARANCE_M = 0.5  # depth of the open space behind an exit's stretch of boundary (more than a body radius)
CENTRE_MARGIN_M = 0.05  # an exit counts as enterable when a centre can lie this far inside JuPedSim's bounds in it
WAYPOINT_DISTANCE_M = 1.0
INSTALL_HINT = "pip install -e '.[bench]' (or pip install jupedsim)"


def _import_jupedsim():
    try:
        import jupedsim
    except ImportError:
        raise MissingDependencyError(f"the JuPedSim backends need JuPedSim, which is not installed: "
                                     f"{INSTALL_HINT}") from None
    return jupedsim


def runner(backend: str):
    """``run(scenario, *, seed, max_time_s) -> BackendRun`` for ``backend`` ("jupedsim_cfsm" or
    "jupedsim_sfm"). Raises :class:`~crowd_env.errors.MissingDependencyError` (with the install hint) when
    JuPedSim is absent, :class:`~crowd_env.errors.NotFoundError` for another name."""
    if backend not in MODELS:
        raise NotFoundError(f"unknown JuPedSim backend {backend!r}; known: {list(MODELS)}")
    _import_jupedsim()

    def run(scenario, *, seed: int, max_time_s: float, frame_rate_per_s: float = FRAME_RATE_PER_S) -> BackendRun:
        return run_jupedsim(scenario, MODELS[backend], seed=seed, max_time_s=max_time_s,
                            frame_rate_per_s=frame_rate_per_s)

    run.__name__ = f"run_{backend}"
    run.__doc__ = f"Run a scenario with {backend} (see :mod:`{__name__}`)."
    return run


# -- set-up ----------------------------------------------------------------------------------------------
def jupedsim_geometry(scenario, radius_m: float | None = None, clearance_m: float = EXIT_CLEARANCE_M):
    """JuPedSim's walkable area: the scenario's walkable area (holes included) united with its exits, so that
    agents can walk into them. An exit against the walkable area's boundary that a disk centre of radius
    ``radius_m`` (default: the scenario's largest) could not enter with JuPedSim's wall behind it (RiMEA 12's
    goal strips, 0.2 m deep, and 0.23 m bodies) gets open space instead: behind each stretch of the boundary
    in that exit (where crowd_env has no wall), a strip ``clearance_m`` deep (flat ends, outside the walkable
    area). Raises :class:`~crowd_env.errors.InputError` if a strip would open one of crowd_env's walls
    (another part of the walkable area close behind the exit) or the result is not one polygon."""
    g = scenario.geometry
    area = g.walkable_area
    navigable = g.navigable_area
    r = float(np.max(scenario.radius_m(), initial=0.0)) if radius_m is None else float(radius_m)
    free = navigable.buffer(-(r + CENTRE_MARGIN_M))  # where JuPedSim lets a centre go, with a margin
    strips = []
    for exit_polygon in g.exits:
        if exit_polygon.intersection(free).area > 1e-9:
            continue  # a centre can enter it as it is
        stretches = shapely.get_parts(shapely.intersection(area.boundary, exit_polygon))
        for line in (part for part in stretches if part.geom_type == "LineString"):
            for a, b in zip(line.coords[:-1], line.coords[1:]):
                seg = shapely.LineString([a, b])
                if seg.length > 1e-9:
                    strips.append(seg.buffer(clearance_m, cap_style="flat").difference(area))
    if not strips:
        return navigable
    out = shapely.union_all([navigable, *strips])
    if g.walls.shape[0]:
        walls = shapely.multilinestrings([[(w[0], w[1]), (w[2], w[3])] for w in g.walls])
        opened = walls.difference(out.boundary.buffer(1e-7)).length
        if opened > 1e-6:
            raise InputError(f"scenario {scenario.name!r}: the walkable area lies within {clearance_m:g} m behind an "
                             f"exit; JuPedSim's geometry would open {opened:.3g} m of crowd_env's walls there")
    if out.geom_type != "Polygon":
        raise InputError(f"scenario {scenario.name!r}: the walkable area united with the exits is a "
                         f"{out.geom_type}; JuPedSim needs one connected polygon")
    return out


def _is_eikonal(navigation) -> bool:
    base = navigation
    while isinstance(base, RigidlyMovedNavigation):
        base = base.base
    return isinstance(base, (NavigationField, DestinationNavigation))


def _waypoints(scenario):
    """``(points (m, 2), distance_m)`` of the cyclic waypoint hook, or None without it."""
    meta = scenario.metadata
    if "jupedsim_waypoints" not in meta:
        return None
    pts = np.asarray(meta["jupedsim_waypoints"], dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2 or pts.shape[0] < 2 or not np.isfinite(pts).all():
        raise InputError(f"scenario {scenario.name!r}: metadata['jupedsim_waypoints'] must be at least two finite "
                         f"(x, y) points, got shape {pts.shape}")
    out = ~shapely.intersects_xy(scenario.geometry.navigable_area, pts[:, 0], pts[:, 1])
    if out.any():
        k = int(np.flatnonzero(out)[0])
        raise InputError(f"scenario {scenario.name!r}: JuPedSim waypoint {k} at {pts[k].tolist()} lies outside "
                         "the walkable area")
    dist = meta.get("jupedsim_waypoint_distance_m", WAYPOINT_DISTANCE_M)
    if isinstance(dist, bool) or not isinstance(dist, (int, float, np.integer, np.floating)) \
            or not math.isfinite(dist) or dist <= 0:
        raise InputError(f"scenario {scenario.name!r}: metadata['jupedsim_waypoint_distance_m'] must be a positive "
                         f"number, got {dist!r}")
    return pts, float(dist)


def _first_waypoints(position_m, pts) -> np.ndarray:
    """(N,) index of the waypoint each start heads for: the end of the nearest segment of the closed polyline."""
    a, b = pts, np.roll(pts, -1, axis=0)
    d = b - a
    length2 = np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
    rel = position_m[:, None, :] - a[None, :, :]
    s = np.clip(np.einsum("nmj,mj->nm", rel, d) / length2, 0.0, 1.0)
    foot = a[None] + s[..., None] * d[None]
    dist = np.linalg.norm(position_m[:, None, :] - foot, axis=2)
    return (np.argmin(dist, axis=1) + 1) % pts.shape[0]


def _exit_field(scenario, k: int) -> NavigationField:
    return NavigationField.cached(scenario.geometry, scenario.navigation_resolution_m, scenario.wall_slowdown,
                                  clearance_m=scenario.navigation_clearance_m, exits=(k,))


def choose_exits(scenario, position_m=None) -> np.ndarray:
    """(N,) the exit each pedestrian walks to in JuPedSim: its destination where it has one, else the exit
    with the smallest eikonal travel time from ``position_m`` (default: the start positions)."""
    pos = scenario.position_m if position_m is None else np.asarray(position_m, dtype=np.float64)
    n, n_exits = pos.shape[0], len(scenario.geometry.exits)
    out = np.full(n, -1, np.int64) if scenario.destination is None else np.array(scenario.destination, np.int64)
    free = out < 0
    if free.any():
        if n_exits == 1:
            out[free] = 0
        else:
            t = np.column_stack([_exit_field(scenario, k).travel_time(pos[free]) for k in range(n_exits)])
            out[free] = np.argmin(t, axis=1)
    return out


@dataclass
class JupedsimSetup:
    """A built JuPedSim simulation of a scenario.

    ``sim`` (``jupedsim.Simulation``); ``model`` ("cfsm"/"sfm"); ``agent_id`` (N,) JuPedSim ids of the
    scenario's pedestrians and ``row_of`` the reverse map; ``radius_m`` (N,) the radii simulated;
    ``desired_speed_m_s`` (N,) each one's speed once walking; ``start_iteration`` (N,) the iteration from
    which it walks (its premovement); ``exit_of`` (N,) the exit it walks to (-1: cyclic waypoints);
    ``exits`` the exit polygons."""

    sim: object
    model: str
    agent_id: np.ndarray
    row_of: dict
    radius_m: np.ndarray
    desired_speed_m_s: np.ndarray
    start_iteration: np.ndarray
    exit_of: np.ndarray
    exits: tuple
    dt_s: float
    sfm_scales: tuple = (2000.0, 2000.0)

    def start_walking(self, iteration: int) -> None:
        """Give their desired speed to the agents whose premovement ends at ``iteration`` (call before
        iterating from ``iteration``)."""
        for k in np.flatnonzero(self.start_iteration == iteration):
            try:
                agent = self.sim.agent(int(self.agent_id[k]))
            except RuntimeError:  # already removed (pushed into its exit while standing)
                continue
            agent.model.desired_speed = float(self.desired_speed_m_s[k])
            if self.model == "sfm":  # it reacts to the others and the walls again
                agent.model.agent_scale, agent.model.obstacle_scale = self.sfm_scales


def build_simulation(scenario, state, model: str, *, dt_s: float = DT_S) -> JupedsimSetup:
    """The JuPedSim simulation of ``scenario`` with the pedestrians of ``state`` (a
    :class:`~crowd_env.core.state.CrowdState`, e.g. ``scenario.make_state(rng)``) and ``model`` ("cfsm" or
    "sfm"): geometry, exit stages and journeys, agents (see the module docstring). Raises
    :class:`~crowd_env.errors.InputError` for a scenario JuPedSim cannot run here (no exits and no waypoint
    hook) or an agent JuPedSim refuses."""
    jps = _import_jupedsim()
    if model not in ("cfsm", "sfm"):
        raise NotFoundError(f"unknown JuPedSim model {model!r}; known: 'cfsm', 'sfm'")
    waypoints = _waypoints(scenario)
    nav = scenario.navigation_field
    exits = tuple(scenario.geometry.exits)
    if waypoints is None and (not exits or (nav is not None and not _is_eikonal(nav))):
        raise InputError(f"scenario {scenario.name!r} has no exit JuPedSim can walk to (its prebuilt navigation "
                         f"{type(nav).__name__} is not an eikonal field to the geometry's exits): JuPedSim cannot run "
                         "it here unless the test provides its own JuPedSim set-up (metadata 'jupedsim_waypoints', "
                         f"see {__name__})")
    n = state.n
    pos = np.asarray(state.position_m, dtype=np.float64)
    radius = np.asarray(state.radius_m, dtype=np.float64) - RADIUS_SHRINK_M
    speed = np.asarray(state.desired_speed_m_s, dtype=np.float64).copy()
    pre = np.asarray(state.premovement_s, dtype=np.float64)
    start = np.maximum(np.ceil(pre / dt_s - 1e-9), 0).astype(np.int64)

    jmodel = jps.CollisionFreeSpeedModel() if model == "cfsm" else jps.SocialForceModel()
    sim = jps.Simulation(model=jmodel, geometry=jupedsim_geometry(scenario, float(np.max(radius, initial=0.0))),
                         dt=dt_s)
    if waypoints is None:
        exit_of = choose_exits(scenario, pos)
        stages = [sim.add_exit_stage(e) for e in exits]
        journeys = [sim.add_journey(jps.JourneyDescription([s])) for s in stages]
        route = [(journeys[e], stages[e]) for e in exit_of]
    else:
        pts, distance = waypoints
        stages = [sim.add_waypoint_stage((float(x), float(y)), distance) for x, y in pts]
        journey = jps.JourneyDescription(stages)
        for k, s in enumerate(stages):
            journey.set_transition_for_stage(s, jps.Transition.create_fixed_transition(stages[(k + 1) % len(stages)]))
        jid = sim.add_journey(journey)
        exit_of = np.full(n, -1, np.int64)
        route = [(jid, stages[w]) for w in _first_waypoints(pos, pts)]

    heading = np.asarray(state.heading_rad, dtype=np.float64)
    velocity = np.asarray(state.velocity_m_s, dtype=np.float64)
    ids = np.empty(n, np.int64)
    for k in range(n):
        journey_id, stage_id = route[k]
        v0 = float(speed[k]) if start[k] <= 0 else 0.0
        common = dict(position=(float(pos[k, 0]), float(pos[k, 1])), journey_id=journey_id, stage_id=stage_id,
                      desired_speed=v0, radius=float(radius[k]))
        if model == "cfsm":
            params = jps.CollisionFreeSpeedModelAgentParameters(**common)
        else:
            params = jps.SocialForceModelAgentParameters(
                **common, orientation=(math.cos(heading[k]), math.sin(heading[k])),
                velocity=(float(velocity[k, 0]), float(velocity[k, 1])), mass=float(state.mass_kg[k]))
            if start[k] > 0:  # standing: no social or wall repulsion acts on it, only body contact forces
                params.agent_scale, params.obstacle_scale = 0.0, 0.0
        try:
            ids[k] = sim.add_agent(params)
        except RuntimeError as exc:
            raise InputError(f"JuPedSim refused pedestrian {k} of scenario {scenario.name!r} at "
                             f"{pos[k].tolist()}: {exc}") from None
    defaults = jps.SocialForceModelAgentParameters()
    return JupedsimSetup(sim, model, ids, {int(a): k for k, a in enumerate(ids)}, radius, speed, start, exit_of,
                         exits, float(dt_s), (float(defaults.agent_scale), float(defaults.obstacle_scale)))


# -- the run ---------------------------------------------------------------------------------------------
def frame_min_gap_m(xy: np.ndarray, radius_m: np.ndarray, geometry=None) -> float:
    """The smallest gap of one frame: centre distance minus radii over all pairs (scipy cKDTree) and, with
    ``geometry``, distance to the walls minus the radius (what crowd_env's ``Simulator.min_gap_m`` measures);
    negative: an overlap; inf with nothing to measure."""
    best = math.inf
    if xy.shape[0] >= 2:
        pairs = cKDTree(xy).query_pairs(2.0 * float(radius_m.max()) + 1.0, output_type="ndarray")
        if pairs.shape[0]:
            i, j = pairs[:, 0], pairs[:, 1]
            best = float(np.min(np.linalg.norm(xy[i] - xy[j], axis=1) - radius_m[i] - radius_m[j]))
    if geometry is not None and xy.shape[0] and geometry.walls.shape[0]:
        best = min(best, float(np.min(geometry.distance_to_walls(xy) - radius_m)))
    return best


def run_jupedsim(scenario, model: str, *, seed: int, max_time_s: float, frame_rate_per_s: float = FRAME_RATE_PER_S,
                 dt_s: float = DT_S) -> BackendRun:
    """Run ``scenario`` in JuPedSim with ``model`` ("cfsm" or "sfm") and the pedestrians crowd_env draws with
    ``seed``, recorded at ``frame_rate_per_s``, until everybody left or ``max_time_s``: a
    :class:`~crowd_env.experiments.validation.rimea.base.BackendRun` with backend ``"jupedsim_<model>"``."""
    check_number("max_time_s", max_time_s, error=InputError, positive=True)
    t0 = time.perf_counter()
    state = scenario.make_state(rng=np.random.default_rng(seed))
    setup = build_simulation(scenario, state, model, dt_s=dt_s)
    sim, n = setup.sim, state.n
    every = steps_per_frame(frame_rate_per_s, dt_s)
    n_frames_max = int(math.ceil(max_time_s / (every * dt_s) - 1e-9))
    left = np.zeros(n, bool)
    starts = np.unique(setup.start_iteration[setup.start_iteration > 0])
    rows = {"frame": [], "id": [], "x": [], "y": [], "h": []}
    gap = math.inf

    def record(frame: int) -> None:
        nonlocal gap
        agents = list(sim.agents())
        k = np.fromiter((setup.row_of[a.id] for a in agents), np.int64, len(agents))
        xy = np.array([a.position for a in agents], dtype=np.float64).reshape(-1, 2)
        ori = np.array([a.orientation for a in agents], dtype=np.float64).reshape(-1, 2)
        here = ~left[k]
        e = setup.exit_of[k]
        for x in np.unique(e[(e >= 0) & here]):  # centre in its own exit: it has left (crowd_env's rule)
            sel = here & (e == x)
            here[sel] &= ~shapely.contains_xy(setup.exits[x], xy[sel, 0], xy[sel, 1])
        gone = np.ones(n, bool)
        gone[k[here]] = False
        left[gone] = True
        k, xy, ori = k[here], xy[here], ori[here]
        rows["frame"].append(np.full(k.shape[0], frame, np.int64))
        rows["id"].append(k)
        rows["x"].append(xy[:, 0])
        rows["y"].append(xy[:, 1])
        rows["h"].append(np.arctan2(ori[:, 1], ori[:, 0]))
        gap = min(gap, frame_min_gap_m(xy, setup.radius_m[k], scenario.geometry))

    record(0)
    frame, iteration = 0, 0
    while frame < n_frames_max and not left.all():
        end = (frame + 1) * every
        try:
            while iteration < end:
                if np.any(starts == iteration):
                    setup.start_walking(iteration)
                later = starts[starts > iteration]
                stop = min(end, int(later[0])) if later.size else end
                sim.iterate(stop - iteration)
                iteration = stop
        except RuntimeError as exc:  # JuPedSim stops when a model pushes an agent out of its walkable area
            at = sim.iteration_count()
            warnings.warn(f"JuPedSim {model} stopped on scenario {scenario.name!r} at t = {at * dt_s:.2f} s: {exc}; "
                          "the run ends there, incomplete, its last frame holding the agents where JuPedSim left them",
                          RuntimeWarning, stacklevel=2)
            frame += 1  # the positions of iteration ``at`` (at most one frame interval early)
            record(frame)
            break
        frame += 1
        record(frame)
    stopped = iteration < frame * every
    traj = Trajectories(np.concatenate(rows["frame"]), np.concatenate(rows["id"]), np.concatenate(rows["x"]),
                        np.concatenate(rows["y"]), np.concatenate(rows["h"]), frame_rate_per_s=1.0 / (every * dt_s))
    exits = exit_times_s(traj, left, frame / traj.frame_rate_per_s)  # a JuPedSim run ends on a frame
    complete = bool(left.all()) and not stopped
    wall = time.perf_counter() - t0
    return BackendRun(f"jupedsim_{model}", scenario.name, traj, exits, float(gap),
                      outside_distance_m(traj, scenario.geometry.walkable_area), complete, False, wall,
                      float(max_time_s))
