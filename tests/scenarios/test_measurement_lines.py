"""Measurement lines that know their direction: by default towards the walkers' destination (the navigation field
at the line's midpoint), a given direction against the walkers refused unless the geometry says so, and a run
where people left but nobody crossed the line reported as such (not complete)."""
import math

import numpy as np
import pytest

from baselines import SocialForceAgent
from crowd_env.analysis.flow import MeasurementLine
from crowd_env.core.geometry import Geometry, GeometryError
from crowd_env.experiments.running.runner import run_scenario
from crowd_env.scenarios import ScenarioError, list_scenarios, make_scenario
from crowd_env.scenarios.polygon import scenario_from_polygon
from crowd_env.scenarios.registry import scenario_factory

STEP_M = 0.1  # a walker's step along its field in the geometric check


def _registered_with_lines():
    """One scenario of every registered factory that has measurement lines (aliases once; the polygon
    scenario, which needs a geometry, with a corridor and a line of its own)."""
    seen, out = set(), []
    for name in list_scenarios():
        factory = scenario_factory(name)
        if factory in seen:
            continue
        seen.add(factory)
        sc = _corridor(line={"ends": [(5.0, 0.0), (5.0, 2.0)]}) if factory is scenario_from_polygon \
            else make_scenario(name)
        if sc.geometry.measurement_lines:
            out.append(sc)
    return out


def _walks(scenario) -> np.ndarray:
    """(K, N, 2): every walker's way from its start along its own navigation field (steps of STEP_M along e_d)
    until it is in an exit."""
    nav = scenario.navigation()
    pos = scenario.position_m.copy()
    index = np.arange(pos.shape[0])
    path = [pos.copy()]
    for _ in range(int(math.ceil(float(nav.sample(pos, index)[1].max() if nav.per_pedestrian
                                       else nav.sample(pos)[1].max()) / STEP_M)) + 50):
        e, t = nav.sample(pos, index) if nav.per_pedestrian else nav.sample(pos)
        moving = ~scenario.geometry.in_exit(pos)
        if not moving.any():
            break
        pos = pos + STEP_M * e * moving[:, None]
        path.append(pos.copy())
    return np.array(path)


def test_every_line_of_every_registered_scenario_counts_its_walkers():
    """Geometric: each walker's way along its field crosses each line it meets in the direction the line counts
    (Scenario.line_direction, as the runner counts), and every line is crossed so by somebody. A line given a
    direction (the bidirectional corridor's "middle", crossed both ways) may be crossed the other way too."""
    scenarios = _registered_with_lines()
    assert {"corner_90", "seyfried_bottleneck", "corridor_bidirectional", "juelich_corridor"} <= {
        s.name for s in scenarios}
    for sc in scenarios:
        path = _walks(sc)
        p0, p1 = path[:-1].reshape(-1, 2), path[1:].reshape(-1, 2)
        for name, ends in sc.geometry.measurement_lines.items():
            line = MeasurementLine(ends[0], ends[1], sc.line_direction(name))
            back = MeasurementLine(ends[0], ends[1], -sc.line_direction(name))
            counted = np.isfinite(line.crossing_fraction(p0, p1)).sum()
            wrong_way = np.isfinite(back.crossing_fraction(p0, p1)).sum()
            assert counted > 0, f"{sc.name}: nobody crosses {name!r} the way it counts"
            if name not in sc.geometry.measurement_line_directions:
                assert wrong_way == 0, f"{sc.name}: {wrong_way} cross {name!r} against its direction"


def test_every_line_of_the_corner_counts_every_walker():
    """On main the corner's "turn_out" and "exit" counted 0 of the 6 who left, and the runs were complete."""
    sc = make_scenario("corner_90", n_pedestrians=6, seed=0)
    for name in ("turn_in", "turn_out", "exit"):
        r = run_scenario(sc, SocialForceAgent(sc.navigation()), max_time_s=40.0, line=name, density_areas=(),
                         lane_area=None)
        assert r.n_evacuated == r.n_passed == 6 and r.complete and not r.missed_line, name


def _corridor(line, n=4):
    """A 10 m x 2 m corridor walked east to a door at x = 10, with ``line`` as its measurement line "middle"."""
    return scenario_from_polygon([(0, 0), (10, 0), (10, 2), (0, 2)], [[(10, 0), (10, 2)]],
                                 [(0.5, 0), (3, 0), (3, 2), (0.5, 2)], n, measurement_lines={"middle": line})


def test_a_line_against_its_walkers_is_refused_unless_it_says_so_and_a_run_missing_it_says_so():
    ends = [(5.0, 0.0), (5.0, 2.0)]
    assert _corridor(ends).line_direction("middle").tolist() == [1.0, -0.0]  # drawn the other way round
    assert _corridor(ends[::-1]).line_direction("middle").tolist() == [1.0, 0.0]  # towards the door either way
    with pytest.raises(ScenarioError, match=r"'middle'.*against its walkers.*against_walkers=True"):
        _corridor({"ends": ends, "direction": (-1.0, 0.3)})
    sc = _corridor({"ends": ends, "direction": (-1.0, 0.3), "against_walkers": True})
    assert sc.line_direction("middle").tolist() == [-1.0, 0.0]
    r = run_scenario(sc, SocialForceAgent(sc.navigation()), max_time_s=20.0, line="middle", density_areas=(),
                     lane_area=None)
    assert r.n_evacuated == 4 and r.n_passed == 0 and r.missed_line and not r.complete
    assert np.isnan(r.flow_per_s)


def test_a_line_the_field_runs_along_needs_a_direction():
    with pytest.raises(ScenarioError, match=r"'middle'.*runs along it.*give it a direction"):
        _corridor([(4.0, 1.0), (6.0, 1.0)])
    assert _corridor({"ends": [(4.0, 1.0), (6.0, 1.1)], "direction": (0.0, 1.0)}).line_direction("middle")[1] > 0


@pytest.mark.parametrize("spec, match", [
    ({"ends": [(5, 0), (5, 2)], "direction": (0.0, 1.0)}, "across the line"),
    ({"ends": [(5, 0), (5, 2)], "direction": (np.nan, 1.0)}, "finite"),
    ({"ends": [(5, 0), (5, 2)], "against_walkers": True}, "needs a direction"),
    ({"ends": [(5, 0), (5, 2)], "against_walkers": "yes", "direction": (1, 0)}, "True or False"),
    ({"end": [(5, 0), (5, 2)]}, "'ends' required"),
])
def test_bad_line_specs_are_refused_naming_the_line(spec, match):
    with pytest.raises(GeometryError, match=f"measurement line 'middle'.*{match}"):
        Geometry([(0, 0), (10, 0), (10, 2), (0, 2)], [[(10, 0), (11, 0), (11, 2), (10, 2)]],
                 measurement_lines={"middle": spec})


def test_a_moved_scenario_moves_its_line_directions():
    sc = make_scenario("corridor_bidirectional", n_per_direction=2)
    turned = sc.moved(0.5 * math.pi, (3.0, -1.0))
    np.testing.assert_allclose(turned.geometry.measurement_line_directions["middle"], [0.0, 1.0], atol=1e-15)
    np.testing.assert_allclose(turned.line_direction("middle"), [0.0, 1.0], atol=1e-15)


def test_line_directions_survive_a_geometry_file_and_a_pickle(tmp_path):
    import pickle

    from crowd_env.analysis.trajectories import read_geometry, write_geometry

    g = _corridor({"ends": [(5.0, 0.0), (5.0, 2.0)], "direction": (-2.0, 0.0), "against_walkers": True}).geometry
    for back in (read_geometry(write_geometry(tmp_path / "g.json", g)[0]), pickle.loads(pickle.dumps(g))):
        assert back.measurement_line_directions["middle"].tolist() == [-1.0, 0.0]
        assert back.lines_against_walkers == {"middle"}
