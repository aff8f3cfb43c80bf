"""The RiMEA suite's frame: test selection and its errors, the shared conditions, the results file, the command."""
import json

import numpy as np
import pytest

from crowd_env.analysis.trajectories import Trajectories
from crowd_env.errors import MissingDependencyError, NotFoundError
from crowd_env.experiments.validation.rimea import format_table, rimea_tests, run_suite, select_tests
from crowd_env.experiments.validation.rimea.base import exit_times_s, outside_distance_m
from crowd_env.scenarios import make_scenario


@pytest.mark.parametrize("number, match", [
    ("2", "needs stairs"), ("3", "needs stairs"), ("13", "needs stairs"),
    ("8", "documentation only"), ("14", "documentation only"),
    ("17", "unknown RiMEA test '17'"), ("x", "unknown RiMEA test 'x'"),
])
def test_tests_that_cannot_run_are_refused_by_name(number, match):
    with pytest.raises(NotFoundError, match=match):
        select_tests([number])


def test_the_jupedsim_column_without_jupedsim_names_the_extra(monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "jupedsim" else real(name, *a))
    with pytest.raises(MissingDependencyError, match=r"pip install -e '\.\[bench\]'"):
        run_suite(["1"], jupedsim=True, progress=None)


def test_test_1_walks_its_corridor_in_the_window_and_writes_its_files(tmp_path):
    results = run_suite(["1"], out_dir=str(tmp_path), progress=None)
    (r,) = results
    v = r.verdicts["crowd_env"]
    # 39.77 m (the centre starts at x = r) at 1.33 m/s is 29.9 s, plus about tau = 0.5 s to reach the speed
    assert 30.0 <= v.value <= 30.8 and r.passed() is True
    data = json.loads((tmp_path / "results.json").read_text())
    assert data["tests"][0]["backends"]["crowd_env"]["passed"] is True
    assert (tmp_path / "rimea_1.png").stat().st_size > 5000
    assert "26-34 s" in format_table(results)


def test_the_scenario_is_a_registered_scenario_users_can_change():
    sc = make_scenario("rimea_1_corridor", length_m=20.0)
    assert sc.n_pedestrians == 1 and sc.pedestrian_params["desired_speed_m_s"] == 1.33
    assert "1" in rimea_tests()


def test_exit_times_and_the_outside_check_read_the_frames():
    import shapely

    t = Trajectories(frame=[0, 1, 2, 0], id=[0, 0, 0, 1], x_m=[0.5, 0.6, 1.2, 0.5], y_m=[0.5] * 4,
                     heading_rad=None, frame_rate_per_s=10.0)
    times = exit_times_s(t, [True, True, False], end_time_s=0.25)
    np.testing.assert_allclose(times[:2], [0.25, 0.1])  # left after the last frame: at most the end of the run
    assert np.isnan(times[2])  # still inside
    box = shapely.box(0, 0, 1, 1)
    assert outside_distance_m(t, box) == pytest.approx(0.2)


def test_kept_results_are_read_back_only_with_the_same_settings(tmp_path, monkeypatch):
    from crowd_env.errors import InputError
    from crowd_env.experiments.validation.rimea import suite

    (first,) = run_suite(["1"], out_dir=str(tmp_path), progress=None)
    assert (tmp_path / "tests" / "rimea_1.json").exists()
    calls = []
    real = suite._runner

    def counting(backend):
        calls.append(backend)
        return real(backend)

    monkeypatch.setattr(suite, "_runner", counting)
    (again,) = run_suite(["1"], out_dir=str(tmp_path), resume=True, progress=None)
    assert calls == []  # read back, not run
    assert again.verdicts["crowd_env"].value == first.verdicts["crowd_env"].value
    assert again.passed() is first.passed() and again.min_gap_m == first.min_gap_m
    assert again.figure == first.figure
    run_suite(["1"], out_dir=str(tmp_path), resume=True, seed=1, progress=None)  # another seed: run again
    assert calls == ["crowd_env"]
    (tmp_path / "rimea_1.png").unlink()  # a kept result whose figure is gone is run again
    run_suite(["1"], out_dir=str(tmp_path), resume=True, seed=1, progress=None)
    assert calls == ["crowd_env", "crowd_env"]
    with pytest.raises(InputError, match="resume needs out_dir"):
        run_suite(["1"], resume=True, progress=None)


def test_a_kept_result_reads_back_with_its_verdict_when_nobody_came_near():
    """Test 7's people walk abreast, far apart: no gap is ever measured (+inf), written as null; read back it
    must still pass (it once read back as NaN, which fails the no-overlap condition)."""
    from crowd_env.experiments.validation.rimea.base import Verdict
    from crowd_env.experiments.validation.rimea.suite import TestResult

    res = TestResult("7", "t", "c", "k", "s", True)
    res.verdicts["crowd_env"] = Verdict("ok", 1.0, True, {})
    res.min_gap_m["crowd_env"], res.outside_m["crowd_env"] = float("inf"), 0.0
    res.complete["crowd_env"], res.wall_time_s["crowd_env"] = True, 1.0
    data = json.loads(json.dumps(res.to_dict()))
    assert data["backends"]["crowd_env"]["min_gap_m"] is None and res.passed() is True
    back = TestResult.from_dict(data)
    assert back.min_gap_m["crowd_env"] == float("inf") and back.passed() is True
    res.min_gap_m["crowd_env"] = -0.01  # an overlap stays one
    assert TestResult.from_dict(json.loads(json.dumps(res.to_dict()))).passed() is False


def test_the_runs_of_an_unfinished_test_are_kept_and_read_back(tmp_path, monkeypatch):
    """A killed test resumes run by run: the runs made before the kill are read back (test 4's reduced version,
    one run per density that can be placed; the kill comes at the third), the rest are run, and the result is
    the uninterrupted one's."""
    from crowd_env.experiments.validation.rimea import suite

    made = []
    real = suite._runner
    monkeypatch.setattr(suite, "_runner", lambda backend: (lambda sc, **kw: made.append(sc.name) or real(backend)(sc, **kw)))
    (whole,) = run_suite(["4"], quick=True, progress=None)
    n_runs = len(made)  # the densities that can be placed
    assert n_runs >= 3
    made.clear()

    def killed_at_the_third(backend):
        run = real(backend)

        def once(sc, **kw):
            if len(made) == 2:
                raise KeyboardInterrupt
            made.append(sc.name)
            return run(sc, **kw)
        return once

    monkeypatch.setattr(suite, "_runner", killed_at_the_third)
    with pytest.raises(KeyboardInterrupt):
        run_suite(["4"], quick=True, out_dir=str(tmp_path), progress=None)
    assert len(list((tmp_path / "runs").glob("rimea_4_*_crowd_env.npz"))) == 2
    assert not (tmp_path / "tests" / "rimea_4.json").exists()
    made.clear()
    monkeypatch.setattr(suite, "_runner", lambda backend: (lambda sc, **kw: made.append(sc.name) or real(backend)(sc, **kw)))
    (resumed,) = run_suite(["4"], quick=True, out_dir=str(tmp_path), resume=True, progress=None)
    assert len(made) == n_runs - 2  # only the runs that were not kept
    assert resumed.verdicts["crowd_env"].value == whole.verdicts["crowd_env"].value
    assert resumed.verdicts["crowd_env"].measured == whole.verdicts["crowd_env"].measured
    assert resumed.min_gap_m == whole.min_gap_m and resumed.complete == whole.complete
    made.clear()
    run_suite(["4"], quick=True, out_dir=str(tmp_path / "other"), seed=1, resume=True, progress=None)
    assert len(made) == n_runs  # kept runs of another seed or folder are never reused


def _run(end_frame: int, *, stalled=False, max_time_s=2.0):
    from crowd_env.experiments.validation.rimea.base import BackendRun

    frames = np.arange(end_frame + 1)
    t = Trajectories(frame=frames, id=np.zeros_like(frames), x_m=np.zeros(frames.size), y_m=np.zeros(frames.size),
                     heading_rad=None, frame_rate_per_s=10.0)
    return BackendRun("crowd_env", "x", t, np.array([np.nan]), 0.01, 0.0, False, stalled, max_time_s=max_time_s)


def test_a_windowed_test_is_complete_when_its_runs_reach_the_time_limit():
    from crowd_env.experiments.validation.rimea.base import RimeaTest, WindowedTest

    full, short, stalled = _run(20), _run(15), _run(20, stalled=True)
    assert full.end_time_s == 2.0 and full.reached_time_limit()
    assert not short.reached_time_limit() and not stalled.reached_time_limit()
    windowed = WindowedTest()
    assert windowed.runs_complete({"a": full}) and not windowed.runs_complete({"a": full, "b": short})
    assert not windowed.runs_complete({"a": stalled})
    assert not RimeaTest().runs_complete({"a": full})  # an evacuation test: somebody is still inside


def _result(number: str, passed, backend: str = "crowd_env"):
    from crowd_env.experiments.validation.rimea.base import Verdict
    from crowd_env.experiments.validation.rimea.suite import TestResult

    r = TestResult(number, f"test {number}", "checks", "criterion", "source", True)
    r.verdicts[backend] = Verdict("x", 1.0, passed)
    r.min_gap_m[backend], r.outside_m[backend], r.complete[backend] = 0.0, 0.0, True
    return r


def test_the_command_closes_with_the_counts_and_the_page_that_explains_the_failures(monkeypatch, tmp_path, capsys):
    """Regression (issue 52): crowd-rimea --quick exited 1 on tests 5 and 16 after the table, without a line that
    counts passes and failures and points to the page that explains them."""
    from pathlib import Path

    import crowd_env.experiments.validation.rimea as rimea
    from crowd_env.cli.rimea import main
    from crowd_env.experiments.validation.rimea.suite import RESULTS_PAGE

    results = [_result("1", True), _result("5", False), _result("8", None), _result("16", False)]
    monkeypatch.setattr(rimea, "run_suite", lambda *a, **k: results)
    assert main(["--quick", "--out", str(tmp_path)]) == 1
    last = capsys.readouterr().out.splitlines()[-1]
    assert last == ("crowd_env: 1 of 4 tests passed, 1 documentation only, 2 failed (5, 16); docs/validation/rimea.md, "
                    "'Reading the results', explains each failure")
    page = (Path(__file__).resolve().parents[4] / RESULTS_PAGE).read_text()
    assert "## Reading the results" in page and "**Test 5 fails" in page and "16 (fundamental diagrams) fail" in page
    monkeypatch.setattr(rimea, "run_suite", lambda *a, **k: results[:1])
    assert main(["--out", str(tmp_path)]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == "crowd_env: 1 of 1 tests passed, none failed"
