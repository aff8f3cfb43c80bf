"""RiMEA tests 4 (fundamental diagram in a corridor) and 16 (single file on a ring): the circulating
navigation, the reference data, the measurements on hand-made configurations, the ring as an RL
environment, and the quick versions run through the suite."""
import math

import numpy as np
import pytest
import shapely

from crowd_env.analysis.rimea_data import (loop_headway_density_per_m, single_file_percentiles,
                                           weidmann_speed_m_s)
from crowd_env.analysis.trajectories import Trajectories
from crowd_env.core.segments import GeometryError
from crowd_env.errors import ScenarioError
from crowd_env.experiments.validation.rimea import run_suite
from crowd_env.experiments.validation.rimea.t04_fundamental_diagram import line_flow_per_m_s, measure_areas
from crowd_env.experiments.validation.rimea.t16_single_file import bin_samples, loop_samples, ring_navigation
from crowd_env.scenarios import Scenario, make_scenario
from crowd_env.walking.circulation import CirculationNavigation, oval_centreline

L_OVAL = 8.0 + 6.0 * math.pi  # the test-16 ring's centreline length (m)


# -- the circulating navigation ------------------------------------------------------------------------
def _circle(radius=3.0, n=720):
    phi = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    return np.column_stack((radius * np.cos(phi), radius * np.sin(phi)))  # anticlockwise


def test_the_oval_centreline_has_the_ring_length_and_starts_at_the_lower_straight():
    c = oval_centreline(4.0, 3.0, 0.05)
    nav = CirculationNavigation(c)
    assert nav.length_m == pytest.approx(L_OVAL, rel=1e-4)
    assert c[0] == pytest.approx([0.0, -3.0])
    assert nav.min_radius_of_curvature_m() == pytest.approx(3.0, rel=0.02)


def test_the_tangent_direction_is_unit_and_tangent_and_travel_time_falls_along_the_loop():
    nav = CirculationNavigation(_circle(3.0))
    rng = np.random.default_rng(0)
    phi = rng.uniform(0, 2 * np.pi, 200)
    r = rng.uniform(2.6, 3.4, 200)
    p = np.column_stack((r * np.cos(phi), r * np.sin(phi)))
    e, t = nav.sample(p)
    assert np.hypot(*e.T) == pytest.approx(np.ones(200), abs=1e-12)
    tangent = np.column_stack((-np.sin(phi), np.cos(phi)))  # anticlockwise
    assert np.all(np.einsum("ij,ij->i", e, tangent) > np.cos(np.deg2rad(0.3)))  # 720-gon: within a fraction of a degree
    assert np.abs(np.einsum("ij,ij->i", e, p / r[:, None])).max() < 6e-3  # no radial part
    # T = (L - s) / V: walking 0.2 rad round the loop lowers it by the 0.6 m of centreline passed (V = 1 m/s,
    # to within one of the 720 segments), everywhere but across the start point (where it jumps back to L)
    away = np.mod(phi, 2 * np.pi) < 2 * np.pi - 0.25
    q = np.column_stack((r * np.cos(phi + 0.2), r * np.sin(phi + 0.2)))
    assert (t - nav.travel_time(q))[away] == pytest.approx(np.full(away.sum(), 0.6), abs=2 * np.pi * 3.0 / 720)
    assert nav.max_travel_time_s == pytest.approx(2 * np.pi * 3.0, rel=1e-4)
    assert np.all((t > 0) & (t <= nav.max_travel_time_s))


def test_the_lookahead_steers_back_to_the_centreline_and_into_the_bend():
    nav = CirculationNavigation(_circle(3.0), lookahead_m=1.0)
    e_out = nav.direction(np.array([[3.2, 0.0]]))[0]  # outside the centreline, heading +y
    e_in = nav.direction(np.array([[2.8, 0.0]]))[0]
    e_on = nav.direction(np.array([[3.0, 0.0]]))[0]
    assert e_out[1] > 0 and e_out[0] < e_on[0] < 0 < e_in[0]  # inward outside; outward inside
    assert np.degrees(np.arctan2(-e_on[0], e_on[1])) == pytest.approx(np.degrees(1.0 / 3.0 / 2.0), rel=0.02)


def test_arc_length_offset_and_reachability():
    nav = CirculationNavigation(oval_centreline(4.0, 3.0, 0.05), half_width_m=0.4)
    s = nav.arc_length(np.array([[0.0, -3.0], [2.0, -3.1], [7.0, 0.0], [2.0, 3.0]]))
    assert s == pytest.approx([0.0, 2.0, 4.0 + 1.5 * math.pi, 8.0 + 3.0 * math.pi - 2.0], abs=1e-3)
    assert nav.offset(np.array([[2.0, -3.1], [2.0, -2.9]])) == pytest.approx([-0.1, 0.1], abs=1e-9)
    nav.check_reachable(np.array([[2.0, -3.3]]))
    with pytest.raises(GeometryError, match="not on the loop"):
        nav.check_reachable(np.array([[2.0, 0.0]]), what="pedestrian")
    with pytest.raises(GeometryError, match="not finite"):
        nav.sample(np.array([[np.nan, 0.0]]))


@pytest.mark.parametrize("bad, match", [
    (np.array([[0.0, 0.0], [1.0, 0.0]]), "at least 3"),
    (np.array([[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]]), "crosses itself"),
])
def test_bad_centrelines_are_refused(bad, match):
    with pytest.raises(GeometryError, match=match):
        CirculationNavigation(bad)


def test_a_half_width_beyond_the_curvature_radius_is_refused():
    with pytest.raises(GeometryError, match="radius of curvature"):
        CirculationNavigation(_circle(1.0), half_width_m=1.2)


# -- the ring scenario -------------------------------------------------------------------------------
def test_the_ring_is_closed_one_agent_wide_and_validated_against_the_loop():
    sc = make_scenario("rimea_16_ring", n_pedestrians=12)
    g = sc.geometry
    assert isinstance(sc, Scenario) and sc.n_pedestrians == 12
    assert g.walkable_area.area == pytest.approx(0.8 * L_OVAL, rel=2e-3)
    # the sealed exit touches no wall and lies within the band no centre can reach
    exit_poly = g.exits[0]
    assert exit_poly.intersection(g.walkable_area.boundary).length == 0.0
    assert shapely.distance(exit_poly, g.walkable_area.boundary) < 0.23 - 0.1
    assert g.walls.shape[0] > 100 and shapely.within(exit_poly, g.walkable_area)
    nav = sc.navigation()
    assert isinstance(nav, CirculationNavigation)
    assert np.diff(np.sort(nav.arc_length(sc.position_m))) == pytest.approx(np.full(11, L_OVAL / 12), rel=1e-3)
    way = np.array(sc.metadata["jupedsim_waypoints"])
    assert way.shape[1] == 2 and 20 <= way.shape[0] <= 30 and sc.metadata["jupedsim_waypoint_distance_m"] == 0.4
    assert np.abs(nav.offset(way)).max() < 1e-9
    with pytest.raises(ScenarioError, match="do not fit"):
        make_scenario("rimea_16_ring", n_pedestrians=60)


def test_the_ring_runs_without_anybody_leaving_and_without_overlap():
    from crowd_env.experiments.validation.rimea.base import run_crowd_env

    sc = make_scenario("rimea_16_ring", n_pedestrians=20, seed=3)
    run = run_crowd_env(sc, seed=3, max_time_s=15.0)
    assert run.n_left == 0 and run.min_gap_m >= -1e-3 and run.outside_m == 0.0
    smp = loop_samples(run.trajectories, ring_navigation(), 5.0)
    assert smp["speed_m_s"].min() > 0.0  # everybody circulates forwards
    assert smp["laps"].min() > 0.2


def test_the_ring_is_an_rl_environment():
    from crowd_env.envs import crowd_v0

    sc = make_scenario("rimea_16_ring", n_pedestrians=8)
    env = crowd_v0.parallel_env(scenario=sc, controlled=[0, 1, 2], frame_skip=5)
    obs, _ = env.reset(seed=0)
    assert len(obs) == 3 and np.isfinite(env.state()).all()
    lay = env.observation_layout
    nav = sc.navigation()
    s0 = nav.arc_length(env.sim.state.position_m[:3])
    for _ in range(40):  # 2 s: each controlled agent walks at 1 m/s along its observed e_d
        obs, rew, term, trunc, _ = env.step({a: np.asarray(o[lay["desired_direction"]], np.float32)
                                             for a, o in obs.items()})
        assert all(np.isfinite(o).all() for o in obs.values()) and not any(term.values())
    travelled = np.mod(nav.arc_length(env.sim.state.position_m[:3]) - s0, nav.length_m)
    assert np.all((travelled > 1.0) & (travelled < 2.5))
    assert env.sim.state.active.all()


# -- reference data and measurements -----------------------------------------------------------------
def test_weidmann_and_the_percentile_table():
    assert weidmann_speed_m_s([0.5, 1, 2, 3, 4, 5]) == pytest.approx([1.298, 1.058, 0.606, 0.331, 0.156, 0.037],
                                                                    abs=1e-3)
    assert weidmann_speed_m_s([5.4, 6.0]) == pytest.approx([0.0, 0.0])
    ref = single_file_percentiles()
    assert ref.density_per_m.size == 34 and ref.density_per_m[0] == 0.0989 and ref.p90[-1] == 0.22065
    assert np.all(ref.p10 <= ref.p50) and np.all(ref.p50 <= ref.p90)
    assert "jupedsim-web-community" in ref.source


def test_1d_voronoi_density_on_hand_placed_pedestrians():
    # headways 1, 2, 3 and 4 m round a 10 m loop: cells 2.5, 1.5, 2.5, 3.5 m
    s = np.array([0.0, 1.0, 3.0, 6.0])
    assert loop_headway_density_per_m(s, 10.0) == pytest.approx(1 / np.array([2.5, 1.5, 2.5, 3.5]))
    # order and wrap-around do not matter; one pedestrian alone has the loop
    assert loop_headway_density_per_m(s[::-1] + 10.0, 10.0) == pytest.approx(1 / np.array([3.5, 2.5, 1.5, 2.5]))
    assert loop_headway_density_per_m([4.0], 10.0) == pytest.approx([0.1])
    # evenly spaced: N / L for everybody
    assert loop_headway_density_per_m(np.arange(7) * 10 / 7, 10.0) == pytest.approx(np.full(7, 0.7))


def _ring_trajectories(n, speed, seconds=20.0, fps=10.0, jitter=0.0):
    """n pedestrians evenly spaced on the test-16 centreline, all walking at ``speed`` along it."""
    nav = ring_navigation()
    frames = np.arange(int(seconds * fps) + 1)
    rows = []
    for i in range(n):
        s = i * nav.length_m / n + speed * frames / fps
        p = nav.point_at(s)
        rows.append((frames, np.full(frames.size, i), p[:, 0], p[:, 1]))
    f, ids, x, y = (np.concatenate(c) for c in zip(*rows))
    return Trajectories(f, ids, x, y, None, fps), nav


def test_loop_samples_read_known_density_and_speed():
    traj, nav = _ring_trajectories(15, 0.8)
    smp = loop_samples(traj, nav, 5.0)
    assert smp["density_per_m"] == pytest.approx(np.full(smp["density_per_m"].size, 15 / nav.length_m), rel=1e-3)
    assert smp["speed_m_s"] == pytest.approx(np.full(smp["speed_m_s"].size, 0.8), rel=1e-3)
    assert smp["time_s"].min() >= 5.0 and smp["speed_m_s"].size == 15 * (200 - 50 - 5 + 1)
    assert smp["laps"] == pytest.approx(np.full(15, 0.8 * 20.0 / nav.length_m), rel=1e-3)
    bins = bin_samples(smp["density_per_m"], smp["speed_m_s"])
    assert len(bins) == 1 and bins[0]["lower_per_m"] == pytest.approx(0.4)
    p10, _, p90 = single_file_percentiles().at(15 / nav.length_m)
    assert bins[0]["position"] == "inside" and bins[0]["p10_m_s"] == pytest.approx(p10)


def test_area_measures_and_line_flow_of_a_lattice_moving_as_a_block():
    # pedestrians on a 0.5 m x 0.5 m lattice (4 /m²) all moving at 0.5 m/s along x
    fps, speed = 10.0, 0.5
    x0, y0 = np.meshgrid(np.arange(0.25, 40.0, 0.5), np.arange(0.25, 10.0, 0.5), indexing="ij")
    x0, y0 = x0.ravel(), y0.ravel()
    frames = np.arange(0, 201)
    f = np.repeat(frames, x0.size)
    ids = np.tile(np.arange(x0.size), frames.size)
    x = np.tile(x0, frames.size) + speed * f / fps
    y = np.tile(y0, frames.size)
    traj = Trajectories(f, ids, x, y, None, fps)
    areas = {"main": shapely.box(19.0, 4.0, 21.0, 6.0)}
    m = measure_areas(traj, areas, 5.0, 15.0)["main"]
    assert m["density_per_m2"] == pytest.approx(4.0, rel=0.06)  # 16 ± one column entering/leaving
    assert m["speed_m_s"] == pytest.approx(speed, rel=1e-6)
    assert m["flow_per_m_s"] == pytest.approx(m["density_per_m2"] * speed, rel=1e-9)
    # 2 columns per metre cross the line each 1/speed metres... J = rho v = 2 /(m s)
    assert line_flow_per_m_s(traj, 20.0, (4.0, 6.0), 5.0, 15.0) == pytest.approx(2.0, rel=0.06)


def test_test_4_reports_a_density_that_does_not_fit_with_its_capacity():
    with pytest.raises(ScenarioError, match=r"6 P/m².*at most \d+ disks.*hexagonal packing: 5.46"):
        make_scenario("rimea_4_fundamental_diagram", density_per_m2=6.0, back_margin_m=20.0, front_margin_m=20.0)


# -- the quick versions through the suite ------------------------------------------------------------
@pytest.fixture(scope="module")
def quick_results(tmp_path_factory):
    out = tmp_path_factory.mktemp("rimea_fd")
    results = run_suite(["4", "16"], quick=True, out_dir=str(out), progress=None)
    return {r.number: r for r in results}, out


def test_quick_test_4_documents_the_diagram(quick_results):
    results, out = quick_results
    r = results["4"]
    v = r.verdicts["crowd_env"]
    table = {row["nominal_density_per_m2"]: row for row in v.details["table"]}
    assert set(table) == {0.5, 2.0, 4.0} and "6" in v.details["unplaceable"]
    assert r.min_gap_m["crowd_env"] >= -1e-3 and r.outside_m["crowd_env"] == 0.0
    # measured, seed 0 (documented ranges, not tuned): free flow up to 2 /m², slower at 4 /m²
    assert 1.30 <= table[0.5]["main_speed_m_s"] <= 1.35 and 1.25 <= table[2.0]["main_speed_m_s"] <= 1.35
    assert 0.4 <= table[4.0]["main_speed_m_s"] <= 0.9
    for rho, row in table.items():
        assert abs(row["main_density_per_m2"] - rho) <= max(0.3, 0.5 * rho)
    assert v.passed is True and (out / "rimea_4.png").exists()


def test_quick_test_16_fails_the_envelope_for_a_physical_reason(quick_results):
    results, out = quick_results
    r = results["16"]
    v = r.verdicts["crowd_env"]
    assert r.min_gap_m["crowd_env"] >= -1e-3 and r.outside_m["crowd_env"] == 0.0
    assert all(run["n_samples"] > 1000 and not run["stalled"] for run in v.details["runs"])
    bins = v.details["bins"]
    # the platoon walks at its slowest member's desired speed at every density (no speed-dependent headway):
    # a flat curve near 0.9-1.05 m/s, above the experiments' p90 from about 1 /m on
    assert all(0.8 <= b["median_speed_m_s"] <= 1.1 for b in bins)
    assert all(b["position"] == "above" for b in bins if b["density_per_m"] > 1.2)
    assert v.passed is False and v.value < 0.75 and (out / "rimea_16.png").exists()
