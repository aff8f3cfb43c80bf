"""Run a scenario to the end with a policy and measure it like the experiment (Kabalan et al. 2016, Eq. 22).

One function serves the bottleneck reproduction, the calibration and the benchmarks:
:func:`run_scenario` steps a :class:`~crowd_env.core.Simulator` until everyone has left (or a time
limit), detects passages of the measurement line within each step (interpolated crossing times),
records densities and mean speeds in the scenario's measurement areas and lateral positions inside
the channel, and tracks the minimum gap. It stops early when the crowd has *stalled*
(:class:`StallDetector`): nobody passes any more, and those left get nowhere.

Complete and incomplete runs. A run is *complete* when nobody remains: every pedestrian crossed the
measurement line or left (without a line: left), and, with a line, somebody crossed it: a run where people left
but nobody crossed the line (``missed_line``: a line off their path, or counting the other way) is not complete.
A line counts passages towards the side :meth:`~crowd_env.scenarios.Scenario.line_direction` gives (by default
towards the walkers' destination). Only a complete run reports a flow: ``flow_per_s`` and
``specific_flow_per_m_s`` (Eq. 22, Δt from the first to the last of all N passages) are nan otherwise,
and ``partial_flow_per_s`` / ``partial_specific_flow_per_m_s`` hold the figure of the passages that
happened (equal to the flow when complete). An incomplete run either *stalled* (``stalled``, with
``stall_time_s``) or reached ``max_time_s`` while still moving.
"""
from __future__ import annotations

from crowd_env.errors import InputError, NotFoundError

import os
import pickle
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from ...analysis.flow import MeasurementLine, specific_flow
from ...core.checks import check_integer, check_number
from ...walking.model import ModelParams
from ...core.polygons import pack_polygons
from ...walking.presets import DEFAULT_PRESET, get_preset
from ...scenarios.scenario import Measurement
from ...walking.agent import SocialForceAgent, compiled_agent
from crowd_env.files import read_signed, write_signed_atomic
from .rollout import (COUNT_FRAMES, COUNT_LATERAL, COUNT_PASSED, COUNT_STEPS, ROLLOUT_CHUNK_STEPS, ROLLOUT_PYTHON_STEP,
                      SCALAR_LAST_EXIT_S, SCALAR_MIN_GAP_M, STALL_LAST_PROGRESS_S, STALL_STALLED, STALL_TIME_S,
                      Measures, StallRule, measure_step, rollout_steps, stall_update)

# Stationary phase for densities: between the passages of these fractions of the pedestrians (the
# middle 60 %), see RunResult.density_window_s.
STATIONARY_PASSAGE_FRACTIONS = (0.2, 0.8)

# Stall rule (StallDetector). Measured on 630 Seyfried runs (b = 0.8-1.2 m, N = 20, 40, 60, seeds 0-9; presets
# calibrated, paper, recalibrated and calibrated with lambda = 0.1, A = 300 N, B = 0.03 m; recalibrated at b = 0.8-0.9 m
# also seeds 10-39): the longest time without a passage in a run that completes is 3.3 s (calibrated), 6.3 s (paper),
# 4.3 s (the lambda = 0.1 point); recalibrated clogs intermittently at b = 0.8 m and 3 of its 330 runs stall (the
# experiment never stood still for 20 s). The net displacement, not the speed: a crowd wedged for good at the Jülich
# corridor's 0.70 m exit shakes in place and got reported as neither stalled nor complete by a mean-speed rule.
# docs/validation/bottleneck.md, "Stalls and incomplete runs".
STALL_WINDOW_S = 20.0
STALL_SPEED_M_S = 0.05
STALL_SNAPSHOTS_PER_WINDOW = 20  # positions kept every window / 20 (1 s by default) for the net displacement

CHECKPOINT_EVERY_S = 600.0  # wall seconds between two checkpoints of a long run (RunCheckpoint)

# The most steps run_scenario takes on by default (its ``step_limit``): 1e5 s of simulated time at the paper's
# h = 0.01 s, far beyond any scenario here, but a run of 300 s at h = 1e-6 s (3e8 steps, hours to days) or
# 1e-9 s is refused at once with the count, instead of running for ever.
MAX_RUN_STEPS = 10_000_000
# Rows the per-step series (densities, speeds) and the stall rule's window start with; they grow (doubling)
# with the steps actually run, never to max_time_s / dt_s at once.
SERIES_START_ROWS = 4096


@dataclass
class RunCheckpoint:
    """Where :func:`run_scenario` keeps a long run so that a killed process can go on from there.

    Every ``every_s`` wall seconds (between two compiled chunks or Python steps) the whole run is pickled
    to ``path``, written atomically: the simulator (state, solver warm starts, clock), the policy, the
    measures so far, the stall detector and the recorder's frames. With ``resume``, a run that finds a
    checkpoint made with the same ``key`` (the caller's description of the run: scenario, seed,
    settings, version) goes on from it, and its result is the uninterrupted run's to the last bit
    (``tests/experiments/running/test_checkpoint.py``), its wall time the sum of both parts; a checkpoint with
    another key is ignored with a :class:`RuntimeWarning` and overwritten. The file is removed once the
    run is over (with ``remove_when_done``; else by the caller, e.g. once it has kept the run's result,
    :meth:`remove`). ``resumed_wall_s``: after the run, the wall time its kept part had taken (0 when it
    started afresh).

    The run is a pickle, which runs code when read, so the file is signed with this account's key
    (:func:`crowd_env.files.write_signed_atomic`) and :func:`read_checkpoint` unpickles it only when the
    signature matches: a checkpoint this account's crowd_env did not write (from a shared run folder, from
    before checkpoints were signed, or altered) raises :class:`~crowd_env.errors.UntrustedFileError`
    without being read."""

    path: str
    key: str
    every_s: float = CHECKPOINT_EVERY_S
    resume: bool = True
    remove_when_done: bool = True
    resumed_wall_s: float = field(default=0.0, init=False)

    def __post_init__(self):
        check_number("checkpoint every_s", self.every_s, error=InputError, minimum=0.0)

    def load(self):
        """The kept run (a dict), or None when there is none to resume."""
        if not self.resume or not os.path.exists(self.path):
            return None
        kept = read_checkpoint(self.path)
        if kept.get("key") != self.key:
            warnings.warn(f"checkpoint {self.path} was made for another run ({kept.get('key')!r}, not {self.key!r}): "
                          "starting afresh", RuntimeWarning, stacklevel=3)
            return None
        return kept

    def save(self, **run) -> None:
        os.makedirs(os.path.dirname(os.path.abspath(self.path)), exist_ok=True)
        write_signed_atomic(self.path, pickle.dumps({"key": self.key, **run}, protocol=pickle.HIGHEST_PROTOCOL))

    def remove(self) -> None:
        if os.path.exists(self.path):
            os.remove(self.path)


def read_checkpoint(path: str) -> dict:
    """The run a :class:`RunCheckpoint` kept at ``path`` (a dict: ``key``, ``sim``, ``policy``, ``measures``,
    ``stall``, ``done``, ``recorder``, ``wall_s``), unpickled only once its signature shows that this account's
    crowd_env wrote it (:func:`crowd_env.files.read_signed`: :class:`~crowd_env.errors.UntrustedFileError`
    otherwise, and nothing in it runs)."""
    payload = read_signed(path, "delete it to start that run afresh")
    return pickle.loads(payload)  # signed by this account's crowd_env: its own pickle


@dataclass
class RunResult:
    """Measured figures of one run (units in the names)."""

    n_pedestrians: int
    width_m: float | None
    seed: int | None
    n_steps: int
    simulated_time_s: float
    wall_time_s: float
    n_evacuated: int
    evacuation_time_s: float
    crossing_times_s: np.ndarray
    flow_per_s: float
    specific_flow_per_m_s: float
    min_gap_m: float
    density_per_m2: dict = field(default_factory=dict)  # area name -> (n_steps,) series
    speed_m_s: dict = field(default_factory=dict)  # area name -> (n_steps,) mean speed there (nan: empty)
    lateral_positions_m: np.ndarray = field(default_factory=lambda: np.zeros(0))
    n_fallback_solves: int = 0
    complete: bool = True  # nobody remains: each pedestrian crossed the line or left (and the line was crossed)
    stalled: bool = False  # stopped by the stall rule (StallDetector)
    stall_time_s: float = float("nan")  # when the stall was detected (the run stopped there)
    partial_flow_per_s: float = float("nan")  # Eq. 22 over the passages that happened (nan: < 2)
    partial_specific_flow_per_m_s: float = float("nan")
    missed_line: bool = False  # people left but nobody crossed the measurement line: not complete

    def __post_init__(self):
        if self.complete:  # a complete run's partial figures are its flows
            if not np.isfinite(self.partial_flow_per_s):
                self.partial_flow_per_s = self.flow_per_s
            if not np.isfinite(self.partial_specific_flow_per_m_s):
                self.partial_specific_flow_per_m_s = self.specific_flow_per_m_s

    @property
    def n_passed(self) -> int:
        """Passages of the measurement line (each pedestrian's first)."""
        return int(self.crossing_times_s.size)

    def density_window_s(self, window: str = "stationary", fractions=STATIONARY_PASSAGE_FRACTIONS) -> tuple:
        """(t_start, t_end) of a density window, from the passage times of the measurement line.

        ``"passages"``: first to last passage (the whole Δt of Eq. 22, filling and draining included).
        ``"stationary"``: from the passage of the ``fractions[0]``-th to the ``fractions[1]``-th part of
        the pedestrians who passed (default the middle 60 %): the jam has formed and is still fed,
        which is the phase whose density Seyfried et al. (2009) report ("fluctuates between 4 and 6
        /m²" in the jam). The draining tail, when the crowd in front of the entrance thins to a few
        people, is excluded. (nan, nan) with fewer than two passages.
        """
        times = np.sort(self.crossing_times_s)
        if times.size < 2:
            return float("nan"), float("nan")
        if window == "passages":
            return float(times[0]), float(times[-1])
        if window != "stationary":
            raise InputError(f"window must be 'stationary' or 'passages', got {window!r}")
        k0, k1 = self._stationary_passages(fractions)
        return float(times[k0]), float(times[k1])

    def _stationary_passages(self, fractions) -> tuple:
        """Ranks (k0, k1) in the sorted passage times of the stationary window's ends (≥ 2 passages)."""
        lo, hi = (float(f) for f in fractions)
        if not 0.0 <= lo < hi <= 1.0:
            raise InputError(f"fractions must satisfy 0 <= lo < hi <= 1, got {fractions!r}")
        n = self.crossing_times_s.size
        k0 = int(round(lo * (n - 1)))
        return k0, max(int(round(hi * (n - 1))), k0 + 1)

    def stationary_specific_flow_per_m_s(self, fractions=STATIONARY_PASSAGE_FRACTIONS) -> float:
        """Passage rate per metre of width over the stationary window of :meth:`density_window_s`:
        (k1 − k0) / ((t_k1 − t_k0) b) between the passages that bound it. Unlike Eq. 22's J_s (first to
        last passage) it leaves out the build-up and the draining tail. In a stationary channel it
        equals ρ_inside · v_inside (continuity), the two means of :meth:`mean_density_per_m2` and
        :meth:`mean_speed_m_s`. nan with fewer than two passages or no width."""
        if self.crossing_times_s.size < 2 or not self.width_m:
            return float("nan")
        times = np.sort(self.crossing_times_s)
        k0, k1 = self._stationary_passages(fractions)
        return float((k1 - k0) / ((times[k1] - times[k0]) * self.width_m))

    def mean_density_per_m2(self, name: str, window: str = "stationary",
                            fractions=STATIONARY_PASSAGE_FRACTIONS) -> float:
        """Mean density in an area over :meth:`density_window_s` (default: the stationary phase)."""
        return self._window_mean(self.density_per_m2[name], window, fractions)

    def mean_speed_m_s(self, name: str, window: str = "stationary", fractions=STATIONARY_PASSAGE_FRACTIONS) -> float:
        """Mean speed ‖u‖ of the pedestrians in an area over :meth:`density_window_s`: the per-step mean
        over the pedestrians there (Seyfried et al. 2009's "speed inside"), averaged over the steps
        in the window at which the area holds someone."""
        return self._window_mean(self.speed_m_s[name], window, fractions)

    def _window_mean(self, series, window, fractions) -> float:
        t0, t1 = self.density_window_s(window, fractions)
        if not np.isfinite(t0):
            return float("nan")
        dt = self.simulated_time_s / max(self.n_steps, 1)
        t = (np.arange(series.shape[0]) + 1) * dt
        values = series[(t >= t0) & (t <= t1)]
        values = values[np.isfinite(values)]
        return float(values.mean()) if values.size else float("nan")


class StallDetector:
    """The stall rule: a crowd that no longer passes and no longer gets anywhere.

    At the end of every step, the run is *stalled* when

    1. pedestrians remain: active, started (past their premovement time: a crowd still waiting is no
       stall) and, with a measurement line, not yet across it;
    2. nobody has crossed the line or left during the last ``window_s`` seconds (the window runs from
       the last passage or exit, or from the start); and
    3. the remaining pedestrians' mean *net* displacement over the last window (from the newest position
       snapshot at least ``window_s`` old; a snapshot every ``window_s`` / :data:`STALL_SNAPSHOTS_PER_WINDOW`)
       is below ``speed_m_s`` times the window: their mean net speed is below ``speed_m_s``.

    Defaults :data:`STALL_WINDOW_S` = 20 s and :data:`STALL_SPEED_M_S` = 0.05 m/s (measurements beside
    them). The net displacement separates a crowd that gets somewhere, however slowly, from one that only
    jitters in place: a wedged crowd whose members shake at several centimetres per second, back and forth,
    is stalled all the same (the mean of instantaneous speeds, the rule before, never fired on the Jülich
    corridor's 0.70 m exit clogged for good). ``window_s`` None switches the rule off. The snapshots are
    allocated for ``n_pedestrians`` (None: at the first :meth:`update`).
    """

    def __init__(self, dt_s: float, window_s: float | None = STALL_WINDOW_S, speed_m_s: float = STALL_SPEED_M_S,
                 start_s: float = 0.0, n_pedestrians: int | None = None):
        self.window_s = None if window_s is None else check_number("stall window_s", window_s, error=InputError,
                                                                   positive=True, suffix=" or None")
        self.speed_m_s = check_number("stall speed_m_s", speed_m_s, error=InputError, minimum=0.0)
        self.dt_s = float(dt_s)
        self.window_steps = 0 if window_s is None else max(1, int(round(self.window_s / self.dt_s)))
        self.snapshot_every = max(1, self.window_steps // STALL_SNAPSHOTS_PER_WINDOW)
        self.state = np.zeros(5)  # the STALL_* slots of crowd_env.experiments.running.rollout
        self.state[STALL_LAST_PROGRESS_S] = float(start_s)
        self.state[STALL_TIME_S] = np.nan
        self.snapshots = self.snapshot_time_s = None
        if n_pedestrians is not None:
            self._allocate(int(n_pedestrians))

    def _allocate(self, n: int) -> None:
        """Room for the snapshots of ``n`` pedestrians over a window and two snapshots more (none when off)."""
        slots = self.window_steps // self.snapshot_every + 2 if self.window_steps else 1
        self.snapshots = np.zeros((slots, n, 2))
        self.snapshot_time_s = np.full(slots, np.nan)

    @property
    def stalled(self) -> bool:
        return bool(self.state[STALL_STALLED])

    @property
    def stall_time_s(self) -> float:
        """When the stall was detected (nan: not stalled)."""
        return float(self.state[STALL_TIME_S])

    @property
    def last_progress_s(self) -> float:
        """The time of the last passage or exit (or the start)."""
        return float(self.state[STALL_LAST_PROGRESS_S])

    def bundle(self) -> StallRule:
        """The rule as :func:`~crowd_env.experiments.running.rollout.stall_update` takes it (its snapshots and state,
        not copies; window_s inf when off)."""
        if self.snapshots is None:
            raise InputError("StallDetector: the number of pedestrians is not known yet (pass n_pedestrians)")
        return StallRule(self.snapshots, self.snapshot_time_s, self.state, self.window_steps, self.snapshot_every,
                         np.inf if self.window_s is None else self.window_s, self.speed_m_s)

    def update(self, time_s: float, position, remaining, progressed: bool) -> bool:
        """Record one step: ``position`` (N, 2) the positions after it, ``remaining`` (N,) bool flags the
        pedestrians left, ``progressed`` says whether someone crossed the line or left during it. Returns True
        when the run is stalled (from then on)."""
        position = np.ascontiguousarray(position, dtype=np.float64)
        if self.snapshots is None:
            self._allocate(position.shape[0])
        return stall_update(self.bundle(), self.dt_s, float(time_s), position, np.asarray(remaining, dtype=bool),
                            bool(progressed))


class _RunMeasures:
    """The arrays :func:`~crowd_env.experiments.running.rollout.measure_step` fills during one run (both paths)."""

    def __init__(self, scenario, n: int, n_steps_max: int, line, density_areas, lane_area, min_gap_m: float,
                 record_every: int):
        geometry = scenario.geometry
        self.has_line = line is not None
        self.line = (np.zeros(2), np.zeros(2), np.zeros(2))
        if line is not None:
            if line not in geometry.measurement_lines:
                raise NotFoundError(f"scenario has no measurement line {line!r}; it has "
                                    f"{sorted(geometry.measurement_lines)}")
            ends = np.asarray(geometry.measurement_lines[line], dtype=float)
            m = MeasurementLine(ends[0], ends[1], scenario.line_direction(line))  # counted towards the destination
            self.line = (m.start_m, m.segment_m, m.normal)
        self.area_names = [name for name in density_areas if name in geometry.measurement_areas]
        polys = [geometry.measurement_areas[name] for name in self.area_names]
        self.lane_area = -1
        lane_poly = geometry.measurement_areas.get(lane_area) if lane_area else None
        if lane_poly is not None:
            if lane_area in self.area_names:
                self.lane_area = self.area_names.index(lane_area)
            else:
                self.lane_area = len(polys)
                polys.append(lane_poly)
        self.areas = pack_polygons(polys).arrays
        self.area_size_m2 = np.array([float(geometry.measurement_areas[name].area) for name in self.area_names])
        self.passed = np.zeros(n, dtype=bool)
        self.cross_ids = np.zeros(n, np.int64)
        self.cross_times = np.zeros(n)
        rows = min(int(n_steps_max), SERIES_START_ROWS)  # grown by room_for with the steps run
        self.density = np.zeros((rows, len(self.area_names)))
        self.speed = np.zeros((rows, len(self.area_names)))
        self.n = n
        self.lateral_chunks = []
        self.lateral = np.zeros(0)
        self.record_every = int(record_every)
        self.counts = np.zeros(4, np.int64)
        self.scalars = np.array([min_gap_m, 0.0])
        self.frame_time_s = np.zeros(0)
        self.frame_position = np.zeros((0, n, 2))
        self.frame_heading = np.zeros((0, n))
        self.frame_active = np.zeros((0, n), dtype=bool)

    def room_for(self, steps: int) -> None:
        """Room in the per-step series, the lateral and the frame buffers for ``steps`` more steps (keeps what
        they hold)."""
        rows = int(self.counts[COUNT_STEPS]) + steps
        if rows > self.density.shape[0]:
            grown = max(rows, 2 * self.density.shape[0])
            self.density = np.concatenate([self.density, np.zeros((grown - self.density.shape[0], self.density.shape[1]))])
            self.speed = np.concatenate([self.speed, np.zeros((grown - self.speed.shape[0], self.speed.shape[1]))])
        need = self.counts[COUNT_LATERAL] + steps * self.n
        if need > self.lateral.shape[0]:
            self.lateral_chunks.append(self.lateral[:self.counts[COUNT_LATERAL]].copy())
            self.lateral = np.zeros(max(need - self.counts[COUNT_LATERAL], 1024))
            self.counts[COUNT_LATERAL] = 0
        self.frames_for(steps)

    def frames_for(self, steps: int) -> None:
        """Frame buffers with room for ``steps`` steps, emptied (the caller has passed the previous frames on);
        they grow when a longer chunk needs more room and are reused otherwise."""
        f = steps // self.record_every + 1 if self.record_every > 0 else 0
        if f > self.frame_time_s.shape[0]:
            self.frame_time_s = np.zeros(f)
            self.frame_position = np.zeros((f, self.n, 2))
            self.frame_heading = np.zeros((f, self.n))
            self.frame_active = np.zeros((f, self.n), dtype=bool)
        self.counts[COUNT_FRAMES] = 0

    def pass_frames(self, recorder) -> None:
        """Hand the frames recorded since :meth:`frames_for` to ``recorder``."""
        if recorder is None:
            return
        ids = np.arange(self.n)
        for f in range(self.counts[COUNT_FRAMES]):
            recorder.record(float(self.frame_time_s[f]), self.frame_position[f], self.frame_heading[f],
                            self.frame_active[f], ids)
        self.counts[COUNT_FRAMES] = 0

    def bundle(self) -> Measures:
        """The arrays as :func:`~crowd_env.experiments.running.rollout.measure_step` fills them (not copies: rebuild
        after :meth:`room_for`)."""
        return Measures(self.line, self.has_line, self.passed, self.cross_ids, self.cross_times, self.areas,
                        self.area_size_m2, self.lane_area, self.density, self.speed, self.lateral, self.record_every,
                        self.frame_time_s, self.frame_position, self.frame_heading, self.frame_active, self.counts,
                        self.scalars)

    def lateral_positions(self) -> np.ndarray:
        return np.concatenate([*self.lateral_chunks, self.lateral[:self.counts[COUNT_LATERAL]]])


def _compiled_agent(policy, sim, compiled: bool):
    """The policy as a :class:`~crowd_env.walking.agent.CompiledAgent` when the run may be rolled out in compiled
    code, else None."""
    if not compiled or sim.exit_polygons is None or not isinstance(policy, SocialForceAgent):
        return None
    nav = policy.compiled(sim.state.n)
    return None if nav is None else compiled_agent(nav, sim.params)


class _FromScenario:
    """The default of :func:`run_scenario`'s ``line``, ``density_areas`` and ``lane_area``: the scenario's own
    (:attr:`Scenario.measurement <crowd_env.scenarios.Scenario.measurement>`)."""

    def __repr__(self) -> str:
        return "FROM_SCENARIO"


FROM_SCENARIO = _FromScenario()


def run_scenario(scenario, policy, params: ModelParams | None = None, *, max_time_s: float = 300.0,
                 line=FROM_SCENARIO, density_areas=FROM_SCENARIO, lane_area=FROM_SCENARIO,
                 width_m: float | None = None, state=None, rng=None, progress=None,
                 stall_window_s: float | None = STALL_WINDOW_S, stall_speed_m_s: float = STALL_SPEED_M_S,
                 compiled: bool = True, recorder=None, record_every: int = 1,
                 chunk_steps: int = ROLLOUT_CHUNK_STEPS, checkpoint: RunCheckpoint | None = None,
                 step_limit: int = MAX_RUN_STEPS) -> RunResult:
    """Simulate ``scenario`` driven by ``policy(sim) -> (intents, desired_heading)`` until all leave, the
    time limit ``max_time_s``, or a stall.

    ``line``, ``density_areas``, ``lane_area``: what to measure (the measurement line's passages, the densities
    and speeds in the areas, the lateral positions in the lane area; None / ``()``: nothing); by default the
    scenario's own (:class:`~crowd_env.scenarios.scenario.Measurement`: the Seyfried bottleneck's line
    "bottleneck" and areas "front" and "inside", the Jülich corridor's "exit" and "measurement", ...).
    ``width_m``: the bottleneck width used in J_s = N/(Δt b) (Eq. 22); defaults to the scenario's
    ``metadata['width_m']``. ``stall_window_s`` / ``stall_speed_m_s``: the stall rule of
    :class:`StallDetector` (None switches it off); a stalled run stops at once with ``stalled`` set. A periodic
    scenario (``sim.period_m`` > 0: no exits, nobody leaves) runs without the rule to ``max_time_s``: a crowd
    standing still there is a point of the fundamental diagram (speed 0), not a failed run.
    ``compiled``: when ``policy`` is the calibrated agent (:class:`~crowd_env.walking.agent.SocialForceAgent`
    with a compiled navigation), run the steps in compiled chunks of up to ``chunk_steps``
    (:mod:`crowd_env.experiments.running.rollout`; the same result to the last bit as ``compiled=False``, which
    runs every step from Python). ``recorder``: a
    :class:`~crowd_env.analysis.recorder.TrajectoryRecorder` that gets the state every ``record_every``-th
    step (at t = step · h). ``progress(sim)`` is called after every step run from Python and after every
    compiled chunk. ``checkpoint``: a :class:`RunCheckpoint` that keeps the run every so often and resumes
    a kept one (then ``state`` and ``recorder`` are brought to the kept run's, in place). ``step_limit``:
    a run whose ``max_time_s`` / ``dt_s`` exceeds it is refused at once (:data:`MAX_RUN_STEPS`); the
    buffers grow with the steps run. Returns a :class:`RunResult`; its flows are nan unless the run is
    complete (module docstring).
    """
    params = get_preset(DEFAULT_PRESET).params() if params is None else params
    line, density_areas, lane_area = measured(scenario, line, density_areas, lane_area)
    record_every = check_integer("record_every", record_every, error=InputError, minimum=1)
    chunk_steps = check_integer("chunk_steps", chunk_steps, error=InputError, minimum=1)
    max_time_s = check_number("max_time_s", max_time_s, error=InputError, positive=True)
    check_step_limit(max_time_s, params.dt_s, step_limit)
    state = scenario.make_state(rng=rng) if state is None else state
    sim = scenario.make_simulator(state, params)  # with the scenario's destinations, if any
    width_m = scenario.metadata.get("width_m") if width_m is None else width_m
    n_steps_max = int(round(max_time_s / params.dt_s))
    measures = _RunMeasures(scenario, state.n, n_steps_max, line, density_areas, lane_area, sim.min_gap_m(),
                            record_every if recorder is not None else 0)
    stall = StallDetector(params.dt_s, None if sim.period_m > 0.0 else stall_window_s, stall_speed_m_s,
                          start_s=sim.time_s, n_pedestrians=state.n)
    done, wall_before_s = 0, 0.0
    kept = checkpoint.load() if checkpoint is not None else None
    if kept is not None:  # go on from the kept run: the caller's state and recorder become its own
        sim, policy, measures, stall, done, wall_before_s = (kept[k] for k in ("sim", "policy", "measures", "stall",
                                                                              "done", "wall_s"))
        checkpoint.resumed_wall_s = wall_before_s
        state.__dict__.update(sim.state.__dict__)
        sim.state = state
        if recorder is not None:
            recorder.__dict__.update(kept["recorder"].__dict__)
    agent = _compiled_agent(policy, sim, compiled)
    t_wall = time.perf_counter()
    t_saved = t_wall
    while done < n_steps_max and state.active.any() and not stall.stalled:
        if checkpoint is not None and time.perf_counter() - t_saved >= checkpoint.every_s:
            checkpoint.save(sim=sim, policy=policy, measures=measures, stall=stall, done=done, recorder=recorder,
                            wall_s=wall_before_s + time.perf_counter() - t_wall)
            t_saved = time.perf_counter()
        python_step = True
        if agent is not None and sim.fused_ready():
            k, python_step = _compiled_chunk(sim, agent, measures, stall, min(chunk_steps, n_steps_max - done))
            done += k
            measures.pass_frames(recorder)
            if progress is not None and k:
                progress(sim)
        if not python_step:
            continue
        _python_step(sim, policy, measures, stall)
        done += 1
        measures.pass_frames(recorder)
        if progress is not None:
            progress(sim)
    if checkpoint is not None and checkpoint.remove_when_done:
        checkpoint.remove()
    return _run_result(scenario, sim, measures, stall, width_m, wall_before_s + time.perf_counter() - t_wall)


def measured(scenario, line=FROM_SCENARIO, density_areas=FROM_SCENARIO, lane_area=FROM_SCENARIO) -> tuple:
    """``(line, density_areas, lane_area)``: each as given, or the scenario's own where it is :data:`FROM_SCENARIO`
    (:attr:`Scenario.measurement <crowd_env.scenarios.Scenario.measurement>`; nothing for an object without one)."""
    own = getattr(scenario, "measurement", None) or Measurement()
    return (own.line if line is FROM_SCENARIO else line,
            own.density_areas if density_areas is FROM_SCENARIO else density_areas,
            own.lane_area if lane_area is FROM_SCENARIO else lane_area)


def check_step_limit(max_time_s: float, dt_s: float, step_limit=MAX_RUN_STEPS) -> None:
    """Refuse a run of more than ``step_limit`` steps (:data:`MAX_RUN_STEPS` by default) at once, with
    :class:`~crowd_env.errors.InputError` (:func:`run_scenario` does; a command checks its runs with it before it
    starts them)."""
    step_limit = check_integer("step_limit", step_limit, error=InputError, minimum=1)
    if round(max_time_s / dt_s) > step_limit:
        raise InputError(f"max_time_s = {max_time_s:g} s at dt_s = {dt_s:g} s needs up to "
                         f"{round(max_time_s / dt_s):,} steps, more than step_limit = {step_limit:,} "
                         f"(default crowd_env.experiments.running.runner.MAX_RUN_STEPS); shorten max_time_s, take a larger "
                         f"dt_s (the paper's 0.01 s), or pass a larger step_limit")


def _compiled_chunk(sim, agent, measures: _RunMeasures, stall: StallDetector, steps: int) -> tuple:
    """Up to ``steps`` steps in one compiled call (:func:`~crowd_env.experiments.running.rollout.rollout_steps`), accounted
    to ``sim``: ``(steps done, whether the next step needs the Python path)``."""
    measures.room_for(steps)
    status, k, clock, rounds = rollout_steps(steps, sim.time_s, sim.step_count, sim.state.array_fields(),
                                             tuple(sim.world), tuple(sim.step_params), agent, measures.bundle(),
                                             stall.bundle())
    sim.advanced(k, clock, rounds)
    return k, status == ROLLOUT_PYTHON_STEP


def _python_step(sim, policy, measures: _RunMeasures, stall: StallDetector) -> None:
    """One step from Python (``policy(sim)``, :meth:`~crowd_env.core.Simulator.step`), measured by the same
    :func:`~crowd_env.experiments.running.rollout.measure_step` as a compiled one."""
    measures.room_for(1)
    idx = sim.active_index
    previous = sim.state.position_m[idx]
    intents, heading = policy(sim)
    t_prev = sim.time_s
    result = sim.step(intents, desired_heading_rad=heading)
    measure_step(sim.state.arrays(), idx, previous, result.exited.shape[0], t_prev, sim.time_s, sim.step_count,
                 result.min_gap_m, sim.step_params.dt_s, sim.world.period_m, measures.bundle(), stall.bundle())


def _run_result(scenario, sim, measures: _RunMeasures, stall: StallDetector, width_m, wall_s: float) -> RunResult:
    """The :class:`RunResult` of a finished run (flows only when complete: module docstring)."""
    state = sim.state
    n_cross = int(measures.counts[COUNT_PASSED])
    times = np.sort(measures.cross_times[:n_cross])
    if times.size >= 2 and width_m:
        flow = specific_flow(times, width_m)
        j, js = flow.flow_per_s, flow.specific_flow_per_m_s
    else:
        j = js = float("nan")
    n_left = int(np.count_nonzero(~state.active))
    missed = bool(measures.has_line and n_left and not n_cross)  # the line is not where (or not how) they walk
    complete = not (state.active & ~measures.passed).any() and not missed  # nobody left who has not passed
    n_measured = int(measures.counts[COUNT_STEPS])
    return RunResult(
        n_pedestrians=state.n, width_m=width_m, seed=scenario.seed, n_steps=sim.step_count,
        simulated_time_s=sim.time_s, wall_time_s=wall_s, n_evacuated=n_left,
        evacuation_time_s=float(measures.scalars[SCALAR_LAST_EXIT_S]) if n_left == state.n else float("nan"),
        crossing_times_s=times, flow_per_s=j if complete else float("nan"),
        specific_flow_per_m_s=js if complete else float("nan"), min_gap_m=float(measures.scalars[SCALAR_MIN_GAP_M]),
        density_per_m2={k: measures.density[:n_measured, a].copy() for a, k in enumerate(measures.area_names)},
        speed_m_s={k: measures.speed[:n_measured, a].copy() for a, k in enumerate(measures.area_names)},
        lateral_positions_m=measures.lateral_positions(),
        n_fallback_solves=sim.n_fallback_solves, complete=bool(complete), stalled=stall.stalled,
        stall_time_s=stall.stall_time_s, partial_flow_per_s=j, partial_specific_flow_per_m_s=js, missed_line=missed,
    )
