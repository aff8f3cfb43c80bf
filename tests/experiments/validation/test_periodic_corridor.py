"""The periodic corridor run by the runner: the compiled rollout equals stepping to the last bit, runs go to their
time limit without exits or a stall, trajectories unwrap for PedPy, and a point of the fundamental diagram
equals the middle of a long open corridor within noise."""
import numpy as np
import pytest
from shapely.geometry import box

from crowd_env.analysis.periodic import periodic_corridor_point, trajectory_frames, unwrap_trajectories, unwrap_x
from crowd_env.analysis.trajectories import Trajectories, export_run, read_geometry
from crowd_env.core.geometry import Geometry
from crowd_env.walking.presets import DEFAULT_PRESET, get_preset
from crowd_env.experiments.validation.periodic import fundamental_diagram_point
from crowd_env.experiments.running.recording import record_run
from crowd_env.experiments.running.runner import run_scenario
from crowd_env.scenarios import Scenario, make_scenario, place_pedestrians
from crowd_env.walking.agent import SocialForceAgent
from crowd_env.walking.navigation import NavigationField

NO_MEASURES = dict(line=None, density_areas=(), lane_area=None)


def _run(scenario, compiled, **kw):
    state = scenario.make_state()
    calls = []
    result = run_scenario(scenario, SocialForceAgent(scenario.navigation()), get_preset(DEFAULT_PRESET).params(),
                          state=state, compiled=compiled, progress=lambda sim: calls.append(sim), **NO_MEASURES, **kw)
    return result, state, calls


def test_periodic_rollout_equals_stepping_bitwise():
    """A dense bidirectional periodic corridor (3 /m², 10 m): the compiled rollout (chunks of 150 steps, zero
    exits) and the Python steps give the same states and the same smallest gap, bit for bit; every x in [0, L)."""
    sc = make_scenario("periodic_corridor", length_m=10.0, density_per_m2=3.0, westbound_fraction=0.5, seed=2)
    a, sa, calls_a = _run(sc, True, max_time_s=4.0, chunk_steps=150)
    b, sb, calls_b = _run(sc, False, max_time_s=4.0)
    assert len(calls_a) == 3 and len(calls_b) == 400  # compiled chunks, not steps from Python
    assert calls_a[-1].n_staged_steps == 0 and calls_a[-1].n_redetections == calls_b[-1].n_redetections
    for name in ("position_m", "velocity_m_s", "heading_rad", "angular_velocity_rad_s", "active"):
        np.testing.assert_array_equal(getattr(sa, name), getattr(sb, name), err_msg=name)
    assert a.min_gap_m == b.min_gap_m >= -1e-9 and a.n_steps == b.n_steps == 400
    assert np.all((sa.position_m[:, 0] >= 0.0) & (sa.position_m[:, 0] < 10.0))


def test_periodic_run_reaches_its_time_limit_without_a_stall():
    """Nobody leaves a periodic corridor (nobody passes, nobody progresses in the stall rule's sense): the rule is
    off there, so even a 5 s window and a 5 m/s threshold, which any crowd stays below, let a counterflow at
    3.5 /m² run compiled to max_time_s = 8 s; it is neither stalled nor complete."""
    sc = make_scenario("periodic_corridor", length_m=10.0, density_per_m2=3.5, westbound_fraction=0.5, seed=0)
    result, state, calls = _run(sc, True, max_time_s=8.0, stall_window_s=5.0, stall_speed_m_s=5.0)
    assert result.simulated_time_s == pytest.approx(8.0) and not result.stalled
    assert not result.complete and result.n_evacuated == 0 and state.active.all()
    assert calls[-1].n_staged_steps == 0 and result.min_gap_m >= -1e-9


def test_trajectories_unwrap_for_pedpy(tmp_path):
    """Recorded x is wrapped into [0, L); unwrapped (k L added at each crossing) no frame-to-frame move exceeds
    a walker's, PedPy's individual speeds by differences have no jumps, their mean is the periodic point's speed,
    and the unwrapped positions differ from the recorded ones by whole periods; the export reads back with the
    geometry's period."""
    pedpy = pytest.importorskip("pedpy")
    sc = make_scenario("periodic_corridor", length_m=10.0, density_per_m2=1.0, seed=0)
    _, traj = record_run(sc, SocialForceAgent(sc.navigation()), frame_rate_per_s=10.0, max_time_s=12.0, **NO_MEASURES)
    assert traj.x_m.min() >= 0.0 and traj.x_m.max() < 10.0
    jumps = np.abs(np.diff(traj.x_m))[np.diff(traj.id) == 0]
    assert jumps.max() > 5.0  # somebody crossed the seam
    un = unwrap_trajectories(traj, 10.0)
    moves = np.abs(np.diff(un.x_m))[np.diff(un.id) == 0]
    assert moves.max() < 0.3  # < 3 m/s at 10 fps
    k = (un.x_m - traj.x_m) / 10.0
    np.testing.assert_allclose(k, np.round(k), atol=1e-9)
    speed = pedpy.compute_individual_speed(traj_data=un.to_pedpy(), frame_step=2,
                                           speed_calculation=pedpy.SpeedCalculation.BORDER_SINGLE_SIDED)
    assert speed["speed"].max() < 3.0
    t, pos, _ = trajectory_frames(traj)
    point = periodic_corridor_point(t, pos, period_m=10.0, width_m=1.8, direction_x=sc.metadata["direction_x"])
    np.testing.assert_allclose(unwrap_x(pos[:, :, 0], 10.0), trajectory_frames(un)[1][:, :, 0], atol=1e-9)
    assert speed["speed"].mean() == pytest.approx(point.speed_m_s, abs=0.05)
    paths = export_run(tmp_path / "periodic", un, sc.geometry)
    assert read_geometry(paths[1]).period_x_m == 10.0
    np.testing.assert_allclose(Trajectories.read_txt(paths[0]).x_m, un.x_m, atol=1e-4)


def test_periodic_point_measures():
    """ρ = N / (L W) exactly; v from positions equals v from velocities for uniform motion; per direction."""
    t = np.linspace(0.0, 2.0, 21)
    x0 = np.array([0.5, 9.8, 3.0])
    u = np.array([1.0, 1.5, -0.8])
    pos = np.stack([np.mod(x0 + np.outer(t, u), 10.0), np.zeros((21, 3))], axis=2)
    vel = np.broadcast_to(np.stack([u, np.zeros(3)], axis=1), pos.shape)
    sign = np.array([1.0, 1.0, -1.0])
    p = periodic_corridor_point(t, pos, period_m=10.0, width_m=2.0, direction_x=sign, window_s=(0.5, 1.5))
    q = periodic_corridor_point(t, pos, period_m=10.0, width_m=2.0, direction_x=sign, velocity_m_s=vel)
    assert p.density_per_m2 == 3 / 20.0 and p.window_s == pytest.approx((0.5, 1.5))
    assert p.speed_m_s == pytest.approx(1.1) and q.speed_m_s == pytest.approx(1.1)
    assert p.speed_by_direction_m_s == pytest.approx({"east": 1.25, "west": 0.8})
    assert p.specific_flow_per_m_s == pytest.approx(0.15 * 1.1)
    from crowd_env.errors import AnalysisError

    with pytest.raises(AnalysisError, match="direction_x"):
        periodic_corridor_point(t, pos, period_m=10.0, width_m=2.0, direction_x=[1, 0, 1])
    with pytest.raises(AnalysisError, match="window_s"):
        periodic_corridor_point(t, pos, period_m=10.0, width_m=2.0, direction_x=sign, window_s=(3.0, 4.0))


def _long_corridor_middle_speed(density_per_m2, seed, t0_s=4.0, t1_s=12.0, length_m=40.0, width_m=1.8):
    """Mean speed along x in the middle (15 m < x < 25 m) of a 40 m x 1.8 m corridor filled at the density, a back
    wall at x = 0 and an open end at x = 40 m, everyone walking east, between t0 and t1 (before the rarefaction
    behind the crowd's back reaches the middle): speeds by differences of frames 0.1 s apart."""
    hw = 0.5 * width_m
    g = Geometry(box(0, -hw, length_m, hw), exits=[box(length_m, -hw, length_m + 1.0, hw)])
    pos = place_pedestrians(box(0, -hw, length_m, hw), radius_m=0.23, rng=np.random.default_rng(seed),
                            density_per_m2=density_per_m2)
    sc = Scenario(geometry=g, position_m=pos, pedestrian_params={"radius_m": 0.23}, seed=seed,
                  navigation_field=NavigationField.uniform(g, (1.0, 0.0)))
    _, traj = record_run(sc, SocialForceAgent(sc.navigation()), frame_rate_per_s=10.0, max_time_s=t1_s, **NO_MEASURES)
    f, ids, x = traj.frame, traj.id, traj.x_m
    same = (ids[1:] == ids[:-1]) & (f[1:] == f[:-1] + 1)
    v = np.diff(x)[same] * traj.frame_rate_per_s
    x_mid, t_mid = 0.5 * (x[1:] + x[:-1])[same], (f[:-1][same] + 0.5) / traj.frame_rate_per_s
    return float(v[(x_mid > 15.0) & (x_mid < 25.0) & (t_mid > t0_s) & (t_mid < t1_s)].mean())


@pytest.mark.parametrize("density_per_m2", [1.0, 2.5])
def test_periodic_point_equals_long_corridor_middle(density_per_m2):
    """One point of the fundamental diagram, 20 m periodic corridor against the middle of a 40 m open one (both
    1.8 m wide, unidirectional, 4 to 12 s, four seeds each): the mean speeds agree within 0.06 m/s (the seeds
    scatter by 0.03-0.05 m/s; the speed falls by about 0.14 m/s from 1 to 2.5 /m²)."""
    seeds = range(4)
    periodic = [fundamental_diagram_point(density_per_m2, seed=s, max_time_s=12.0, transient_s=4.0)[0].speed_m_s
                for s in seeds]
    long = [_long_corridor_middle_speed(density_per_m2, s) for s in seeds]
    assert abs(np.mean(periodic) - np.mean(long)) < 0.06, (periodic, long)
    assert 0.9 < np.mean(periodic) < 1.4


def test_line_crossings_see_no_seam():
    """A measurement line at x = L/2 of a periodic strip: walkers starting just before the seam cross the seam
    first (x jumps from L to 0 in a step) and reach the line about 5 s later; the runner counts their passage
    then, not at the seam (the move of a step is the nearest image of the displacement)."""
    g = Geometry(box(0, -0.9, 10, 0.9), exits=(), measurement_lines={"middle": [(5.0, -0.9), (5.0, 0.9)]},
                 period_x_m=10.0)
    sc = Scenario(geometry=g, position_m=[[9.0, -0.4], [9.0, 0.4], [8.4, 0.0]], seed=0,
                  pedestrian_params={"radius_m": 0.23, "desired_speed_m_s": 1.2},
                  navigation_field=NavigationField.uniform(g, (1.0, 0.0)))
    for compiled in (True, False):
        result = run_scenario(sc, SocialForceAgent(sc.navigation()), max_time_s=9.0, line="middle",
                              density_areas=(), lane_area=None, compiled=compiled)
        assert result.n_passed == 3 and result.crossing_times_s.min() > 4.0, result.crossing_times_s
