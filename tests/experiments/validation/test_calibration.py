"""Calibration runs (crowd_env.experiments.validation.calibration, Kabalan Section 4.1.2): resumable grids of ε_T over
(A, B) and their outputs, clogged, interrupted and failed runs, the optimiser and the landscape along one
parameter, Ray, process and serial backends, the command line, bad input. (The error measures themselves:
tests/experiments/validation/test_calibration_errors.py.)"""
from __future__ import annotations

import json
import math
import socket
import time

import numpy as np
import pytest

from crowd_env.experiments.validation.calibration.errors import CalibrationError, censored_specific_flow
from crowd_env.analysis.experiment import ExperimentTable
from crowd_env.cli import calibrate as cli
from crowd_env.experiments.running.backends import RayBackend, SerialBackend, check_reachable, make_backend
from crowd_env.experiments.validation.bottleneck import run_one
from crowd_env.experiments.validation.bottleneck import run_one as run_task
from crowd_env.experiments.validation.calibration import analyse_surface, evaluate_grid, make_task, optimise, write_grid_outputs
from crowd_env.experiments.running.store import RunStore
from tests.conftest import exp_js
from tests.experiments.conftest import config

WIDTHS = [0.8, 1.0, 1.2]


class FakeRun:
    """Synthetic J_s(A, B, b, N, seed) with a known ε_T; counts executions."""

    def __init__(self, a0=400.0, b0=0.05, fail=None, interrupt_after=None, passed=None):
        self.a0, self.b0, self.calls, self.fail, self.interrupt_after = a0, b0, 0, fail, interrupt_after
        self.passed = passed  # task -> number of passages (default: all N)

    def js(self, task):
        p = task["params"]
        dev = 0.5 * math.log(p["social_strength_n"] / self.a0) ** 2 + 0.5 * math.log(p["social_range_m"] / self.b0) ** 2
        base = exp_js(task["width_m"]) if task["n_pedestrians"] == 60 else 2.0
        return base * (1.0 + dev) * (1.0 + 0.01 * task["seed"])

    def __call__(self, task):
        if self.interrupt_after is not None and self.calls >= self.interrupt_after:
            raise KeyboardInterrupt
        self.calls += 1
        if self.fail is not None and self.fail(task):
            raise RuntimeError("solver exploded")
        n_passed = self.passed(task) if self.passed else task["n_pedestrians"]
        return {"width_m": task["width_m"], "n_pedestrians": task["n_pedestrians"], "seed": task["seed"],
                "specific_flow_per_m_s": self.js(task), "n_passages": n_passed, "first_passage_s": 5.0}


# --- resumable grid ---------------------------------------------------------------------------------------

def test_grid_epsilon_matches_hand_computation_and_resume_skips_done_runs(tmp_path):
    fake = FakeRun()
    a_values, b_values, seeds = [200.0, 400.0], [0.05, 0.1], [0, 1]
    res = evaluate_grid(tmp_path, config(), a_values, b_values, WIDTHS, [60], seeds, SerialBackend(), run_fn=fake)
    assert fake.calls == 2 * 2 * 3 * 2
    for i, a in enumerate(a_values):
        for j, bb in enumerate(b_values):
            flows = {w: np.mean([fake.js(make_task(config(), {"social_strength_n": a, "social_range_m": bb}, {}, w, 60, s))
                                 for s in seeds]) for w in WIDTHS}
            hand = np.mean([(flows[w] / exp_js(w) - 1) ** 2 for w in WIDTHS])
            assert res.epsilon_total[i, j] == pytest.approx(hand, rel=1e-12)
    # a rerun executes nothing; deleting runs (a crash before they were saved) reruns exactly those
    evaluate_grid(tmp_path, config(), a_values, b_values, WIDTHS, [60], seeds, SerialBackend(), run_fn=fake)
    assert fake.calls == 24
    files = sorted((tmp_path / "runs").glob("*.json"))
    for f in files[:3]:
        f.unlink()
    again = evaluate_grid(tmp_path, config(), a_values, b_values, WIDTHS, [60], seeds, SerialBackend(), run_fn=fake)
    assert fake.calls == 27
    np.testing.assert_array_equal(again.epsilon_total, res.epsilon_total)
    # outputs: table, valley, summary, figure
    analysis = analyse_surface(again)
    paths = write_grid_outputs(again, tmp_path, analysis)
    assert all(p.exists() for p in paths)
    rows = (tmp_path / "surface.csv").read_text().splitlines()
    assert len(rows) == 1 + 4 and rows[0].startswith("social_strength_n,social_range_m,epsilon_total")
    summary = json.loads((tmp_path / "calibration.json").read_text())
    assert summary["best_point"]["social_strength_n"] == 400.0 and summary["best_point"]["social_range_m"] == 0.05


def test_clogged_runs_count_with_the_time_limit_bound(tmp_path):
    assert np.allclose(censored_specific_flow([3.0, 1.9, 2.0], 60, [7, 60, 0], [12.0, 3.0, np.nan], 300.0, 0.8),
                       [60 / (288.0 * 0.8), 1.9, 60 / (300.0 * 0.8)])
    # b = 0.8 m clogs: 7 of 60 pass; its partial J_s (large) is replaced by 60 / ((300 - 5) 0.8)
    fake = FakeRun(a0=400.0, b0=0.05, passed=lambda t: 7 if t["width_m"] == 0.8 else t["n_pedestrians"])
    res = evaluate_grid(tmp_path, config(), [400.0], [0.05], WIDTHS, [60], [0], SerialBackend(), run_fn=fake)
    hand = np.mean([(60 / (295.0 * 0.8) / exp_js(0.8) - 1) ** 2, 0.0, 0.0])
    assert res.epsilon_total[0, 0] == pytest.approx(hand, rel=1e-12)
    assert res.n_clogged[0, 0] == 1
    # 'partial': the reproduction's J_s of the passages so far (no new runs)
    calls = fake.calls
    part = evaluate_grid(tmp_path, config(), [400.0], [0.05], WIDTHS, [60], [0], SerialBackend(), run_fn=fake,
                         incomplete="partial")
    assert fake.calls == calls and part.epsilon_total[0, 0] == pytest.approx(0.0, abs=1e-15)
    with pytest.raises(CalibrationError, match="incomplete"):
        evaluate_grid(tmp_path, config(), [400.0], [0.05], WIDTHS, [60], [0], SerialBackend(), run_fn=fake,
                      incomplete="drop")


def test_interrupted_grid_keeps_finished_runs(tmp_path):
    fake = FakeRun(interrupt_after=5)
    with pytest.raises(KeyboardInterrupt):
        evaluate_grid(tmp_path, config(), [100.0, 300.0], [0.08], WIDTHS, [60], [0], SerialBackend(), run_fn=fake)
    assert len(list((tmp_path / "runs").glob("*.json"))) == 5
    assert not list((tmp_path / "runs").glob(".*tmp"))
    fake.interrupt_after = None
    res = evaluate_grid(tmp_path, config(), [100.0, 300.0], [0.08], WIDTHS, [60], [0], SerialBackend(), run_fn=fake)
    assert fake.calls == 6 and np.isfinite(res.epsilon_total).all()


def test_failed_runs_are_logged_and_retried(tmp_path):
    fake = FakeRun(fail=lambda t: t["params"]["social_strength_n"] == 100.0 and t["width_m"] == 1.0)
    res = evaluate_grid(tmp_path, config(), [100.0, 300.0], [0.08], WIDTHS, [60], [0], SerialBackend(), run_fn=fake)
    assert res.n_failed_runs == 1 and np.isnan(res.epsilon_total[0, 0]) and np.isfinite(res.epsilon_total[1, 0])
    assert "solver exploded" in (tmp_path / "errors.jsonl").read_text()
    assert res.failure_report.startswith("1 of 6 run(s) failed: ") and "RuntimeError: solver exploded; a rerun " \
        "retries them and can help if the cause was the machine" in res.failure_report
    fake.fail = None
    res = evaluate_grid(tmp_path, config(), [100.0, 300.0], [0.08], WIDTHS, [60], [0], SerialBackend(), run_fn=fake)
    assert fake.calls == 7 and np.isfinite(res.epsilon_total).all()


def test_folder_of_another_configuration_is_refused_and_untouched(tmp_path):
    evaluate_grid(tmp_path, config(), [100.0], [0.08], [1.0], [60], [0], SerialBackend(), run_fn=FakeRun())
    before = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    fake = FakeRun()
    with pytest.raises(CalibrationError, match=r"different configuration.*params.normal_dissipation_kg"):
        evaluate_grid(tmp_path, config(normal_dissipation_kg=1e3), [100.0], [0.08], [1.0], [60], [0], SerialBackend(),
                      run_fn=fake)
    assert fake.calls == 0
    assert {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()} == before
    # a folder of runs without config.json (e.g. a reproduction output) is refused too
    (tmp_path / "other" / "runs").mkdir(parents=True)
    (tmp_path / "other" / "runs" / "b1.000_n60_s0.json").write_text("{}")
    with pytest.raises(CalibrationError, match="not a calibration folder"):
        RunStore(tmp_path / "other", config())


def test_grid_bad_input(tmp_path):
    be = SerialBackend()
    for a, b, msg in [([], [0.08], "empty"), ([-10.0, 100.0], [0.08], "> 0"), ([100.0], [0.0], "> 0"),
                      ([100.0, 50.0], [0.08], "increasing"), ([100.0, 100.0000001], [0.08], "coincide")]:
        with pytest.raises(CalibrationError, match=msg):
            evaluate_grid(tmp_path, config(), a, b, [1.0], [60], [0], be, run_fn=FakeRun())
    for widths, sizes, seeds, msg in [([], [60], [0], "at least one"), ([1.0], [1], [0], ">= 2"),
                                      ([1.0, 1.0], [60], [0], "distinct"), ([1.0], [60], [-1], "seeds")]:
        with pytest.raises(CalibrationError, match=msg):
            evaluate_grid(tmp_path, config(), [100.0], [0.08], widths, sizes, seeds, be, run_fn=FakeRun())
    with pytest.raises(CalibrationError, match="experimental counterpart"):
        evaluate_grid(tmp_path, config(), [100.0], [0.08], [1.0], [20], [0], be, run_fn=FakeRun())
    with pytest.raises(CalibrationError, match="grid axes"):
        evaluate_grid(tmp_path, config(), [100.0], [0.08], [1.0], [60], [0], be, run_fn=FakeRun(),
                      model={"social_range_m": 0.1})
    assert not list((tmp_path / "runs").glob("*.json"))


# --- optimiser ----------------------------------------------------------------------------------------------

def test_optimiser_finds_the_minimum_and_resumes_from_its_cache(tmp_path):
    fake = FakeRun(a0=400.0, b0=0.05)
    kw = dict(x0={"A": 790.0, "B": 0.08}, max_evaluations=80, xatol=1e-3, fatol=1e-12, run_fn=fake, verbose=False)
    res = optimise(tmp_path, config(), ["A", "B"], WIDTHS, [60], [0], SerialBackend(), **kw)
    assert res.best["A"] == pytest.approx(400.0, rel=0.01) and res.best["B"] == pytest.approx(0.05, rel=0.01)
    assert res.objective < 1e-6 and 0 < res.n_computed <= res.n_evaluations
    calls = fake.calls
    again = optimise(tmp_path, config(), ["A", "B"], WIDTHS, [60], [0], SerialBackend(), **kw)
    assert fake.calls == calls and again.n_computed == 0 and again.best == res.best
    assert (tmp_path / "optimise" / "optimum.json").exists()
    history = (tmp_path / "optimise" / "history.csv").read_text().splitlines()
    assert len(history) == again.n_evaluations + 1


def test_optimiser_bad_input(tmp_path):
    be = SerialBackend()
    for kw, msg in [(dict(free=["A", "C"]), "unknown free"), (dict(free=[]), "no free"),
                    (dict(free=["A"], x0={"A": -5.0}), "> 0"), (dict(free=["A"], x0={"B": 0.1}), "not free"),
                    (dict(free=["B"], bounds={"B": (0.2, 0.1)}), "low < high"),
                    (dict(free=["A"], x0={"A": 1e5}), "outside its bounds"),
                    (dict(free=["A"], method="BFGS"), "unknown method"),
                    (dict(free=["A"], max_evaluations=0), "max_evaluations")]:
        free = kw.pop("free")
        with pytest.raises(CalibrationError, match=msg):
            optimise(tmp_path, config(), free, [1.0], [60], [0], be, run_fn=FakeRun(), verbose=False, **kw)


# --- real runs: same numbers as the reproduction; Ray -------------------------------------------------------

def test_pedestrian_override_path_equals_run_one_at_the_defaults():
    task = make_task(config(), {}, {}, 1.0, 20, 3)
    custom = make_task(config(), {}, {"tau_s": 0.5, "desired_speed_mean_m_s": 1.34, "desired_speed_std_m_s": 0.26},
                       1.0, 20, 3)
    ref = run_one(task)
    assert run_task(task)["specific_flow_per_m_s"] == ref["specific_flow_per_m_s"]
    assert run_task(custom)["specific_flow_per_m_s"] == pytest.approx(ref["specific_flow_per_m_s"], rel=1e-12)
    with pytest.raises(CalibrationError, match="unknown pedestrian"):
        make_task(config(), {}, {"mass_kg": 80.0}, 1.0, 20, 0)
    with pytest.raises(CalibrationError, match="> 0"):
        make_task(config(), {}, {"tau_s": 0.0}, 1.0, 20, 0)
    with pytest.raises(CalibrationError, match="social_strength_n"):
        make_task(config(), {"social_strength_n": -1.0}, {}, 1.0, 20, 0)


def test_ray_backend_runs_a_tiny_grid_like_the_reproduction(tmp_path):
    pytest.importorskip("ray")
    ref = ExperimentTable.from_arrays([1.0], [20], [1.9])
    with RayBackend(num_cpus=2) as backend:
        res = evaluate_grid(tmp_path, config(), [400.0, 790.0], [0.08], [1.0], [20], [0], backend, reference=ref)
    assert np.isfinite(res.epsilon_total).all()
    # the 790 N / 0.08 m point is the reproduction's default run: identical J_s
    js = run_one(make_task(config(), {}, {}, 1.0, 20, 0))["specific_flow_per_m_s"]
    assert res.epsilon_total[1, 0] == pytest.approx((js / 1.9 - 1) ** 2, rel=1e-12)
    assert len(list((tmp_path / "runs").glob("*.json"))) == 2


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_unreachable_ray_address_fails_fast():
    t0 = time.perf_counter()
    with pytest.raises(CalibrationError, match="cannot reach the Ray cluster"):
        check_reachable(f"127.0.0.1:{_closed_port()}", timeout_s=2.0)
    with pytest.raises(CalibrationError, match="cannot reach the Ray cluster"):
        check_reachable("ray://192.0.2.1:10001", timeout_s=1.0)  # TEST-NET: never answers
    assert time.perf_counter() - t0 < 10.0
    with pytest.raises(CalibrationError, match="host:port"):
        check_reachable("no-port-here")
    with pytest.raises(CalibrationError, match="unknown backend"):
        make_backend("dask")
    with pytest.raises(CalibrationError, match="needs the ray backend"):
        make_backend("serial", address="127.0.0.1:6379")


# --- command line -------------------------------------------------------------------------------------------

def test_cli_grid_end_to_end_and_errors(tmp_path, capsys):
    ref = tmp_path / "ref.csv"
    ref.write_text("# custom reference\nb_m,n_pedestrians,specific_flow_per_m_s\n1.0,20,1.9\n")
    out = tmp_path / "cal"
    argv = ["grid", "--A-values", "790", "--B-values", "0.08", "--widths", "1.0", "--sizes", "20", "--backend",
            "serial", "--reference", str(ref), "--out", str(out)]
    assert cli.main(argv) == 0
    assert "best grid point: A = 790 N, B = 0.08 m" in capsys.readouterr().out
    for name in ("surface.csv", "valley.csv", "calibration.json", "fig10_epsilon_surface.png", "config.json"):
        assert (out / name).exists(), name
    run_file = next((out / "runs").glob("*.json"))
    mtime = run_file.stat().st_mtime_ns
    assert cli.main(argv) == 0 and run_file.stat().st_mtime_ns == mtime  # resumed: nothing rerun
    bad = [(["--A-values", "-1", "5"], "> 0"), (["--grid-size", "0", "4"], "integer >= 1"),
           (["--A-range", "10", "100"], "do not combine"),
           (["--kn", "1000"], "different configuration"),
           (["--backend", "ray", "--address", f"127.0.0.1:{_closed_port()}", "--connect-timeout", "1"],
            "cannot reach the Ray cluster")]
    for extra, msg in bad:
        args = [a for a in argv if a not in ("--backend", "serial")] if "--backend" in extra else list(argv)
        if "--grid-size" in extra:
            args = [a for a in args if a not in ("--A-values", "790")]
        with pytest.raises(SystemExit, match=msg):
            cli.main(args + extra)


def test_process_backend_and_powell_give_the_serial_numbers(tmp_path):
    from crowd_env.experiments.running.backends import ProcessBackend

    serial = evaluate_grid(tmp_path / "s", config(), [200.0, 400.0], [0.05], WIDTHS, [60], [0], SerialBackend(),
                           run_fn=FakeRun())
    with ProcessBackend(2) as be:
        pooled = evaluate_grid(tmp_path / "p", config(), [200.0, 400.0], [0.05], WIDTHS, [60], [0], be,
                               run_fn=FakeRun())
    np.testing.assert_array_equal(pooled.epsilon_total, serial.epsilon_total)
    res = optimise(tmp_path / "s", config(), ["A"], WIDTHS, [60], [0], SerialBackend(), x0={"A": 200.0},
                   method="Powell", max_evaluations=40, run_fn=FakeRun(b0=0.08), verbose=False)
    assert res.best["A"] == pytest.approx(400.0, rel=0.05)


# --- landscape along one parameter -------------------------------------------------------------------------

def test_landscape_is_the_optimisers_objective_along_a_line_and_shares_its_cache(tmp_path):
    from crowd_env.experiments.validation.calibration.landscape import landscape, write_landscape
    from crowd_env.experiments.validation.calibration.optimize import PointEvaluator

    fake = FakeRun(a0=400.0, b0=0.05)
    cfg = config(social_range_m=0.05)  # B fixed at the fake's optimum: ε_T(A) = mean((1 + 0.5 ln²(A/400))·... - 1)²
    ev = PointEvaluator(tmp_path, cfg, WIDTHS, [60], [0], SerialBackend(), run_fn=fake)
    a_values = [200.0, 400.0, 800.0]
    entries = landscape(ev, "A", a_values, verbose=False)
    dev = [0.5 * math.log(a / 400.0) ** 2 for a in a_values]
    assert [e["epsilon_total"] for e in entries] == pytest.approx([d ** 2 for d in dev], abs=1e-12)
    assert entries[1]["objective"] == pytest.approx(0.0, abs=1e-12)
    calls = fake.calls
    # the optimiser in the same folder evaluates the same point from the cache: no new run
    again = PointEvaluator(tmp_path, cfg, WIDTHS, [60], [0], SerialBackend(), run_fn=fake)
    assert again({"A": 800.0}) == entries[2] and fake.calls == calls and again.n_computed == 0
    paths = write_landscape("A", entries, tmp_path, figure=True)
    rows = paths[0].read_text().splitlines()
    assert rows[0].startswith("A,objective,epsilon_total") and len(rows) == 4
    assert paths[1].stat().st_size > 0
    for values, msg in [(["x"], "could not convert|outside"), ([1e9], "outside its admissible"), ([], "at least one"),
                        ([300.0, 300.0], "repeated")]:
        with pytest.raises((CalibrationError, ValueError), match=msg):
            landscape(ev, "A", values, verbose=False)
    with pytest.raises(CalibrationError, match="unknown parameter"):
        landscape(ev, "C", [1.0], verbose=False)


def test_an_impossible_plan_is_refused_before_a_backend_starts(tmp_path, monkeypatch):
    """Regression (issue 52): crowd-calibrate started Ray (seconds, and a cluster's resources) before it refused
    an impossible plan. Every mode now checks its plan first and starts the backend at its first run."""
    def started(*args, **kwargs):
        raise AssertionError("a backend was started")

    monkeypatch.setattr(cli, "make_backend", started)
    with pytest.raises(SystemExit, match=r"need at least one width, group size and seed, got 1, 1, 0"):
        cli.main(["landscape", "--vary", "A", "--values", "500", "--objective", "epsilon", "--widths", "1.0",
                  "--sizes", "20", "--seeds", "0", "--backend", "ray", "--out", str(tmp_path / "l")])
    (tmp_path / "t").mkdir()
    (tmp_path / "t" / "calibrated").mkdir()
    (tmp_path / "t" / "calibrated" / "config.json").write_text('{"kind": "another"}')
    with pytest.raises(SystemExit, match=r"different configuration"):
        cli.main(["targets", "--presets", "calibrated", "--seeds", "1", "--backend", "ray", "--out",
                  str(tmp_path / "t")])
