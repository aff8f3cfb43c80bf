"""Demonstrations from recorded trajectories: what each recorded pedestrian saw and did, as an agent of the
environment would see and do it.

A recording (PedPy's format: one row per pedestrian and frame, :class:`~crowd_env.analysis.trajectories.
Trajectories`) is replayed in its scenario (:mod:`crowd_env.scenarios`, e.g. ``juelich_corridor`` for the UO runs):

1. **Positions**: each trajectory, smoothed by a centred moving average over ``smoothing_s`` (the window shrinks
   symmetrically at a trajectory's ends, which stay where they were recorded: it takes out the gait's sway, about
   0.1 m/s sideways in the UO runs, not the reactions), is read at the decision times t_k = k Δ (Δ =
   ``frame_skip`` × the simulator's step; time = frame / frame rate, as PedPy counts it; linear interpolation
   between consecutive frames; from the first multiple of Δ in the recording on). A pedestrian is on the floor at
   t_k when it is recorded on both frames around t_k.
2. **State**: the velocity at t_k is the mean velocity over the previous decision interval, (p_k − p_{k−1}) / Δ
   (over the next one at a pedestrian's first decision); the heading is the environment's own: the heading
   spring-damper of the core (:func:`crowd_env.core.step.smooth_update`, Kabalan Eq. 15) driven, step by step of
   the simulator, towards the target the environment's ``heading_target`` gives (``"desired_direction"``: the
   angle of e_d at the recorded position, the shoulders turned at a narrow aperture when the model turns them,
   :func:`~crowd_env.walking.agent.facing_headings_rad` with the recorded crowd on the floor; the recordings hold
   no heading), starting at that target with no angular velocity when the pedestrian first appears.
3. **Observation**: the environment's own :class:`~crowd_env.envs.observations.ObservationBuilder` with the
   policy's options (:func:`policy_options`) on that state, every pedestrian on the floor a neighbour: the
   observation an agent of :mod:`crowd_env.envs.crowd_v0` would get in that state (``tests/experiments/training/
   test_demonstrations.py`` checks it against the environment's own on the same state).
4. **Action**: the velocity over the next decision interval, a_k = (p_{k+1} − p_k) / Δ, in the observation's
   frame (the body frame of the heading at t_k when egocentric, as the environment reads an action): integrated,
   the actions give back the recorded positions (to rounding; without smoothing, the file's own positions at the
   frames that fall on decisions).

**The camera's edges.** Nobody outside the camera's view is in the file, so the neighbours of a pedestrian near
its edges may be missing. The edges are where trajectories begin or end other than at the recording's first and
last frames (the UO runs: people appear at y ≈ 7.8 m behind the entrance and vanish at y ≈ −6 m); each
decision records ``edge_distance_m``, its distance to the nearest such point, and ``reach_m``, how far its
observation looks at others (the k-th nearest neighbour's distance, or the neighbour radius when fewer than k
are within it; a ``local_density`` disc's radius). A decision is ``seen`` when ``edge_distance_m >= reach_m``:
anybody unseen beyond the edge is then farther than everybody its observation holds, so the observation is
the one the full crowd would give. Training uses the seen decisions only; the others are kept, flagged.

The dataset (:class:`Demonstrations`, :meth:`Demonstrations.save`) is one ``.npz`` file, format
:data:`DEMONSTRATIONS_FORMAT`, read with ``allow_pickle=False`` (data only): arrays ``observation`` (n, D)
float32, ``action`` (n, 2) float64 (m/s, observation frame), ``pedestrian`` (n,) int64 (the file's ids),
``time_s`` (n,), ``position_m`` (n, 2), ``velocity_m_s`` (n, 2) (world frame, the state's), ``heading_rad``
(n,), ``seen`` (n,) bool, ``edge_distance_m`` (n,), ``reach_m`` (n,), and ``meta`` (JSON: the format, the
source, the scenario and its options, the policy options, ``decision_dt_s``, ``smoothing_s``, the observation
layout, counts).
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from crowd_env.errors import TrainingError
from crowd_env.files import write_npz_atomic

from ...core.bundles import StepInputs, StepParams
from ...core.params import PedestrianDefaults
from ...core.segments import as_segments
from ...core.state import CrowdState
from ...core.step import smooth_update
from ...envs.config import ENV_DEFAULTS, observation_policy_options
from ...envs.background import OBSERVATION_POLICY_OPTIONS
from ...envs.observations import ObservationBuilder, to_body_frame, to_world_frame
from ...walking.agent import facing_headings_rad, walking_bundle
from ...walking.model import ModelParams

__all__ = ["DEMONSTRATIONS_FORMAT", "HUMAN_POLICY_OPTIONS", "DEFAULT_SMOOTHING_S", "policy_options", "Replay",
           "replay_trajectories", "Demonstrations", "demonstrations_from_replay", "demonstrations_from_trajectories",
           "load_demonstrations", "observation_builder", "observation_reach_m", "recorded_state"]

DEMONSTRATIONS_FORMAT = "crowd_env.demonstrations/1"
DEFAULT_SMOOTHING_S = 0.5
# The observation and action of a policy learned from recordings: egocentric (the recordings' corridor runs
# towards −y, Seyfried's bottleneck along another axis), the heading turned towards e_d (the recordings hold
# none), no travel time (it would tell where the recorded exit is), no own velocity (a clone that sees it copies
# it and its crowd does not get going: docs/validation/human_policy.md), a decision every 0.1 s.
HUMAN_POLICY_OPTIONS = {"observation_frame": "egocentric", "heading_target": "desired_direction",
                        "observation_components": ["desired_direction", "neighbors", "wall_rays"],
                        "n_neighbors": 8, "n_rays": 16, "neighbor_radius_m": 4.0, "ray_range_m": 5.0,
                        "frame_skip": 10, "action_max_m_s": 2.5}


def policy_options(overrides: dict | None = None) -> dict:
    """:data:`HUMAN_POLICY_OPTIONS` with ``overrides`` (any of the environment's observation-policy options,
    :data:`~crowd_env.envs.background.OBSERVATION_POLICY_OPTIONS`), checked as the environment checks them."""
    overrides = dict(overrides or {})
    unknown = sorted(set(overrides) - set(OBSERVATION_POLICY_OPTIONS))
    if unknown:
        raise TrainingError(f"unknown policy option(s) {unknown}; known: {list(OBSERVATION_POLICY_OPTIONS)}")
    merged = {**HUMAN_POLICY_OPTIONS, **overrides}
    observation_policy_options(merged, what="policy options: ")
    return merged


def observation_builder(options: dict, navigation, walls, *, period_m: float = 0.0) -> ObservationBuilder:
    """The environment's observation assembler with the policy ``options`` (the declared bounds as an
    environment would set them)."""
    o = {k: options.get(k, ENV_DEFAULTS[k]) for k in OBSERVATION_POLICY_OPTIONS}
    return ObservationBuilder(navigation, walls, n_neighbors=int(o["n_neighbors"]), n_rays=int(o["n_rays"]),
                              neighbor_radius_m=float(o["neighbor_radius_m"]), ray_range_m=float(o["ray_range_m"]),
                              velocity_bound_m_s=max(20.0, 2.0 * float(o["action_max_m_s"])),
                              travel_time_bound_s=navigation.max_travel_time_s + 1.0, frame=o["observation_frame"],
                              period_m=period_m, components=o["observation_components"])


def observation_reach_m(builder: ObservationBuilder, position_m: np.ndarray, active: np.ndarray,
                        index: np.ndarray) -> np.ndarray:
    """How far the observation of each pedestrian ``index`` looks at others (module docstring): the distance of
    its k-th nearest other on the floor within the neighbour radius (the radius when fewer lie within it) when a
    component reads neighbours, and the radius of any component that has one (``local_density``); 0 when none
    looks at others."""
    reach = np.zeros(index.shape[0])
    comps = builder.components
    if any(c.uses_neighbors for c in comps) and index.size:
        k = builder.n_neighbors
        others = np.flatnonzero(active)
        tree = cKDTree(position_m[others])
        d, _ = tree.query(position_m[index], k=min(k + 1, others.size), distance_upper_bound=builder.neighbor_radius_m)
        d = d.reshape(index.size, -1)
        kth = d[:, k] if d.shape[1] > k else np.full(index.size, np.inf)  # column 0: the pedestrian itself
        reach = np.where(np.isfinite(kth), kth, builder.neighbor_radius_m)
    radii = [float(c.radius_m) for c in comps if hasattr(c, "radius_m")]
    return np.maximum(reach, max(radii)) if radii else reach


@dataclass(frozen=True, eq=False)
class Replay:
    """A recording replayed at the decision times (module docstring, steps 1-2): ``ids`` (P,) the file's ids,
    ``time_s`` (K,), and per decision and pedestrian ``present`` (K, P), ``position_m`` (K, P, 2) (NaN where
    absent), ``velocity_m_s`` (K, P, 2), ``heading_rad`` (K, P); ``edge_points_m`` (E, 2): where trajectories
    begin or end inside the recording (the camera's edges), ``edge_appears`` (E,) True where one begins;
    ``decision_dt_s``, ``smoothing_s``."""

    ids: np.ndarray
    time_s: np.ndarray
    present: np.ndarray
    position_m: np.ndarray
    velocity_m_s: np.ndarray
    heading_rad: np.ndarray
    edge_points_m: np.ndarray
    edge_appears: np.ndarray
    decision_dt_s: float
    smoothing_s: float
    frame_rate_per_s: float

    def actions_world(self) -> tuple:
        """``(mask (K−1, P), actions (K−1, P, 2))``: the velocity over each decision interval, where the pedestrian
        is on the floor at both of its ends."""
        mask = self.present[:-1] & self.present[1:]
        with np.errstate(invalid="ignore"):
            act = (self.position_m[1:] - self.position_m[:-1]) / self.decision_dt_s
        return mask, np.where(mask[..., None], act, 0.0)


def _frames_grid(traj, smoothing_s: float) -> tuple:
    """``(ids (P,), first frame, positions (F, P, 2) smoothed, NaN where absent)`` of a recording."""
    if len(traj) == 0:
        raise TrainingError("the recording holds no rows")
    ids, col = np.unique(traj.id, return_inverse=True)
    f0 = int(traj.frame.min())
    grid = np.full((int(traj.frame.max()) - f0 + 1, ids.size, 2), np.nan)
    grid[traj.frame - f0, col, 0] = traj.x_m
    grid[traj.frame - f0, col, 1] = traj.y_m
    half = int(round(0.5 * smoothing_s * traj.frame_rate_per_s))
    if half > 0:
        grid = _smoothed(grid, half)
    return ids, f0, grid


def _smoothed(grid: np.ndarray, half: int) -> np.ndarray:
    """Centred moving average of every run of consecutive frames of each column over up to ±``half`` frames,
    the window shrunk symmetrically at the run's ends (which stay put)."""
    out = grid.copy()
    present = np.isfinite(grid[:, :, 0])
    for p in range(grid.shape[1]):
        frames = np.flatnonzero(present[:, p])
        if frames.size < 3:
            continue
        breaks = np.flatnonzero(np.diff(frames) > 1)
        for run in np.split(frames, breaks + 1):
            a, b = int(run[0]), int(run[-1])
            cs = np.vstack([np.zeros((1, 2)), np.cumsum(grid[a:b + 1, p], axis=0)])
            i = np.arange(b - a + 1)
            h = np.minimum(np.minimum(i, b - a - i), half)
            out[a:b + 1, p] = (cs[i + h + 1] - cs[i - h]) / (2 * h + 1)[:, None]
    return out


def _at_times(grid: np.ndarray, f0: int, fps: float, times_s: np.ndarray) -> tuple:
    """``(present (K, P), positions (K, P, 2))``: the grid read at ``times_s`` by linear interpolation between
    the two frames around each time (both recorded), or at the frame itself when a time falls on one."""
    u = times_s * fps - f0
    j = np.floor(u + 1e-9).astype(np.int64)
    frac = np.clip(u - j, 0.0, 1.0)
    on_frame = frac < 1e-9
    j1 = np.minimum(j + 1, grid.shape[0] - 1)
    a, b = grid[j], grid[np.where(on_frame, j, j1)]
    w = np.where(on_frame, 0.0, frac)[:, None, None]
    pos = a + w * (b - a)
    return np.isfinite(pos[..., 0]), pos


def _edge_points(traj) -> tuple:
    """``(points (E, 2), appears (E,))``: where trajectories begin after the recording's first frame (appears)
    or end before its last (raw positions)."""
    order = np.lexsort((traj.frame, traj.id))
    ids, frame, x, y = traj.id[order], traj.frame[order], traj.x_m[order], traj.y_m[order]
    first = np.r_[True, ids[1:] != ids[:-1]]
    last = np.r_[ids[1:] != ids[:-1], True]
    begins = first & (frame > frame.min())
    keep = begins | (last & (frame < frame.max()))
    return np.column_stack([x[keep], y[keep]]), begins[keep]


def replay_trajectories(trajectories, scenario, *, options: dict | None = None, params: ModelParams | None = None,
                        smoothing_s: float = DEFAULT_SMOOTHING_S) -> Replay:
    """``trajectories`` replayed in ``scenario`` at the decisions of the policy ``options`` (module docstring,
    steps 1-2); ``params``: the simulator step and the rotation switch (default :class:`ModelParams`)."""
    options = policy_options(options)
    params = ModelParams() if params is None else params
    if not (np.isfinite(smoothing_s) and smoothing_s >= 0.0):
        raise TrainingError(f"smoothing_s must be a number >= 0, got {smoothing_s!r}")
    fps = float(trajectories.frame_rate_per_s)
    ids, f0, grid = _frames_grid(trajectories, smoothing_s)
    dt = float(params.dt_s)
    skip = int(options["frame_skip"])
    delta = skip * dt
    t_start = np.ceil(f0 / fps / delta - 1e-9) * delta  # decisions on multiples of Δ, whatever the file's extent
    n_steps = int(np.floor(((f0 + grid.shape[0] - 1) / fps - t_start) / dt + 1e-9))
    step_times = t_start + dt * np.arange(n_steps + 1)
    heading = _replay_headings(grid, f0, fps, step_times, scenario, options, params)
    times = step_times[::skip]
    present, pos = _at_times(grid, f0, fps, times)
    vel = np.zeros_like(pos)
    with np.errstate(invalid="ignore"):
        back = (pos[1:] - pos[:-1]) / delta
    both = present[1:] & present[:-1]
    vel[1:][both] = back[both]
    first = present[:-1] & ~np.r_[np.zeros((1, ids.size), bool), present[:-2]] & present[1:]  # first decision: ahead
    vel[:-1][first] = back[first]
    return Replay(ids, times, present, pos, vel, heading[::skip], *_edge_points(trajectories), delta,
                  float(smoothing_s), fps)


def _replay_headings(grid, f0: int, fps: float, step_times, scenario, options: dict, params) -> np.ndarray:
    """(S, P) headings at ``step_times`` (every simulator step): the core's heading spring-damper towards the
    environment's target (module docstring, step 2); NaN where a pedestrian is absent."""
    if options["heading_target"] != "desired_direction":
        raise TrainingError("a replay turns headings towards e_d (heading_target='desired_direction'): the recordings "
                            f"hold no intent to turn towards; got heading_target={options['heading_target']!r}")
    navigation = scenario.navigation()
    n = grid.shape[1]
    radius = scenario.radius_m()[0] if scenario.n_pedestrians else PedestrianDefaults().radius_m
    bodies = CrowdState.create(np.column_stack([np.arange(n) * 10.0, np.zeros(n)]), radius_m=radius)
    walls = as_segments(scenario.geometry.walls)
    rule = walking_bundle(params).shoulder_turn  # with the model's shoulder turn, the shoulders turn at a narrow gap
    theta = np.zeros(n)
    omega = np.zeros(n)
    zeros2 = np.zeros((n, 2))
    out = np.full((step_times.size, n), np.nan)
    present, pos = _at_times(grid, f0, fps, step_times)
    before = np.zeros(n, bool)
    dt = float(params.dt_s)
    arrays = bodies.arrays()
    step = StepParams(dt, 0.0, 0.0, 0.0, 0.0, bool(params.rotation), 0, 0, 0, 0.0)  # smooth_update reads h, rotation
    for s in range(step_times.size):
        idx = np.flatnonzero(present[s])
        new = present[s] & ~before
        before = present[s]
        out[s, idx] = theta[idx]
        if not idx.size or s == step_times.size - 1:
            continue
        target = np.zeros(n)
        target[idx] = facing_headings_rad(navigation, pos[s], bodies.radius_m, theta, idx, walls, rule)
        theta[new] = target[new]
        omega[new] = 0.0
        out[s, new] = theta[new]
        vel = smooth_update(arrays._replace(velocity_m_s=zeros2, angular_velocity_rad_s=omega, heading_rad=theta),
                            StepInputs(zeros2, target, True, zeros2, False), idx, step)
        omega[idx] = vel[:, 2]
        theta[idx] = np.pi - np.mod(np.pi - (theta[idx] + dt * vel[:, 2]), 2.0 * np.pi)  # wrap_angle_scalar's
    return out


def recorded_state(replay: Replay, k: int, radius_m: float) -> CrowdState:
    """The crowd of decision ``k`` as a :class:`CrowdState` (every pedestrian of the file a row, those on the floor
    active; not validated: recorded people stand closer than two radii)."""
    n = replay.ids.size
    present = replay.present[k]
    pos = np.where(present[:, None], replay.position_m[k], 0.0)
    d = PedestrianDefaults()
    mass = np.full(n, d.mass_kg)
    radius = np.full(n, float(radius_m))
    inertia = 0.5 * mass * radius ** 2
    stiffness = np.full(n, d.heading_stiffness_n_m_per_rad)
    return CrowdState(position_m=pos, heading_rad=np.where(present, replay.heading_rad[k], 0.0),
                      velocity_m_s=np.where(present[:, None], replay.velocity_m_s[k], 0.0),
                      angular_velocity_rad_s=np.zeros(n), mass_kg=mass, inertia_kg_m2=inertia, radius_m=radius,
                      desired_speed_m_s=np.full(n, d.desired_speed_mean_m_s), tau_s=np.full(n, d.tau_s),
                      heading_stiffness=stiffness,
                      heading_damping=2.0 * d.heading_damping_ratio * np.sqrt(inertia * stiffness),
                      active=present.copy())


@dataclass(frozen=True, eq=False)
class Demonstrations:
    """Observation-action pairs of recorded pedestrians (module docstring: the arrays, their units, ``meta``)."""

    observation: np.ndarray
    action: np.ndarray
    pedestrian: np.ndarray
    time_s: np.ndarray
    position_m: np.ndarray
    velocity_m_s: np.ndarray
    heading_rad: np.ndarray
    seen: np.ndarray
    edge_distance_m: np.ndarray
    reach_m: np.ndarray
    meta: dict = field(default_factory=dict)

    ARRAYS = ("observation", "action", "pedestrian", "time_s", "position_m", "velocity_m_s", "heading_rad", "seen",
              "edge_distance_m", "reach_m")

    def __len__(self) -> int:
        return int(self.action.shape[0])

    @property
    def options(self) -> dict:
        """The policy options the observations were made with."""
        return dict(self.meta["options"])

    def world_actions(self) -> np.ndarray:
        """The actions (n, 2) in the world frame (turned back from the body frame when egocentric)."""
        if self.meta["options"]["observation_frame"] == "egocentric":
            return to_world_frame(self.action, np.cos(self.heading_rad), np.sin(self.heading_rad))
        return self.action.copy()

    def select(self, mask) -> "Demonstrations":
        """The decisions where ``mask`` (n,) holds."""
        mask = np.asarray(mask, bool)
        return Demonstrations(*(getattr(self, a)[mask] for a in self.ARRAYS), meta=dict(self.meta))

    def save(self, path) -> str:
        """Write the dataset to ``path`` (``.npz``, atomically; module docstring)."""
        write_npz_atomic(str(path), {**self.meta, "format": DEMONSTRATIONS_FORMAT},
                         **{a: getattr(self, a) for a in self.ARRAYS})
        return str(path)


def load_demonstrations(path) -> Demonstrations:
    """The dataset :meth:`Demonstrations.save` wrote; :class:`TrainingError` naming the file otherwise."""
    try:
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            if meta.get("format") != DEMONSTRATIONS_FORMAT:
                raise TrainingError(f"{path} is a {meta.get('format')!r} file, not {DEMONSTRATIONS_FORMAT!r}")
            return Demonstrations(*(data[a] for a in Demonstrations.ARRAYS), meta=meta)
    except (OSError, ValueError, KeyError) as exc:
        raise TrainingError(f"{path} is not a demonstrations file: {exc}") from None


def demonstrations_from_replay(replay: Replay, scenario, options: dict, *, meta: dict | None = None) -> Demonstrations:
    """Observations and actions of every decision of ``replay`` that has a next one (module docstring, steps 3-4
    and the camera's edges), observed in ``scenario`` with the policy ``options``."""
    options = policy_options(options)
    builder = observation_builder(options, scenario.navigation(), scenario.geometry.walls,
                                  period_m=scenario.geometry.period_x_m)
    edges = cKDTree(replay.edge_points_m) if replay.edge_points_m.size else None
    radius = float(scenario.radius_m()[0]) if scenario.n_pedestrians else PedestrianDefaults().radius_m
    mask, act = replay.actions_world()
    parts = []
    for k in range(mask.shape[0]):
        idx = np.flatnonzero(mask[k])
        if not idx.size:
            continue
        state = recorded_state(replay, k, radius)
        obs, _ = builder.build(state, idx)
        theta = replay.heading_rad[k, idx]
        a = act[k, idx]
        if builder.frame == "egocentric":
            a = to_body_frame(a, np.cos(theta), np.sin(theta))
        pos = replay.position_m[k, idx]
        edge = edges.query(pos)[0] if edges is not None else np.full(idx.size, np.inf)
        reach = observation_reach_m(builder, state.position_m, state.active, idx)
        parts.append((obs, a, replay.ids[idx], np.full(idx.size, replay.time_s[k]), pos, replay.velocity_m_s[k, idx],
                      theta, edge >= reach, edge, reach))
    if not parts:
        raise TrainingError("the replay holds no decision with a next one (a recording shorter than two decisions?)")
    arrays = [np.concatenate(col) for col in zip(*parts)]
    arrays[0] = arrays[0].astype(np.float32)
    info = {"options": options, "decision_dt_s": replay.decision_dt_s, "smoothing_s": replay.smoothing_s,
            "frame_rate_per_s": replay.frame_rate_per_s, "layout": {k: [s.start, s.stop] for k, s in builder.layout.items()},
            "n_decisions": int(arrays[1].shape[0]), "n_seen": int(arrays[7].sum()), "n_pedestrians": int(replay.ids.size),
            "radius_m": radius, **(meta or {})}
    return Demonstrations(*arrays, meta=info)


def demonstrations_from_trajectories(trajectories, scenario, *, options: dict | None = None,
                                     params: ModelParams | None = None, smoothing_s: float = DEFAULT_SMOOTHING_S,
                                     meta: dict | None = None) -> Demonstrations:
    """:func:`replay_trajectories` then :func:`demonstrations_from_replay`: the dataset of a recording in its
    scenario (``meta``: provenance to keep, e.g. the source file and the scenario's options)."""
    options = policy_options(options)
    replay = replay_trajectories(trajectories, scenario, options=options, params=params, smoothing_s=smoothing_s)
    return demonstrations_from_replay(replay, scenario, options, meta=meta)
