"""Run a scenario to the end with a policy and measure it like the experiment (Kabalan et al. 2016, Eq. 22).

One function serves the bottleneck reproduction, the calibration and the benchmarks:
:func:`run_scenario` steps a :class:`~crowd_env.core.Simulator` until everyone has left (or a time
limit), detects passages of the measurement line within each step (interpolated crossing times),
records densities and mean speeds in the scenario's measurement areas and lateral positions inside
the channel, and tracks the minimum gap. It stops early when the crowd has *stalled*
(:class:`StallDetector`): nobody passes any more, and those left stand still.

Complete and incomplete runs. A run is *complete* when nobody remains: every pedestrian crossed the
measurement line or left (without a line: left). Only a complete run reports a flow: ``flow_per_s`` and
``specific_flow_per_m_s`` (Eq. 22, Δt from the first to the last of all N passages) are nan otherwise,
and ``partial_flow_per_s`` / ``partial_specific_flow_per_m_s`` hold the figure of the passages that
happened (equal to the flow when complete). An incomplete run either *stalled* (``stalled``, with
``stall_time_s``) or reached ``max_time_s`` while still moving.
"""
from __future__ import annotations

from crowd_env.errors import InputError, NotFoundError

import time
from dataclasses import dataclass, field

import numba as nb
import numpy as np
import shapely

from ..analysis.flow import MeasurementLine, PassageCounter, specific_flow
from ..core.params import ModelParams
from ..core.presets import DEFAULT_PRESET, get_preset

# Stationary phase for densities: between the passages of these fractions of the pedestrians (the
# middle 60 %), see RunResult.density_window_s.
STATIONARY_PASSAGE_FRACTIONS = (0.2, 0.8)

# Stall rule (StallDetector). Measured on 630 Seyfried runs that all complete (b = 0.8-1.2 m, N = 20, 40,
# 60, seeds 0-9; presets paper and recalibrated, and lambda = 0.1, A = 300 N, B = 0.03 m; recalibrated at
# b = 0.8-0.9 m also seeds 10-39): with paper and the lambda = 0.1 point the longest time without a
# passage is 6.3 s, and during pauses over 5 s the pedestrians not yet passed still move at 0.12-0.57 m/s
# on average; the calibrated preset (150 runs, b = 0.8-1.2 m, N = 20/40/60, seeds 0-9): 3.3 s. A crowd that clogs for good stands at 0-5 mm/s (paper, b = 1.0 m, N = 180, seed 0: 158 of
# 180 at 4 mm/s after 22 passages; a pair beside the entrance at A = 752.5 N, B = 0.2 m: 0 m/s). The
# recalibrated preset clogs intermittently at b = 0.8 m (86 pauses over 5 s in 330 runs, at 3 mm/s to
# 0.3 m/s); 3 of them lasted 27, 29 and 133 s at 1-3 cm/s before the arch broke, and this rule reports
# those three as stalled (the experiment never stood still for 20 s). See README, "Stalls".
STALL_WINDOW_S = 20.0
STALL_SPEED_M_S = 0.05


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
    complete: bool = True  # nobody remains: each pedestrian crossed the line or left
    stalled: bool = False  # stopped by the stall rule (StallDetector)
    stall_time_s: float = float("nan")  # when the stall was detected (the run stopped there)
    partial_flow_per_s: float = float("nan")  # Eq. 22 over the passages that happened (nan: < 2)
    partial_specific_flow_per_m_s: float = float("nan")

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


@nb.njit(cache=True)
def _mean_speed(velocity, active, inside):
    """Mean ‖u‖ of the active pedestrians flagged by ``inside`` (one flag per active pedestrian, in
    index order); nan when none is."""
    total = 0.0
    count = 0
    k = 0
    for i in range(active.shape[0]):
        if active[i]:
            if inside[k]:
                total += np.sqrt(velocity[i, 0] ** 2 + velocity[i, 1] ** 2)
                count += 1
            k += 1
    return total / count if count else np.nan


@nb.njit(cache=True)
def _mean_speed_of(velocity, mask):
    """Mean ‖u‖ over the pedestrians flagged in ``mask`` (N,); nan when none is."""
    total = 0.0
    count = 0
    for i in range(mask.shape[0]):
        if mask[i]:
            total += np.sqrt(velocity[i, 0] ** 2 + velocity[i, 1] ** 2)
            count += 1
    return total / count if count else np.nan


class StallDetector:
    """The stall rule: a crowd that no longer passes and stands still.

    At the end of every step, the run is *stalled* when

    1. pedestrians remain: active and, with a measurement line, not yet across it;
    2. nobody has crossed the line or left during the last ``window_s`` seconds (the window runs from
       the last passage or exit, or from the start); and
    3. the mean speed ‖u‖ of the remaining pedestrians, averaged over the steps of that window, is below
       ``speed_m_s``.

    Defaults :data:`STALL_WINDOW_S` = 20 s and :data:`STALL_SPEED_M_S` = 0.05 m/s (measurements beside
    them): 3x the longest pause of runs that keep moving, and 10x the speed of a crowd clogged for good.
    The averaged speed separates a standstill from a slow crowd: pedestrians who still move, even a few
    centimetres per second, keep the mean above the threshold. ``window_s`` None switches the rule off.
    """

    def __init__(self, dt_s: float, window_s: float | None = STALL_WINDOW_S, speed_m_s: float = STALL_SPEED_M_S,
                 start_s: float = 0.0):
        if window_s is not None and not (np.isfinite(window_s) and window_s > 0):
            raise InputError(f"stall window must be a positive number of seconds or None, got {window_s!r}")
        if not (np.isfinite(speed_m_s) and speed_m_s >= 0):
            raise InputError(f"stall speed must be a finite number >= 0, got {speed_m_s!r}")
        self.window_s = None if window_s is None else float(window_s)
        self.speed_m_s = float(speed_m_s)
        self.dt_s = float(dt_s)
        self._k = 0 if window_s is None else max(1, int(round(self.window_s / self.dt_s)))
        self._speeds = np.zeros(self._k)
        self._n = 0  # steps recorded since the last progress (capped by the window)
        self._sum = 0.0
        self.last_progress_s = float(start_s)
        self.stalled = False
        self.stall_time_s = float("nan")

    def update(self, time_s: float, velocity, remaining, progressed: bool) -> bool:
        """Record one step: ``remaining`` (N,) bool flags the pedestrians left, ``progressed`` says whether
        someone crossed the line or left during it. Returns True when the run is stalled (from then on)."""
        if self.stalled or self.window_s is None:
            return self.stalled
        if progressed or not remaining.any():
            self.last_progress_s = float(time_s)
            self._n, self._sum = 0, 0.0
            return False
        v = _mean_speed_of(velocity, remaining)
        slot = self._n % self._k
        if self._n >= self._k:
            self._sum -= self._speeds[slot]
        self._speeds[slot] = v
        self._sum += v
        self._n += 1
        if self._n >= self._k and time_s - self.last_progress_s >= self.window_s - 0.5 * self.dt_s \
                and self._sum / self._k < self.speed_m_s:
            self.stalled = True
            self.stall_time_s = float(time_s)
        return self.stalled


def run_scenario(scenario, policy, params: ModelParams | None = None, *, max_time_s: float = 300.0,
                 line: str = "bottleneck", density_areas=("front", "inside"), lane_area: str | None = "inside",
                 width_m: float | None = None, state=None, rng=None, progress=None,
                 stall_window_s: float | None = STALL_WINDOW_S, stall_speed_m_s: float = STALL_SPEED_M_S) -> RunResult:
    """Simulate ``scenario`` driven by ``policy(sim) -> (intents, desired_heading)`` until all leave, the
    time limit ``max_time_s``, or a stall.

    ``width_m``: the bottleneck width used in J_s = N/(Δt b) (Eq. 22); defaults to the scenario's
    ``metadata['width_m']``. ``stall_window_s`` / ``stall_speed_m_s``: the stall rule of
    :class:`StallDetector` (None switches it off); a stalled run stops at once with ``stalled`` set.
    Returns a :class:`RunResult`; its flows are nan unless the run is complete (module docstring).
    """
    params = get_preset(DEFAULT_PRESET).params() if params is None else params
    state = scenario.make_state(rng=rng) if state is None else state
    sim = scenario.make_simulator(state, params)  # with the scenario's destinations, if any
    geometry = scenario.geometry
    width_m = scenario.metadata.get("width_m") if width_m is None else width_m
    counter = None
    if line is not None:
        if line not in geometry.measurement_lines:
            raise NotFoundError(f"scenario has no measurement line {line!r}; it has {sorted(geometry.measurement_lines)}")
        ends = np.asarray(geometry.measurement_lines[line], dtype=float)
        counter = PassageCounter(MeasurementLine(ends[0], ends[1]))
    areas = {name: geometry.measurement_areas[name] for name in density_areas if name in geometry.measurement_areas}
    area_size = {name: float(poly.area) for name, poly in areas.items()}
    density = {name: [] for name in areas}
    speed = {name: [] for name in areas}
    lane_poly = geometry.measurement_areas.get(lane_area) if lane_area else None
    lateral = []
    n_steps_max = int(round(max_time_s / params.dt_s))
    min_gap = sim.min_gap_m()
    t_wall = time.perf_counter()
    last_exit_time = 0.0
    ids = np.arange(state.n)
    stall = StallDetector(params.dt_s, stall_window_s, stall_speed_m_s, start_s=sim.time_s)
    passed = np.zeros(state.n, dtype=bool)
    for _ in range(n_steps_max):
        if not state.active.any():
            break
        intents, heading = policy(sim)
        prev = state.position_m.copy()
        t_prev = sim.time_s
        result = sim.step(intents, desired_heading_rad=heading)
        progressed = result.exited.size > 0
        if progressed:
            last_exit_time = sim.time_s
        if counter is not None:
            new = counter.update(prev, state.position_m, t_prev, sim.time_s, ids)
            if new:
                passed[counter.ids[-new:]] = True
                progressed = True
        pos = state.position_m[state.active]
        masks = {}
        for name, poly in areas.items():
            masks[name] = shapely.contains_xy(poly, pos[:, 0], pos[:, 1])
            density[name].append(np.count_nonzero(masks[name]) / area_size[name])
            speed[name].append(_mean_speed(state.velocity_m_s, state.active, masks[name]))
        if lane_poly is not None:
            inside = masks[lane_area] if lane_area in masks else shapely.contains_xy(lane_poly, pos[:, 0], pos[:, 1])
            lateral.append(pos[inside, 1])
        min_gap = min(min_gap, result.min_gap_m)  # pairs farther apart than the candidates cannot overlap
        if progress is not None:
            progress(sim)
        if stall.update(sim.time_s, state.velocity_m_s, state.active & ~passed, progressed):
            break
    times = np.sort(np.asarray(counter.times_s if counter is not None else [], dtype=float))
    n_passed = times.size
    if n_passed >= 2 and width_m:
        flow = specific_flow(times, width_m)
        j, js = flow.flow_per_s, flow.specific_flow_per_m_s
    else:
        j = js = float("nan")
    n_left = int(np.count_nonzero(~state.active))
    complete = not (state.active & ~passed).any()  # nobody left who has not passed
    return RunResult(
        n_pedestrians=state.n, width_m=width_m, seed=scenario.seed, n_steps=sim.step_count,
        simulated_time_s=sim.time_s, wall_time_s=time.perf_counter() - t_wall, n_evacuated=n_left,
        evacuation_time_s=last_exit_time if n_left == state.n else float("nan"),
        crossing_times_s=times, flow_per_s=j if complete else float("nan"),
        specific_flow_per_m_s=js if complete else float("nan"), min_gap_m=float(min_gap),
        density_per_m2={k: np.asarray(v) for k, v in density.items()},
        speed_m_s={k: np.asarray(v, dtype=float) for k, v in speed.items()},
        lateral_positions_m=np.concatenate(lateral) if lateral else np.zeros(0),
        n_fallback_solves=sim.n_fallback_solves, complete=bool(complete), stalled=stall.stalled,
        stall_time_s=stall.stall_time_s, partial_flow_per_s=j, partial_specific_flow_per_m_s=js,
    )
