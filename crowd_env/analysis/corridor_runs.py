"""The Jülich corridor runs (UO) as they were measured: the per-run table, the recordings, and one measurement for
the recordings and the model alike.

Zhang, Klingsch, Schadschneider, Seyfried (2011), J. Stat. Mech. P06004: nine unidirectional runs in a 1.8 m
corridor, each with its entrance and exit (``data/juelich_uo_runs_1.8m.csv``, one row per run, PedPy 1.5 on the
recordings; the recordings in ``data/juelich_uo/``, PedPy's example data, 16 frames/s, cm). The measurement,
:func:`measure_uo_run`, is the one PedPy's fundamental-diagram notebook applies to these recordings:

- the Voronoi density and speed (method D, no cut-off) in the area x in [0, b_c], y in [−2, 0], the Voronoi
  cells bounded by :func:`uo_measurement_walkable_area` (the notebook's walkable area: the corridor with 1 m
  of floor beside it before y = 4 m and after y = −4 m), individual speeds over ±5 frames (one-sided at the
  ends of a trajectory), averaged over the frames of the steady state;
- the flows: first crossings of y = 0 and of the exit line y = −4 m (towards −y) per second of the steady
  state, counted between its first and last frame.

The steady state of the shipped rows was chosen by hand for each run (PedPy's notebook). A model run has no such
hand: :func:`steady_frames` takes it from the passage of the 15 % to the 90 % of the walkers across y = 0
(:data:`STEADY_CROSSING_FRACTIONS`), the mean of where the hand-chosen windows lie in the nine recordings
(from 5-27 % to 80-94 %). Measured this way, the nine recordings give their shipped rows within 7 % in density,
0.05 m/s in speed and 7 % in exit flow (``tests/analysis/test_corridor_runs.py``, which also checks the
hand-chosen windows to the shipped figures). Only rows inside the walkable area count, as the camera saw them.

PedPy is an optional dependency (``pip install 'crowd_env[analysis]'``); :func:`measure_uo_run` needs it.
"""
from __future__ import annotations

import gzip
import math
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources

import numpy as np
import shapely
from shapely.geometry import Polygon

from crowd_env.errors import ExperimentError, InputError, NotFoundError

from .flow import MeasurementLine, trajectory_crossings
from .speed import centred_velocities_m_s, speed_profile
from .trajectories import Trajectories, require_pedpy

__all__ = ["SteadyStateFigures", "UORun", "juelich_uo_runs", "uo_run", "recorded_uo_trajectories", "uo_measurement_walkable_area",
           "uo_measurement_area", "steady_frames", "UORunMeasures", "measure_uo_run", "crossing_times_s",
           "STEADY_CROSSING_FRACTIONS", "UO_FRAME_RATE_PER_S", "UO_SPEED_FRAME_STEP", "DoorPassage", "door_passage",
           "approach_profile", "NeighbourSpacing", "neighbour_spacing", "uo_scenario", "passage_lapses",
           "lapse_summary", "LapseSummary", "OpeningEntry", "opening_entries"]

UO_FRAME_RATE_PER_S = 16.0  # the recordings' frame rate
UO_SPEED_FRAME_STEP = 5  # individual speeds over ±5 frames (±0.3125 s), PedPy's notebook
STEADY_CROSSING_FRACTIONS = (0.15, 0.90)  # the steady state of a run without a hand-chosen one (module docstring)
_EXIT_Y_M = -4.0
_MEASUREMENT_Y_M = (-2.0, 0.0)
_COLUMNS = ["run", "b_entrance_m", "b_corridor_m", "b_exit_m", "n_pedestrians", "steady_from_frame", "steady_to_frame",
            "density_voronoi_per_m2", "density_sd", "speed_voronoi_m_s", "speed_sd", "flow_at_y0_per_s",
            "flow_exit_per_s", "specific_flow_corridor", "specific_flow_exit"]


@dataclass(frozen=True)
class SteadyStateFigures:
    """What a UO run's steady state measures (module docstring): its first and last frame, the Voronoi density and
    speed (means over its frames, ``*_sd`` their spread over frames), the flows across y = 0 and the exit."""

    steady_from_frame: int
    steady_to_frame: int
    density_per_m2: float
    density_sd_per_m2: float
    speed_m_s: float
    speed_sd_m_s: float
    flow_y0_per_s: float
    flow_exit_per_s: float


@dataclass(frozen=True)
class UORun(SteadyStateFigures):
    """One run of the shipped table: its set-up (entrance, corridor, exit widths in m, N) and the figures measured
    over its hand-chosen steady frames."""

    name: str
    entrance_width_m: float
    corridor_width_m: float
    exit_width_m: float
    n_pedestrians: int


@lru_cache(maxsize=1)
def juelich_uo_runs() -> tuple:
    """The nine runs (:class:`UORun`), in the file's order: five with a narrowed entrance, three with a narrowed exit,
    and the open one."""
    text = resources.files("crowd_env.analysis").joinpath("data", "juelich_uo_runs_1.8m.csv").read_text(encoding="utf-8")
    rows = [ln.split(",") for ln in text.splitlines() if ln.strip()]
    if rows[0] != _COLUMNS:
        raise ExperimentError(f"juelich_uo_runs_1.8m.csv: expected columns {_COLUMNS}, got {rows[0]}")
    return tuple(UORun(int(r[5]), int(r[6]), float(r[7]), float(r[8]), float(r[9]), float(r[10]), float(r[11]),
                       float(r[12]), name=r[0], entrance_width_m=float(r[1]), corridor_width_m=float(r[2]),
                       exit_width_m=float(r[3]), n_pedestrians=int(r[4])) for r in rows[1:])


def uo_run(name: str) -> UORun:
    """The run called ``name`` (e.g. ``"uo-180-180-070"``); :class:`NotFoundError` listing the names otherwise."""
    for run in juelich_uo_runs():
        if run.name == name:
            return run
    raise NotFoundError(f"no Jülich corridor run {name!r}; the runs are {[r.name for r in juelich_uo_runs()]}")


def uo_scenario(name: str, **options):
    """The ``juelich_corridor`` scenario of run ``name`` (its entrance, corridor and exit widths and N; seed 0 unless
    ``options`` say otherwise; ``options``: the scenario's other options)."""
    from ..scenarios import make_scenario

    run = uo_run(name)
    return make_scenario("juelich_corridor", **{"entrance_width_m": run.entrance_width_m,
                                                "exit_width_m": run.exit_width_m,
                                                "corridor_width_m": run.corridor_width_m,
                                                "n_pedestrians": run.n_pedestrians, "seed": 0, **options})


def recorded_uo_trajectories(name: str) -> Trajectories:
    """The recording of run ``name`` (16 frames/s, positions converted from cm to m; headings unknown)."""
    uo_run(name)
    raw = resources.files("crowd_env.analysis").joinpath("data", "juelich_uo", f"{name}.txt.gz").read_bytes()
    data = np.loadtxt(gzip.decompress(raw).decode("ascii").splitlines(), comments="#", usecols=(0, 1, 2, 3))
    return Trajectories(data[:, 1], data[:, 0], data[:, 2] / 100.0, data[:, 3] / 100.0, None, UO_FRAME_RATE_PER_S)


def uo_measurement_walkable_area(corridor_width_m: float = 1.8) -> Polygon:
    """The area the Voronoi cells are bounded by (PedPy's notebook for these runs, for any corridor width): the
    corridor x in [0, b_c], y in [−4, 4], and 1 m of floor beside it on both sides for y in [4, 8] and
    [−6.5, −4]."""
    b = float(corridor_width_m)
    if not b > 0:
        raise InputError(f"corridor_width_m must be > 0, got {corridor_width_m!r}")
    return Polygon([(b + 1.0, -6.5), (b + 1.0, -4.0), (b, -4.0), (b, 4.0), (b + 1.0, 4.0), (b + 1.0, 8.0), (-1.0, 8.0),
                    (-1.0, 4.0), (0.0, 4.0), (0.0, -4.0), (-1.0, -4.0), (-1.0, -6.5)])


def uo_measurement_area(corridor_width_m: float = 1.8) -> Polygon:
    """The measurement area: x in [0, b_c], y in [−2, 0]."""
    return shapely.box(0.0, _MEASUREMENT_Y_M[0], float(corridor_width_m), _MEASUREMENT_Y_M[1])


def crossing_times_s(trajectories: Trajectories, *, y_m: float, x_range_m: tuple) -> np.ndarray:
    """Sorted times of the first crossings of the line y = ``y_m``, x in ``x_range_m``, towards −y (interpolated
    between frames)."""
    line = MeasurementLine((x_range_m[0], y_m), (x_range_m[1], y_m), direction=(0.0, -1.0))
    _, times = trajectory_crossings(trajectories.frame, trajectories.id, trajectories.x_m, trajectories.y_m,
                                    trajectories.frame_time_s, line)
    return np.sort(times)


def steady_frames(y0_crossing_times_s, *, frame_rate_per_s: float, fractions=STEADY_CROSSING_FRACTIONS) -> tuple:
    """``(first, last)`` frame of the steady state: from the passage of the ``fractions[0]`` part of the walkers
    across y = 0 to that of the ``fractions[1]`` part (ranks rounded to the nearest). Raises :class:`InputError`
    with fewer than two passages."""
    times = np.sort(np.asarray(y0_crossing_times_s, dtype=np.float64))
    k0, k1 = _steady_ranks(times.size, fractions, "a steady state needs at least two passages of y = 0")
    return int(np.ceil(times[k0] * frame_rate_per_s - 1e-9)), int(np.ceil(times[k1] * frame_rate_per_s - 1e-9))


def passage_lapses(trajectories: Trajectories, *, y_m: float, x_range_m: tuple,
                   fractions=STEADY_CROSSING_FRACTIONS) -> np.ndarray:
    """The time lapses (s) between successive first passages of the line y = ``y_m`` (x in ``x_range_m``, towards
    −y), from the passage of the ``fractions[0]`` part of those who cross it to that of the ``fractions[1]`` part
    (ranks as :func:`steady_frames` rounds them): the line's own steady state, the same rule for a recording and a
    model run. A flow through an opening that clogs for a while shows as lapses far longer than the typical one:
    the distribution of these lapses is how clogging is measured at bottlenecks (Zuriguel et al. 2014, "Clogging
    transition of many-particle systems flowing through bottlenecks", Sci. Rep. 4:7324). Raises
    :class:`InputError` with fewer than two passages."""
    if not x_range_m[0] < x_range_m[1]:
        raise InputError(f"x_range_m must be (low, high) with low < high, got {x_range_m!r}")
    times = crossing_times_s(trajectories, y_m=float(y_m), x_range_m=x_range_m)
    k0, k1 = _steady_ranks(times.size, fractions, f"lapses between passages need at least two passages of y = {y_m:g} m")
    return np.diff(times[k0:k1 + 1])


def _steady_ranks(n: int, fractions, too_few: str) -> tuple:
    """The ranks (first, last) of the passages of the ``fractions`` parts among ``n`` sorted passages (rounded to the
    nearest, at least one apart); :class:`InputError` for fractions outside 0 <= lo < hi <= 1 or n < 2 (``too_few``
    says what needed them)."""
    lo, hi = (float(f) for f in fractions)
    if not 0.0 <= lo < hi <= 1.0:
        raise InputError(f"fractions must satisfy 0 <= lo < hi <= 1, got {fractions!r}")
    if n < 2:
        raise InputError(f"{too_few}, got {n}")
    k0 = int(round(lo * (n - 1)))
    return k0, max(int(round(hi * (n - 1))), k0 + 1)


@dataclass(frozen=True)
class LapseSummary:
    """:func:`lapse_summary` of the lapses between passages: their median and mean (s; the mean is the inverse of
    the flow), the 95 % quantile and the longest (s), the share of the time spent in lapses longer than ``long_s``
    (the opening blocked for that long) and the flow (1/s) the other lapses alone would carry (the passages as
    they are, the long blockages taken out)."""

    median_s: float
    mean_s: float
    q95_s: float
    longest_s: float
    share_of_time_in_long: float
    flow_without_long_per_s: float
    long_s: float


def lapse_summary(lapses_s, *, long_s: float = 2.0) -> LapseSummary:
    """The figures of :class:`LapseSummary` of ``lapses_s`` (non-negative, at least one); ``long_s`` > 0: what counts
    as a long lapse (default 2 s, longer than any lapse of the recordings' narrow openings)."""
    lapses = np.asarray(lapses_s, dtype=np.float64).ravel()
    if lapses.size == 0 or not np.all(np.isfinite(lapses)) or np.any(lapses < 0.0):
        raise InputError(f"lapses_s must be finite non-negative times, at least one, got {lapses_s!r}")
    if not (math.isfinite(long_s) and long_s > 0.0):
        raise InputError(f"long_s must be a positive time in s, got {long_s!r}")
    total = float(lapses.sum())
    short = lapses[lapses <= long_s]
    return LapseSummary(float(np.median(lapses)), float(lapses.mean()), float(np.quantile(lapses, 0.95)),
                        float(lapses.max()), 1.0 - float(short.sum()) / total if total > 0.0 else 0.0,
                        short.size / float(short.sum()) if short.sum() > 0.0 else math.nan, float(long_s))


@dataclass(frozen=True)
class UORunMeasures(SteadyStateFigures):
    """A run measured as the shipped rows (module docstring): its steady state's figures and the passages counted
    across y = 0 and the exit over the whole run."""

    n_crossings_y0: int
    n_crossings_exit: int


def measure_uo_run(trajectories: Trajectories, *, corridor_width_m: float = 1.8, exit_width_m: float | None = None,
                   steady: tuple | None = None, fractions=STEADY_CROSSING_FRACTIONS) -> UORunMeasures:
    """Measure a UO run (recorded or simulated) as the shipped rows were measured (module docstring).

    ``steady``: ``(first, last)`` frame of the steady state (the shipped row's for a recording); None takes it
    from the passages across y = 0 (:func:`steady_frames` with ``fractions``). ``exit_width_m``: the exit line's
    width, centred on the corridor (default the corridor's). Rows outside :func:`uo_measurement_walkable_area`
    are left out (beyond the camera). Raises :class:`InputError` for a window without frames or a run with
    fewer than two passages of y = 0 when the window is to be found."""
    pedpy = require_pedpy()
    import pandas as pd

    b = float(corridor_width_m)
    bx = b if exit_width_m is None else float(exit_width_m)
    walkable = uo_measurement_walkable_area(b)
    inside = shapely.contains_xy(walkable, trajectories.x_m, trajectories.y_m)
    fps = trajectories.frame_rate_per_s
    t_y0 = crossing_times_s(trajectories, y_m=0.0, x_range_m=(0.0, b))
    t_exit = crossing_times_s(trajectories, y_m=_EXIT_Y_M, x_range_m=(0.5 * (b - bx), 0.5 * (b + bx)))
    f0, f1 = steady_frames(t_y0, frame_rate_per_s=fps, fractions=fractions) if steady is None else \
        (int(steady[0]), int(steady[1]))
    in_window = inside & (trajectories.frame >= f0) & (trajectories.frame <= f1)
    if f1 <= f0 or not np.any(in_window):
        raise InputError(f"the steady state, frames {f0} to {f1}, holds no recorded frame inside the corridor's area")
    data = pd.DataFrame({"id": trajectories.id[in_window], "frame": trajectories.frame[in_window],
                         "x": trajectories.x_m[in_window], "y": trajectories.y_m[in_window]})
    traj = pedpy.TrajectoryData(data=data, frame_rate=fps)
    area = pedpy.MeasurementArea(uo_measurement_area(b))
    cells = pedpy.compute_individual_voronoi_polygons(traj_data=traj, walkable_area=pedpy.WalkableArea(walkable))
    density, intersecting = pedpy.compute_voronoi_density(individual_voronoi_data=cells, measurement_area=area)
    speed = pedpy.compute_individual_speed(traj_data=traj, frame_step=UO_SPEED_FRAME_STEP,
                                           speed_calculation=pedpy.SpeedCalculation.BORDER_SINGLE_SIDED)
    voronoi_speed = pedpy.compute_voronoi_speed(traj_data=traj, individual_voronoi_intersection=intersecting,
                                                individual_speed=speed, measurement_area=area)
    rho = density["density"].to_numpy(dtype=np.float64)
    v = voronoi_speed["speed"].to_numpy(dtype=np.float64)
    duration_s = (f1 - f0) / fps

    def rate(times):
        return float(np.count_nonzero((times >= f0 / fps) & (times < f1 / fps)) / duration_s)

    return UORunMeasures(f0, f1, float(rho.mean()), float(rho.std()), float(v.mean()), float(v.std()), rate(t_y0),
                         rate(t_exit), int(t_y0.size), int(t_exit.size))


@dataclass(frozen=True)
class DoorPassage:
    """How walkers pass a line across an opening over a window (:func:`door_passage`): the median and mean time
    between successive passages, the median speed at the line, the spread of where they cross it (10 % to 90 %
    of x, and its standard deviation), how many passed, the share of them that crossed farther than
    ``off_axis_m`` from the middle of the line's x range (NaN when not asked), and how successive passers follow
    each other: the median distance along the walk (``following_median_m``: each passer's speed at the line times
    the time since the one before it passed) and across it (``lateral_step_median_m``: ``|x_j − x_{j−1}|``), and the
    share of successive passers who crossed on opposite sides of the middle (``side_alternation``; about 0.5 when
    the sides are independent, 1 for strict alternation). One file follows at a body length or more with lateral
    steps near 0; two staggered files (a zipper) at less than a body length, each passer beside the one before, on
    the other side."""

    headway_median_s: float
    headway_mean_s: float
    speed_median_m_s: float
    lateral_p10_m: float
    lateral_p90_m: float
    lateral_sd_m: float
    n_passages: int
    share_off_axis: float = float("nan")
    following_median_m: float = float("nan")
    lateral_step_median_m: float = float("nan")
    side_alternation: float = float("nan")


def door_passage(trajectories: Trajectories, *, y_m: float, x_range_m: tuple, window_frames: tuple,
                 off_axis_m: float | None = None) -> DoorPassage:
    """The passages of the line y = ``y_m`` (x in ``x_range_m``, towards −y) within ``window_frames`` (first, last
    frame): time headways between successive passages, each walker's speed over ±5 frames around its crossing and
    the x where it crossed (as the data README's table of the narrowed exits measures the recordings), and how far
    behind and beside the one before each passer crossed (:class:`DoorPassage`); with
    ``off_axis_m`` (≥ 0) also the share of the passages farther than that from the middle of ``x_range_m`` (for an
    opening of width b on that axis and disks of radius r, b/2 − r: where no disk's centre can pass)."""
    if off_axis_m is not None and not (math.isfinite(off_axis_m) and off_axis_m >= 0.0):
        raise InputError(f"off_axis_m must be a distance >= 0 in m, got {off_axis_m!r}")
    fps = trajectories.frame_rate_per_s
    ids, frame, x, y = _by_walker(trajectories)
    k, xc, tc = _first_crossings(ids, frame, x, y, y_m, x_range_m)
    tc = tc / fps
    inside = (tc >= window_frames[0] / fps) & (tc <= window_frames[1] / fps)
    order = np.argsort(tc[inside], kind="stable")
    k, xc, tc = k[inside][order], xc[inside][order], tc[inside][order]
    speeds = np.full(k.size, np.nan)
    for n, j in enumerate(k):
        lo = max(j - UO_SPEED_FRAME_STEP + 1, 0)
        while ids[lo] != ids[j]:
            lo += 1
        hi = min(j + UO_SPEED_FRAME_STEP, ids.size - 1)
        while ids[hi] != ids[j]:
            hi -= 1
        if frame[hi] > frame[lo]:
            speeds[n] = np.hypot(x[hi] - x[lo], y[hi] - y[lo]) * fps / (frame[hi] - frame[lo])
    headways = np.diff(tc)
    following = speeds[1:] * headways
    following = following[np.isfinite(following)]
    measured = speeds[np.isfinite(speeds)]
    nan = float("nan")
    return DoorPassage(float(np.median(headways)) if headways.size else nan,
                       float(headways.mean()) if headways.size else nan,
                       float(np.median(measured)) if measured.size else nan,
                       float(np.quantile(xc, 0.1)) if xc.size else nan, float(np.quantile(xc, 0.9)) if xc.size else nan,
                       float(xc.std()) if xc.size else nan, int(tc.size),
                       float(np.mean(np.abs(xc - 0.5 * (x_range_m[0] + x_range_m[1])) > off_axis_m))
                       if off_axis_m is not None and xc.size else nan,
                       float(np.median(following)) if following.size else nan,
                       float(np.median(np.abs(np.diff(xc)))) if xc.size > 1 else nan,
                       float(np.mean(np.diff(xc > 0.5 * (x_range_m[0] + x_range_m[1])))) if xc.size > 1 else nan)


@dataclass(frozen=True)
class OpeningEntry:
    """Where the next walker was when the one before it left an opening (:func:`opening_entries`), over the pairs of
    successive walkers through it: how long after the other left it entered (``wait_median_s``; negative: both were
    in the opening at once), how far before the opening's upstream face it then stood (``before_median_m``, its
    position interpolated between frames; negative: already inside), how far off the opening's axis
    (``offset_median_m``), the share standing beside the opening's span rather than in line with it
    (``share_beside``: ``|x − axis| > b/2``, to enter it must move sideways round its edge), and its speed then
    (``speed_median_m_s``); ``positions_m``: each pair's (x − axis, distance before the face) of the next one, in the
    order of the exits. ``n_pairs`` = 0 (every figure NaN) where the trajectories do not reach the opening's upstream
    face (the recordings of the entrances: the camera starts past it)."""

    n_pairs: int
    wait_median_s: float = float("nan")
    before_median_m: float = float("nan")
    offset_median_m: float = float("nan")
    share_beside: float = float("nan")
    speed_median_m_s: float = float("nan")
    positions_m: tuple = ()


def _first_crossings(ids, frame, x, y, y_m: float, x_range_m: tuple) -> tuple:
    """Each walker's first crossing of the line y = ``y_m`` towards −y with x in ``x_range_m``, rows sorted by walker
    then frame (:func:`_by_walker`): ``(row before the crossing, x at the crossing, time in frames)`` (interpolated),
    one entry per walker in walker order."""
    step = (ids[1:] == ids[:-1]) & (frame[1:] == frame[:-1] + 1) & (y[:-1] > y_m) & (y[1:] <= y_m)
    k = np.flatnonzero(step)
    alpha = (y[k] - y_m) / (y[k] - y[k + 1])
    xc = x[k] + alpha * (x[k + 1] - x[k])
    keep = (xc >= x_range_m[0]) & (xc <= x_range_m[1])
    _, first = np.unique(ids[k][keep], return_index=True)
    return k[keep][first], xc[keep][first], (frame[k] + alpha)[keep][first]


def opening_entries(trajectories: Trajectories, *, upstream_y_m: float, downstream_y_m: float, x_range_m: tuple,
                    window_frames: tuple) -> OpeningEntry:
    """How the next walker gets into an opening through a wall between y = ``upstream_y_m`` and ``downstream_y_m``
    (walking towards −y; x in ``x_range_m``, the opening's span): for successive walkers leaving it (crossing the
    downstream face, ordered by time, the follower's exit within ``window_frames``), where the follower stood and
    how fast it moved in the frame the one before left, and how long after that it entered (crossed the upstream
    face). The same function measures the recordings and the model's runs; it needs trajectories upstream of the
    opening (:class:`OpeningEntry`)."""
    if not upstream_y_m > downstream_y_m:
        raise InputError(f"the upstream face (y = {upstream_y_m!r} m) must lie above the downstream face "
                         f"(y = {downstream_y_m!r} m): walkers go towards −y")
    fps = trajectories.frame_rate_per_s
    ids, frame, x, y = _by_walker(trajectories)
    k, _, t = _first_crossings(ids, frame, x, y, upstream_y_m, x_range_m)
    entered = dict(zip(ids[k].tolist(), t.tolist()))
    k, _, t = _first_crossings(ids, frame, x, y, downstream_y_m, x_range_m)
    through = sorted((t, w) for w, t in zip(ids[k].tolist(), t.tolist()) if w in entered)
    vx, vy = centred_velocities_m_s(trajectories, frame_step=UO_SPEED_FRAME_STEP).T  # rows: as _by_walker's
    span = int(frame.max()) + 2 if frame.size else 1
    keys = ids * span + frame  # rows are sorted by walker, then frame: so are their keys

    def row(walker, f):
        """The row of ``walker`` at frame ``f``, or None."""
        key = walker * span + f
        r = int(np.searchsorted(keys, key))
        return r if r < keys.size and keys[r] == key else None

    axis = 0.5 * (x_range_m[0] + x_range_m[1])
    half = 0.5 * (x_range_m[1] - x_range_m[0])
    figures = []
    for (t_before, _leader), (t_next, walker) in zip(through[:-1], through[1:]):
        if not window_frames[0] <= t_next <= window_frames[1]:
            continue
        f0 = int(np.floor(t_before))
        r0, r1 = row(walker, f0), row(walker, f0 + 1)
        if r0 is None or r1 is None:  # the follower is not seen then
            continue
        a = t_before - f0  # its position interpolated between the frames, as the crossing times are
        figures.append(((entered[walker] - t_before) / fps, x[r0] + a * (x[r1] - x[r0]) - axis,
                        y[r0] + a * (y[r1] - y[r0]) - upstream_y_m,
                        np.hypot(vx[r0], vy[r0])))
    if not figures:
        return OpeningEntry(0)
    f = np.array(figures)
    offset = np.abs(f[:, 1])
    speed = f[:, 3][np.isfinite(f[:, 3])]
    return OpeningEntry(len(f), float(np.median(f[:, 0])), float(np.median(f[:, 2])), float(np.median(offset)),
                        float(np.mean(offset > half)), float(np.median(speed)) if speed.size else float("nan"),
                        tuple((float(u), float(v)) for u, v in f[:, 1:3]))


def approach_profile(trajectories: Trajectories, *, corridor_width_m: float, window_frames: tuple,
                     edges_y_m=tuple(np.arange(-4.0, 0.01, 0.5))) -> tuple:
    """Density (counted, 1/m²) and mean speed (m/s, over ±5 frames) in bands of the corridor between ``edges_y_m``
    (default 0.5 m bands from the exit wall y = −4 m to y = 0), over the frames of ``window_frames``: how a queue
    thins and speeds up into its exit (the speed: :func:`~crowd_env.analysis.speed.speed_profile`'s, over ±5 frames).
    Returns ``(band centres (m), density, speed)``."""
    f0, f1 = window_frames
    fps = trajectories.frame_rate_per_s
    _, frame, x, y = _by_walker(trajectories)
    edges = np.asarray(edges_y_m, dtype=np.float64)
    in_window = (frame >= f0) & (frame <= f1) & (x >= 0.0) & (x <= corridor_width_m)
    density = np.array([np.count_nonzero(in_window & (y >= lo) & (y < hi)) / (f1 - f0 + 1)
                        / ((hi - lo) * corridor_width_m) for lo, hi in zip(edges[:-1], edges[1:])])
    speed = speed_profile(trajectories, direction=(0.0, 1.0), edges_m=edges, frame_step=UO_SPEED_FRAME_STEP,
                          window_s=(f0 / fps, f1 / fps), area=(0.0, edges[0], corridor_width_m, edges[-1]),
                          magnitude=True).speed_m_s
    return 0.5 * (edges[:-1] + edges[1:]), density, speed


def _by_walker(trajectories: Trajectories) -> tuple:
    """``(id, frame, x, y)`` of ``trajectories``, whose rows are sorted by walker, then frame (its invariant)."""
    return trajectories.id, trajectories.frame, trajectories.x_m, trajectories.y_m


@dataclass(frozen=True)
class NeighbourSpacing:
    """How close walkers come to each other, by bearing (:func:`neighbour_spacing`): per bearing bin (edges
    ``bearing_edges_deg``, 0° = straight ahead or behind along the walker's velocity, 90° = beside it), the
    ``quantiles`` of the centre distance to every other walker within the search radius (``distance_m``, bins ×
    quantiles, m; NaN for an empty bin), the number of pairs in each bin (``n_pairs``) and the share of them closer
    than ``closer_than_m`` (``share_closer``)."""

    bearing_edges_deg: np.ndarray
    quantiles: tuple
    distance_m: np.ndarray
    n_pairs: np.ndarray
    closer_than_m: float
    share_closer: np.ndarray


def neighbour_spacing(trajectories: Trajectories, *, area: Polygon, window_frames: tuple, max_distance_m: float = 1.0,
                      min_speed_m_s: float = 0.1, bearing_edges_deg=(0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 90.0),
                      quantiles=(0.01, 0.05, 0.5), closer_than_m: float = 0.46) -> NeighbourSpacing:
    """The centre distances from each walker in ``area`` on the frames of ``window_frames`` (first, last) who moves at
    least ``min_speed_m_s`` (speed over ±5 frames, as :func:`measure_uo_run`'s) to every other walker of the same
    frame within ``max_distance_m``, binned by the bearing of the other from the walker's velocity folded into
    [0°, 90°] (0°: ahead or behind, 90°: beside): what the bodies let people do, front to back against side by side.
    The same function measures a recording and a model run (for a disk model no distance is below 2 r)."""
    edges = np.asarray(bearing_edges_deg, dtype=np.float64)
    q = tuple(float(v) for v in quantiles)
    if edges.ndim != 1 or edges.size < 2 or np.any(np.diff(edges) <= 0) or edges[0] < 0.0 or edges[-1] > 90.0:
        raise ExperimentError(f"bearing_edges_deg must increase within [0, 90], got {bearing_edges_deg!r}")
    if not q or any(not 0.0 <= v <= 1.0 for v in q):
        raise ExperimentError(f"quantiles must lie in [0, 1], got {quantiles!r}")
    if not (max_distance_m > 0.0 and min_speed_m_s >= 0.0 and closer_than_m > 0.0):
        raise ExperimentError(f"neighbour_spacing needs max_distance_m > 0, min_speed_m_s >= 0 and closer_than_m > 0, "
                              f"got {max_distance_m}, {min_speed_m_s}, {closer_than_m}")
    f0, f1 = (int(f) for f in window_frames)
    if f1 < f0:
        raise ExperimentError(f"window_frames must be (first, last) with first <= last, got {window_frames!r}")
    ids, frame, x, y = _by_walker(trajectories)
    vx, vy = centred_velocities_m_s(trajectories, frame_step=UO_SPEED_FRAME_STEP).T  # rows: as _by_walker's
    rows = np.flatnonzero((frame >= f0) & (frame <= f1))
    moving = np.zeros(x.size, np.bool_)  # the walkers measured: in the window, moving, inside the area
    moving[rows] = (np.hypot(vx[rows], vy[rows]) >= min_speed_m_s) & shapely.contains_xy(area, x[rows], y[rows])
    distances, bearings = [], []
    rows = rows[np.argsort(frame[rows], kind="stable")]
    for part in np.split(rows, np.flatnonzero(np.diff(frame[rows])) + 1):
        walkers = part[moving[part]]
        if not walkers.size or part.size < 2:
            continue
        ex, ey = x[part][None, :] - x[walkers][:, None], y[part][None, :] - y[walkers][:, None]
        d = np.hypot(ex, ey)
        near = (d <= max_distance_m) & (walkers[:, None] != part[None, :])
        a, b = np.nonzero(near)
        along = np.abs(ex[a, b] * vx[walkers[a]] + ey[a, b] * vy[walkers[a]]) / (d[a, b] * np.hypot(vx[walkers[a]],
                                                                                                   vy[walkers[a]]))
        distances.append(d[a, b])
        bearings.append(np.degrees(np.arccos(np.clip(along, 0.0, 1.0))))
    d = np.concatenate(distances) if distances else np.zeros(0)
    phi = np.concatenate(bearings) if bearings else np.zeros(0)
    n_bins = edges.size - 1
    table, counts, share = np.full((n_bins, len(q)), np.nan), np.zeros(n_bins, np.int64), np.full(n_bins, np.nan)
    for k in range(n_bins):
        last = k == n_bins - 1
        m = (phi >= edges[k]) & ((phi <= edges[k + 1]) if last else (phi < edges[k + 1]))
        counts[k] = int(np.count_nonzero(m))
        if counts[k]:
            table[k] = np.quantile(d[m], q)
            share[k] = float(np.mean(d[m] < closer_than_m))
    return NeighbourSpacing(edges, q, table, counts, float(closer_than_m), share)
