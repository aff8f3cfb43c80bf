"""The stall rule (crowd_env.experiments.running.runner.StallDetector): a constructed clog stops early as stalled and reports no
J_s; slow but moving Seyfried runs are never called stalled; incomplete runs reach every consumer (the
reproduction's records and table, older stored records, the calibration's point errors)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from baselines import SocialForceAgent
from crowd_env.walking import ModelParams
from crowd_env.walking.presets import DEFAULT_PRESET, get_preset
from crowd_env.experiments.running.runner import STALL_SPEED_M_S, STALL_WINDOW_S, RunResult, StallDetector, run_scenario
from crowd_env.scenarios import make_scenario
from crowd_env.scenarios.bottleneck import BottleneckScenario, bottleneck_geometry
from tests.experiments.conftest import point_field_geometry


def _clog(n_rows: int = 2):
    """Disks of diameter 0.6 m in front of a 0.5 m wide channel: the point field (clearance 0) leads them
    into it, so the scenario's reachability check passes, but no disk fits through."""
    geometry = bottleneck_geometry(0.5, corridor_width_m=3.0, corridor_length_m=4.0, channel_length_m=1.0)
    xs, ys = np.meshgrid(-1.0 - 0.8 * np.arange(n_rows), [-0.8, 0.0, 0.8])
    return BottleneckScenario(geometry=geometry, position_m=np.column_stack([xs.ravel(), ys.ravel()]),
                              pedestrian_params={"radius_m": 0.3, "desired_speed_m_s": 1.34},
                              navigation_clearance_m=0.0, metadata={"width_m": 0.5})


def test_constructed_clog_stops_as_stalled_well_before_the_time_limit():
    sc = _clog()
    r = run_scenario(sc, SocialForceAgent(sc.navigation()), ModelParams(), max_time_s=300.0)
    assert r.stalled and not r.complete
    # nobody ever passes: stalled one window after the start (the crowd stands still within seconds)
    assert STALL_WINDOW_S <= r.stall_time_s == r.simulated_time_s < STALL_WINDOW_S + 10.0
    assert r.n_passed == 0 and r.n_evacuated == 0
    assert np.isnan(r.specific_flow_per_m_s) and np.isnan(r.flow_per_s) and np.isnan(r.partial_specific_flow_per_m_s)
    assert np.isnan(r.evacuation_time_s)
    # they do press into the entrance: it is a clog, not a crowd that never started
    x = sc.make_state().position_m[:, 0]
    assert r.min_gap_m > -1e-3 and x.max() < -0.9
    # the rule switched off: the same run goes on to the time limit, incomplete but not stalled
    off = run_scenario(sc, SocialForceAgent(sc.navigation()), ModelParams(), max_time_s=30.0, stall_window_s=None)
    assert not off.stalled and not off.complete and off.simulated_time_s == pytest.approx(30.0)
    assert np.isnan(off.specific_flow_per_m_s)


def test_stall_after_some_passed_keeps_the_partial_flow_apart():
    """Ten pedestrians; the three farthest from the entrance have desired speed 0 and stay behind. The run
    stops as stalled one window after the last passage; J_s is nan, the partial J_s of the seven who
    passed is kept under its own name."""
    base = make_scenario("seyfried_bottleneck", width_m=1.0, n_pedestrians=10, seed=0)
    far = np.argsort(base.position_m[:, 0])[:3]
    speeds = np.full(10, 1.34)
    speeds[far] = 0.0
    sc = BottleneckScenario(geometry=base.geometry, position_m=base.position_m, metadata=base.metadata,
                            pedestrian_params={"radius_m": 0.23, "desired_speed_m_s": speeds})
    r = run_scenario(sc, SocialForceAgent(sc.navigation()), ModelParams(), max_time_s=300.0)
    assert r.stalled and not r.complete and r.n_passed == 7
    last = r.crossing_times_s.max()
    assert last + STALL_WINDOW_S <= r.stall_time_s < last + STALL_WINDOW_S + 5.0
    assert np.isnan(r.specific_flow_per_m_s) and np.isnan(r.flow_per_s)
    assert r.partial_specific_flow_per_m_s == pytest.approx(7 / ((last - r.crossing_times_s.min()) * 1.0))


@pytest.mark.parametrize("preset, width_m, n, seed", [("paper", 0.8, 60, 1), ("paper", 0.8, 20, 0),
                                                      (DEFAULT_PRESET, 0.8, 60, 0)])
def test_slow_seyfried_runs_are_not_stalled(preset, width_m, n, seed):
    """b = 0.8 m is the slowest Seyfried width; with the paper preset seed 1 at N = 60 holds the longest
    pause between passages of seeds 0-9 (5.9 s when measured)."""
    p = get_preset(preset)
    sc = make_scenario("seyfried_bottleneck", width_m=width_m, n_pedestrians=n, seed=seed,
                       navigation_clearance_m=p.navigation_clearance_m)
    r = run_scenario(sc, SocialForceAgent(sc.navigation()), p.params(), max_time_s=300.0)
    assert r.complete and not r.stalled and np.isnan(r.stall_time_s)
    assert r.n_passed == n and np.isfinite(r.specific_flow_per_m_s)
    assert r.partial_specific_flow_per_m_s == r.specific_flow_per_m_s
    assert np.diff(np.concatenate([[0.0], r.crossing_times_s])).max() < STALL_WINDOW_S / 2


def test_stall_detector_rule():
    """The rule reads the remaining pedestrians' net displacement over the window: a crowd creeping on at 1.2x the
    threshold speed never stalls, one at 0.8x stalls one window (and a step) after the start, one that shakes in
    place at 0.5 m/s without getting anywhere stalls too (the mean of instantaneous speeds did not: it was 0.5 m/s),
    a passage restarts the window, a pedestrian who passed does not count."""
    dt = 0.01
    k = int(round(STALL_WINDOW_S / dt))
    remaining = np.array([True, True, False])

    def run(net_speed, steps, progress_at=(), shake_m=0.0):
        d = StallDetector(dt)
        for i in range(steps):
            t = (i + 1) * dt
            p = np.array([[net_speed * t + shake_m * (-1) ** i, 0.0], [0.0, net_speed * t - shake_m * (-1) ** i],
                          [5.0 * t, 0.0]])  # the third has passed and walks on: it must not count
            if d.update(t, p, remaining, i in progress_at):
                return d
        return d

    slow = run(1.2 * STALL_SPEED_M_S, 3 * k)
    assert not slow.stalled  # slow but getting somewhere: never
    still = run(0.8 * STALL_SPEED_M_S, 3 * k)
    assert still.stalled and still.stall_time_s == pytest.approx(STALL_WINDOW_S + dt)
    shaking = run(0.0, 3 * k, shake_m=0.0025)  # 5 mm back and forth every step: 0.5 m/s, net 0
    assert shaking.stalled and shaking.stall_time_s == pytest.approx(STALL_WINDOW_S + dt)
    reset = run(0.0, 3 * k, progress_at=(k // 2,))  # a passage restarts the window
    assert reset.stall_time_s == pytest.approx((k // 2 + 1) * dt + STALL_WINDOW_S)
    d = StallDetector(dt)
    assert not d.update(100.0, np.zeros((3, 2)), np.zeros(3, dtype=bool), False)  # nobody remains: never stalled
    off = StallDetector(dt, window_s=None)
    assert not any(off.update((i + 1) * dt, np.zeros((3, 2)), remaining, False) for i in range(2 * k))
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="stall window"):
            StallDetector(dt, window_s=bad)
    with pytest.raises(ValueError, match="stall speed"):
        StallDetector(dt, speed_m_s=-0.1)


def test_stall_detector_memory_does_not_grow_with_the_window_in_steps():
    """The rule keeps a position snapshot every window / 20, whatever the step: at dt_s = 1e-9 (2e10 steps a
    window) it holds 22 snapshots, as at the paper's 0.01 s."""
    from crowd_env.experiments.running.runner import STALL_SNAPSHOTS_PER_WINDOW

    for dt in (0.01, 1e-9):
        d = StallDetector(dt, n_pedestrians=100)
        assert d.snapshots.shape == (STALL_SNAPSHOTS_PER_WINDOW + 2, 100, 2)


def test_run_result_defaults_keep_older_constructions_valid():
    r = RunResult(n_pedestrians=2, width_m=1.0, seed=0, n_steps=10, simulated_time_s=0.1, wall_time_s=0.0,
                  n_evacuated=2, evacuation_time_s=0.1, crossing_times_s=np.array([0.01, 0.05]), flow_per_s=50.0,
                  specific_flow_per_m_s=50.0, min_gap_m=0.0)
    assert r.complete and not r.stalled and r.partial_specific_flow_per_m_s == 50.0 and r.n_passed == 2


# --- the reproduction's records, table and stored runs -------------------------------------------------------

def _record(b, n, seed, js, complete=True, stalled=False, n_passages=None):
    n_passages = n if n_passages is None else n_passages
    return {"width_m": b, "n_pedestrians": n, "seed": seed, "specific_flow_per_m_s": js if complete else np.nan,
            "flow_per_s": js * b if complete else np.nan, "complete": complete, "stalled": stalled,
            "stall_time_s": 40.0 if stalled else np.nan, "partial_specific_flow_per_m_s": js,
            "partial_flow_per_s": js * b, "n_evacuated": n_passages, "n_passages": n_passages, "min_gap_m": -1e-4,
            "density_front_per_m2": 3.0, "density_inside_per_m2": 1.5, "speed_inside_m_s": 1.2,
            "stationary_specific_flow_per_m_s": js}


def test_summary_means_over_complete_runs_and_counts_stalls(capsys):
    from crowd_env.cli.reproduce_bottleneck import print_summary
    from crowd_env.experiments.validation.bottleneck import summarise

    records = [_record(1.0, 60, 0, 1.8), _record(1.0, 60, 1, 2.0), _record(1.0, 60, 2, 9.9, False, True, 20),
               _record(1.0, 60, 3, 5.0, False, False, 59), _record(0.8, 60, 0, 1.6), _record(1.2, 60, 0, 2.2)]
    rows = {r["width_m"]: r for r in summarise(records)}
    row = rows[1.0]
    assert (row["runs"], row["complete"], row["stalled"], row["incomplete"]) == (4, 2, 1, 1)
    assert row["specific_flow_mean"] == pytest.approx(1.9) and row["flow_mean"] == pytest.approx(1.9)
    assert row["stationary_specific_flow"] == pytest.approx(1.9)
    assert rows[0.8]["stalled"] == 0 and rows[0.8]["complete"] == 1
    print_summary(list(rows.values()), records)
    out = capsys.readouterr().out
    assert "stall/inc" in out and "1/1" in out
    assert "* mean over the complete runs only (2 of 6 runs incomplete)" in out
    assert "N = 60: flow J(b)" in out
    # a width without any complete run has no mean (nan), and the fit of J(b) leaves it out
    only_bad = summarise([_record(1.0, 60, 0, 3.0, False, True, 5)])[0]
    assert np.isnan(only_bad["specific_flow_mean"]) and only_bad["stalled"] == 1


def test_records_saved_before_the_stall_rule_load_as_incomplete():
    from crowd_env.experiments.running.store import normalise_record

    old_clogged = {"width_m": 1.0, "n_pedestrians": 60, "seed": 0, "specific_flow_per_m_s": 3.3, "flow_per_s": 3.3,
                   "n_evacuated": 22, "n_passages": 22}
    r = normalise_record(old_clogged)
    assert r["complete"] is False and r["stalled"] is False and np.isnan(r["specific_flow_per_m_s"])
    assert r["partial_specific_flow_per_m_s"] == 3.3 and np.isnan(r["flow_per_s"])
    old_done = dict(old_clogged, n_evacuated=60, n_passages=60)
    r = normalise_record(old_done)
    assert r["complete"] is True and r["specific_flow_per_m_s"] == 3.3 == r["partial_specific_flow_per_m_s"]
    new = _record(1.0, 60, 0, 2.0, False, True, 10)
    assert normalise_record(new) == new


def test_reproduction_records_and_csv_carry_the_stall_columns(tmp_path):
    from crowd_env.experiments.validation.bottleneck import run_one, run_sweep, write_results

    geometry = point_field_geometry()
    params = ModelParams().to_dict()
    task = {"width_m": 1.0, "n_pedestrians": 10, "seed": 0, "geometry": geometry, "params": params, "max_time_s": 60.0}
    rec = run_one(task)
    assert rec["complete"] is True and rec["stalled"] is False
    assert rec["partial_specific_flow_per_m_s"] == rec["specific_flow_per_m_s"]
    # desired speeds of 1 mm/s for everybody (pedestrian override, as the calibration uses): a stall
    still = run_one(dict(task, pedestrian={"desired_speed_mean_m_s": 1e-3, "desired_speed_std_m_s": 1e-6}))
    assert still["stalled"] is True and still["complete"] is False and np.isnan(still["specific_flow_per_m_s"])
    assert still["simulated_time_s"] < STALL_WINDOW_S + 5.0
    json.dumps(still)  # JSON-able
    # a stored record of an older version (no stall keys) loads normalised through run_sweep
    (tmp_path / "runs").mkdir()
    old = {k: v for k, v in still.items() if k not in ("complete", "stalled", "stall_time_s",
                                                        "partial_specific_flow_per_m_s", "partial_flow_per_s")}
    (tmp_path / "runs" / "b1.000_n10_s0.json").write_text(json.dumps(old))
    (loaded,) = run_sweep([task], tmp_path, jobs=1)
    assert loaded["complete"] is False and loaded["stalled"] is False
    write_results([loaded], tmp_path)
    header = (tmp_path / "results.csv").read_text().splitlines()[0].split(",")
    for col in ("complete", "stalled", "stall_time_s", "partial_specific_flow_per_m_s"):
        assert col in header


# --- calibration: a stalled run fails its point ------------------------------------------------------------

def test_a_stalled_run_fails_its_calibration_point(tmp_path):
    from crowd_env.analysis.experiment import seyfried_2009
    from crowd_env.experiments.running.backends import SerialBackend
    from crowd_env.experiments.validation.calibration import analyse_surface, base_config, evaluate_grid, write_grid_outputs
    from crowd_env.experiments.validation.calibration.grid import STALLED_OBJECTIVE

    exp = seyfried_2009()
    geometry = point_field_geometry()
    config = base_config(geometry, ModelParams(), 300.0)

    def fake(task):
        b, a = task["width_m"], task["params"]["social_strength_n"]
        js = float(exp.specific_flow_per_m_s[exp.lookup(b, 60)[0]])
        stalled = a == 100.0 and b == 0.8  # the exact flows elsewhere: ε_T = 0 without the stall
        return {"width_m": b, "n_pedestrians": 60, "seed": task["seed"],
                "specific_flow_per_m_s": np.nan if stalled else js, "complete": not stalled, "stalled": stalled, "partial_specific_flow_per_m_s": js,
                "n_passages": 20 if stalled else 60, "first_passage_s": 5.0}

    res = evaluate_grid(tmp_path, config, [100.0, 300.0], [0.08], [0.8, 1.0], [60], [0], SerialBackend(), run_fn=fake,
                        incomplete="partial")
    assert res.n_stalled.tolist() == [[1], [0]] and res.n_clogged.tolist() == [[1], [0]]
    # ε_T is the measured one (the partial flow equals the experiment here), the objective fails the point
    assert res.epsilon_total[0, 0] == pytest.approx(0.0, abs=1e-15)
    assert res.objective[0, 0] == pytest.approx(STALLED_OBJECTIVE * 1.5)
    assert res.objective[1, 0] == pytest.approx(0.0, abs=1e-15)
    analysis = analyse_surface(res)
    assert analysis["best"]["social_strength_n"] == 300.0  # the stalled point is never the best
    write_grid_outputs(res, tmp_path, analysis, figure=False)
    rows = (tmp_path / "surface.csv").read_text().splitlines()
    header = rows[0].split(",")
    assert rows[1].split(",")[header.index("n_stalled")] == "1"
    assert json.loads((tmp_path / "calibration.json").read_text())["n_points_with_stalls"] == 1


def test_a_crowd_wedged_at_the_0_70_m_exit_is_reported_stalled_though_it_shakes():
    """The Jülich run uo-180-180-070 with the paper's body (r = 0.23 m) and calibrated's social force: two disks
    wedge against the 0.70 m exit's edges and the corridor behind them freezes, shaking in place at several cm/s
    (the mean of instantaneous speeds, the rule before, never fired). The run stops as stalled one window after its
    last passage, reports no flow, and its stall time leaves no doubt that nobody passed in between."""
    from crowd_env.analysis.corridor_runs import uo_run

    run = uo_run("uo-180-180-070")
    sc = make_scenario("juelich_corridor", entrance_width_m=run.entrance_width_m, exit_width_m=run.exit_width_m,
                       n_pedestrians=run.n_pedestrians, seed=0)
    r = run_scenario(sc, SocialForceAgent(sc.navigation()), get_preset("calibrated").params(), max_time_s=300.0,
                     line="exit", density_areas=(), lane_area=None)
    assert r.stalled and not r.complete and 0 < r.n_passed < run.n_pedestrians
    last = r.crossing_times_s.max()
    assert last + STALL_WINDOW_S <= r.stall_time_s <= last + STALL_WINDOW_S + 30.0
    assert np.isnan(r.flow_per_s) and np.isnan(r.specific_flow_per_m_s)
