"""The Jülich corridor set-up (crowd_env.scenarios.juelich_corridor): its openings, lines and area where the
experiment has them, the crowd at 3 /m² in the waiting area, every run of the experiment buildable, bad set-ups
refused by name."""
from __future__ import annotations

import numpy as np
import pytest
import shapely

from crowd_env.analysis.corridor_runs import juelich_uo_runs
from crowd_env.analysis.flow import MeasurementLine
from crowd_env.errors import ScenarioError
from crowd_env.scenarios import make_scenario


def _opening_width(area, y_m):
    """Width of the walkable area along the line y = ``y_m``."""
    return shapely.LineString([(-10, y_m), (10, y_m)]).intersection(area).length


def test_geometry_has_the_experiments_openings_and_measurement():
    sc = make_scenario("juelich_corridor", entrance_width_m=0.5, exit_width_m=0.7, n_pedestrians=60, seed=0)
    g = sc.geometry
    area = g.walkable_area
    assert _opening_width(area, 8.15) == pytest.approx(0.5)  # inside the 0.3 m barrier
    assert _opening_width(area, 6.0) == pytest.approx(5.0)  # the open floor
    assert _opening_width(area, 0.0) == pytest.approx(1.8) and _opening_width(area, -3.9) == pytest.approx(1.8)
    assert _opening_width(area, -4.05) == pytest.approx(0.7)  # inside the 0.1 m end wall
    assert _opening_width(area, -5.0) == pytest.approx(5.0)
    # the openings lie on the corridor's axis x = 0.9 m
    gap = shapely.LineString([(-10, -4.05), (10, -4.05)]).intersection(area)
    assert np.mean(gap.xy[0]) == pytest.approx(0.9)
    # every line counts walkers towards -y and spans what it measures
    for name, y, width in (("entrance", 8.0, 0.5), ("y0", 0.0, 1.8), ("exit", -4.0, 0.7)):
        ends = np.asarray(g.measurement_lines[name])
        assert np.all(ends[:, 1] == y) and np.ptp(ends[:, 0]) == pytest.approx(width)
        assert MeasurementLine(ends[0], ends[1]).normal @ np.array([0.0, -1.0]) == pytest.approx(1.0)
    assert g.measurement_areas["measurement"].bounds == pytest.approx((0.0, -2.0, 1.8, 0.0))
    # the exit lies beyond the camera's view (y >= -6 m); the crowd starts in the waiting area at 3 /m²
    assert g.exits[0].bounds[3] < -6.0
    wait = sc.spawn_area
    assert wait.bounds[1] == pytest.approx(8.3) and wait.area * 3.0 == pytest.approx(60)
    assert np.all(shapely.contains_xy(wait, sc.position_m[:, 0], sc.position_m[:, 1]))


@pytest.mark.parametrize("run", juelich_uo_runs(), ids=lambda r: r.name)
def test_every_run_of_the_experiment_builds_and_its_exit_is_reachable(run):
    sc = make_scenario("juelich_corridor", entrance_width_m=run.entrance_width_m, exit_width_m=run.exit_width_m,
                       n_pedestrians=run.n_pedestrians, seed=1)
    assert sc.n_pedestrians == run.n_pedestrians and sc.metadata["run"] == run.name
    direction, _ = sc.navigation().sample(sc.position_m)
    assert np.all(np.isfinite(direction))  # every start reaches the exit through the entrance


def test_bad_set_ups_are_refused_by_name():
    with pytest.raises(ScenarioError, match="entrance_width_m = 0.4 m is not wider than a pedestrian"):
        make_scenario("juelich_corridor", entrance_width_m=0.4)
    with pytest.raises(ScenarioError, match="exit_width_m = 2 m is wider than the corridor"):
        make_scenario("juelich_corridor", exit_width_m=2.0)
    with pytest.raises(ScenarioError, match="n_pedestrians"):
        make_scenario("juelich_corridor", n_pedestrians=0)
    with pytest.raises(ScenarioError, match="barrier_thickness_m"):
        make_scenario("juelich_corridor", barrier_thickness_m=-0.1)
    with pytest.raises(ScenarioError, match="navigation_wall_slowdown: wall_slowdown speed_factor"):
        make_scenario("juelich_corridor", navigation_wall_slowdown=(0.35, 1.5))


def test_a_wall_slowdown_turns_the_way_of_a_walker_against_the_barrier_off_it():
    """Beside the 0.5 m entrance, a centre one radius from the barrier: the disk centres' field leads it along the
    barrier to the gap; with a slower wavefront within 0.35 m of walls (Eq. 11, V < 1 there) the way leaves the
    barrier first. Far from every wall the field is the same."""
    plain = make_scenario("juelich_corridor", entrance_width_m=0.5, n_pedestrians=61)
    slow = make_scenario("juelich_corridor", entrance_width_m=0.5, n_pedestrians=61,
                         navigation_wall_slowdown=[0.35, 0.5])
    assert plain.metadata["navigation_wall_slowdown"] is None and slow.metadata["navigation_wall_slowdown"] == [0.35, 0.5]
    beside = np.array([[0.9 - 0.6, 8.3 + 0.24], [0.9 + 0.6, 8.3 + 0.24]])
    along, _ = plain.navigation().sample(beside)
    off, _ = slow.navigation().sample(beside)
    np.testing.assert_allclose(np.abs(along[:, 0]), 1.0, atol=0.05)  # along the barrier, towards the gap
    assert np.all(off[:, 1] > 0.3) and np.all(along[:, 0] * off[:, 0] > 0)  # away from it, still towards the gap
    far = np.array([[0.9, 10.5]])
    np.testing.assert_allclose(plain.navigation().sample(far)[0], slow.navigation().sample(far)[0], atol=0.05)


def test_a_few_walkers_stand_in_the_front_rows_of_a_waiting_area_one_metre_deep():
    sc = make_scenario("juelich_corridor", n_pedestrians=12, seed=0)
    assert sc.spawn_area.bounds[3] - sc.spawn_area.bounds[1] == pytest.approx(1.0)
    assert sc.n_pedestrians == 12 and sc.position_m[:, 1].max() < 8.3 + 1.0
