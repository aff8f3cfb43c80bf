"""crowd-fundamental-diagram's density sweep and candidates modes: outputs, resumption, refusals."""
import json

import pytest

from crowd_env.cli.fundamental_diagram import main


def test_sweep_writes_the_table_and_figure_and_resumes(tmp_path, capsys):
    out = tmp_path / "fd"
    argv = ["--sweep", "--preset", "vision", "--seeds", "1", "--densities", "1.147", "--single-file-densities",
            "1.119", "--sweep-time", "12", "--transient", "4", "--backend", "serial", "--out", str(out)]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "corridor (vision, 1 seed)" in text and "single file headway fit" in text
    assert (out / "fd_sweep.png").stat().st_size > 0
    rows = (out / "fd_sweep.csv").read_text().splitlines()
    assert rows[0].startswith("setup,density,nominal_density,speed_m_s") and len(rows) == 3
    runs = sorted((out / "runs").iterdir())
    assert len(runs) == 2
    mtimes = [p.stat().st_mtime_ns for p in runs]
    assert main(argv) == 0  # resumes: nothing runs again
    assert [p.stat().st_mtime_ns for p in runs] == mtimes
    assert capsys.readouterr().out.splitlines()[1] == text.splitlines()[1]


def test_sweep_runs_the_preset_with_set_changes(tmp_path, capsys):
    out = tmp_path / "fd"
    argv = ["--sweep", "--preset", "vision", "--set", "vision_time_gap_s=0.5", "--setups", "corridor", "--seeds", "1",
            "--densities", "1.147", "--sweep-time", "4", "--transient", "2", "--backend", "serial", "--out", str(out)]
    assert main(argv) == 0
    params = json.loads((out / "config.json").read_text())["params"]
    assert params["vision_time_gap_s"] == 0.5 and params["vision_rays"] == 11  # the change on top of the preset
    with pytest.raises(Exception, match="vision_time_gap"):
        main(argv[:4] + ["vision_time_gap=0.5"] + argv[5:])


def test_candidates_measure_door_and_corridor_and_are_read_back(tmp_path, capsys):
    out = tmp_path / "cand"
    argv = ["--candidates", "--preset", "vision", "--grid", "vision_time_gap_s=1.0", "--out", str(out)]
    assert main(argv) == 0
    row = json.loads((out / "candidates.jsonl").read_text())
    assert row["preset"] == "vision" and row["changes"] == {"vision_time_gap_s": 1.0}
    assert sorted(row["door"]) == ["0.8", "1.0", "1.2"] and len(row["corridor"]) == 6
    assert all(d["runs"] == 2 for d in row["door"].values())
    assert (out / "candidates.png").stat().st_size > 0
    printed = capsys.readouterr().out.splitlines()[-2]
    assert main(argv) == 0  # the kept point is printed, not run again
    assert len((out / "candidates.jsonl").read_text().splitlines()) == 1
    assert capsys.readouterr().out.splitlines()[-2] == printed


@pytest.mark.parametrize("argv, match", [
    (["--sweep", "--candidates"], "not both"),
    (["--candidates", "--grid", "vision_rays"], "expected NAME=VALUE"),
    (["--candidates", "--set", "vision_rays=x"], "is not a number"),
    (["--candidates", "--grid", "vision_rays=2"], "vision_rays must be an odd integer"),
])
def test_bad_options_are_refused_naming_them(tmp_path, argv, match):
    with pytest.raises(SystemExit, match=match):
        main(argv + ["--out", str(tmp_path / "x")])


def test_a_failed_sweep_run_says_why_and_that_a_rerun_fails_alike(tmp_path):
    """Regression (issue 52): --densities 9 printed '1 run(s) failed (see errors.jsonl); rerun to retry them',
    the reason (9 /m² cannot be placed) only in the file, and a rerun fails the same way."""
    argv = ["--sweep", "--setups", "corridor", "--seeds", "1", "--densities", "9", "--backend", "serial",
            "--out", str(tmp_path / "fd")]
    with pytest.raises(SystemExit, match=r"^error: 1 of 1 run\(s\) failed: \S+: ScenarioError: "
                                         r"density_per_m2 = 9\.0 cannot be placed .*; a rerun fails the same way"):
        main(argv)


def test_one_seed_prints_no_spread_and_a_corridor_run_is_named_as_one(tmp_path, capsys):
    """Regression (issue 52): with one seed the sweep printed '± nan', and it stored a corridor run as
    'b1.800_n324_s0', the name of a bottleneck run of width 1.8 m."""
    out = tmp_path / "fd"
    assert main(["--sweep", "--setups", "corridor", "--seeds", "1", "--densities", "1.147", "--sweep-time", "4",
                 "--transient", "2", "--backend", "serial", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "nan" not in text and "corridor (calibrated, 1 seed): density (1/m²), speed (m/s) (one seed: no spread)" in text
    assert [p.name for p in (out / "runs").iterdir()] == ["corridor_w1.800_rho1.147_n41_s0.json"]
