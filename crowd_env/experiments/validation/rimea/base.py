"""The building blocks of the RiMEA verification suite: runs, verdicts and the test registry.

A RiMEA test (RiMEA 4.1.1, Annex 1) is a :class:`RimeaTest`: one or more scenarios (data, built with the
public scenario API in :mod:`crowd_env.scenarios.rimea`), run by a *backend* into a :class:`BackendRun`
(trajectories at a fixed frame rate, exit times, the smallest gap and the largest excursion outside the
walkable area), then judged by the test's :meth:`RimeaTest.evaluate` into a :class:`Verdict`. The
evaluation reads only the runs, so the same test judges crowd_env and JuPedSim alike
(:mod:`crowd_env.experiments.validation.rimea.jupedsim_backend`).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import shapely

from crowd_env.errors import InputError, NotFoundError

from ....analysis.trajectories import Trajectories
from ....core.checks import check_number
from ....walking.presets import DEFAULT_PRESET, get_preset
from ....walking.agent import SocialForceAgent
from ...running.recording import record_run

__all__ = ["BackendRun", "Verdict", "RimeaTest", "register_test", "rimea_tests", "select_tests", "run_crowd_env",
           "WindowedTest", "start_times_s", "walking_speeds_m_s", "exits_used", "evacuation_curve", "outside_distance_m", "exit_times_s",
           "STAIRS_TESTS", "DOCUMENTATION_TESTS", "OVERLAP_LIMIT_M", "FRAME_RATE_PER_S"]

# Tests RiMEA 4.1.1 defines that a flat 2D model cannot run: stairs (2, 3, 13) and documentation only (8, 14).
STAIRS_TESTS = ("2", "3", "13")
DOCUMENTATION_TESTS = ("8", "14")
OVERLAP_LIMIT_M = 1e-3  # the bound: no overlap beyond 1 mm, in every test
FRAME_RATE_PER_S = 10.0  # trajectory frames per second of every run (RiMEA's tests need no finer)

_REGISTRY: dict = {}


@dataclass
class BackendRun:
    """One scenario run by one backend.

    ``trajectories``: every pedestrian on the floor at ``FRAME_RATE_PER_S`` (ids = scenario indices);
    ``exit_time_s`` (N,): when each left (nan: still inside at the end); ``min_gap_m``: the smallest gap
    between two disks or a disk and a wall over the run (negative: an overlap; crowd_env measures it every
    step, JuPedSim at the frames); ``outside_m``: the farthest any centre lay outside the walkable area (0: never);
    ``complete``: everybody left; ``stalled``: stopped by crowd_env's stall rule.
    """

    backend: str
    scenario_name: str
    trajectories: Trajectories
    exit_time_s: np.ndarray
    min_gap_m: float
    outside_m: float
    complete: bool
    stalled: bool = False
    wall_time_s: float = float("nan")
    max_time_s: float = float("nan")

    @property
    def n_pedestrians(self) -> int:
        return int(self.exit_time_s.shape[0])

    @property
    def n_left(self) -> int:
        return int(np.isfinite(self.exit_time_s).sum())

    @property
    def end_time_s(self) -> float:
        """The time of the run's last recorded frame (nan when nothing was recorded)."""
        t = self.trajectories
        return float(t.frame.max() / t.frame_rate_per_s) if len(t) else float("nan")

    def reached_time_limit(self) -> bool:
        """The run went on to ``max_time_s`` (within one frame), without stalling or being stopped early."""
        frame_s = 1.0 / self.trajectories.frame_rate_per_s
        return bool(not self.stalled and self.end_time_s >= self.max_time_s - 1.5 * frame_s)

    @property
    def evacuation_time_s(self) -> float:
        """When the last pedestrian left (nan unless everybody did: an incomplete run has no evacuation time)."""
        return float(np.max(self.exit_time_s)) if self.complete and self.n_pedestrians else float("nan")

    def positions(self, pedestrian: int) -> tuple:
        """``(time_s, xy (k, 2))`` of one pedestrian's frames."""
        t = self.trajectories  # rows sorted by (id, frame): one pedestrian's rows are a contiguous block
        lo, hi = np.searchsorted(t.id, [int(pedestrian), int(pedestrian) + 1])
        rows = slice(int(lo), int(hi))
        return t.frame[rows] / t.frame_rate_per_s, np.column_stack((t.x_m[rows], t.y_m[rows]))


@dataclass
class Verdict:
    """A test's reading of one backend's runs: ``measured`` (the figure as printed), ``value`` (the number
    behind it), ``passed`` (None where RiMEA asks only for documentation) and ``details`` (numbers for the
    results file)."""

    measured: str
    value: float
    passed: bool | None
    details: dict = field(default_factory=dict)


class RimeaTest:
    """One RiMEA test: subclasses set the class attributes and implement :meth:`scenarios` and
    :meth:`evaluate` (and :meth:`plot` for its figure).

    ``number`` (a string: "12a"), ``title``, ``checks`` (what it verifies, one line), ``criterion`` (RiMEA's
    criterion, or the quantitative reading used where RiMEA's is qualitative, stated as such), ``source``
    (where the reading comes from).
    """

    number: str = ""
    title: str = ""
    checks: str = ""
    criterion: str = ""
    source: str = ""
    #: the runs are measured over a time window and end at the time limit by design (a ring, a filled
    #: corridor): such a run is complete when it reached the limit, not when everybody left
    runs_to_time_limit: bool = False

    def runs_complete(self, runs: dict) -> bool:
        """Every run finished as the test intends: everybody left, or (``runs_to_time_limit``) the run
        went on to its time limit without stalling or being stopped."""
        if self.runs_to_time_limit:
            return all(r.reached_time_limit() for r in runs.values())
        return all(r.complete for r in runs.values())

    def scenarios(self, quick: bool, seed: int) -> dict:
        """Variant name -> :class:`~crowd_env.scenarios.Scenario` (the reduced version with ``quick``)."""
        raise NotImplementedError

    def max_time_s(self, quick: bool) -> float:
        """The time limit of each run (a run that does not finish is incomplete, never cut into a figure)."""
        return 300.0

    def evaluate(self, runs: dict) -> Verdict:
        """The verdict on one backend's runs (variant name -> :class:`BackendRun`)."""
        raise NotImplementedError

    def plot(self, ax, runs_by_backend: dict) -> None:
        """Draw the test's figure on ``ax`` (matplotlib axes) from ``{backend: {variant: BackendRun}}``."""
        first = next(iter(runs_by_backend.values()))
        run = next(iter(first.values()))
        t = run.trajectories
        ax.plot(t.x_m, t.y_m, ",", alpha=0.3)
        ax.set_aspect("equal")


def register_test(cls):
    """Class decorator: add a :class:`RimeaTest` subclass to the suite under its ``number``."""
    if not cls.number or cls.number in _REGISTRY:
        raise InputError(f"RiMEA test number {cls.number!r} is empty or taken")
    _REGISTRY[cls.number] = cls
    return cls


def _sort_key(number: str):
    digits = "".join(c for c in number if c.isdigit())
    return int(digits), number[len(digits):]


def rimea_tests() -> list:
    """The registered test numbers in order ("1", "4", ..., "12a", ...)."""
    return sorted(_REGISTRY, key=_sort_key)


def select_tests(numbers=None) -> list:
    """Instances of the tests ``numbers`` (default: all). A test that needs stairs, one that is
    documentation only or an unknown number raises :class:`~crowd_env.errors.NotFoundError` naming it.
    "12" selects 12a-12d."""
    known = rimea_tests()
    if not numbers:
        return [_REGISTRY[k]() for k in known]
    out = []
    for raw in numbers:
        key = str(raw).strip().lower()
        if key in STAIRS_TESTS:
            raise NotFoundError(f"RiMEA test {key} needs stairs, which a flat 2D model does not have; the flat "
                                f"tests are {', '.join(known)}")
        if key in DOCUMENTATION_TESTS:
            raise NotFoundError(f"RiMEA test {key} is documentation only (no criterion to run); the runnable tests "
                                f"are {', '.join(known)}")
        group = [k for k in known if k == key or (k.rstrip("abcd") == key and k != key)]
        if not group:
            raise NotFoundError(f"unknown RiMEA test {raw!r}; RiMEA 4.1.1 numbers them 1-16 and the flat ones here "
                                f"are {', '.join(known)}")
        out.extend(_REGISTRY[k]() for k in group if all(type(t) is not _REGISTRY[k] for t in out))
    return out


def outside_distance_m(trajectories: Trajectories, walkable_area) -> float:
    """The farthest any recorded centre lies outside ``walkable_area`` (0 when all lie in it or on its edge)."""
    if len(trajectories) == 0:
        return 0.0
    x, y = trajectories.x_m, trajectories.y_m
    inside = shapely.intersects_xy(walkable_area, x, y)
    if inside.all():
        return 0.0
    out = np.flatnonzero(~inside)
    points = shapely.points(x[out], y[out])
    return float(shapely.distance(walkable_area, points).max())


def exit_times_s(trajectories: Trajectories, left, end_time_s: float) -> np.ndarray:
    """(N,) when each pedestrian flagged in ``left`` (N,) bool left: the time of the first frame it is no
    longer recorded in (it left between that frame and the one before), at most ``end_time_s`` (the end
    of the run, which may fall between frames); nan for those still inside."""
    left = np.asarray(left, dtype=bool)
    out = np.full(left.shape[0], np.nan)
    t = trajectories
    last = np.full(left.shape[0], -1, np.int64)
    if len(t):
        np.maximum.at(last, t.id, t.frame)
    out[left] = np.minimum((last[left] + 1) / t.frame_rate_per_s, end_time_s)
    return out


def run_crowd_env(scenario, *, seed: int, max_time_s: float, params=None,
                  frame_rate_per_s: float = FRAME_RATE_PER_S, checkpoint=None) -> BackendRun:
    """Run ``scenario`` with the calibrated agent (default preset) and record it: a :class:`BackendRun`.
    ``checkpoint``: a :class:`~crowd_env.experiments.running.runner.RunCheckpoint` (long runs: kept every so often,
    resumed after a killed process)."""
    check_number("max_time_s", max_time_s, error=InputError, positive=True)
    params = get_preset(DEFAULT_PRESET).params() if params is None else params
    t0 = time.perf_counter()
    state = scenario.make_state(rng=np.random.default_rng(seed))
    result, traj = record_run(scenario, SocialForceAgent(scenario.navigation()), params, state=state,
                              frame_rate_per_s=frame_rate_per_s, max_time_s=max_time_s, line=None, density_areas=(),
                              lane_area=None, checkpoint=checkpoint)
    wall = time.perf_counter() - t0 + (checkpoint.resumed_wall_s if checkpoint is not None else 0.0)
    exits = exit_times_s(traj, ~state.active, result.simulated_time_s)
    complete = not bool(state.active.any())
    return BackendRun("crowd_env", scenario.name, traj, exits, float(result.min_gap_m),
                      outside_distance_m(traj, scenario.geometry.walkable_area), complete, bool(result.stalled), wall,
                      float(max_time_s))


def start_times_s(run: BackendRun, threshold_m: float = 0.05) -> np.ndarray:
    """(N,) when each pedestrian first lies more than ``threshold_m`` from its start (JuPedSim's reading of
    "starts to move" in RiMEA test 5), nan if never."""
    out = np.full(run.n_pedestrians, np.nan)
    for i in range(run.n_pedestrians):
        time_s, xy = run.positions(i)
        if time_s.size == 0:
            continue
        moved = np.flatnonzero(np.hypot(*(xy - xy[0]).T) > threshold_m)
        if moved.size:
            out[i] = time_s[moved[0]]
    return out


def walking_speeds_m_s(run: BackendRun, *, skip_s: float = 3.0, window_s: float = 1.0) -> np.ndarray:
    """(N,) each pedestrian's median speed over windows of ``window_s`` after its first ``skip_s`` of
    frames (the acceleration), nan where too few frames remain."""
    fps = run.trajectories.frame_rate_per_s
    k = max(1, int(round(window_s * fps)))
    out = np.full(run.n_pedestrians, np.nan)
    for i in range(run.n_pedestrians):
        time_s, xy = run.positions(i)
        keep = time_s >= time_s[0] + skip_s if time_s.size else time_s.astype(bool)
        xy, time_s = xy[keep], time_s[keep]
        if xy.shape[0] <= k:
            continue
        v = np.hypot(*(xy[k:] - xy[:-k]).T) / (time_s[k:] - time_s[:-k])
        out[i] = float(np.median(v))
    return out


def exits_used(run: BackendRun, geometry) -> np.ndarray:
    """(N,) the index of the exit nearest to each pedestrian's last recorded position (the exit it left by,
    for one that left), -1 for those still inside at the end."""
    out = np.full(run.n_pedestrians, -1, np.int64)
    for i in range(run.n_pedestrians):
        if not np.isfinite(run.exit_time_s[i]):
            continue
        _, xy = run.positions(i)
        p = shapely.Point(*xy[-1])
        out[i] = int(np.argmin([e.distance(p) for e in geometry.exits]))
    return out


def evacuation_curve(run: BackendRun) -> tuple:
    """(times, number left by then): the N(t) staircase of a run's exit times."""
    t = np.sort(run.exit_time_s[np.isfinite(run.exit_time_s)])
    return t, np.arange(1, t.size + 1)


class WindowedTest(RimeaTest):
    """A test measured over a time window after a transient (a fundamental diagram), not to the end of an
    evacuation: its runs last ``transient_s + window_s`` of its design, ``FULL_DESIGN`` or, with ``quick``,
    ``QUICK_DESIGN`` (dicts with at least those two keys). :meth:`scenarios` records the design it built
    in ``self._design``; :meth:`design_for` recovers it from the runs' time limit when it did not."""

    FULL_DESIGN: dict = {}
    QUICK_DESIGN: dict = {}
    runs_to_time_limit = True

    def __init__(self):
        self._design = None

    @classmethod
    def design(cls, quick: bool) -> dict:
        return dict(cls.QUICK_DESIGN if quick else cls.FULL_DESIGN)

    def max_time_s(self, quick: bool) -> float:
        d = self.design(quick)
        return d["transient_s"] + d["window_s"]

    def design_for(self, runs: dict) -> dict:
        """The design the ``runs`` were made with."""
        if self._design is not None:
            return self._design
        t_max = max(r.max_time_s for r in runs.values())
        return self.design(abs(t_max - self.max_time_s(True)) < 1e-9)
