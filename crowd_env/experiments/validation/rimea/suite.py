"""Run RiMEA tests on crowd_env (and JuPedSim beside it) and report: one table, a figure per test, a
results file.

:func:`run_suite` runs every selected test's scenarios with each backend, judges them with the test's own
:meth:`~crowd_env.experiments.validation.rimea.base.RimeaTest.evaluate`, and checks the two conditions every test
shares: no overlap beyond 1 mm (``OVERLAP_LIMIT_M``) and no centre outside the walkable area. A test passes
for a backend when its criterion holds and both conditions do; a run that did not finish is reported as
incomplete, never as a figure.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field

import numpy as np

from crowd_env.errors import InputError, MissingDependencyError

from ....analysis.trajectories import Trajectories
from ...output import tables
from ...running.runner import RunCheckpoint
from crowd_env.files import save_figure_atomic, write_atomic, write_json_atomic, write_npz_atomic
from .base import OVERLAP_LIMIT_M, BackendRun, Verdict, run_crowd_env, select_tests

__all__ = ["TestResult", "run_suite", "summary_line", "load_test_result", "test_result_path", "run_path", "save_run", "load_run",
           "format_table", "write_results", "write_markdown", "BACKENDS", "JUPEDSIM_BACKENDS"]

JUPEDSIM_BACKENDS = ("jupedsim_cfsm", "jupedsim_sfm")
BACKENDS = ("crowd_env",) + JUPEDSIM_BACKENDS
OUTSIDE_LIMIT_M = 1e-9  # a centre farther than this outside the walkable area counts as outside


@dataclass
class TestResult:
    """One test's outcome: its description, and per backend the verdict, the shared conditions and the cost."""

    number: str
    title: str
    checks: str
    criterion: str
    source: str
    quick: bool
    verdicts: dict = field(default_factory=dict)  # backend -> Verdict
    min_gap_m: dict = field(default_factory=dict)  # backend -> smallest gap over all the test's runs
    outside_m: dict = field(default_factory=dict)  # backend -> largest excursion outside the walkable area
    complete: dict = field(default_factory=dict)  # backend -> every run finished
    wall_time_s: dict = field(default_factory=dict)
    figure: str | None = None

    def passed(self, backend: str = "crowd_env"):
        """The criterion and both shared conditions (None: documentation only, and the conditions hold)."""
        v = self.verdicts.get(backend)
        if v is None:
            return None
        shared = self.min_gap_m[backend] >= -OVERLAP_LIMIT_M and self.outside_m[backend] <= OUTSIDE_LIMIT_M
        if v.passed is None:
            return None if shared else False
        return bool(v.passed and shared)

    def to_dict(self) -> dict:
        out = {k: getattr(self, k) for k in ("number", "title", "checks", "criterion", "source", "quick", "figure")}
        out["backends"] = {b: {"measured": v.measured, "value": _json_number(v.value), "criterion_met": v.passed,
                               "passed": self.passed(b), "min_gap_m": _json_number(self.min_gap_m[b]),
                               "outside_m": _json_number(self.outside_m[b]), "complete": self.complete[b],
                               "wall_time_s": _json_number(self.wall_time_s[b]),
                               "details": _jsonable(v.details)} for b, v in self.verdicts.items()}
        return out


    @classmethod
    def from_dict(cls, data: dict) -> "TestResult":
        """The inverse of :meth:`to_dict` (a result read back from its file; the runs themselves are not kept)."""
        res = cls(data["number"], data["title"], data["checks"], data["criterion"], data["source"],
                  bool(data["quick"]), figure=data.get("figure"))
        for b, d in data["backends"].items():
            res.verdicts[b] = Verdict(d["measured"], _from_json_number(d["value"]), d["criterion_met"],
                                      d.get("details") or {})
            # null: no two bodies (nor a body and a wall) ever came within measuring range, a gap of +inf
            # (JSON has no infinity); an overlap is always a finite number
            res.min_gap_m[b] = math.inf if d["min_gap_m"] is None else float(d["min_gap_m"])
            res.outside_m[b] = _from_json_number(d["outside_m"])
            res.complete[b] = bool(d["complete"])
            res.wall_time_s[b] = _from_json_number(d["wall_time_s"])
        return res


def _from_json_number(x) -> float:
    return float("nan") if x is None else float(x)


def _json_number(x):
    x = float(x)
    return x if math.isfinite(x) else None


def _jsonable(value):
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_jsonable(v) for v in np.asarray(value, dtype=object).tolist()] if isinstance(value, np.ndarray) \
            else [_jsonable(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return _json_number(value)
    return value


def _runner(backend: str):
    if backend == "crowd_env":
        return run_crowd_env
    from . import jupedsim_backend  # needs the benchmark extra

    return jupedsim_backend.runner(backend)


def check_jupedsim() -> None:
    """Raise :class:`~crowd_env.errors.MissingDependencyError` naming how to install JuPedSim when it is absent."""
    import importlib.util

    if importlib.util.find_spec("jupedsim") is None:
        raise MissingDependencyError("the JuPedSim columns need JuPedSim, which is not installed: "
                                     "pip install -e '.[bench]' (or pip install jupedsim)")


def test_result_path(out_dir, number: str) -> str:
    """Where :func:`run_suite` keeps one test's result: ``<out_dir>/tests/rimea_<number>.json``."""
    return os.path.join(out_dir, "tests", f"rimea_{number}.json")


def _settings(quick: bool, seed: int, backends) -> dict:
    return {"quick": bool(quick), "seed": int(seed), "backends": list(backends)}


def load_test_result(out_dir, number: str, *, quick: bool, seed: int, backends):
    """The kept result of test ``number`` in ``out_dir`` when it was run with these settings (version, seed,
    backends) and its figure is still there; None otherwise (a result made with other settings is never
    reused)."""
    path = test_result_path(out_dir, number)
    if not os.path.exists(path):
        return None
    with open(path) as fh:
        data = json.load(fh)
    if data.get("settings") != _settings(quick, seed, backends):
        return None
    res = TestResult.from_dict(data["result"])
    if res.figure is not None and not os.path.exists(res.figure):
        return None
    return res


def _keep_test_result(out_dir, res: TestResult, *, quick: bool, seed: int, backends) -> None:
    write_json_atomic(test_result_path(out_dir, res.number),
                      {"settings": _settings(quick, seed, backends), "result": res.to_dict()})


def run_path(out_dir, number: str, variant: str, backend: str) -> str:
    """Where :func:`run_suite` keeps one scenario run: ``<out_dir>/runs/rimea_<number>_<variant>_<backend>.npz``."""
    return os.path.join(out_dir, "runs", f"rimea_{number}_{variant}_{backend}.npz")


def save_run(run: BackendRun, path: str, settings: dict) -> None:
    """Keep ``run`` at ``path`` (compressed arrays and a JSON header with ``settings``), written atomically."""
    t = run.trajectories
    meta = {"settings": settings, "backend": run.backend, "scenario_name": run.scenario_name,
            "min_gap_m": run.min_gap_m, "outside_m": run.outside_m, "complete": run.complete, "stalled": run.stalled,
            "wall_time_s": run.wall_time_s, "max_time_s": run.max_time_s, "frame_rate_per_s": t.frame_rate_per_s}
    write_npz_atomic(path, meta, frame=t.frame, id=t.id, x_m=t.x_m, y_m=t.y_m, heading_rad=t.heading_rad,
                     exit_time_s=run.exit_time_s)


def load_run(path: str, settings: dict):
    """The run kept at ``path`` when it was made with ``settings``; None otherwise. Read as data only (arrays and
    JSON, ``allow_pickle=False``); a file that is not such a run raises :class:`~crowd_env.errors.InputError`
    naming it."""
    if not os.path.exists(path):
        return None
    try:
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            if meta["settings"] != settings:
                return None
            traj = Trajectories(data["frame"], data["id"], data["x_m"], data["y_m"], data["heading_rad"],
                                meta["frame_rate_per_s"])
            return BackendRun(meta["backend"], meta["scenario_name"], traj, data["exit_time_s"], meta["min_gap_m"],
                              meta["outside_m"], meta["complete"], meta["stalled"], meta["wall_time_s"],
                              meta["max_time_s"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise InputError(f"{path} is not a run kept by crowd-rimea ({type(exc).__name__}: {exc}); delete it to make "
                         "that run again") from None


def run_suite(numbers=None, *, quick: bool = False, jupedsim: bool = False, seed: int = 0, out_dir=None,
              resume: bool = False, progress=print) -> list:
    """Run the tests ``numbers`` (default: all flat ones; see :func:`~.base.select_tests`) with crowd_env and,
    with ``jupedsim``, JuPedSim's collision-free speed and social force models. ``quick``: the reduced
    versions. ``out_dir``: where figures (``rimea_<n>.png``), each test's result (``tests/rimea_<n>.json``,
    written as soon as the test is done), each scenario run (``runs/``, :func:`run_path`, written as soon as
    it is done) and ``results.json`` (the selected tests) go (None: nothing written). ``resume``: a test
    whose kept result in ``out_dir`` was made with the same version, seed and backends is read back instead
    of run again, and so is each kept run of a test that was not finished (the full suite costs hours, one
    run of test 4 alone more than an hour: see the verification page). A test's wall time is the sum of its
    runs' own, wherever they were made. Returns the :class:`TestResult` list."""
    tests = select_tests(numbers)
    backends = BACKENDS if jupedsim else ("crowd_env",)
    if jupedsim:
        check_jupedsim()
    if resume and out_dir is None:
        raise InputError("resume needs out_dir, where the kept results are")
    if out_dir is not None:
        os.makedirs(out_dir, exist_ok=True)
    results = []
    for test in tests:
        if resume:
            kept = load_test_result(out_dir, test.number, quick=quick, seed=seed, backends=backends)
            if kept is not None:
                if progress is not None:
                    progress(f"RiMEA {test.number}: kept result read from {test_result_path(out_dir, test.number)}")
                results.append(kept)
                continue
        scenarios = test.scenarios(quick, seed)
        res = TestResult(test.number, test.title, test.checks, test.criterion, test.source, quick)
        runs_by_backend = {}
        for backend in backends:
            run = _runner(backend)
            runs = {}
            for name, sc in scenarios.items():
                settings = {**_settings(quick, seed, [backend]), "test": test.number, "variant": name,
                            "max_time_s": float(test.max_time_s(quick))}
                path = run_path(out_dir, test.number, name, backend) if out_dir is not None else None
                runs[name] = load_run(path, settings) if resume else None
                if runs[name] is None:
                    extra = {}
                    if path is not None and backend == "crowd_env":  # hour-long runs: kept every 10 min
                        extra["checkpoint"] = RunCheckpoint(path + ".checkpoint.pkl", json.dumps(settings, sort_keys=True),
                                                            resume=resume, remove_when_done=False)
                    runs[name] = run(sc, seed=seed, max_time_s=test.max_time_s(quick), **extra)
                    if path is not None:
                        save_run(runs[name], path, settings)
                    if extra:  # the run is kept: its checkpoint is not needed any more
                        extra["checkpoint"].remove()
                elif progress is not None:
                    progress(f"RiMEA {test.number} {backend} {name}: kept run read from {path}")
            runs_by_backend[backend] = runs
            res.verdicts[backend] = test.evaluate(runs)
            res.min_gap_m[backend] = min(r.min_gap_m for r in runs.values())
            res.outside_m[backend] = max(r.outside_m for r in runs.values())
            res.complete[backend] = test.runs_complete(runs)
            res.wall_time_s[backend] = float(sum(r.wall_time_s for r in runs.values()))
            if progress is not None:
                v = res.verdicts[backend]
                progress(f"RiMEA {test.number} {backend}: {v.measured} -> {_word(res.passed(backend))} "
                         f"({res.wall_time_s[backend]:.1f} s)")
        if out_dir is not None:
            res.figure = _figure(test, runs_by_backend, os.path.join(out_dir, f"rimea_{test.number}.png"))
            _keep_test_result(out_dir, res, quick=quick, seed=seed, backends=backends)
        results.append(res)
    if out_dir is not None:
        write_results(results, os.path.join(out_dir, "results.json"), seed=seed)
    return results


def _figure(test, runs_by_backend, path) -> str:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.0, 4.5))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    test.plot(ax, runs_by_backend)
    ax.set_title(f"RiMEA test {test.number}: {test.title}", fontsize=9)
    fig.tight_layout()
    return save_figure_atomic(fig, path, dpi=110)


def write_results(results, path, *, seed: int) -> str:
    """``results.json``: every test's figures per backend (machine-readable)."""
    write_json_atomic(path, {"suite": "RiMEA 4.1.1, Annex 1 (flat tests)", "seed": seed,
                             "overlap_limit_m": OVERLAP_LIMIT_M, "tests": [r.to_dict() for r in results]})
    return path


def _word(passed) -> str:
    return {True: "pass", False: "FAIL", None: "documented"}[passed]


def _cells(r: TestResult, b: str) -> list:
    """The two cells of one backend: the figure measured (marked when a run did not finish) and the result
    (with the overlap or excursion that failed the shared conditions)."""
    note = "" if r.complete[b] else " (incomplete)"
    gap = r.min_gap_m[b]
    extra = f"; overlap {-gap * 1e3:.1f} mm" if gap < -OVERLAP_LIMIT_M else ""
    extra += f"; {r.outside_m[b]:.3f} m outside" if r.outside_m[b] > OUTSIDE_LIMIT_M else ""
    return [r.verdicts[b].measured + note, _word(r.passed(b)) + extra]


def format_table(results, backends=None) -> str:
    """The table: test, what it checks, criterion, then per backend the figure measured and pass/fail."""
    backends = backends or [b for b in BACKENDS if results and b in results[0].verdicts]
    head = ["test", "checks", "criterion"]
    for b in backends:
        head += [f"{b}: measured", f"{b}: result"]
    rows = []
    for r in results:
        row = [r.number, r.checks, r.criterion]
        for b in backends:
            v: Verdict | None = r.verdicts.get(b)
            if v is None:
                row += ["-", "-"]
                continue
            row += _cells(r, b)
        rows.append(row)
    return tables.format_table(head, rows, separator="-|-")


RESULTS_PAGE = "docs/validation/rimea.md"  # its section "Reading the results" explains each failure


def summary_line(results, backends=None) -> str:
    """The closing line of a suite: per backend how many of the tests passed, which failed and how many are
    documentation only, and the page that explains the failures."""
    backends = backends or [b for b in BACKENDS if results and b in results[0].verdicts]
    parts = []
    for b in backends:
        judged = [r for r in results if b in r.verdicts]
        failed = [r.number for r in judged if r.passed(b) is False]
        documented = sum(r.passed(b) is None for r in judged)
        passed = len(judged) - len(failed) - documented
        parts.append(f"{b}: {passed} of {len(judged)} tests passed" + (f", {documented} documentation only"
                                                                       if documented else "")
                     + (f", {len(failed)} failed ({', '.join(failed)})" if failed else ", none failed"))
    failures = any(r.passed(b) is False for r in results for b in backends)
    why = f"; {RESULTS_PAGE}, 'Reading the results', explains each failure" if failures else ""
    return "; ".join(parts) + why


def write_markdown(results, path, *, command: str, figure_prefix: str = "") -> str:
    """The results as a Markdown page fragment (the table, then each test's figure), for the documentation's
    verification page, which includes it: figures (beside ``path``) are referred to as ``figure_prefix`` +
    file name, the prefix being their folder as seen from the including page."""
    backends = [b for b in BACKENDS if results and b in results[0].verdicts]
    head = ["test", "checks", "criterion"] + [x for b in backends for x in (f"{b}: measured", f"{b}")]
    rows = [[r.number, r.checks, r.criterion] + [x for b in backends for x in _cells(r, b)] for r in results]
    lines = [f"<!-- written by `{command}`; do not edit by hand -->", "", tables.format_table(head, rows, markdown=True),
             ""]
    mode = "reduced versions (--quick)" if results and results[0].quick else "full versions"
    lines.append(f"Run: {mode}; smallest gap over all runs: " + ", ".join(
        f"{b} {min(r.min_gap_m[b] for r in results) * 1e3:.3g} mm" for b in backends) + "; wall time: " + ", ".join(
        f"{b} {sum(r.wall_time_s[b] for r in results):.0f} s" for b in backends) + ".")
    lines.append("")
    for r in results:
        if r.figure:
            lines += [f"### Test {r.number}: {r.title}", "", f"Source: {r.source}.", "",
                      f"![RiMEA test {r.number}]({figure_prefix}{os.path.basename(r.figure)})", ""]
    write_atomic(path, "\n".join(lines))
    return path
