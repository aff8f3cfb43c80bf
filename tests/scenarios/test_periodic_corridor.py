"""The periodic corridor scenario: its geometry (periodic, no exits), placement at a density, the walking
directions, the errors naming the argument, and the single file below 4 r."""
import numpy as np
import pytest

from crowd_env.scenarios import ScenarioError, make_scenario
from crowd_env.walking.agent import SocialForceAgent


def test_periodic_corridor_geometry_and_crowd():
    """20 m x 1.8 m at 2 /m²: N = 72, period 20 m, no exits, side walls only, nobody overlapping (across the
    seam neither), e_d = (+1, 0) for eastbound and (−1, 0) for westbound walkers, half of each at 0.5."""
    sc = make_scenario("periodic_corridor", density_per_m2=2.0, westbound_fraction=0.5, seed=3)
    g = sc.geometry
    assert g.period_x_m == 20.0 and g.exits == () and g.walls.shape == (2, 4)
    assert sc.n_pedestrians == 72 and sc.metadata["density_per_m2"] == pytest.approx(2.0)
    sign = np.asarray(sc.metadata["direction_x"])
    assert np.count_nonzero(sign < 0) == sc.metadata["n_westbound"] == 36
    e_d = SocialForceAgent(sc.navigation()).desired_direction(sc.make_simulator())
    np.testing.assert_array_equal(e_d, np.column_stack([sign, np.zeros(72)]))
    np.testing.assert_allclose(np.cos(sc.heading_rad), sign, atol=1e-12)
    sim = sc.make_simulator()  # checks overlaps across the seam
    assert sim.period_m == 20.0 and sim.min_gap_m() >= 0.0
    assert make_scenario("periodic_corridor", n_pedestrians=10).n_pedestrians == 10
    assert make_scenario("periodic_corridor").metadata["density_per_m2"] == pytest.approx(1.0)


@pytest.mark.parametrize("options, match", [
    (dict(density_per_m2=6.0), "density_per_m2 = 6.0 cannot be placed"),
    (dict(n_pedestrians=400), "n_pedestrians = 400 cannot be placed"),
    (dict(density_per_m2=1.0, n_pedestrians=10), "density_per_m2 or n_pedestrians, not both"),
    (dict(density_per_m2=-1.0), "density_per_m2"),
    (dict(westbound_fraction=1.5), "westbound_fraction"),
    (dict(width_m=0.4), "width_m"),
    (dict(length_m=0.0), "length_m"),
])
def test_periodic_corridor_errors_name_the_argument(options, match):
    with pytest.raises(ScenarioError, match=match):
        make_scenario("periodic_corridor", **options)


def test_periodic_scenario_cannot_be_moved():
    with pytest.raises(ScenarioError, match="periodic"):
        make_scenario("periodic_corridor", n_pedestrians=5).moved(0.5)


def test_single_file_ring_keeps_its_order():
    """0.7 m wide (< 4 r): a straight ring of single file. 20 walkers on 20 m for 20 s with the calibrated
    agent: they walk (every one over 10 m) and nobody overtakes anybody: the cyclic order along x never changes."""
    from crowd_env.analysis.periodic import trajectory_frames, unwrap_x
    from crowd_env.experiments.running.recording import record_run

    sc = make_scenario("periodic_corridor", width_m=0.7, n_pedestrians=20, seed=1)
    assert sc.metadata["single_file"]
    _, traj = record_run(sc, SocialForceAgent(sc.navigation()), frame_rate_per_s=10.0, max_time_s=20.0, line=None,
                         density_areas=(), lane_area=None)
    _, pos, _ = trajectory_frames(traj)
    x = unwrap_x(pos[:, :, 0], 20.0)
    assert (x[-1] - x[0]).min() > 10.0
    file = x[:, np.argsort(x[0])]  # unwrapped positions in the start order, rearmost first
    # each one stays ahead of the one behind it, and the rearmost stays behind the foremost (round the ring):
    # two disks staggered across the 0.24 m the centres have are still sqrt(0.46² - 0.24²) = 0.39 m apart along x
    assert np.diff(file, axis=1).min() > 0.39 - 1e-9
    assert (file[:, 0] + 20.0 - file[:, -1]).min() > 0.39 - 1e-9


def test_overlap_across_the_seam_is_refused():
    """A scenario on a periodic geometry whose start positions overlap across the seam raises naming the pair."""
    from shapely.geometry import box

    from crowd_env.core.geometry import Geometry
    from crowd_env.scenarios import Scenario
    from crowd_env.walking.navigation import NavigationField

    g = Geometry(box(0, -0.9, 10, 0.9), exits=(), period_x_m=10.0)
    with pytest.raises(ScenarioError, match="pedestrians 0 and 1 overlap"):
        Scenario(geometry=g, position_m=[[0.1, 0.0], [9.75, 0.0]], pedestrian_params={"radius_m": 0.23},
                 navigation_field=NavigationField.uniform(g, (1.0, 0.0)))
