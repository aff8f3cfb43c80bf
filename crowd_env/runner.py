"""Run a scenario to the end with a policy and measure it like the experiment (no RL here).

One function serves the bottleneck reproduction, the calibration and the benchmarks:
:func:`run_scenario` steps a :class:`~crowd_env.core.Simulator` until everyone has left (or a time
limit), detects passages of the measurement line within each step (interpolated crossing times),
records densities and mean speeds in the scenario's measurement areas and lateral positions inside
the channel, and tracks the minimum gap.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numba as nb
import numpy as np
import shapely

from .analysis.flow import MeasurementLine, PassageCounter, specific_flow
from .core.params import ModelParams

# Stationary phase for densities: between the passages of these fractions of the pedestrians (the
# middle 60 %), see RunResult.density_window_s.
STATIONARY_PASSAGE_FRACTIONS = (0.2, 0.8)


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
            raise ValueError(f"window must be 'stationary' or 'passages', got {window!r}")
        k0, k1 = self._stationary_passages(fractions)
        return float(times[k0]), float(times[k1])

    def _stationary_passages(self, fractions) -> tuple:
        """Ranks (k0, k1) in the sorted passage times of the stationary window's ends (≥ 2 passages)."""
        lo, hi = (float(f) for f in fractions)
        if not 0.0 <= lo < hi <= 1.0:
            raise ValueError(f"fractions must satisfy 0 <= lo < hi <= 1, got {fractions!r}")
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


def run_scenario(scenario, policy, params: ModelParams | None = None, *, max_time_s: float = 300.0,
                 line: str = "bottleneck", density_areas=("front", "inside"), lane_area: str | None = "inside",
                 width_m: float | None = None, state=None, rng=None, progress=None) -> RunResult:
    """Simulate ``scenario`` driven by ``policy(sim) -> (intents, desired_heading)`` until all leave.

    ``width_m``: the bottleneck width used in J_s = N/(Δt b) (Eq. 22); defaults to the scenario's
    ``metadata['width_m']``. Returns a :class:`RunResult`.
    """
    params = ModelParams() if params is None else params
    state = scenario.make_state(rng=rng) if state is None else state
    sim = scenario.make_simulator(state, params)  # with the scenario's destinations, if any
    geometry = scenario.geometry
    width_m = scenario.metadata.get("width_m") if width_m is None else width_m
    counter = None
    if line is not None:
        if line not in geometry.measurement_lines:
            raise KeyError(f"scenario has no measurement line {line!r}; it has {sorted(geometry.measurement_lines)}")
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
    for _ in range(n_steps_max):
        if not state.active.any():
            break
        intents, heading = policy(sim)
        prev = state.position_m.copy()
        t_prev = sim.time_s
        result = sim.step(intents, desired_heading_rad=heading)
        if result.exited.size:
            last_exit_time = sim.time_s
        if counter is not None:
            counter.update(prev, state.position_m, t_prev, sim.time_s, ids)
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
    times = np.sort(np.asarray(counter.times_s if counter is not None else [], dtype=float))
    n_passed = times.size
    if n_passed >= 2 and width_m:
        flow = specific_flow(times, width_m)
        j, js = flow.flow_per_s, flow.specific_flow_per_m_s
    else:
        j = js = float("nan")
    n_left = int(np.count_nonzero(~state.active))
    return RunResult(
        n_pedestrians=state.n, width_m=width_m, seed=scenario.seed, n_steps=sim.step_count,
        simulated_time_s=sim.time_s, wall_time_s=time.perf_counter() - t_wall, n_evacuated=n_left,
        evacuation_time_s=last_exit_time if n_left == state.n else float("nan"),
        crossing_times_s=times, flow_per_s=j, specific_flow_per_m_s=js, min_gap_m=float(min_gap),
        density_per_m2={k: np.asarray(v) for k, v in density.items()},
        speed_m_s={k: np.asarray(v, dtype=float) for k, v in speed.items()},
        lateral_positions_m=np.concatenate(lateral) if lateral else np.zeros(0),
        n_fallback_solves=sim.n_fallback_solves,
    )
