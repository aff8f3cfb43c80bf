"""Turning the shoulders at a narrow aperture (crowd_env.walking.shoulder_turn): the aperture by hand-worked cases and
against a sampled one, the turn angle of Warren & Whang's rule, the parameters checked by name and off by default, the
compiled rollout equal to stepping, and a walker of three circles turning through a gap that a walker facing it
cannot pass."""
import math

import numpy as np
import pytest

from crowd_env.core.params import ParameterError
from crowd_env.walking import ModelParams
from crowd_env.walking.apertures import apertures_m
from crowd_env.walking.shoulder_turn import ShoulderTurn, shoulder_turn

from .scenes import gap_world, random_scene

R = 0.23
CORRIDOR = np.array([[-5.0, -0.4, 5.0, -0.4], [-5.0, 0.4, 5.0, 0.4]])  # walls at y = ±0.4


def _pairs(n):
    return np.array([(a, b) for a in range(n) for b in range(a + 1, n)], np.int64).reshape(-1, 2)


def _aperture(positions, walk, walls=CORRIDOR, lookahead_m=0.3, radius=R, period_m=0.0):
    positions = np.asarray(positions, float)
    n = len(positions)
    return apertures_m(positions, np.full(n, radius), np.arange(n), np.asarray(walk, float), _pairs(n), walls,
                       float(period_m), lookahead_m)


def test_aperture_between_walls_and_a_neighbour():
    """Walking along +x between walls at y = ±0.4: the aperture is 0.8 m; a neighbour whose disk crosses the lines
    across the path up to q = x + (r + L) e narrows it: centred 0.3 m left of q, 0.07 m are left on that side; 0.1 m
    beyond q, 0.3 − √(r² − 0.1²); a disk beyond every line leaves it 0.8 m."""
    walk = [(1.0, 0.0), (0.0, 1.0)]  # the neighbour's own walk does not matter here
    ahead = R + 0.3
    a, left, right = _aperture([(0.0, 0.0), (ahead, 0.3)], walk)
    assert a[0] == pytest.approx(0.4 + 0.07, abs=1e-12)
    assert left[0] == pytest.approx(0.07, abs=1e-12) and right[0] == pytest.approx(0.4, abs=1e-12)
    a, left, _ = _aperture([(0.0, 0.0), (ahead + 0.1, 0.3)], walk)
    assert left[0] == pytest.approx(0.3 - math.sqrt(R ** 2 - 0.1 ** 2), abs=1e-12)
    a, left, _ = _aperture([(0.0, 0.0), (ahead + R + 0.01, 0.3)], walk)
    assert a[0] == pytest.approx(0.8, abs=1e-12)
    # a disk across the path (covering the lines' centres from s = r + L − 0.13 on) is followed, not passed: the
    # lines it covers are left out, the others see the walls
    a, _, _ = _aperture([(0.0, 0.0), (ahead + 0.1, 0.05)], walk)
    assert a[0] == pytest.approx(0.8, abs=1e-12)
    # ... and beside it a narrow gap to a wall still counts: the neighbour 0.3 m left, a wall 0.2 m right
    walls = np.array([[-5.0, -0.2, 5.0, -0.2], [-5.0, 2.0, 5.0, 2.0]])
    a, left, right = _aperture([(0.0, 0.0), (ahead, 0.3)], walk, walls=walls)
    assert left[0] == pytest.approx(0.07, abs=1e-12) and right[0] == pytest.approx(0.2, abs=1e-12)


def test_aperture_equals_a_sampled_one():
    """Random crowds between random walls: each walker's aperture equals the narrowest free width over the lines
    across its path (s from 0 to r + L, as the kernel spaces them), found by stepping 0.5 mm from each line's centre
    until a wall or a disk is met (an independent computation)."""
    rng = np.random.default_rng(3)
    t = np.arange(1, 10001) * 5e-4  # up to 5 m
    for trial in range(8):
        n = 6
        pos, ang, walk, walls = random_scene(rng, n, 3)
        got, _, _ = _aperture(pos, walk, walls=walls)
        n_lines = int(np.ceil((R + 0.3) / 0.05)) + 1
        for k in range(n):
            perp = np.array([-walk[k, 1], walk[k, 0]])
            want = np.inf
            for s in np.linspace(0.0, R + 0.3, n_lines):
                q = pos[k] + s * walk[k]
                if any(np.hypot(*(q - pos[j])) < R for j in range(n) if j != k):
                    continue  # a disk covers the line's centre: no aperture, left out
                width = 0.0
                for sign in (1.0, -1.0):
                    pts = q + sign * t[:, None] * perp
                    blocked = np.zeros(t.shape, bool)
                    for j in range(n):
                        if j != k:
                            blocked |= np.hypot(*(pts - pos[j]).T) < R
                    for x0, y0, x1, y1 in walls:  # the segment crossed between two samples
                        d = np.array([x1 - x0, y1 - y0])
                        side = (pts[:, 0] - x0) * d[1] - (pts[:, 1] - y0) * d[0]
                        along = ((pts - [x0, y0]) @ d) / (d @ d)
                        prev = np.r_[(q[0] - x0) * d[1] - (q[1] - y0) * d[0], side[:-1]]
                        blocked |= (np.sign(side) != np.sign(prev)) & (along >= 0) & (along <= 1)
                    width += t[np.argmax(blocked)] if blocked.any() else 5.0
                want = min(want, width)
            want = min(want, 10.0)  # every line covered: no aperture at all (the kernel's 2 FAR_M)
            assert got[k] == pytest.approx(want, abs=1.5e-3), (trial, k)


def _turn(aperture_m, heading, ratio=1.3):
    """The rule for one walker along +x whose aperture is set by walls at ±A/2 (no neighbour)."""
    walls = np.array([[-5.0, -aperture_m / 2, 5.0, -aperture_m / 2], [-5.0, aperture_m / 2, 5.0, aperture_m / 2]])
    theta_d = np.zeros(1)
    turned = shoulder_turn(theta_d, np.array([heading]), np.zeros((1, 2)), np.full(1, R), np.arange(1),
                           np.array([[1.0, 0.0]]), np.zeros((0, 2), np.int64), walls, 0.0,
                           ShoulderTurn(ratio, 0.3).checked().resolved())
    return theta_d[0], turned


def test_the_turn_of_warren_and_whang():
    """No turn at A ≥ ρ S; at A = S, φ = arccos(1/ρ) (about 40° for ρ = 1.3), the way the body is already turned;
    the narrower the aperture, the further; ρ = 0 switches the rule off."""
    assert _turn(1.3 * 2 * R + 0.01, 0.0) == (0.0, 0)
    theta, turned = _turn(2 * R, 0.0)
    assert turned == 1 and theta == pytest.approx(math.acos(1 / 1.3)) and math.degrees(theta) == pytest.approx(39.7,
                                                                                                               abs=0.1)
    assert _turn(2 * R, -0.2)[0] == pytest.approx(-math.acos(1 / 1.3))
    assert _turn(0.6 * 2 * R, 0.0)[0] == pytest.approx(math.acos(0.6 / 1.3))
    assert _turn(0.3, 0.0, ratio=0.0) == (0.0, 0)


def test_parameters_are_checked_by_name_and_default_off():
    assert ModelParams().shoulder_turn_critical_ratio == 0.0
    assert ModelParams(shoulder_turn_critical_ratio=1.3).walking.shoulder_turn == ShoulderTurn(1.3, 0.3)
    for name, value, match in [("shoulder_turn_critical_ratio", -0.1, "shoulder_turn_critical_ratio must be >= 0"),
                               ("shoulder_turn_lookahead_m", float("nan"), "shoulder_turn_lookahead_m must be a finite"),
                               ("shoulder_turn_lookahead_m", -1.0, "shoulder_turn_lookahead_m must be >= 0")]:
        with pytest.raises(ParameterError, match=match):
            ModelParams(**{name: value})


def test_compiled_rollout_equals_stepping_with_the_turn():
    from crowd_env.walking.presets import get_preset

    from .rollout_check import assert_rollout_equals_stepping

    assert_rollout_equals_stepping(get_preset("calibrated").params().replace(shoulder_turn_critical_ratio=1.3,
                                                                             body_depth_m=0.25),
                                   n_pedestrians=40, max_time_s=6.0)


def test_a_walker_of_three_circles_turns_through_a_gap_it_cannot_pass_facing_it():
    """One walker of the agent (without the social force) towards a 0.40 m gap in a wall (narrower than its shoulders, 0.46 m; wider
    than its depth, 0.25 m): facing its path it stops at the gap's corners; turning its shoulders (ρ = 1.3) it goes
    through, turned by more than 45° as it passes."""
    from baselines.social_force import SocialForceAgent
    from crowd_env.core import CrowdState, Simulator

    geometry, navigation = gap_world(0.20)
    runs = {}
    for ratio in (0.0, 1.3):
        params = ModelParams(body_depth_m=0.25, shoulder_turn_critical_ratio=ratio, social_forces=False)
        st = CrowdState.create(np.array([[0.0, 0.0]]), radius_m=R, desired_speed_m_s=1.0)
        sim = Simulator(st, geometry=geometry, params=params)
        agent = SocialForceAgent(navigation)
        crossing = None
        for _ in range(800):
            intents, theta_d = agent(sim)
            sim.step(intents, desired_heading_rad=theta_d)
            assert sim.min_gap_m() > -1e-3
            x = sim.state.position_m[0, 0] if sim.state.active[0] else np.inf
            if crossing is None and x >= 1.05:
                crossing = abs(math.remainder(sim.state.heading_rad[0], 2 * math.pi))
        runs[ratio] = (sim.state.position_m[0, 0] if sim.state.active[0] else np.inf, crossing)
    assert runs[0.0][0] < 1.0 and runs[0.0][1] is None  # stuck before the gap
    assert runs[1.3][0] > 1.1 and runs[1.3][1] > math.radians(45)


def test_the_heading_a_learned_policy_faces_is_the_agents_turned_at_a_narrow_aperture():
    """``facing_headings_rad`` (the heading target of a policy with heading_target="desired_direction"): the angle of
    e_d, turned as the calibrated agent turns its own when it walks along e_d (no social force: its walk is e_d), by
    arccos(A/(ρ S)) at a gap A narrower than ρ S; a walker off the floor neither turns nor narrows anyone's gap."""
    from crowd_env.core import CrowdState, Simulator
    from crowd_env.walking.agent import SocialForceAgent, desired_direction, facing_headings, facing_headings_rad

    geometry, navigation = gap_world()
    pos = np.array([[0.75, 0.0], [0.6, 1.0], [-2.0, -1.5], [1.25, 0.3]])  # the last one just past the gap
    for ratio in (0.0, 1.3):
        params = ModelParams(body_depth_m=0.25, shoulder_turn_critical_ratio=ratio, social_forces=False)
        st = CrowdState.create(pos, radius_m=R, heading_rad=np.array([0.05, 0.0, 0.0, 0.0]), desired_speed_m_s=1.0)
        st.active[3] = False
        sim = Simulator(st, geometry=geometry, params=params)
        agent_theta = SocialForceAgent(navigation)(sim)[1]
        active = sim.active_index
        np.testing.assert_allclose(facing_headings(navigation, sim, active), agent_theta[active], atol=1e-12)
        e_d = desired_direction(navigation, pos, np.arange(4))
        plain = np.arctan2(e_d[:, 1], e_d[:, 0])
        theta = facing_headings(navigation, sim, np.arange(4))
        assert theta[3] == plain[3]  # off the floor: e_d's angle
        if ratio == 0.0:
            np.testing.assert_array_equal(theta, plain)
            continue
        # the first walker, 0.25 m before a 0.40 m gap: A = 0.40 m < 1.3 × 0.46 m; it turns the way it faces (+)
        assert theta[0] == pytest.approx(plain[0] + math.acos(0.40 / (1.3 * 2 * R)), abs=1e-9)
        np.testing.assert_allclose(theta[1:3], plain[1:3])  # the open room: no turn
        # the walker off the floor, just past the gap, narrows nobody's aperture; on the floor it narrows the first's
        assert theta[0] == facing_headings_rad(navigation, pos[:3], np.full(3, R), st.heading_rad[:3], np.arange(3),
                                               sim.walls, params.walking.shoulder_turn)[0]
        on_floor = facing_headings_rad(navigation, pos, np.full(4, R), st.heading_rad, np.arange(4), sim.walls,
                                       params.walking.shoulder_turn)
        assert on_floor[0] > theta[0] + 0.1
