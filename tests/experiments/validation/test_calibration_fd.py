"""Calibration against the bottleneck and the fundamental diagram at once (issue 36, item 4): the fundamental
diagram's runs in every point's tasks (common random numbers), one executor and store, resumable, the extended
objective in the optimiser, the vision parameters free, the command line. (The objective's terms on constructed
records: tests/experiments/validation/test_objective.py.)"""
from __future__ import annotations

import json
import math
from functools import partial

import numpy as np
import pytest

from crowd_env.experiments.validation.calibration.errors import CalibrationError
from crowd_env.analysis.experiment import seyfried_2009
from crowd_env.analysis.fd_reference import juelich_corridor, single_file
from crowd_env.experiments.validation.calibration.objective import FD_TERMS, TargetWeights, corridor_fd_bins, required_cases
from crowd_env.cli import calibrate as cli
from crowd_env.experiments.running.backends import SerialBackend
from crowd_env.experiments.validation.calibration import optimise
from crowd_env.experiments.validation.calibration.optimize import FREE_PARAMETERS, PointEvaluator, _setup_hash
from crowd_env.experiments.validation.calibration.tasks import FDPlan, make_fd_tasks
from crowd_env.experiments.validation.fundamental_diagram import CORRIDOR_DENSITIES, run_fd_one
from crowd_env.experiments.running.store import RunStore
from tests.experiments.conftest import config

WIDTHS = [1.0, 1.2]  # the fewest the target objective takes: N = 20, 40, 60 and 120 at the capacity widths
SMALL_PLAN = FDPlan(seeds=(0, 1), corridor_densities=(0.394, 1.629, 3.101), single_file_densities=(0.658, 1.399))


class FakeBottleneck:
    """Bottleneck records on every target of the experiment, whatever the parameters; counts executions."""

    def __init__(self):
        self.calls = 0

    def __call__(self, task):
        self.calls += 1
        ref = seyfried_2009()
        b, n = task["width_m"], task["n_pedestrians"]
        js = float(ref.specific_flow_per_m_s[ref.lookup(b, 60)[0]]) if n == 60 else 2.0
        return {"width_m": b, "n_pedestrians": n, "seed": task["seed"], "n_evacuated": n, "complete": True,
                "stalled": False, "specific_flow_per_m_s": js, "stationary_specific_flow_per_m_s": 1.9,
                "speed_inside_m_s": 1.1, "density_inside_per_m2": 1.6, "density_front_per_m2": 5.0, "min_gap_m": 0.0}


class FakeSweep:
    """Fundamental-diagram records whose speed is the bin's + (T − 1 s), T the vision time gap (0 when off), and
    a single file on the experiment's headway line; counts executions."""

    def __init__(self):
        self.calls = 0

    def __call__(self, task):
        self.calls += 1
        table = juelich_corridor() if task["setup"] == "corridor" else single_file()
        shift = task["params"]["vision_time_gap_s"] - 1.0
        v = float(table.speed_at(task["density"])) + shift
        record = {"setup": task["setup"], "density": task["density"], "seed": task["seed"],
                  "n_pedestrians": task["n_pedestrians"], "speed_m_s": v, "complete": True, "stalled": False,
                  "min_gap_m": 0.0}
        if task["setup"] == "single_file":
            speeds = np.linspace(0.1, 1.2, 12)
            record.update(headway_samples_m=(0.34 + 1.08 * speeds).tolist(), speed_samples_m_s=speeds.tolist())
        return record


def test_every_point_runs_the_bottleneck_and_the_sweep_with_the_same_seeds(tmp_path):
    ev = PointEvaluator(tmp_path, config(), WIDTHS, [60], [0, 1], SerialBackend(), objective="targets+fd",
                        fd_plan=SMALL_PLAN)
    one = ev.tasks({"A": 300.0, "tau": 0.6})
    two = ev.tasks({"A": 500.0, "tau": 0.6})
    fd_one = [t for t in one if "setup" in t]
    bottleneck = [t for t in one if "setup" not in t]
    assert len(bottleneck) == len(required_cases(WIDTHS)) * 2 and len(fd_one) == SMALL_PLAN.n_runs == 10
    # common random numbers: every point has the same set-ups, densities, seeds and crowds; only its parameters differ
    plan = [(t["setup"], t["density"], t["seed"], t["n_pedestrians"]) for t in fd_one]
    assert plan == [(t["setup"], t["density"], t["seed"], t["n_pedestrians"]) for t in two if "setup" in t]
    assert sorted({p[2] for p in plan}) == [0, 1]
    assert {t["params"]["social_strength_n"] for t in fd_one} == {300.0}
    assert all(t["pedestrian"] == {"tau_s": 0.6} for t in fd_one)
    # the default plan: every shipped bin, the bottleneck's seeds
    default = PointEvaluator(tmp_path, config(), WIDTHS, [60], [3, 4], SerialBackend(), objective="targets+fd")
    assert default.fd_plan.seeds == (3, 4) and default.fd_plan.corridor_densities == CORRIDOR_DENSITIES
    assert tuple(corridor_fd_bins()[:, 0]) == CORRIDOR_DENSITIES  # the objective scores what the sweep runs
    # bottleneck-only objectives run no sweep
    assert not any("setup" in t for t in PointEvaluator(tmp_path, config(), WIDTHS, [60], [0], SerialBackend(),
                                                        objective="targets").tasks({"A": 300.0}))


def test_fd_plan_and_configuration_errors_are_named():
    with pytest.raises(CalibrationError, match="no shipped bins"):
        FDPlan(corridor_densities=(1.0,))
    with pytest.raises(CalibrationError, match="seeds"):
        FDPlan(seeds=())
    with pytest.raises(CalibrationError, match="transient"):
        FDPlan(max_time_s=10.0, transient_s=10.0)
    cfg = config()
    cfg["geometry"] = dict(cfg["geometry"], radius_m=0.2)
    with pytest.raises(CalibrationError, match="r = 0.23 m"):
        make_fd_tasks(cfg, {}, {}, FDPlan())


def test_bottleneck_only_target_set_up_keeps_its_cache_hash():
    """Evaluations cached before the fundamental diagram's weights existed stay valid."""
    import hashlib

    ref = seyfried_2009()
    old = {"widths": WIDTHS, "sizes": [20, 40, 60, 120], "seeds": [0], "range_weight": 0.0, "incomplete": "bound",
           "ref": [ref.width_m.tolist(), ref.n_pedestrians.tolist(), ref.specific_flow_per_m_s.tolist()],
           "objective": "targets", "weights": {k: 1.0 for k in ("epsilon_60", "small_groups", "ordering",
                                                               "speed_inside", "density_inside", "density_front",
                                                               "capacity")}}
    expected = hashlib.sha256(json.dumps(old, sort_keys=True).encode()).hexdigest()[:16]
    assert _setup_hash(WIDTHS, [20, 40, 60, 120], [0], None, 0.0, "bound", "targets", TargetWeights()) == expected
    fd = _setup_hash(WIDTHS, [20, 40, 60, 120], [0], None, 0.0, "bound", "targets+fd", TargetWeights(), SMALL_PLAN)
    assert fd != expected != _setup_hash(WIDTHS, [20, 40, 60, 120], [0], None, 0.0, "bound", "targets+fd",
                                         TargetWeights(), FDPlan(seeds=(0,)))


def test_optimiser_over_a_vision_parameter_finds_the_fundamental_diagram_and_resumes(tmp_path):
    assert {"vision_time_gap_s", "vision_jam_gap_m", "vision_half_angle_rad", "vision_body_scale"} <= set(FREE_PARAMETERS)
    bottleneck, sweep = FakeBottleneck(), FakeSweep()
    kw = dict(x0={"vision_time_gap_s": 2.0}, max_evaluations=30, xatol=1e-3, fatol=1e-12, run_fn=bottleneck,
              fd_run_fn=sweep, verbose=False, objective="targets+fd", fd_plan=SMALL_PLAN)
    res = optimise(tmp_path, config(), ["vision_time_gap_s"], WIDTHS, [60], [0, 1], SerialBackend(), **kw)
    assert res.objective == pytest.approx(0.0, abs=1e-12)
    assert abs(res.best["vision_time_gap_s"] - 1.0) <= 0.1 + 1e-9  # inside the ±0.10 m/s band of every bin
    first = res.history[0]  # T = 2: every bin 1 m/s off, 0.9 beyond the band
    rho = np.array(SMALL_PLAN.corridor_densities)
    assert first["terms"]["corridor_fd"] == pytest.approx(np.mean((0.9 / juelich_corridor().speed_at(rho)) ** 2))
    assert set(FD_TERMS) <= set(first["terms"]) and first["terms"]["headway_fit"] == pytest.approx(0.0, abs=1e-12)
    assert first["figures"]["fd_speed_m_s corridor rho0.394"] == pytest.approx(1.362 + 1.0)
    out = tmp_path / "optimise"
    assert json.loads((out / "optimum.json").read_text())["terms"]["corridor_fd"] == pytest.approx(0.0, abs=1e-12)
    header = (out / "history.csv").read_text().splitlines()[0].split(",")
    assert header[:2] == ["evaluation", "vision_time_gap_s"] and "single_file" in header and "headway_fit" in header
    stored = [RunStore(tmp_path, config(), keyed_by="task").load(t) for t in
              PointEvaluator(tmp_path, config(), WIDTHS, [60], [0, 1], SerialBackend(), objective="targets+fd",
                             fd_plan=SMALL_PLAN).tasks(res.best)]
    assert sum("setup" in r for r in stored) == SMALL_PLAN.n_runs  # the sweep's runs are in the run store
    calls = (bottleneck.calls, sweep.calls)
    again = optimise(tmp_path, config(), ["vision_time_gap_s"], WIDTHS, [60], [0, 1], SerialBackend(), **kw)
    assert again.n_computed == 0 and (bottleneck.calls, sweep.calls) == calls and again.best == res.best


def test_weights_zero_give_the_bottleneck_objective(tmp_path):
    sweep = FakeSweep()
    zero = TargetWeights(**{k: 0.0 for k in FD_TERMS})
    ev = PointEvaluator(tmp_path / "a", config(), WIDTHS, [60], [0], SerialBackend(), run_fn=FakeBottleneck(),
                        fd_run_fn=sweep, objective="targets+fd", fd_plan=SMALL_PLAN, weights=zero)
    entry = ev({"vision_time_gap_s": 3.0})
    assert entry["terms"]["corridor_fd"] > 0 and entry["objective"] == pytest.approx(0.0, abs=1e-12)
    bottleneck_only = PointEvaluator(tmp_path / "b", config(), WIDTHS, [60], [0], SerialBackend(),
                                     run_fn=FakeBottleneck(), objective="targets")({"vision_time_gap_s": 3.0})
    assert set(bottleneck_only["terms"]).isdisjoint(FD_TERMS) and bottleneck_only["objective"] == 0.0


def test_a_real_tiny_sweep_point_runs_and_scores(tmp_path):
    """The sweep's real runs (a short strip, a few seconds simulated) through the evaluator, with a pedestrian
    override reaching them; the bottleneck stays faked to keep this test at seconds."""
    plan = FDPlan(seeds=(0,), corridor_densities=(0.394,), single_file_densities=(0.658,), length_m=6.0,
                  max_time_s=4.0, transient_s=2.0)
    ev = PointEvaluator(tmp_path, config(), WIDTHS, [60], [0], SerialBackend(), run_fn=FakeBottleneck(),
                        objective="targets+fd", fd_plan=plan)
    slow = ev({"speed_mean": 0.6})
    assert not slow["failed_point"] and all(math.isfinite(slow["terms"][k]) for k in FD_TERMS)
    v = slow["figures"]["fd_speed_m_s corridor rho0.394"]
    assert 0.2 < v < 0.8  # walks at about its desired 0.6 m/s, far below the bin's 1.36
    assert slow["terms"]["corridor_fd"] == pytest.approx(((1.362 - v - 0.1) / 1.362) ** 2)
    fast = ev({"speed_mean": 1.34})
    assert fast["figures"]["fd_speed_m_s corridor rho0.394"] > v + 0.3
    task = [t for t in ev.tasks({"speed_mean": 0.6}) if t.get("setup") == "corridor"][0]
    assert run_fd_one(task)["speed_m_s"] == v  # the stored run is the run: deterministic


CLI_ARGV = ["optimize", "--preset", "vision", "--objective", "targets+fd", "--free", "vision_body_scale",
            "--max-evaluations", "1", "--widths", "1.0", "1.2", "--seeds", "1", "--backend", "serial",
            "--fd-densities", "0.394", "--fd-single-file-densities", "0.658", "--fd-length", "6", "--fd-time", "4",
            "--fd-transient", "2"]


def test_cli_optimise_with_the_fundamental_diagram(tmp_path, capsys, monkeypatch):
    """The command line's options reach the evaluator: a tiny budget (one point), the sweep's
    real runs on the serial backend; the bottleneck runs faked to keep this at seconds (the slow test below runs
    them too)."""
    monkeypatch.setattr(cli, "optimise", partial(optimise, run_fn=FakeBottleneck()))
    out = tmp_path / "cal"
    argv = CLI_ARGV + ["--weight", "headway_fit=2", "--out", str(out)]
    assert cli.main(argv) == 0
    optimum = json.loads((out / "optimise" / "optimum.json").read_text())
    assert set(FD_TERMS) <= set(optimum["terms"]) and "vision_body_scale" in optimum["best"]
    stored = [json.loads(p.read_text())["task"] for p in (out / "runs").glob("*.json")]
    assert sum("setup" in t for t in stored) == 2  # one corridor + one single-file run
    assert {t["length_m"] for t in stored if "setup" in t} == {6.0}
    assert "each point: 8 bottleneck runs + 2 fundamental-diagram runs" in capsys.readouterr().err
    mtimes = {p: p.stat().st_mtime_ns for p in (out / "runs").glob("*.json")}
    assert cli.main(argv) == 0 and {p: p.stat().st_mtime_ns for p in (out / "runs").glob("*.json")} == mtimes
    for extra, msg in [(["--fd-densities", "1.0"], "no shipped bins"), (["--weight", "nope=1"], "unknown weight"),
                       (["--free", "vision_rays"], "unknown free parameter")]:
        with pytest.raises(SystemExit, match=msg):
            cli.main(argv + extra)


@pytest.mark.slow
def test_cli_optimise_with_the_fundamental_diagram_all_real(tmp_path):
    """The same with every run real: the vision preset's bottleneck runs at 1.0 and 1.2 m (about 20 s)."""
    out = tmp_path / "cal"
    assert cli.main(CLI_ARGV + ["--out", str(out)]) == 0
    lines = (out / "optimise" / "evaluations.jsonl").read_text().splitlines()
    entries = [json.loads(x) for x in lines]
    assert len(entries) == 1 and (entries[0]["failed_point"] or set(FD_TERMS) <= set(entries[0]["terms"]))
    assert len(list((out / "runs").glob("*.json"))) == 8 + 2


TARGETS_ARGV = ["targets", "--presets", "calibrated", "--widths", "1.0", "1.2", "--seeds", "1", "--backend", "serial",
                "--max-time", "40"]
TARGETS_FD_ARGV = ["--fd", "--fd-densities", "0.394", "1.629", "--fd-single-file-densities", "0.658", "1.399",
                   "--fd-length", "6", "--fd-time", "4", "--fd-transient", "2"]


def test_cli_targets_with_the_fundamental_diagram(tmp_path, capsys):
    """``crowd-calibrate targets --fd``: a preset's real bottleneck runs (40 s: N = 120 is still walking, a failed
    point, which keeps this at seconds) and its sweep's, the five rows of the fundamental diagram printed and stored,
    resumable; without --fd the same folder gives the bottleneck's table alone, from the same runs."""
    out = tmp_path / "targets"
    assert cli.main(TARGETS_ARGV + TARGETS_FD_ARGV + ["--out", str(out)]) == 0
    printed = capsys.readouterr().out
    stored = json.loads((out / "targets.json").read_text())
    assert set(stored["figures"]) == {"calibrated"}  # each preset's seed means, for crowd-calibrate band
    rows = stored["tables"]["calibrated"]
    fd_rows = rows[-5:]
    assert [r["target"].split(":")[0] for r in fd_rows] == ["corridor 1.8 m"] * 3 + ["single file"] * 2
    assert fd_rows[0]["target"] == "corridor 1.8 m: speed at the bins 0.394-1.629 /m²"
    assert fd_rows[0]["figure"].startswith(("0 of 2,", "1 of 2,", "2 of 2,"))
    assert fd_rows[3]["target"] == "single file: speed at the bins 0.658-1.399 /m"
    assert all(r["target"] in printed and r["figure"] in printed for r in fd_rows)
    assert "fundamental diagram: 1 seed(s) per density" in printed
    assert stored["fd"]["corridor_densities"] == [0.394, 1.629] and stored["fd"]["max_time_s"] == 4.0
    runs = [json.loads(p.read_text())["task"] for p in (out / "calibrated" / "runs").glob("*.json")]
    assert len(runs) == 8 + 4 and sum("setup" in t for t in runs) == 4
    mtimes = {p: p.stat().st_mtime_ns for p in (out / "calibrated" / "runs").glob("*.json")}
    assert cli.main(TARGETS_ARGV + TARGETS_FD_ARGV + ["--out", str(out)]) == 0  # resumed: nothing rerun
    assert {p: p.stat().st_mtime_ns for p in (out / "calibrated" / "runs").glob("*.json")} == mtimes
    capsys.readouterr()
    assert cli.main(TARGETS_ARGV + ["--out", str(out)]) == 0
    printed = capsys.readouterr().out
    plain = json.loads((out / "targets.json").read_text())
    assert plain["tables"]["calibrated"] == rows[:-5] and "fd" not in plain
    assert "fundamental diagram" not in printed and "corridor 1.8 m" not in printed
    with pytest.raises(SystemExit, match="no shipped bins"):
        cli.main(TARGETS_ARGV + TARGETS_FD_ARGV + ["--fd-densities", "1.0", "--out", str(out)])


@pytest.mark.parametrize("argv, named", [
    (TARGETS_ARGV + ["--fd-time", "10"], "--fd-time"),
    (TARGETS_ARGV + ["--fd-densities", "0.394", "--fd-seeds", "2"], "--fd-seeds, --fd-densities"),
    (["optimize", "--objective", "targets", "--fd-transient", "5"], "--fd-transient"),
])
def test_fd_options_without_the_fundamental_diagrams_runs_are_refused_naming_them(tmp_path, argv, named):
    """An --fd-* option given where no fundamental-diagram run is made (targets without --fd, an objective without
    the sweep) is an error naming it, not silently ignored."""
    with pytest.raises(SystemExit, match=named):
        cli.main(argv + ["--out", str(tmp_path / "x")])
