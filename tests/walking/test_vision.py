"""Vision (crowd_env.walking.vision): the free distance, the speed rule and the choice of direction against
hand-computed cases, and the agent with vision in compiled and Python stepping alike."""
import math

import numpy as np
import pytest

from crowd_env.core.params import ParameterError
from crowd_env.walking import ModelParams
from crowd_env.walking.vision import (Sight, Vision, free_distances, gives_way, ray_circle_distance, through_a_door,
                                     vision_walk)

NO_WALLS = np.zeros((0, 4))
ALL_PAIRS = np.array([[0, 1], [0, 2], [1, 2]], np.int64)


def _walk(position, e_d, v0=1.34, T=1.0, l=0.2, half=0.0, rays=1, kappa=1.0, walls=NO_WALLS, pairs=None, radius=0.23,
          kappa_standing=None, velocity=None, anticipation=0.0, leader_time=0.0, right_of_way=False, travel_time=None,
          period_m=0.0, door_time=None, door_ratio=3.0):
    position = np.asarray(position, dtype=float)
    n = position.shape[0]
    if pairs is None:
        pairs = np.array([(i, j) for i in range(n) for j in range(i + 1, n)], np.int64).reshape(-1, 2)
    velocity = np.zeros((n, 2)) if velocity is None else np.asarray(velocity, dtype=float)
    times = np.zeros(0) if travel_time is None else np.asarray(travel_time, dtype=float)
    return vision_walk(position, np.full(n, radius), np.arange(n), np.asarray(e_d, dtype=float), np.full(n, v0),
                       velocity, pairs, walls, period_m,
                       Vision(T, l, half, rays, kappa, kappa if kappa_standing is None else kappa_standing,
                              anticipation, leader_time, bool(right_of_way or travel_time is not None),
                              T if door_time is None else door_time, door_ratio), times)


def test_ray_circle_distance_analytic():
    # head-on: centre 2 m ahead, R = 0.46 -> 1.54 m; offset 0.3 m laterally -> 2 - sqrt(0.46² - 0.3²)
    assert ray_circle_distance(0.0, 0.0, 1.0, 0.0, 2.0, 0.0, 0.46) == pytest.approx(1.54)
    assert ray_circle_distance(0.0, 0.0, 1.0, 0.0, 2.0, 0.3, 0.46) == pytest.approx(2.0 - math.sqrt(0.46**2 - 0.09))
    assert ray_circle_distance(0.0, 0.0, 1.0, 0.0, 2.0, 0.5, 0.46) == math.inf  # passes beside
    assert ray_circle_distance(0.0, 0.0, 1.0, 0.0, -2.0, 0.0, 0.46) == math.inf  # behind
    assert ray_circle_distance(0.0, 0.0, 1.0, 0.0, 0.4, 0.0, 0.46) == 0.0  # touching, walking into it
    assert ray_circle_distance(0.0, 0.0, 1.0, 0.0, -0.4, 0.0, 0.46) == math.inf  # touching, walking away


def test_free_walker_keeps_desired_speed_and_direction():
    speed, walk = _walk([[0.0, 0.0]], [[0.6, 0.8]], half=1.2, rays=9)
    assert speed[0] == 1.34
    np.testing.assert_allclose(walk[0], [0.6, 0.8], atol=1e-15)


@pytest.mark.parametrize("gap_m", [0.1, 0.5, 0.9, 1.3])
def test_follower_speed_is_the_speed_rule(gap_m):
    # a follower behind a pedestrian straight ahead: v = min(v0, max(0, (f - l)/T)), f = centre distance - 2r
    centre = 0.46 + gap_m
    speed, _ = _walk([[0.0, 0.0], [centre, 0.0]], [[1.0, 0.0], [1.0, 0.0]], T=0.8, l=0.2)
    assert speed[0] == pytest.approx(min(1.34, max(0.0, (gap_m - 0.2) / 0.8)))
    assert speed[1] == 1.34  # the leader sees nobody ahead


def test_body_scale_lets_an_offset_neighbour_pass():
    # neighbour 1 m ahead and 0.3 m aside: blocks with kappa = 1 (0.3 < 0.46), not with kappa = 0.5 (0.3 > 0.23)
    pos = [[0.0, 0.0], [1.0, 0.3]]
    e = [[1.0, 0.0], [1.0, 0.0]]
    blocked, _ = _walk(pos, e, kappa=1.0)
    free, _ = _walk(pos, e, kappa=0.5)
    f = 1.0 - math.sqrt(0.46**2 - 0.09)
    assert blocked[0] == pytest.approx((f - 0.2) / 1.0)
    assert free[0] == 1.34


def test_body_scale_shrinks_with_the_walkers_own_speed():
    # kappa_0 = 1 at rest, kappa = 0.5 at the desired speed: the same neighbour (1 m ahead, 0.3 m aside) blocks a
    # standing walker, not one at its desired speed; at half of it kappa = 0.75 (0.3 < 0.345: blocks)
    pos = [[0.0, 0.0], [1.0, 0.3]]
    e = [[1.0, 0.0], [1.0, 0.0]]
    standing, _ = _walk(pos, e, kappa=0.5, kappa_standing=1.0)
    walking, _ = _walk(pos, e, kappa=0.5, kappa_standing=1.0, velocity=[[1.34, 0.0], [0.0, 0.0]])
    half, _ = _walk(pos, e, kappa=0.5, kappa_standing=1.0, velocity=[[0.0, 0.67], [0.0, 0.0]])
    assert standing[0] == pytest.approx(1.0 - math.sqrt(0.46**2 - 0.09) - 0.2)
    assert walking[0] == 1.34
    assert half[0] == pytest.approx(1.0 - math.sqrt(0.345**2 - 0.09) - 0.2)


def test_anticipation_sees_a_leader_walk_on():
    # leader 1 m ahead walking away at 1.0 m/s, follower's v0 = 1.34: relative closing speed 0.34 m/s (w = 1)
    pos = [[0.0, 0.0], [1.0, 0.0]]
    e = [[1.0, 0.0], [1.0, 0.0]]
    vel = [[0.0, 0.0], [1.0, 0.0]]
    static, _ = _walk(pos, e, velocity=vel, T=1.0, l=0.2)
    moving, _ = _walk(pos, e, velocity=vel, T=1.0, l=0.2, anticipation=1.0)
    half, _ = _walk(pos, e, velocity=vel, T=1.0, l=0.2, anticipation=0.5)
    assert static[0] == pytest.approx(1.0 - 0.46 - 0.2)
    # contact after t = (1 - 0.46) / 0.34 s, walking 1.34 t; beyond the horizon l + T v0 = 1.54 m: free
    assert moving[0] == 1.34
    t = (1.0 - 0.46) / (1.34 - 0.5)  # the leader at half its speed
    assert half[0] == pytest.approx(min(1.34, 1.34 * t - 0.2))
    # a standing leader: the same as without anticipation
    still, _ = _walk(pos, e, velocity=[[0.0, 0.0], [0.0, 0.0]], anticipation=1.0)
    assert still[0] == pytest.approx(static[0])
    with pytest.raises(ParameterError, match="vision_anticipation"):
        ModelParams(vision_anticipation=2.0)


def test_leader_pulling_away_lends_its_gap():
    # follower at 0.3 m/s, leader 1.2 m ahead pulling away at 1.0 m/s: f = 1.2 - 0.46 = 0.74; with T_a = 0.5 s
    # the gap gains 0.5 * (1.0 - 0.3) = 0.35 m: v = (0.74 + 0.35 - 0.2) / 1.0
    pos = [[0.0, 0.0], [1.2, 0.0]]
    e = [[1.0, 0.0], [1.0, 0.0]]
    vel = [[0.3, 0.0], [1.0, 0.0]]
    static, _ = _walk(pos, e, velocity=vel, T=1.0, l=0.2)
    lent, _ = _walk(pos, e, velocity=vel, T=1.0, l=0.2, leader_time=0.5)
    assert static[0] == pytest.approx(0.74 - 0.2)
    assert lent[0] == pytest.approx(0.74 + 0.35 - 0.2)
    assert lent[1] == 1.34  # the leader sees nobody ahead
    # steady following (u_l = u_i), a standing or an approaching leader: the rule without T_a, to the bit
    for v_leader in (0.3, 0.0, -0.8):
        same, _ = _walk(pos, e, velocity=[[0.3, 0.0], [v_leader, 0.0]], T=1.0, l=0.2, leader_time=0.5)
        assert same[0] == static[0]
    # only the velocity along the chosen direction counts: a leader walking sideways lends nothing
    side, _ = _walk(pos, e, velocity=[[0.3, 0.0], [0.0, 1.0]], T=1.0, l=0.2, leader_time=0.5)
    assert side[0] == static[0]
    # a wall ahead of a walker moving forward lends nothing (its u_l is 0)
    wall = np.array([[1.0, -5.0, 1.0, 5.0]])
    walled, _ = _walk([[0.0, 0.0]], [[1.0, 0.0]], velocity=[[0.3, 0.0]], walls=wall, leader_time=2.0)
    assert walled[0] == pytest.approx(1.0 - 0.23 - 0.2)
    with pytest.raises(ParameterError, match="vision_leader_time_s"):
        ModelParams(vision_leader_time_s=-0.1)


def test_right_of_way_lets_the_walker_nearer_the_exit_go_first():
    # a standoff: two walkers head-on in a strip 0.6 m wide, each within l of the other along every ray
    strip = np.array([[-5.0, -0.3, 5.0, -0.3], [-5.0, 0.3, 5.0, 0.3]])
    pos = [[0.0, 0.0], [0.6, 0.0]]
    e = [[1.0, 0.0], [-1.0, 0.0]]
    both, _ = _walk(pos, e, T=1.0, l=0.2, half=math.radians(75), rays=11, walls=strip)
    assert both[0] == 0.0 and both[1] == 0.0  # without the right of way: both stand, for good
    first, _ = _walk(pos, e, T=1.0, l=0.2, half=math.radians(75), rays=11, walls=strip, travel_time=[1.0, 2.0])
    assert first[0] == 1.34 and first[1] == 0.0  # the one nearer its exit (smaller T) goes, the other waits
    # a neighbour ahead (nearer the exit) blocks as before, to the bit; one behind never blocks
    follow = [[0.0, 0.0], [1.2, 0.0]]
    ahead, _ = _walk(follow, [[1.0, 0.0], [1.0, 0.0]], T=1.0, l=0.2)
    ahead_row, _ = _walk(follow, [[1.0, 0.0], [1.0, 0.0]], T=1.0, l=0.2, travel_time=[5.0, 4.0])
    assert ahead_row[0] == ahead[0] == pytest.approx(1.2 - 0.46 - 0.2)
    back, _ = _walk([[0.0, 0.0], [-1.2, 0.0]], [[-1.0, 0.0], [-1.0, 0.0]], T=1.0, l=0.2, travel_time=[5.0, 6.0])
    assert back[0] == 1.34  # the one ahead of it (nearer the exit) walks free
    with pytest.raises(ParameterError, match="vision_right_of_way"):
        ModelParams(vision_right_of_way=1)


def test_right_of_way_in_a_periodic_world_reads_behind_along_e_d_by_the_minimum_image():
    # period 10 m: the leader at x = 0.5 is 1.2 m ahead of the follower at x = 9.3 across the seam; the uniform
    # field's T jumps there (the leader's T is the larger), yet the leader still blocks: behind/ahead is read
    # along e_d by the minimum image
    pos = [[9.3, 0.0], [0.5, 0.0]]
    e = [[1.0, 0.0], [1.0, 0.0]]
    plain, _ = _walk(pos, e, T=1.0, l=0.2, period_m=10.0)
    row, _ = _walk(pos, e, T=1.0, l=0.2, period_m=10.0, travel_time=[0.7, 9.5])
    assert row[0] == plain[0] == pytest.approx(1.2 - 0.46 - 0.2)
    assert row[1] == 1.34  # the follower, behind the leader, never blocks it
    assert not gives_way(9.5, 0.7, 1.2, 0.0, 1.0, 0.0, True) and gives_way(0.7, 9.5, -1.2, 0.0, 1.0, 0.0, True)
    assert gives_way(2.0, 1.0, 0.0, 0.0, 1.0, 0.0, False) and not gives_way(1.0, 2.0, 0.0, 0.0, 1.0, 0.0, False)
    # a navigation without travel times (circulation round a loop) reads positions along e_d the same way
    loop, _ = _walk([[0.0, 0.0], [1.2, 0.0]], e, T=1.0, l=0.2, right_of_way=True)
    assert loop[0] == pytest.approx(1.2 - 0.46 - 0.2) and loop[1] == 1.34


def test_fan_steers_round_a_standing_pedestrian():
    # somebody 0.8 m straight ahead: along e_d the free distance is 0.34 m; a side ray passes them
    speed, walk = _walk([[0.0, 0.0], [0.8, 0.0]], [[1.0, 0.0], [0.0, 1.0]], half=math.radians(75), rays=11)
    angle = math.degrees(math.atan2(walk[0, 1], walk[0, 0]))
    assert 10.0 < abs(angle) <= 75.0 + 1e-9
    # the chosen direction's own free distance sets the speed, and it beats walking straight
    straight, _ = _walk([[0.0, 0.0], [0.8, 0.0]], [[1.0, 0.0], [0.0, 1.0]])
    assert speed[0] > straight[0]


def test_symmetric_tie_goes_to_the_direction_of_e_d():
    # nothing anywhere: every ray is free, e_d (the first ray) wins exactly
    _, walk = _walk([[0.0, 0.0]], [[1.0, 0.0]], half=1.0, rays=5)
    assert walk[0, 1] == 0.0 and walk[0, 0] == 1.0


def test_wall_ahead_stops_the_walker():
    # a wall across the way 1 m ahead: the disk touches it after 1 - r
    wall = np.array([[1.0, -5.0, 1.0, 5.0]])
    speed, _ = _walk([[0.0, 0.0]], [[1.0, 0.0]], walls=wall, T=1.0, l=0.2)
    assert speed[0] == pytest.approx((1.0 - 0.23 - 0.2) / 1.0)
    free, leader = free_distances(np.zeros((1, 2)), np.full(1, 0.23), np.zeros((1, 2)), np.arange(1), np.arange(1),
                                  np.array([[0.0, math.pi]]), (np.zeros(0, np.int64), np.zeros(2, np.int64)), wall, 0.0,
                                  Sight(np.full(1, 5.0), np.ones(1), np.full(1, 1.34), 0.0, 0), np.zeros(0),
                                  np.array([[1.0, 0.0]]))
    assert free[0, 0] == pytest.approx(0.77) and free[0, 1] == 5.0
    assert leader[0, 0] == 0.0 and leader[0, 1] == 0.0


def test_vision_parameters_are_checked():
    with pytest.raises(ParameterError, match="vision_rays"):
        ModelParams(vision_rays=4)
    with pytest.raises(ParameterError, match="vision_half_angle_rad"):
        ModelParams(vision_rays=3)
    with pytest.raises(ParameterError, match="vision_body_scale"):
        ModelParams(vision_body_scale=0.0)
    with pytest.raises(ParameterError, match="vision_body_scale_standing"):
        ModelParams(vision_body_scale_standing=1.5)
    with pytest.raises(ParameterError, match="vision_time_gap_s"):
        ModelParams(vision_time_gap_s=-1.0)
    with pytest.raises(ParameterError, match="vision_door_time_gap_s"):
        ModelParams(vision_time_gap_s=1.0, vision_door_time_gap_s=0.0)
    with pytest.raises(ParameterError, match="vision_door_time_gap_s .* needs vision switched on"):
        ModelParams(vision_door_time_gap_s=0.5)
    with pytest.raises(ParameterError, match="vision_door_ratio"):
        ModelParams(vision_time_gap_s=1.0, vision_door_ratio=-1.0)
    assert ModelParams(vision_time_gap_s=1.0).walking_bundle.vision.door_time_gap_s == 1.0  # None: T


def _corridor(width_m, door_m=None, door_x_m=3.0):
    """Walls along +x at y = ±width/2, and with ``door_m`` an end wall 0.1 m thick at x = ``door_x_m`` with a door of
    that width (its posts' upstream and inner faces)."""
    h = 0.5 * width_m
    walls = [[-10.0, -h, 10.0, -h], [-10.0, h, 10.0, h]]
    if door_m is not None:
        d = 0.5 * door_m
        walls += [[door_x_m, -h, door_x_m, -d], [door_x_m, d, door_x_m, h],
                  [door_x_m, -d, door_x_m + 0.1, -d], [door_x_m, d, door_x_m + 0.1, d]]
    return np.array(walls, float)


def _channel(corridor_m, channel_m, start_x_m, end_x_m):
    """A corridor along +x narrowing at ``start_x_m`` into a channel ending at ``end_x_m`` in open floor."""
    h, c = 0.5 * corridor_m, 0.5 * channel_m
    return np.array([[-10.0, -h, start_x_m, -h], [-10.0, h, start_x_m, h], [start_x_m, -h, start_x_m, -c],
                     [start_x_m, h, start_x_m, c], [start_x_m, -c, end_x_m, -c], [start_x_m, c, end_x_m, c]], float)


def _bend(width_m, turn_x_m):
    """A corridor along +x of ``width_m`` turning left (+y) at ``turn_x_m``: its inner wall ends there, its outer wall
    meets the end wall across the path; the leg going up is as wide."""
    h = 0.5 * width_m
    return np.array([[-10.0, h, turn_x_m, h], [turn_x_m, h, turn_x_m, 10.0],  # inner corner, then the leg's wall
                     [-10.0, -h, turn_x_m + width_m, -h],  # outer wall to the corner
                     [turn_x_m + width_m, -h, turn_x_m + width_m, 10.0]], float)  # across the path, the leg's wall


@pytest.mark.parametrize("walls, x_m, door", [
    (_corridor(1.8), 0.0, False),         # a corridor of 3.9 shoulder widths
    (_corridor(1.2), 0.0, False),         # 2.6 shoulder widths all along: a channel, no door
    (_corridor(1.8, 0.95), 0.0, False),   # the door 3 m ahead, beyond r + H = 0.23 + 0.2 + 1.34 = 1.77 m
    (_corridor(1.8, 0.95), 1.4, True),    # 1.6 m ahead, the stretch through it: narrows, opens again
    (_corridor(1.8, 0.95), 1.3, False),   # 1.7 m ahead: the stretch ends in the door, not yet through it
    (_corridor(1.8, 0.95), 3.05, True),   # in the door
    (_corridor(1.8, 0.95), 3.15, False),  # just past it: the posts behind, the corridor's walls go on (1.8 m)
    (_channel(1.8, 1.0, 2.0, 10.0), 1.0, False),  # into a channel longer than the stretch: no door
    (_channel(1.8, 1.0, 2.0, 10.0), 9.0, True),   # near its end, where it opens into the floor
    (_bend(0.8, 2.0), 1.0, False),        # a corridor of 0.8 m turning left 1 m ahead: opens on one side only
])
def test_door_time_gap_where_the_way_passes_a_door(walls, x_m, door):
    """A follower 0.5 m (surface gap) behind a standing leader: v = (f − l)/T_d where its stretch (r + l + T v0
    ahead) passes a door, a narrowing below ρ_d = 3 shoulder widths (1.38 m) that opens again, (f − l)/T elsewhere;
    with T_d = T (or None) the rule is vision's. Walls only: the leader ahead does not narrow the way."""
    pos = [[x_m, 0.0], [x_m + 0.46 + 0.5, 0.0]]
    e = [[1.0, 0.0], [1.0, 0.0]]
    speed, _ = _walk(pos, e, T=1.0, l=0.2, walls=walls, door_time=0.5)
    assert speed[0] == pytest.approx((0.5 - 0.2) / (0.5 if door else 1.0))
    plain, _ = _walk(pos, e, T=1.0, l=0.2, walls=walls)
    same, _ = _walk(pos, e, T=1.0, l=0.2, walls=walls, door_time=1.0)
    assert plain[0] == pytest.approx(0.3) and same[0] == plain[0]


def test_door_time_gap_caps_at_the_desired_speed():
    """In the door a leader 0.9 m ahead leaves (0.9 − l)/T_d = 1.4 m/s: the walker walks at v0 (the horizon
    l + T_d v0 = 0.87 m); in the corridor before it, (0.9 − l)/T = 0.7 m/s."""
    walls = _corridor(1.8, 0.95)
    e = [[1.0, 0.0], [1.0, 0.0]]
    speed, _ = _walk([[3.05, 0.0], [3.05 + 0.46 + 0.9, 0.0]], e, walls=walls, door_time=0.5)
    assert speed[0] == 1.34
    speed, _ = _walk([[-2.0, 0.0], [-2.0 + 0.46 + 0.9, 0.0]], e, walls=walls, door_time=0.5)
    assert speed[0] == pytest.approx(0.7)


def test_door_ratio_sets_the_width_called_a_door():
    """A door of 1.2 m is 2.6 shoulder widths: a door for ρ_d = 3, not for ρ_d = 2.5."""
    pos = [[1.4, 0.0], [2.36, 0.0]]
    e = [[1.0, 0.0], [1.0, 0.0]]
    narrow, _ = _walk(pos, e, walls=_corridor(1.8, 1.2), door_time=0.5, door_ratio=3.0)
    wide, _ = _walk(pos, e, walls=_corridor(1.8, 1.2), door_time=0.5, door_ratio=2.5)
    assert narrow[0] == pytest.approx(0.6) and wide[0] == pytest.approx(0.3)


def test_through_a_door_reads_the_sides_in_order():
    def door(*widths):  # symmetric lines of these widths
        return through_a_door(np.array([[0.5 * w, 0.5 * w] for w in widths]), 1.38)

    assert door(1.8, 1.8, 0.9, 0.9, 1.8)
    assert not door(1.8, 1.8, 0.9, 0.9, 0.9)  # only narrows
    assert not door(0.9, 0.9, 0.9)  # stays narrow
    assert not door(1.8, 1.8)
    assert door(0.9, 1.38)
    # a bend: past the narrow part the room opens on the left only
    assert not through_a_door(np.array([[0.4, 0.4], [0.4, 0.4], [5.0, 0.4], [5.0, 0.4]]), 1.38)
    assert through_a_door(np.array([[0.4, 0.4], [5.0, 0.69], [5.0, 0.4]]), 1.38)


@pytest.mark.parametrize("leader_time_s, right_of_way", [(0.0, False), (1.0, True)])
def test_compiled_rollout_equals_stepping_with_vision(leader_time_s, right_of_way):
    """The compiled rollout and Python stepping run the same vision walk, to the last bit (trajectories), and it
    differs from the default preset's."""
    from crowd_env.walking.presets import get_preset

    from .rollout_check import assert_rollout_equals_stepping

    assert_rollout_equals_stepping(get_preset("vision").params(vision_leader_time_s=leader_time_s,
                                                               vision_right_of_way=right_of_way))


def test_compiled_rollout_equals_stepping_with_a_door_time_gap():
    """At a 0.5 m entrance (the Jülich corridor run, its waiting crowd at the barrier) the door's time gap acts (the
    walk differs from vision's without it) and the compiled rollout and Python stepping run it to the last bit."""
    from crowd_env.scenarios import make_scenario
    from crowd_env.walking.presets import get_preset

    from .rollout_check import assert_rollout_equals_stepping

    scenario = make_scenario("juelich_corridor", entrance_width_m=0.5, n_pedestrians=20, seed=1)
    vision = get_preset("vision").params()
    assert_rollout_equals_stepping(vision.replace(vision_door_time_gap_s=0.5), scenario=scenario, reference=vision,
                                   max_time_s=3.0)
