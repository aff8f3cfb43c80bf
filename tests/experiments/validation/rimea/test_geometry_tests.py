"""RiMEA tests 6 (corner), 12a-12d (bottlenecks) and 15 (large crowd round a corner): their set-ups, their
measurements on hand-made trajectories, and the quick versions run through the suite."""
import numpy as np
import pytest
import shapely

from crowd_env.analysis.trajectories import Trajectories
from crowd_env.experiments.validation.rimea import run_suite, select_tests
from crowd_env.experiments.validation.rimea.base import BackendRun, run_crowd_env
from crowd_env.experiments.validation.rimea.t06_corner import CornerTest, distance_to_square_m, forbidden_points
from crowd_env.experiments.validation.rimea.t12_bottlenecks import area_counts, clearance_time_s
from crowd_env.scenarios import make_scenario
from crowd_env.scenarios.rimea import RIMEA_RADIUS_M
from crowd_env.scenarios.rimea.t12_bottlenecks import preset_desired_speeds


def _width_at(area, x, y0=-1.0, y1=100.0) -> float:
    return area.intersection(shapely.LineString([(x, y0), (x, y1)])).length


def _exit_width(sc, k=0) -> float:
    """Length of the stretch the exit polygon shares with the walkable area's boundary (the door)."""
    return sc.geometry.exits[k].intersection(sc.geometry.walkable_area.boundary).length


def _run(trajectory_points, n=None, complete=True, fps=10.0):
    """A BackendRun from {id: [(x, y) per frame]}."""
    frame, ids, xs, ys = [], [], [], []
    for i, pts in trajectory_points.items():
        for f, (x, y) in enumerate(pts):
            frame.append(f), ids.append(i), xs.append(x), ys.append(y)
    traj = Trajectories(frame=frame, id=ids, x_m=xs, y_m=ys, heading_rad=None, frame_rate_per_s=fps)
    n = len(trajectory_points) if n is None else n
    exits = np.array([len(trajectory_points[i]) / fps for i in range(n)])
    return BackendRun("hand", "hand", traj, exits, 0.1, 0.0, complete)


# -- set-ups -----------------------------------------------------------------------------------------
def test_6_is_a_2_m_corridor_with_10_m_arms_and_20_people_in_the_first_6_m():
    sc = make_scenario("rimea_6_corner")
    area = sc.geometry.walkable_area
    assert area.area == pytest.approx(12 * 2 + 10 * 2)  # two 10 m arms + the 2 m x 2 m turn
    assert _width_at(area, 5.0) == pytest.approx(2.0)
    assert area.intersection(shapely.LineString([(0, 7), (20, 7)])).length == pytest.approx(2.0)
    assert _exit_width(sc) == pytest.approx(2.0) and sc.geometry.exits[0].bounds[1] == pytest.approx(12.0)
    p = sc.position_m
    assert sc.n_pedestrians == 20 and np.all(p[:, 0] <= 6.0 - RIMEA_RADIUS_M) and np.all(p[:, 0] >= RIMEA_RADIUS_M)
    assert forbidden_points(p[:, 0], p[:, 1]).size == 0
    assert "desired_speed_m_s" not in sc.pedestrian_params  # the preset's distribution


@pytest.mark.parametrize("name, options, area_m2, width_m", [
    ("rimea_12a_goal_distance", {"goal_distance_m": 4.0}, 200.2, 1.0),
    ("rimea_12b_bottleneck_length", {"bottleneck_length_m": 0.2}, 200.2, 1.0),
    ("rimea_12b_bottleneck_length", {"bottleneck_length_m": 5.0}, 205.0, 1.0),
    ("rimea_12c_two_bottlenecks", {}, 250.4, 1.0),
    ("rimea_12d_bottleneck_width", {"width_m": 0.8}, 204.0, 0.8),
    ("rimea_12d_bottleneck_width", {"width_m": 1.2}, 206.0, 1.2),
])
def test_12_rooms_bottlenecks_and_the_crowd_in_the_left_half_of_room_1(name, options, area_m2, width_m):
    sc = make_scenario(name, **options)
    area = sc.geometry.walkable_area
    assert area.area == pytest.approx(area_m2)
    assert _width_at(area, 5.0) == pytest.approx(10.0)  # room 1
    assert _width_at(area, 10.1) == pytest.approx(width_m)  # the (first) bottleneck
    assert sc.n_pedestrians == 150
    assert np.all(sc.position_m[:, 0] <= 5.0 - RIMEA_RADIUS_M)


def test_12a_goal_strip_lies_a_behind_the_opening_and_12c_has_two_identical_openings():
    for a in (0.0, 8.0):
        (goal,) = make_scenario("rimea_12a_goal_distance", goal_distance_m=a, n_pedestrians=10).geometry.exits
        assert goal.bounds == pytest.approx((10.2 + a, 0.0, 12.2 + a, 10.0))
    area = make_scenario("rimea_12c_two_bottlenecks", n_pedestrians=10).geometry.walkable_area
    assert _width_at(area, 10.1) == pytest.approx(1.0) and _width_at(area, 20.3) == pytest.approx(1.0)
    assert _width_at(area, 15.0) == pytest.approx(10.0) and _width_at(area, 23.0) == pytest.approx(10.0)


def test_12_replicate_speeds_follow_the_preset_distribution():
    v = preset_desired_speeds(2000, 3)
    assert 1.30 < v.mean() < 1.38 and v.min() >= 1.34 - 2 * 0.26 - 1e-9 and v.max() <= 1.34 + 2 * 0.26 + 1e-9
    assert not np.allclose(preset_desired_speeds(10, 0), preset_desired_speeds(10, 1))
    names = select_tests(["12a"])[0].scenarios(True, 0)
    assert sorted(names) == ["a=0/r0", "a=0/r1", "a=0/r2", "a=8/r0", "a=8/r1", "a=8/r2"]
    np.testing.assert_array_equal(names["a=0/r1"].pedestrian_params["desired_speed_m_s"],
                                  names["a=8/r1"].pedestrian_params["desired_speed_m_s"])  # common random numbers


def test_15_three_geometries_with_20_m_exits_and_500_people_at_the_far_end():
    long_ = make_scenario("rimea_15_corridor")
    short = make_scenario("rimea_15_corridor", length_m=50.0)
    corner = make_scenario("rimea_15_corner")
    assert long_.geometry.walkable_area.area == pytest.approx(20 * 81.4)
    assert short.geometry.walkable_area.area == pytest.approx(20 * 50)
    # 20 m x 60 m leg less the 10 m x 10 m / 2 chamfer, plus the 10 m x 20 m stub
    assert corner.geometry.walkable_area.area == pytest.approx(1200 - 50 + 200)
    for sc, y_far in ((long_, 81.4), (short, 50.0), (corner, 60.0)):
        assert sc.n_pedestrians == 500 and _exit_width(sc) == pytest.approx(20.0)
        assert np.all(sc.position_m[:, 1] >= y_far - 6.0 + RIMEA_RADIUS_M - 1e-9)
    assert corner.geometry.exits[0].bounds[0] == pytest.approx(72.0)  # the door at the end of the stub


# -- measurements on hand-made trajectories -------------------------------------------------------------
def test_the_forbidden_square_catches_a_trajectory_that_cuts_the_corner():
    along = [(x, 1.0) for x in np.arange(1.0, 11.01, 0.5)] + [(11.0, y) for y in np.arange(1.5, 12.01, 0.5)]
    cut = [(1.0 + k * 0.5, 1.0 + k * 0.5) for k in range(21)]  # the diagonal from (1, 1) to (11, 11)
    ok = CornerTest().evaluate({"corner": _run({0: along})})
    assert ok.passed is True and ok.value == 0
    bad = CornerTest().evaluate({"corner": _run({0: along, 1: cut})})
    assert bad.passed is False and bad.value == 17  # (2, 2), (2.5, 2.5) ... (10, 10) lie in the closed square
    assert bad.details["first_violation"]["id"] == 1 and bad.details["min_distance_to_forbidden_square_m"] == 0.0
    incomplete = CornerTest().evaluate({"corner": _run({0: along}, complete=False)})
    assert incomplete.passed is False
    np.testing.assert_allclose(distance_to_square_m([11.0, 5.0, 12.0], [1.0, 5.0, 14.0]),
                               [np.hypot(1, 1), 0, np.hypot(2, 2)])


def test_clearance_crossings_and_queue_counts_read_the_frames():
    # id 0 crosses x = 10 between frames 1 and 2 (x 9.8 -> 10.2: t = 0.15 s); id 1 never does
    run = _run({0: [(9.6, 5.0), (9.8, 5.0), (10.2, 5.0)], 1: [(9.0, 5.0), (9.1, 5.0), (9.2, 5.0)]})
    run.exit_time_s[1] = np.nan  # id 1 is still inside at the end
    t, n = clearance_time_s(run)
    assert n == 1 and np.isnan(t)  # not everybody crossed: no clearance time
    # id 1 left (into the goal behind the line) between two frames without a frame past the line: it
    # crossed, no later than its exit time (0.3 s)
    run.exit_time_s[1] = 0.3
    t, n = clearance_time_s(run)
    assert n == 2 and t == pytest.approx(0.3)
    t, n = clearance_time_s(_run({0: [(9.6, 5.0), (9.8, 5.0), (10.2, 5.0)]}))
    assert n == 1 and t == pytest.approx(0.15)
    frames, counts = area_counts(run, (8.0, 3.5, 10.0, 6.5))
    np.testing.assert_array_equal(counts, [2, 2, 1])


# -- the quick versions through the suite -------------------------------------------------------------
@pytest.fixture(scope="module")
def quick_results():
    return {r.number: r for r in run_suite(["6", "12", "15"], quick=True, seed=0, progress=None)}


def test_quick_runs_keep_the_shared_conditions(quick_results):
    assert sorted(quick_results) == ["12a", "12b", "12c", "12d", "15", "6"]
    for r in quick_results.values():
        assert r.min_gap_m["crowd_env"] >= -1e-3 and r.outside_m["crowd_env"] <= 1e-9 and r.complete["crowd_env"]


def test_6_quick_everybody_arrives_and_no_centre_enters_the_square(quick_results):
    r = quick_results["6"]
    d = r.verdicts["crowd_env"].details
    assert r.passed() is True and d["n_arrived"] == 20 and d["points_in_forbidden_square"] == 0
    # the bodies touch the inner walls (the shortest way round) but never cross them: clearance = radius
    assert d["min_distance_to_forbidden_square_m"] == pytest.approx(RIMEA_RADIUS_M, abs=2e-3)


def test_12a_quick_goal_distance(quick_results):
    """Quick (50 persons, a = 0 and 8 m, 3 replicates, seed 0): T1(a=0) = 28.9 s <= T1(a=8) = 30.4 s, a pass
    (+1.5 ± 0.3 s, paired SE; a = 8 is slower in each replicate by 1.1-2.1 s). The effect does not hold at full
    size: with 150 persons (a = 0..8, seed 0) T1 = 79.8 / 79.0 / 80.9 / 79.8 / 78.7 s, no trend, and the check
    fails by 1.1 ± 0.8 s (test_12a_full_fails_within_its_noise): the goal behind an opening barely changes how
    fast room 1 empties in this model (those past the opening walk away freely into an empty room). The total
    time (the walk of a metres included, JuPedSim's reading) grows with a: 29.2 -> 39.4 s here."""
    r = quick_results["12a"]
    v = r.verdicts["crowd_env"]
    assert r.passed() is True
    assert v.details["room1_clearance_mean_s"]["a=0"] == pytest.approx(28.9, abs=0.5)
    assert v.details["room1_clearance_mean_s"]["a=8"] == pytest.approx(30.4, abs=0.5)
    assert v.details["total_evacuation_mean_s"]["a=8"] - v.details["total_evacuation_mean_s"]["a=0"] > 8 / 1.86 - 1


def test_12b_quick_longer_bottleneck_takes_longer(quick_results):
    """Quick (50 persons, 3 replicates): T_short = 39.4 s < T_long = 43.1 s, a pass; most of the 3.7 s is the
    4.8 m longer walk (3.6 s at 1.34 m/s): room 1 empties as fast behind either (30.4 vs 29.1 s)."""
    r = quick_results["12b"]
    d = r.verdicts["crowd_env"].details
    assert r.passed() is True
    assert np.mean(d["total_evacuation_s"]["long"]) > np.mean(d["total_evacuation_s"]["short"])


def test_12c_quick_the_queue_forms_before_the_first_opening(quick_results):
    r = quick_results["12c"]
    d = r.verdicts["crowd_env"].details
    assert r.passed() is True and all(d["checks"].values())
    assert d["line_1"]["peak_queue"] > 3 * d["line_2"]["peak_queue"] > 0


def test_12d_quick_flow_grows_with_width(quick_results):
    """Quick (50 persons, 3 replicates): J = 1.22 / 2.00 / 2.56 1/s at 0.8 / 1.0 / 1.2 m against 1.9 w = 1.52 /
    1.90 / 2.28: below the line in single file (0.8 m < two bodies of 0.46 m), above it at 1.2 m."""
    r = quick_results["12d"]
    mean = r.verdicts["crowd_env"].details["flow_mean_per_s"]
    assert r.passed() is True and mean["w=0.8"] < mean["w=1"] < mean["w=1.2"]
    assert mean["w=0.8"] < 1.9 * 0.8 < 1.9 * 1.2 < mean["w=1.2"]


def test_15_quick_corner_lies_between_the_straight_corridors(quick_results):
    """Quick (100 persons): T_short = 53 s <= T_corner = 63 s <= T_long = 90 s, a pass. The full version (500)
    FAILS: T_corner = 126 s > T_long = 101 s (test_15_full_corner_is_slower_than_the_long_corridor)."""
    r = quick_results["15"]
    t = r.verdicts["crowd_env"].details["evacuation_time_s"]
    assert r.passed() is True and t["short"] <= t["corner"] <= t["long"]


# -- full sizes, documenting the failures ----------------------------------------------------------------
@pytest.mark.slow
def test_15_full_corner_is_slower_than_the_long_corridor():
    """Full test 15 (500 persons, seed 0) fails: T_short = 62 s, T_corner = 126 s, T_long = 101 s. The eikonal
    field sends every pedestrian along the shortest path, i.e. to the inner corner (62, 20): the crowd piles up
    there in a half-disc at ~3 /m² and leaves along the stub's inner wall, so the 20 m wide corridor carries a
    stream a few metres wide: 6 arrivals/s (20-80 % of the crowd) against 20/s (long) and 29/s (short)
    corridors, which use their full width. JuPedSim's notebook run shows the same (corner 235 s vs 125 / 107
    s). With 100 persons the jam is short and the quick version passes."""
    test = select_tests(["15"])[0]
    runs = {k: run_crowd_env(sc, seed=0, max_time_s=600.0) for k, sc in test.scenarios(False, 0).items()
            if k in ("corner", "long")}
    t = {k: r.evacuation_time_s for k, r in runs.items()}
    assert all(r.complete and r.min_gap_m >= -1e-3 for r in runs.values())
    assert t["corner"] > t["long"] + 15.0
    from crowd_env.experiments.validation.rimea.t15_large_corner import arrival_flow_per_s

    assert arrival_flow_per_s(runs["corner"]) < 0.5 * arrival_flow_per_s(runs["long"])


@pytest.mark.slow
def test_12a_full_fails_within_its_noise():
    """Full test 12a (150 persons, a = 0, 2, 4, 6, 8 m, 3 replicates, seed 0): room 1 is cleared at 79.8 /
    79.0 / 80.9 / 79.8 / 78.7 s, so T1(a=0) <= T1(a=8) fails by 1.1 s, less than 1.5 standard errors: in this
    model the goal's distance does not change the flow through the opening."""
    test = select_tests(["12a"])[0]
    scen = {k: sc for k, sc in test.scenarios(False, 0).items() if k.split("/")[0] in ("a=0", "a=8")}
    v = test.evaluate({k: run_crowd_env(sc, seed=0, max_time_s=400.0) for k, sc in scen.items()})
    assert v.passed is False and -3.0 < v.value < 0.0
    assert abs(v.value) < 2.0 * v.details["room1_difference_se_s"]
