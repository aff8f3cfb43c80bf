"""The RiMEA suite's frame: test selection and its errors, the shared conditions, the results file, the command."""
import json

import numpy as np
import pytest

from crowd_env.analysis.trajectories import Trajectories
from crowd_env.errors import MissingDependencyError, NotFoundError
from crowd_env.experiments.rimea import format_table, rimea_tests, run_suite, select_tests
from crowd_env.experiments.rimea.base import exit_times_s, outside_distance_m
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
