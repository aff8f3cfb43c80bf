"""Virtual experiments (crowd_env.experiments.validation.virtual_experiments): the runs of a plan, each case's
quantities beside the experiment with the tolerance decided on the complete runs only, stalled runs counted apart,
the command's table and files."""
from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from crowd_env.analysis.corridor_runs import uo_run
from crowd_env.walking.presets import get_preset
from crowd_env.errors import InputError
from crowd_env.experiments.validation.virtual_experiments import (QUICK_PLAN, VirtualPlan, format_rows, virtual_config,
                                                                  virtual_rows, virtual_tasks)


def _config():
    p = get_preset("calibrated")
    return virtual_config(p.params(), navigation_clearance_m=p.navigation_clearance_m)


def test_the_quick_plan_runs_two_corridor_runs_one_door_and_one_bin_on_the_same_seeds():
    tasks = virtual_tasks(_config(), QUICK_PLAN)
    kinds = [t["experiment"] for t in tasks]
    assert kinds.count("bottleneck") == 2 and kinds.count("corridor") == 4 and kinds.count("single_file") == 2
    assert {t["seed"] for t in tasks} == {0, 1}
    corridor = [t for t in tasks if t["experiment"] == "corridor"]
    assert {(t["run"], t["entrance_width_m"], t["exit_width_m"], t["n_pedestrians"]) for t in corridor} == {
        ("uo-070-180-180", 0.7, 1.8, 111), ("uo-180-180-095", 1.8, 0.95, 159)}
    neck = [t for t in tasks if t["experiment"] == "bottleneck"]
    assert all(t["geometry"]["navigation_clearance_m"] == 0.23 and t["width_m"] == 1.0 for t in neck)


def test_plans_refuse_what_no_experiment_has():
    with pytest.raises(InputError, match="unknown experiment"):
        VirtualPlan(experiments=("ring",))
    with pytest.raises(InputError, match="unknown corridor run"):
        VirtualPlan(corridor_runs=("uo-999",))
    with pytest.raises(InputError, match="no shipped bins"):
        VirtualPlan(single_file_densities=(0.5,))
    with pytest.raises(InputError, match="seeds"):
        VirtualPlan(seeds=())


def _corridor_record(run, seed, rho, v, flow, complete=True, stalled=False):
    nan = math.nan
    return {"experiment": "corridor", "run": run, "seed": seed, "complete": complete, "stalled": stalled,
            "density_per_m2": rho if complete else nan, "speed_m_s": v if complete else nan,
            "flow_exit_per_s": flow if complete else nan, "flow_y0_per_s": flow if complete else nan, "min_gap_m": 0.0}


def test_rows_decide_on_the_complete_runs_and_count_the_others():
    run = uo_run("uo-180-180-070")
    records = [_corridor_record(run.name, 0, run.density_per_m2 * 1.14, run.speed_m_s + 0.09, run.flow_exit_per_s * 1.2),
               _corridor_record(run.name, 1, run.density_per_m2 * 1.14, run.speed_m_s + 0.09, run.flow_exit_per_s * 1.0),
               _corridor_record(run.name, 2, 99.0, 9.0, 99.0, complete=False, stalled=True),
               _corridor_record(run.name, 3, 99.0, 9.0, 99.0, complete=False)]
    rows = {r["quantity"]: r for r in virtual_rows(records)}
    assert rows["density (1/m²)"]["model"] == pytest.approx(run.density_per_m2 * 1.14)  # the stalled run left out
    assert rows["density (1/m²)"]["within"] and rows["speed (m/s)"]["within"]
    assert rows["exit flow (1/s)"]["model"] == pytest.approx(run.flow_exit_per_s * 1.1)  # +10 %: at the edge
    assert (rows["exit flow (1/s)"]["runs"], rows["exit flow (1/s)"]["complete"], rows["exit flow (1/s)"]["stalled"],
            rows["exit flow (1/s)"]["incomplete"]) == (4, 2, 1, 1)
    off = virtual_rows([_corridor_record(run.name, 0, run.density_per_m2 * 1.16, run.speed_m_s + 0.11, 1.0)])
    assert not any(r["within"] for r in off)
    never = virtual_rows([_corridor_record(run.name, 0, 0, 0, 0, complete=False, stalled=True)])
    assert all(not r["within"] and np.isnan(r["model"]) for r in never)  # nothing complete: no figure, no pass
    text = format_rows(virtual_rows(records))
    assert "2/4 (1/1)" in text and text.splitlines()[-1].startswith("2 of 3 quantities within tolerance; 1 run(s) stalled")


def test_the_command_runs_resumes_and_writes_its_table(tmp_path, capsys):
    from crowd_env.cli.virtual_experiments import main

    argv = ["--quick", "--experiments", "single_file", "--backend", "serial", "--out", str(tmp_path), "--no-figure"]
    assert main(argv) == 0
    first = capsys.readouterr().out
    assert "single_file" in first and "quantities within tolerance" in first
    assert (tmp_path / "virtual_experiments.csv").exists() and (tmp_path / "virtual_experiments.md").exists()
    stored = sorted((tmp_path / "runs").iterdir())
    assert len(stored) == 2
    assert main(argv) == 0  # resumes: nothing run again, the same table
    assert capsys.readouterr().out.splitlines()[-3:] == first.splitlines()[-3:]
    assert main(["--param", "bogus=1", "--out", str(tmp_path / "x")]) == 2
    assert "unknown model parameter" in capsys.readouterr().err


def test_a_body_radius_reaches_every_experiment():
    p = get_preset("calibrated")
    config = virtual_config(p.params(), navigation_clearance_m=p.navigation_clearance_m, radius_m=0.2)
    tasks = virtual_tasks(config, QUICK_PLAN)
    for t in tasks:
        if t["experiment"] == "bottleneck":
            assert t["geometry"]["radius_m"] == 0.2 == t["geometry"]["navigation_clearance_m"]
        elif t["experiment"] == "corridor":
            assert t["geometry"] == {"radius_m": 0.2}
        else:
            assert t["radius_m"] == 0.2 and t["width_m"] == pytest.approx(0.7 * 0.2 / 0.23)
    assert "radius_m" not in virtual_config(p.params(), navigation_clearance_m=0.23)


def test_passage_rows_set_the_model_beside_the_recording_measured_alike(tmp_path):
    from crowd_env.experiments.validation.corridor_runs import ENTRY_FIELDS, PASSAGE_FIELDS, recorded_passage_figures
    from crowd_env.experiments.validation.virtual_experiments import (PASSAGE_QUANTITIES, entry_figure,
                                                                      format_passage_rows, passage_rows,
                                                                      passing_figure)

    recorded = recorded_passage_figures("uo-180-180-070")
    assert recorded["exit_headway_median_s"] == pytest.approx(0.61, abs=0.01)  # the data README's table: 0.61 s
    assert recorded["exit_speed_median_m_s"] == pytest.approx(0.68, abs=0.01)
    assert recorded["exit_lateral_sd_m"] == pytest.approx(0.16, abs=0.01)
    fields = PASSAGE_FIELDS + tuple(f"entry_{k}" for k in ENTRY_FIELDS)
    assert [q for q, _ in PASSAGE_QUANTITIES] == list(fields)  # every figure a record keeps has its row
    keys = [f"{where}_{k}" for where in ("exit", "entrance") for k in fields]
    records = [dict(_corridor_record("uo-180-180-070", s, 3.0, 0.3, 1.6), width_m=0.7,
                    **{k: recorded[k] * (1 + 0.1 * s) for k in keys}) for s in (0, 1)]
    records.append(dict(_corridor_record("uo-180-180-070", 2, 3.0, 0.3, 1.6, complete=False, stalled=True),
                        width_m=0.7))  # no figures: left out
    entrance = recorded_passage_figures("uo-050-180-180")
    assert entrance["entrance_speed_median_m_s"] == pytest.approx(1.45, abs=0.01)  # a file at free speed
    assert entrance["entrance_headway_median_s"] == pytest.approx(0.77, abs=0.01)
    records.append(dict(_corridor_record("uo-050-180-180", 0, 0.3, 1.3, 0.6), width_m=1.8,
                        **{k: entrance[k] * 2.0 for k in keys}))  # the narrowed entrance: its line, not the exit's
    records.append(dict(_corridor_record("uo-180-180-180", 0, 1.0, 1.2, 2.4), width_m=1.8,
                        **dict.fromkeys(keys, 0.5)))  # no narrowed opening
    records.append(dict(_corridor_record("uo-180-180-070", 3, 3.0, 0.3, 1.6), width_m=0.7,
                        **{k: recorded[k] for k in keys if "following" not in k}))  # stored before that figure
    rows = passage_rows(records)
    n = len(fields)
    assert [r["run"] for r in rows] == ["uo-050-180-180"] * n + ["uo-180-180-070"] * n
    assert [r["opening"] for r in rows] == ["entrance 0.5 m"] * n + ["exit 0.7 m"] * n
    assert [r["runs"] for r in rows] == [1] * n + [3 if "following" not in f else 2 for f in fields]
    assert rows[0]["model"] == pytest.approx(entrance["entrance_headway_median_s"] * 2.0)
    assert rows[0]["recorded"] == entrance["entrance_headway_median_s"]
    assert rows[n]["model"] == pytest.approx((1.0 + 1.1 + 1.0) / 3 * recorded["exit_headway_median_s"])
    assert rows[n]["recorded"] == recorded["exit_headway_median_s"]
    following = PASSAGE_FIELDS.index("following_median_m")
    assert rows[n + following]["model"] == pytest.approx(recorded["exit_following_median_m"] * 1.05)
    assert format_passage_rows(rows).count("uo-180-180-070 | exit 0.7 m") == n
    # people pass the 0.70 m door in two staggered files: each 0.39 m behind and 0.25 m beside the one before, one
    # body width (0.46 m) between successive heads
    assert recorded["exit_following_median_m"] == pytest.approx(0.39, abs=0.01)
    assert recorded["exit_lateral_step_median_m"] == pytest.approx(0.25, abs=0.01)
    assert recorded["exit_side_alternation"] > 0.7  # each on the other side of the one before, three times in four
    assert passing_figure(records, tmp_path / "passing.png").stat().st_size > 0
    assert passing_figure(records[-2:], tmp_path / "none.png") is None  # no narrowed opening
    for r in records:  # where the next walkers stood: the exit's as recorded, the entrance's beside the gap
        if r["complete"]:
            r["exit_entry_positions_m"] = recorded["exit_entry_positions_m"]
            r["entrance_entry_positions_m"] = [[0.3, 0.2], [-0.3, 0.25]]
    assert entry_figure(records, tmp_path / "entries.png").stat().st_size > 0
    assert entry_figure([records[-2]], tmp_path / "none.png") is None  # the open 1.8 / 1.8 m run has no opening

    # people's heads cross the 0.70 m door farther off its axis than a 0.46 m disk's centre can (0.12 m), most of them
    assert recorded["exit_share_off_axis"] == pytest.approx(0.63, abs=0.05)
    # as one leaves the 0.70 m door the next is already at it, in line with its span: 0.22 m before the wall's face,
    # 0.20 m off the axis, at 0.48 m/s, and enters 0.47 s later; the camera does not see before the entrances
    assert recorded["exit_entry_before_median_m"] == pytest.approx(0.22, abs=0.01)
    assert recorded["exit_entry_offset_median_m"] == pytest.approx(0.20, abs=0.01)
    assert recorded["exit_entry_wait_median_s"] == pytest.approx(0.47, abs=0.01)
    assert recorded["exit_entry_share_beside"] < 0.05
    positions = np.array(recorded["exit_entry_positions_m"])  # every pair's, whose medians the rows give
    assert np.median(positions[:, 1]) == pytest.approx(recorded["exit_entry_before_median_m"])
    assert np.median(np.abs(positions[:, 0])) == pytest.approx(recorded["exit_entry_offset_median_m"])
    assert entrance["entrance_entry_positions_m"] == []
    assert all(np.isnan(entrance[f"entrance_entry_{k}"]) for k in ENTRY_FIELDS)
    assert [r["recorded"] for r in rows[:n] if r["quantity"].startswith("next one")] == [pytest.approx(math.nan, nan_ok=True)] * 4


def test_lapse_rows_take_each_runs_narrower_opening_beside_the_recording(tmp_path):
    from crowd_env.analysis.corridor_runs import lapse_summary
    from crowd_env.experiments.validation.corridor_runs import recorded_passage_figures
    from crowd_env.experiments.validation.virtual_experiments import format_lapse_rows, lapse_figure, lapse_rows

    blocked = [0.8, 0.7, 3.0, 0.9, 0.8]  # one arch of 3 s at the 0.5 m entrance
    records = [dict(_corridor_record("uo-050-180-180", s, 0.4, 1.3, 1.0), width_m=1.8, entrance_lapses_s=blocked,
                    exit_lapses_s=[9.0, 9.0]) for s in (0, 1)]
    records.append(dict(_corridor_record("uo-050-180-180", 2, 0.4, 1.3, 1.0, complete=False, stalled=True),
                        width_m=1.8))  # stalled: no lapses, counted
    records.append(dict(_corridor_record("uo-180-180-095", 0, 2.4, 0.4, 1.7), width_m=0.95,
                        entrance_lapses_s=[9.0, 9.0], exit_lapses_s=[0.5, 0.6, 0.7]))
    rows = lapse_rows(records)
    assert [r["run"] for r in rows] == ["uo-050-180-180"] * 6 + ["uo-180-180-095"] * 6
    assert rows[0]["opening"] == "entrance 0.5 m" and rows[6]["opening"] == "exit 0.95 m"  # the narrower one
    by = {(r["run"], r["quantity"]): r for r in rows}
    long = by[("uo-050-180-180", "share of the time in lapses > 2 s")]
    assert long["model"] == pytest.approx(3.0 / sum(blocked)) and long["runs"] == "2/3" and long["stalled"] == 1
    assert by[("uo-050-180-180", "flow without the lapses > 2 s (1/s)")]["model"] == pytest.approx(4 / 3.2)
    assert by[("uo-180-180-095", "lapse, median (s)")]["model"] == pytest.approx(0.6)  # the exit's, not the 9 s
    recorded = lapse_summary(recorded_passage_figures("uo-050-180-180")["entrance_lapses_s"])
    assert by[("uo-050-180-180", "longest lapse (s)")]["recorded"] == recorded.longest_s < 2.0
    assert format_lapse_rows(rows).count("uo-050-180-180") == 6
    assert lapse_figure(records, tmp_path / "lapses.png").stat().st_size > 0
    wedged = lapse_rows([records[2]])  # every seed stalled: listed, no figure of the model's
    assert len(wedged) == 6 and all(math.isnan(r["model"]) and r["runs"] == "0/1" and r["stalled"] == 1
                                    for r in wedged)
    assert lapse_figure([records[2]], tmp_path / "wedged.png").stat().st_size > 0
    assert lapse_rows([]) == [] and lapse_figure([], tmp_path / "none.png") is None


def test_corridor_options_reach_every_corridor_run_and_bad_ones_are_refused():
    from crowd_env.errors import ScenarioError

    p = get_preset("calibrated")
    config = virtual_config(p.params(), navigation_clearance_m=0.23, radius_m=0.2,
                            corridor_geometry={"barrier_thickness_m": 0.1})
    corridor = [t for t in virtual_tasks(config, QUICK_PLAN) if t["experiment"] == "corridor"]
    assert corridor and all(t["geometry"] == {"barrier_thickness_m": 0.1, "radius_m": 0.2} for t in corridor)
    with pytest.raises(ScenarioError, match="unknown option"):
        virtual_config(p.params(), navigation_clearance_m=0.23, corridor_geometry={"barrier_m": 0.1})


def test_one_navigation_clearance_reaches_the_bottleneck_and_every_corridor_run(capsys):
    from crowd_env.cli.virtual_experiments import build_parser, config_from_args, main
    from crowd_env.scenarios import make_scenario

    base = ["--preset", "joint", "--param", "body_depth_m=0.25", "--quick"]
    config = config_from_args(build_parser().parse_args(base + ["--navigation-clearance", "0.125"]))
    tasks = virtual_tasks(config, QUICK_PLAN)
    neck = [t for t in tasks if t["experiment"] == "bottleneck"]
    corridor = [t for t in tasks if t["experiment"] == "corridor"]
    assert neck and all(t["geometry"]["navigation_clearance_m"] == 0.125 and t["geometry"]["radius_m"] == 0.214
                        for t in neck)  # not reset to the radius by the body
    assert corridor and all(t["geometry"] == {"navigation_clearance_m": 0.125, "radius_m": 0.214} for t in corridor)
    built = make_scenario("juelich_corridor", entrance_width_m=0.5, **corridor[0]["geometry"])
    assert built.navigation_clearance_m == 0.125
    default = virtual_tasks(config_from_args(build_parser().parse_args(base)), QUICK_PLAN)
    assert {t["geometry"]["navigation_clearance_m"] for t in default if t["experiment"] == "bottleneck"} == {0.214}
    assert all("navigation_clearance_m" not in t["geometry"] for t in default if t["experiment"] == "corridor")
    twice = base + ["--navigation-clearance", "0.1", "--corridor-option", "navigation_clearance_m=0.1"]
    assert main(twice) == 2 and "give the clearance once" in capsys.readouterr().err


def test_one_wall_slowdown_reaches_the_bottleneck_and_every_corridor_run(capsys):
    from crowd_env.cli.virtual_experiments import build_parser, config_from_args, main
    from crowd_env.scenarios import make_scenario

    base = ["--quick", "--navigation-wall-slowdown", "0.35", "0.5"]
    tasks = virtual_tasks(config_from_args(build_parser().parse_args(base)), QUICK_PLAN)
    neck = [t for t in tasks if t["experiment"] == "bottleneck"]
    corridor = [t for t in tasks if t["experiment"] == "corridor"]
    assert neck and all(t["geometry"]["navigation_wall_slowdown"] == [0.35, 0.5] for t in neck)
    assert corridor and all(t["geometry"] == {"navigation_wall_slowdown": [0.35, 0.5]} for t in corridor)
    assert make_scenario("seyfried_bottleneck", **neck[0]["geometry"]).wall_slowdown == (0.35, 0.5)
    assert make_scenario("juelich_corridor", **corridor[0]["geometry"]).wall_slowdown == (0.35, 0.5)
    plain = virtual_tasks(config_from_args(build_parser().parse_args(["--quick"])), QUICK_PLAN)
    assert all("navigation_wall_slowdown" not in t["geometry"] for t in plain if t["experiment"] != "single_file")
    assert main(["--quick", "--navigation-wall-slowdown", "0.35", "1.5"]) == 2
    assert "speed_factor" in capsys.readouterr().err
    twice = base + ["--corridor-option", "navigation_wall_slowdown=[0.35,0.5]"]
    assert main(twice) == 2 and "give the wall slowdown once" in capsys.readouterr().err


def test_joint_passes_the_070_m_exit_and_keeps_what_it_was_calibrated_to_meet(tmp_path, capsys):
    """The reduced virtual experiment of the ``joint`` preset through the command (``--quick``: seeds 0-1, Seyfried's
    b = 1.0 m at N = 60; ``--corridor-runs``: the 1.0 m entrance run and the 0.70 m exit that wedges ``calibrated``
    for good): everybody out, no stall, the corridor runs' density, speed and exit flow and the door's J_s within
    tolerance (0 clogs in 20 seeds: docs/validation/virtual_experiments.md). Its misses (the narrow entrances, the
    queues behind the wider exits, the channel's speed) are in the docs' table, not here."""
    from crowd_env.cli.virtual_experiments import main

    argv = ["--preset", "joint", "--quick", "--experiments", "corridor", "bottleneck", "--corridor-runs",
            "uo-100-180-180", "uo-180-180-070", "--backend", "serial", "--no-figure", "--out", str(tmp_path)]
    assert main(argv) == 0
    assert "seeds [0, 1]" in capsys.readouterr().out
    table = list(csv.DictReader((tmp_path / "virtual_experiments.csv").open()))
    corridor = [r for r in table if r["experiment"] == "corridor"]
    assert len(corridor) == 6 and all(r["within"] == "True" for r in corridor), corridor
    assert all(int(r["complete"]) == 2 and int(r["stalled"]) == 0 for r in corridor)
    door = [r for r in table if r["experiment"] == "bottleneck" and r["quantity"].startswith("J_s")]
    assert len(door) == 1 and door[0]["within"] == "True", door
    # How close walkers come (spacing.md): never closer than the disks' two radii (no overlap), where the recorded
    # people walk beside each other closer than that (docs/validation/virtual_experiments.md, "The body").
    records = [json.loads(p.read_text())["record"] for p in (tmp_path / "runs").glob("*.json")]
    spaced = [r for r in records if r.get("experiment") == "corridor"]
    assert len(spaced) == 4 and all(np.nanmin(r["spacing_q01_m"]) >= 2 * 0.214 - 1e-3 for r in spaced)
    rows = (tmp_path / "spacing.md").read_text().splitlines()
    beside = [r.split("|") for r in rows if "beside" in r and "5 % quantile" in r]
    assert len(beside) == 2 and all(float(cells[5]) < 2 * 0.214 for cells in beside)  # recorded, beside
    # How the narrower opening is passed (passage_lapses.md): the 0.70 m exit never blocked for 2 s
    assert all(max(r["exit_lapses_s"]) < 2.0 for r in spaced if r["run"] == "uo-180-180-070")
    assert (tmp_path / "passage_lapses.md").read_text().count("uo-180-180-070 | exit 0.7 m") == 6
    # and the next walker enters the door as people do: as one leaves, the next stands in line with the door just
    # before it and enters about half a second later (recorded 0.47 s, 0.22 m before, 0.20 m off the axis)
    from crowd_env.experiments.validation.corridor_runs import recorded_passage_figures

    recorded = recorded_passage_figures("uo-180-180-070")
    door = [r for r in spaced if r["run"] == "uo-180-180-070"]
    assert len(door) == 2
    for key, within in (("wait_median_s", 0.1), ("before_median_m", 0.1), ("offset_median_m", 0.05)):
        assert all(abs(r[f"exit_entry_{key}"] - recorded[f"exit_entry_{key}"]) < within for r in door), key


def test_a_learned_policy_drives_every_run_and_an_unknown_one_is_refused(capsys):
    from crowd_env.cli.virtual_experiments import main

    p = get_preset("calibrated")
    config = virtual_config(p.params(), navigation_clearance_m=0.23, policy="bottleneck_ppo")
    tasks = virtual_tasks(config, QUICK_PLAN)
    assert {t["experiment"] for t in tasks} == {"bottleneck", "corridor", "single_file"}
    assert all(t["policy"] == {"name": "bottleneck_ppo", "learned_fraction": 1.0} for t in tasks)
    assert config["policy"] == {"name": "bottleneck_ppo", "learned_fraction": 1.0}
    assert virtual_config(p.params(), navigation_clearance_m=0.23, policy="calibrated") == _config()
    assert not any("policy" in t for t in virtual_tasks(_config(), QUICK_PLAN))
    assert main(["--quick", "--policy", "no_such_policy", "--out", "unused"]) == 2
    assert "no_such_policy" in capsys.readouterr().err
    pushed = virtual_config(p.params(), navigation_clearance_m=0.23, policy="bottleneck_ppo", policy_social_force=True)
    assert pushed["policy"] == {"name": "bottleneck_ppo", "learned_fraction": 1.0, "social_force": True}
    assert main(["--quick", "--policy-social-force", "--out", "unused"]) == 2  # a social force for no policy
    assert "name the policy" in capsys.readouterr().err
    assert main(["--quick", "--policy-social-force-below", "0.3", "--out", "unused"]) == 2  # its gate, likewise
    assert "name the policy" in capsys.readouterr().err
    assert main(["--quick", "--policy", "bottleneck_ppo", "--policy-social-force-below", "0.3", "--out", "unused"]) == 2
    assert "with social_force on" in capsys.readouterr().err  # a gate without the force it gates


def test_shoulders_pass_the_070_m_exit_off_the_axis_where_no_disk_can(tmp_path, capsys, monkeypatch):
    """The preset ``shoulders`` (bodies of three circles that turn their shoulders; docs/validation/
    virtual_experiments.md, "A body narrower front to back") through the command on the 0.70 m exit that wedges
    ``calibrated``'s disks for good, seeds 0-1: nobody stalls, and a good share of the passages cross the door
    farther off its axis than the centre of a 0.46 m disk can (the recorded people: 0.66; a disk: 0 by geometry);
    some walkers stand closer beside each other than two such disks can. The snapshot of a run draws each body
    as its three circles."""
    from crowd_env.cli.virtual_experiments import main
    from crowd_env.experiments.validation import virtual_experiments as ve

    argv = ["--preset", "shoulders", "--quick", "--experiments", "corridor", "--corridor-runs", "uo-180-180-070",
            "--backend", "serial", "--no-figure", "--out", str(tmp_path)]
    assert main(argv) == 0
    records = [json.loads(p.read_text())["record"] for p in (tmp_path / "runs").glob("*.json")]
    assert len(records) == 2 and all(r["complete"] and not r["stalled"] for r in records)
    assert all(r["exit_share_off_axis"] > 0.3 for r in records), [r["exit_share_off_axis"] for r in records]
    assert all(np.nanmin(r["spacing_q01_m"]) < 2 * 0.23 for r in records)
    drawn = {}

    def keep(fig, path):
        from matplotlib.patches import Circle

        patches = fig.axes[0].patches
        drawn["circles"] = sum(isinstance(p, Circle) for p in patches)
        drawn["arrows"] = len(patches) - drawn["circles"]  # two per walker: velocity and intent
        drawn["path"] = path
        return path

    monkeypatch.setattr(ve, "save_figure", keep)
    assert main(["--preset", "shoulders", "--snapshot", "uo-180-180-070", "--at", "12", "--out", str(tmp_path)]) == 0
    assert drawn["path"].name == "snapshot_uo-180-180-070.png"
    assert drawn["circles"] > 0 and drawn["circles"] == 3 * drawn["arrows"] // 2


def test_snapshot_frames_the_runs_narrower_opening(tmp_path):
    """The snapshot of a corridor run shows the crowd at its narrower opening: the entrance's barrier (y = 8-8.3 m)
    and the waiting crowd for a narrowed entrance, the corridor's last 5 m before a narrowed exit; a short run of the
    0.5 m entrance draws."""
    from crowd_env.experiments.validation.virtual_experiments import (VirtualPlan, run_snapshot, snapshot_figure,
                                                                       snapshot_window_m, virtual_config, virtual_tasks)
    from crowd_env.walking.presets import get_preset

    assert snapshot_window_m("uo-050-180-180") == ((-1.7, 3.5), (6.0, 10.0))
    assert snapshot_window_m("uo-180-180-070") == ((-1.0, 2.8), (-5.0, 0.0))
    assert snapshot_window_m("uo-180-180-180")[1] == (6.0, 10.0)  # as wide at both ends: the entrance
    plan = VirtualPlan(experiments=("corridor",), corridor_runs=("uo-050-180-180",), seeds=(0,))
    preset = get_preset("calibrated")
    config = virtual_config(preset.params(), navigation_clearance_m=preset.navigation_clearance_m)
    task = next(t for t in virtual_tasks(config, plan))
    study = run_snapshot(task, at_s=2.0)
    ys = study["snapshot"]["position_m"][study["snapshot"]["active"], 1]
    assert ys.min() > 6.0  # after 2 s the first have just come through the entrance ...
    assert np.mean((ys > 6.0) & (ys < 10.0)) > 0.5  # ... and most stand within the window
    assert snapshot_figure(study, tmp_path / "snapshot.png").stat().st_size > 0


def test_a_snapshot_follows_a_bottleneck_run_of_any_seed_as_the_virtual_experiments_run_it(tmp_path):
    """``--snapshot bottleneck-B-N``: Seyfried's bottleneck followed step by step, the same run as the virtual
    experiments' (its passages through the bottleneck line are the run's); a bad case is refused by name."""
    from crowd_env.experiments.validation.bottleneck import run_one
    from crowd_env.experiments.validation.virtual_experiments import (VirtualPlan, run_snapshot, snapshot_case,
                                                                       snapshot_figure, snapshot_window_m,
                                                                       virtual_config, virtual_tasks)
    from crowd_env.walking.presets import get_preset

    keywords, case = snapshot_case("bottleneck-0.8-20")
    assert case == "bottleneck-0.8-20" and keywords == {"experiments": ("bottleneck",), "widths_m": (0.8,),
                                                         "sizes": (20,)}
    assert snapshot_case("uo-180-180-070") == ({"experiments": ("corridor",), "corridor_runs": ("uo-180-180-070",)},
                                               "uo-180-180-070")
    for bad in ("bottleneck-0.8", "bottleneck-wide-20", "bottleneck-0-20", "uo-999-180-180"):
        with pytest.raises(InputError, match="snapshot case"):
            snapshot_case(bad)
    assert snapshot_window_m("bottleneck-0.8-20") == ((-3.0, 3.3), (-2.0, 2.0))
    preset = get_preset("calibrated")
    config = virtual_config(preset.params(), navigation_clearance_m=preset.navigation_clearance_m)
    task = next(t for t in virtual_tasks(config, VirtualPlan(seeds=(3,), **keywords)))
    study = run_snapshot(task, at_s=8.0)
    assert study["run"] == "bottleneck-0.8-20" and study["seed"] == 3
    crossed = np.sort(run_one(task)["crossing_times_s"])  # the virtual experiments' run of that seed ...
    assert study["crossing_times_s"].size > 0  # ... passes the bottleneck's line at the same times, to the bit
    np.testing.assert_array_equal(np.round(study["crossing_times_s"], 4), crossed[:study["crossing_times_s"].size])
    # (the record keeps them to 0.1 ms)
    assert crossed[study["crossing_times_s"].size] > study["snapshot"]["time_s"]
    xs = study["snapshot"]["position_m"][study["snapshot"]["active"], 0]
    assert np.all(xs > -7.0) and np.mean(xs < 3.3) > 0.9  # those left stand in the window, before or in the channel
    assert snapshot_figure(study, tmp_path / "snapshot.png").stat().st_size > 0
