"""The calibration on every shipped experiment as it was run (objective 'virtual'): the corridor runs' term on
constructed records, the sum with the bottleneck's and the single file's terms, the runs of a point with its body
radius, and the evaluator's plumbing with stand-in runs."""
from __future__ import annotations

import numpy as np
import pytest

from crowd_env.analysis.corridor_runs import juelich_uo_runs
from crowd_env.walking.presets import get_preset
from crowd_env.experiments.running.backends import SerialBackend
from crowd_env.experiments.validation.bottleneck import bottleneck_config
from crowd_env.experiments.validation.calibration.errors import CalibrationError
from crowd_env.experiments.validation.calibration.objective import (FAILED_POINT_OBJECTIVE, corridor_runs_term,
                                                                    target_error, virtual_error)
from crowd_env.experiments.validation.calibration.optimize import PointEvaluator
from crowd_env.walking import ModelParams
from crowd_env.cli.options import model_params_from_args
from crowd_env.experiments.validation.calibration.tasks import base_config, make_virtual_tasks
from crowd_env.experiments.validation.fundamental_diagram import SINGLE_FILE_WIDTH_M
from tests.experiments.validation.test_objective import WIDTHS, _fd_records, _records


def _corridor(density_factor=1.0, speed_shift=0.0, flow_factor=1.0, seeds=(0, 1), complete=True):
    """Records of the nine runs whose seed means are the experiment's figures times/plus the given misses."""
    out = []
    for run in juelich_uo_runs():
        for k, s in enumerate(seeds):
            d = 0.001 * (1 if k % 2 else -1)
            out.append({"experiment": "corridor", "run": run.name, "seed": s, "n_pedestrians": run.n_pedestrians,
                        "complete": complete, "stalled": not complete, "min_gap_m": 0.0,
                        "density_per_m2": run.density_per_m2 * density_factor + d,
                        "speed_m_s": run.speed_m_s + speed_shift + d,
                        "flow_exit_per_s": run.flow_exit_per_s * flow_factor + d, "flow_y0_per_s": run.flow_y0_per_s})
    return out


def test_the_corridor_runs_cost_only_their_misses_beyond_the_tolerances():
    assert corridor_runs_term(_corridor())[0] == pytest.approx(0.0, abs=1e-12)
    assert corridor_runs_term(_corridor(density_factor=1.14, speed_shift=-0.09, flow_factor=0.91))[0] == \
        pytest.approx(0.0, abs=1e-9)  # inside every tolerance
    # +25 % density everywhere: a miss of 0.10 beyond the ±15 %, one quantity of three
    assert corridor_runs_term(_corridor(density_factor=1.25))[0] == pytest.approx(0.10 ** 2 / 3, rel=1e-3)
    term, figures = corridor_runs_term(_corridor(flow_factor=0.5))  # half the flow: 0.40 beyond ±10 %
    assert term == pytest.approx(0.40 ** 2 / 3, rel=1e-3)
    assert figures["flow_exit_per_s uo-180-180-070"] == pytest.approx(juelich_uo_runs()[5].flow_exit_per_s * 0.5)
    with pytest.raises(CalibrationError, match="uo-050-180-180"):
        corridor_runs_term([r for r in _corridor() if r["run"] != "uo-050-180-180"])


def test_the_objective_sums_the_three_experiments_and_a_stalled_corridor_run_fails_the_point():
    neck = _records(js60_factor=1.1)
    single = [r for r in _fd_records(single_shift=0.3) if r["setup"] == "single_file"]
    corridor = _corridor(flow_factor=0.5)
    score = virtual_error(neck + single + corridor)
    bottleneck_only = target_error(neck, fd=False)
    assert score.terms["epsilon_60"] == pytest.approx(bottleneck_only.terms["epsilon_60"])
    assert score.terms["corridor_runs"] == pytest.approx(0.40 ** 2 / 3, rel=1e-3)
    assert score.terms["single_file"] > 0 and "corridor_fd" not in score.terms
    assert score.objective == pytest.approx(sum(score.terms.values()))
    failed = virtual_error(neck + single + _corridor(complete=False, seeds=(0,)) + corridor)
    assert failed.failed and FAILED_POINT_OBJECTIVE < failed.objective < FAILED_POINT_OBJECTIVE + 1
    with pytest.raises(CalibrationError, match="corridor runs and single-file runs"):
        virtual_error(neck + single)
    with pytest.raises(CalibrationError, match="periodic corridor"):
        virtual_error(neck + _fd_records() + corridor)


def test_a_point_runs_every_experiment_with_its_body():
    preset = get_preset("calibrated")
    params = preset.params()
    config = base_config(bottleneck_config(params, navigation_clearance_m=preset.navigation_clearance_m)["geometry"],
                         params, 300.0)
    tasks = make_virtual_tasks(config, {"social_range_m": 0.3}, {"tau_s": 0.4}, WIDTHS, (0, 1), radius_m=0.18)
    neck = [t for t in tasks if "setup" not in t and t.get("experiment") != "corridor"]
    corridor = [t for t in tasks if t.get("experiment") == "corridor"]
    single = [t for t in tasks if t.get("setup") == "single_file"]
    assert len(neck) == 2 * 17 and len(corridor) == 2 * 9 and len(single) == 2 * 6
    assert all(t["geometry"]["radius_m"] == 0.18 == t["geometry"]["navigation_clearance_m"] for t in neck)
    assert all(t["geometry"] == {"radius_m": 0.18} for t in corridor)
    assert all(t["radius_m"] == 0.18 and t["width_m"] == pytest.approx(SINGLE_FILE_WIDTH_M * 0.18 / 0.23)
               for t in single)
    assert all(t["params"]["social_range_m"] == 0.3 and t["pedestrian"] == {"tau_s": 0.4} for t in neck + single)
    assert all(t["params"]["social_range_m"] == 0.3 and t["pedestrian"] == {"tau_s": 0.4} for t in corridor)


def test_a_presets_body_reaches_every_experiment_when_no_radius_is_given():
    """``crowd-calibrate targets --virtual`` and a calibration of a preset with its own body give no radius: the
    configuration's body (joint's 0.214 m) is every experiment's, the corridor runs' and the single file's too;
    Kabalan's body leaves every task as it was (stored runs stay valid)."""
    def tasks_of(name):
        preset = get_preset(name)
        params = preset.params()
        geometry = bottleneck_config(params, navigation_clearance_m=preset.navigation_clearance_m,
                                     radius_m=preset.radius_m)["geometry"]
        return make_virtual_tasks(base_config(geometry, params, 300.0), {}, {}, WIDTHS, (0,))

    joint = tasks_of("joint")
    assert all(t["geometry"]["radius_m"] == 0.214 for t in joint if t.get("experiment") == "corridor")
    assert all(t["radius_m"] == 0.214 for t in joint if t.get("setup") == "single_file")
    assert all(t["geometry"]["radius_m"] == 0.214 == t["geometry"]["navigation_clearance_m"]
               for t in joint if "setup" not in t and t.get("experiment") != "corridor")
    calibrated = tasks_of("calibrated")
    assert all(t["geometry"] == {} for t in calibrated if t.get("experiment") == "corridor")
    assert all("radius_m" not in t for t in calibrated if t.get("setup") == "single_file")


def test_the_evaluator_scores_a_point_on_stand_in_runs_and_keeps_the_radius_to_this_objective(tmp_path):
    preset = get_preset("calibrated")
    params = preset.params()
    config = base_config(bottleneck_config(params, navigation_clearance_m=preset.navigation_clearance_m)["geometry"],
                         params, 300.0)
    neck = {(r["width_m"], r["n_pedestrians"], r["seed"]): r for r in _records()}
    single = {(r["density"], r["seed"]): r for r in _fd_records() if r["setup"] == "single_file"}
    corridor = {(r["run"], r["seed"]): r for r in _corridor(flow_factor=0.5)}
    ev = PointEvaluator(tmp_path, config, WIDTHS, (20, 40, 60), [0, 1], SerialBackend(), objective="virtual",
                        run_fn=lambda t: neck[(t["width_m"], t["n_pedestrians"], t["seed"])],
                        fd_run_fn=lambda t: single[(t["density"], t["seed"])],
                        corridor_run_fn=lambda t: corridor[(t["run"], t["seed"])])
    entry = ev({"A": 300.0, "radius": 0.2})
    assert entry["terms"]["corridor_runs"] == pytest.approx(0.40 ** 2 / 3, rel=1e-3)
    assert entry["objective"] == pytest.approx(sum(entry["terms"].values()))
    assert ev({"A": 300.0, "radius": 0.2}) == entry and ev.n_computed == 1  # cached
    targets = PointEvaluator(tmp_path / "t", config, WIDTHS, (20, 40, 60), [0], SerialBackend(), objective="targets")
    with pytest.raises(CalibrationError, match="radius is calibrated with --objective virtual"):
        targets.tasks({"radius": 0.2})
    assert np.isfinite(entry["epsilon_total"])
    # A walking-model parameter freed by its name reaches every run's parameters (here the range beside a walker).
    tasks = ev.tasks({"A": 300.0, "social_lateral_range_scale": 0.4})
    with_params = [t for t in tasks if "params" in t]
    assert len(with_params) == len(tasks) and all(
        ModelParams.from_dict(t["params"]).walking.social.lateral_range_scale == 0.4 for t in with_params)


def test_the_wall_slowdown_reaches_the_bottleneck_and_every_corridor_run_but_not_the_ring(tmp_path):
    """``crowd-calibrate ... --navigation-wall-slowdown`` (the configuration's) and a freed constant reach the
    bottleneck's field and every corridor run's alike; the single file's ring has no walls; a pair that is not one
    (a constant missing, or out of range) is refused before anything runs."""
    preset = get_preset("calibrated")
    params = preset.params()
    config = base_config(bottleneck_config(params, navigation_clearance_m=preset.navigation_clearance_m,
                                           navigation_wall_slowdown=(0.35, 0.5))["geometry"], params, 300.0)

    def slowdowns(tasks):
        neck = {tuple(t["geometry"]["navigation_wall_slowdown"]) for t in tasks
                if "setup" not in t and t.get("experiment") != "corridor"}
        corridor = {tuple(t["geometry"]["navigation_wall_slowdown"]) for t in tasks
                    if t.get("experiment") == "corridor"}
        ring = [t for t in tasks if t.get("setup") == "single_file"]
        assert ring and all("navigation_wall_slowdown" not in str(t) for t in ring)
        return neck, corridor

    assert slowdowns(make_virtual_tasks(config, {}, {}, WIDTHS, (0,))) == ({(0.35, 0.5)}, {(0.35, 0.5)})
    assert slowdowns(make_virtual_tasks(config, {}, {}, WIDTHS, (0,), navigation_wall_slowdown=(0.2, 0.8))) == \
        ({(0.2, 0.8)}, {(0.2, 0.8)})
    ev = PointEvaluator(tmp_path / "v", config, WIDTHS, (20, 40, 60), [0], SerialBackend(), objective="virtual")
    assert slowdowns(ev.tasks({"A": 300.0, "wall_slowdown_m": 0.6})) == ({(0.6, 0.5)}, {(0.6, 0.5)})
    assert slowdowns(ev.tasks({"wall_slowdown_m": 0.6, "wall_speed_factor": 0.7})) == ({(0.6, 0.7)}, {(0.6, 0.7)})
    plain = base_config(bottleneck_config(params, navigation_clearance_m=preset.navigation_clearance_m)["geometry"],
                        params, 300.0)
    assert all("navigation_wall_slowdown" not in t["geometry"] for t in make_virtual_tasks(plain, {}, {}, WIDTHS, (0,))
               if "geometry" in t)  # off unless asked: stored runs keep their keys
    bare = PointEvaluator(tmp_path / "b", plain, WIDTHS, (20, 40, 60), [0], SerialBackend(), objective="virtual")
    with pytest.raises(CalibrationError, match="free wall_speed_factor too, or give the other constant"):
        bare.tasks({"wall_slowdown_m": 0.6})
    assert slowdowns(bare.tasks({"wall_slowdown_m": 0.6, "wall_speed_factor": 0.7})) == ({(0.6, 0.7)}, {(0.6, 0.7)})
    targets = PointEvaluator(tmp_path / "t", config, WIDTHS, (20, 40, 60), [0], SerialBackend(), objective="targets")
    with pytest.raises(CalibrationError, match="wall slowdown is calibrated with --objective virtual"):
        targets.tasks({"wall_speed_factor": 0.7})


def test_an_explicit_clearance_reaches_the_calibrations_corridor_runs_as_in_the_virtual_experiments():
    """``crowd-calibrate optimize --objective virtual --navigation-clearance M`` (and ``targets --virtual``) give the
    field's clearance to every corridor run as ``crowd-virtual-experiments --navigation-clearance M`` does; without
    it, or where no corridor run is part of the objective, the configuration keeps the form earlier folders have."""
    from crowd_env.cli.calibrate import _calibration_config, build_parser

    def config(*argv):
        args = build_parser().parse_args(list(argv))
        return _calibration_config(args, model_params_from_args(args))

    virtual = config("optimize", "--objective", "virtual", "--preset", "joint", "--navigation-clearance", "0.125")
    assert virtual["corridor_geometry"] == {"navigation_clearance_m": 0.125}
    assert virtual["geometry"]["navigation_clearance_m"] == 0.125
    corridor = [t for t in make_virtual_tasks(virtual, {}, {}, WIDTHS, (0,)) if t.get("experiment") == "corridor"]
    assert len(corridor) == 9 and all(t["geometry"] == {"navigation_clearance_m": 0.125, "radius_m": 0.214}
                                      for t in corridor)
    assert "corridor_geometry" not in config("optimize", "--objective", "virtual", "--preset", "joint")
    assert "corridor_geometry" not in config("optimize", "--objective", "targets", "--navigation-clearance", "0.125")
    assert config("targets", "--virtual", "--navigation-clearance", "0.2")["corridor_geometry"] == \
        {"navigation_clearance_m": 0.2}


def test_the_corridor_table_has_a_row_per_run_and_judges_each_on_every_tolerance():
    from crowd_env.experiments.validation.calibration.objective import corridor_table

    rows = corridor_table(_corridor(density_factor=1.14, speed_shift=0.09, flow_factor=1.09))
    assert len(rows) == 9 and all(r["passed"] for r in rows)
    assert rows[0]["target"].startswith("corridor uo-050-180-180 (entrance 0.5 m, exit 1.8 m, N = 61)")
    assert "0.49 / 1.34 / 1.17" in rows[0]["criterion"]
    off = corridor_table(_corridor(flow_factor=1.11))
    assert not any(r["passed"] for r in off)
    stalled = corridor_table(_corridor(complete=False))
    assert all(not r["passed"] and r["figure"] == "stalled 2 of 2" for r in stalled)
    some = corridor_table(_corridor() + _corridor(complete=False, seeds=(2,)))
    assert not some[0]["passed"] and "(1 of 3 stalled or incomplete)" in some[0]["figure"]
