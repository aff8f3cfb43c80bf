"""The body of three circles across the shoulders (crowd_env.core.body): its geometry, the lever arms of its
contacts (momentum conserved, a shoulder hit turns the body) and what it can do that a disk cannot (pass a slot
narrower than the shoulders, turned), with no overlap."""
from __future__ import annotations

import math

import numpy as np
import pytest

from crowd_env.core import CrowdState, ParameterError, Simulator
from crowd_env.core.body import body_circles, body_gaps, check_body_depth, circle
from crowd_env.core.bundles import Links, StepParams
from crowd_env.core.contacts import contact_candidates
from crowd_env.core.params import PhysicsParams
from crowd_env.core.segments import endpoint_owners
from crowd_env.core.solvers.impact import resolve_impacts

R, D = 0.23, 0.28  # the paper's radius; a chest-to-back depth of 0.28 m
ARM = R - D / 2


def _brute_gap(pos, heading, radius, depth, i, j):
    """The gap of bodies i and j from 2000 points sampled on each circle's outline (independent of body_gaps)."""
    t = np.linspace(0.0, 2.0 * math.pi, 2000, endpoint=False)

    def outline(k):
        pts = []
        for s in range(3 if depth > 0 else 1):
            ox, oy, rc = circle(heading[k], radius[k], depth, s)
            pts.append(np.c_[pos[k, 0] + ox + rc * np.cos(t), pos[k, 1] + oy + rc * np.sin(t)])
        return np.vstack(pts)

    a, b = outline(i), outline(j)
    d = np.sqrt(((a[:, None, :] - b[None, :, :]) ** 2).sum(-1))
    return d.min()


def test_circles_span_the_shoulders_and_the_depth_inside_the_disk():
    """Three circles of radius D/2 on the shoulder axis (perpendicular to the heading): 2 r across, D deep, inside
    the disk of radius r; D = 0 is the disk itself."""
    for heading in (0.0, 0.7, -2.1):
        offs = [circle(heading, R, D, s) for s in range(3)]
        for ox, oy, rc in offs:
            assert rc == D / 2
            assert math.hypot(ox, oy) + rc <= R + 1e-15  # inside the paper's disk
            assert abs(ox * math.cos(heading) + oy * math.sin(heading)) < 1e-15  # on the shoulder axis
        across = max(math.hypot(ox, oy) for ox, oy, _ in offs) * 2 + D
        assert across == pytest.approx(2 * R, abs=1e-15)
        # the left shoulder (s = 1) lies to the left of the heading
        ox, oy, _ = offs[1]
        assert math.cos(heading) * oy - math.sin(heading) * ox == pytest.approx(ARM)
    assert circle(0.3, R, 0.0, 0) == (0.0, 0.0, R)


def test_body_gaps_analytic_and_sampled():
    """Side by side, the shoulders touch at 2 r between centres; face to face, the torsos at D (where disks would
    overlap by 2 r − D); any pose: equal to the gap sampled on the outlines."""
    pos = np.array([[0.0, 0.0], [0.0, 2 * R], [D + 0.01, 0.0], [0.5, 0.45]])
    heading = np.array([0.0, 0.0, math.pi, 1.1])
    radius = np.full(4, R)
    pairs = np.array([[0, 1], [0, 2], [0, 3], [1, 3], [2, 3]], np.int64)
    gaps = body_gaps(pos, heading, radius, D, pairs)
    assert gaps[0] == pytest.approx(0.0, abs=1e-15)
    assert gaps[1] == pytest.approx(0.01, abs=1e-15)
    for (i, j), g in zip(pairs, gaps):
        assert g == pytest.approx(_brute_gap(pos, heading, radius, D, i, j), abs=2e-6)
    disk = body_gaps(pos, heading, radius, 0.0, pairs)
    np.testing.assert_allclose(disk, np.hypot(*(pos[pairs[:, 0]] - pos[pairs[:, 1]]).T) - 2 * R, atol=1e-15)


def test_body_depth_is_checked():
    check_body_depth(0.0, np.full(3, R))
    check_body_depth(0.3, np.full(3, R))
    for bad in (0.46, 0.5):
        with pytest.raises(ParameterError, match="body_depth_m"):
            check_body_depth(bad, np.array([R, R]))
    with pytest.raises(ParameterError, match="body_depth_m"):
        PhysicsParams(body_depth_m=-0.1)
    st = CrowdState.create(np.array([[0.0, 0.0]]), radius_m=0.2)
    with pytest.raises(ParameterError, match="below the smallest body's width"):
        Simulator(st, params=PhysicsParams(body_depth_m=0.4))


def _impact(pos, heading, vel, walls=np.zeros((0, 4)), k_n=1e5):
    """The Frémond impact of touching bodies of three circles (the production narrow phase and solver)."""
    n = pos.shape[0]
    index = np.arange(n, dtype=np.int64)
    radius = np.full(n, R)
    speed = np.hypot(vel[:, 0], vel[:, 1]) + np.abs(vel[:, 2]) * ARM
    pairs = np.array([[i, j] for i in range(n) for j in range(i + 1, n)], np.int64).reshape(-1, 2)
    con = contact_candidates(pos, heading, radius, D, speed, index, pairs, walls, endpoint_owners(walls), 1e-3, 0.01)
    mass = np.full(n, 83.0)
    inertia = 0.5 * mass * R ** 2
    params = StepParams(0.01, 1e-3, k_n, 0.0, 0.0, True, 400, 400, 400, D)
    z = np.zeros(0, np.int64)
    e = np.zeros((0, 2))
    v = vel.copy()
    p_n, *_ = resolve_impacts(v, mass, inertia, con, Links(z, z, e, e, e), params, 1e-9)
    return con, v, mass, inertia, p_n


def test_an_impact_on_a_shoulder_conserves_momentum_and_turns_the_body_hit():
    """Body 1, turned sideways, walks shoulder first into body 0's left shoulder (one contact, along x): the impact
    conserves the total momentum and angular momentum (about the origin), as the contact's lever arms require;
    body 0, hit at a lever arm across the normal, turns (anticlockwise: a push along −x at +y); body 1, whose lever
    arm lies along the normal, does not (a disk hit anywhere would not turn: its normal passes through its
    centre)."""
    pos = np.array([[0.0, 0.0], [D + 0.0005 + ARM, ARM]])  # body 1's left shoulder 0.5 mm from body 0's (ε = 1 mm)
    heading = np.array([0.0, math.pi / 2])
    vel = np.array([[0.0, 0.0, 0.0], [-1.2, 0.0, 0.0]])
    con, v, mass, inertia, p_n = _impact(pos, heading, vel)
    assert (p_n > 0).sum() == 1
    c = int(np.argmax(p_n))
    assert con.sub[c] == 1 * 3 + 1  # left shoulder against left shoulder

    def momenta(u):
        lin = (mass[:, None] * u[:, :2]).sum(0)
        ang = (inertia * u[:, 2] + mass * (pos[:, 0] * u[:, 1] - pos[:, 1] * u[:, 0])).sum()
        return lin, ang

    lin0, ang0 = momenta(vel)
    lin1, ang1 = momenta(v)
    np.testing.assert_allclose(lin1, lin0, atol=1e-9)
    assert ang1 == pytest.approx(ang0, abs=1e-9)
    assert v[0, 0] < 0.0 and v[0, 2] > 0.1  # pushed back and turned
    assert v[1, 2] == pytest.approx(0.0, abs=1e-12)


def test_a_turned_body_squares_up_against_a_wall():
    """A body walking obliquely into a wall touches it with one shoulder: the impact leaves its angular momentum
    about the contact point unchanged (the wall's percussion passes through it) and turns it towards the wall
    (its heading's error from the wall's normal shrinks)."""
    theta = 0.3
    ox, oy, rc = circle(theta, R, D, 2)  # the right shoulder is the one ahead when turned anticlockwise
    x_wall = ox + rc + 0.0005
    walls = np.array([[x_wall, -3.0, x_wall, 3.0]])
    pos = np.zeros((1, 2))
    vel = np.array([[1.0, 0.0, 0.0]])
    con, v, mass, inertia, p_n = _impact(pos, np.array([theta]), vel, walls)
    assert p_n.max() > 0.0 and con.sub[np.argmax(p_n)] == 2
    px, py = x_wall, oy  # the contact point on the wall

    def about_contact(u):
        return inertia[0] * u[0, 2] + mass[0] * ((pos[0, 0] - px) * u[0, 1] - (pos[0, 1] - py) * u[0, 0])

    assert about_contact(v) == pytest.approx(about_contact(vel), abs=1e-9)
    assert v[0, 2] < 0.0  # turns clockwise, towards heading 0 (square to the wall)
    assert v[0, 0] < 1.0


def _slot_run(depth_m, seconds=4.0):
    """One walker at 1 m/s towards a slot 0.36 m wide in a wall at x = 1 m (narrower than its shoulders, 0.46 m,
    wider than its depth, 0.28 m), turned sideways (desired heading along the wall)."""
    half = 0.18
    walls = np.array([[1.0, -3.0, 1.0, -half], [1.0, half, 1.0, 3.0]])
    st = CrowdState.create(np.array([[0.0, 0.0]]), heading_rad=math.pi / 2, radius_m=R)
    sim = Simulator(st, walls=walls, params=PhysicsParams(body_depth_m=depth_m))
    worst = np.inf
    for _ in range(int(seconds / 0.01)):
        sim.step(np.array([[1.0, 0.0]]), desired_heading_rad=np.array([math.pi / 2]))
        worst = min(worst, sim.min_gap_m())
        centre, rad, _ = body_circles(sim.state.position_m, sim.state.heading_rad, sim.state.radius_m,
                                      np.array([0]), depth_m)
        # independent: each circle against the two segments, by hand (the wall points are on x = 1)
        for (cx, cy), rc in zip(centre, rad):
            qy = min(max(cy, half), 3.0) if cy > 0 else max(min(cy, -half), -3.0)
            assert math.hypot(cx - 1.0, cy - qy) - rc > -1e-3
    return sim, worst


def test_a_body_turned_sideways_passes_a_slot_a_disk_cannot():
    """A slot 0.36 m wide: the paper's disk (0.46 m) stops against the slot's corners; the body of three circles, turned, passes
    it (its depth 0.28 m), without overlapping the wall (ε = 1 mm)."""
    disk, gap_disk = _slot_run(0.0)
    body, gap_body = _slot_run(D)
    stop = 1.0 - math.sqrt(R ** 2 - 0.18 ** 2)  # where the disk touches the slot's two corners
    assert stop - 0.01 < disk.state.position_m[0, 0] < stop + 1e-3
    assert body.state.position_m[0, 0] > 2.0
    assert gap_disk > -1e-3 and gap_body > -1e-3


def test_a_crowd_of_bodies_never_overlaps_in_a_bottleneck():
    """60 walkers of three circles through Seyfried's 0.8 m bottleneck for 20 s: the smallest gap between any two
    bodies (sampled on their outlines where the circles' gap is below 2 cm) or a body and a wall stays above
    −ε."""
    from baselines.social_force import SocialForceAgent
    from crowd_env.scenarios import make_scenario

    sc = make_scenario("seyfried_bottleneck", width_m=0.8, n_pedestrians=60, seed=1)
    agent = SocialForceAgent(sc.navigation())
    sim = Simulator(sc.make_state(rng=np.random.default_rng(1)), geometry=sc.geometry,
                    params=PhysicsParams(body_depth_m=D))
    worst = np.inf
    checked = 0
    for step in range(2000):
        intents, heading = agent(sim)
        sim.step(intents, desired_heading_rad=heading)
        worst = min(worst, sim.min_gap_m())
        if step % 100 == 99:
            st = sim.state
            idx = np.flatnonzero(st.active)
            pairs = np.array([[i, j] for a, i in enumerate(idx) for j in idx[a + 1:]
                              if np.hypot(*(st.position_m[i] - st.position_m[j])) < 2 * R + 0.02], np.int64)
            if pairs.size:
                gaps = body_gaps(st.position_m, st.heading_rad, st.radius_m, D, pairs)
                for (i, j), g in zip(pairs, gaps):
                    if g < 0.02:
                        assert _brute_gap(st.position_m, st.heading_rad, st.radius_m, D, i, j) > -1e-3
                        checked += 1
    assert worst > -1e-3
    assert checked > 20
    assert (~sim.state.active).sum() > 10  # the crowd did pass the bottleneck


def test_a_body_turning_between_two_walls_stops_turning_instead_of_failing():
    """A body 0.25 m deep standing sideways in a slot 0.254 m wide (2 mm from each wall, beyond the contact tolerance)
    and turning at 3 rad/s: within one step both shoulders would reach the two walls, a closure no translation can
    undo (the projection moves bodies, not headings). The body stops turning (ω = 0, which only takes energy away)
    and the step succeeds without overlap; at rest it keeps its heading."""
    depth = 0.25
    half = depth / 2 + 0.002
    walls = np.array([[-half, -3.0, -half, 3.0], [half, -3.0, half, 3.0]])
    st = CrowdState.create(np.array([[0.0, 0.0]]), heading_rad=0.0, angular_velocity_rad_s=3.0, radius_m=R,
                           heading_stiffness=0.0, heading_damping=0.0)
    sim = Simulator(st, walls=walls, params=PhysicsParams(body_depth_m=depth))
    heading0 = float(sim.state.heading_rad[0])
    for _ in range(20):
        sim.step(np.zeros((1, 2)))
        assert sim.min_gap_m() > -1e-3
    assert sim.state.angular_velocity_rad_s[0] == 0.0
    assert abs(sim.state.heading_rad[0] - heading0) < 0.02  # it turned less than the 2 mm allowed


def test_the_start_checks_are_the_bodies():
    """A start that keeps the bodies apart but not their disks is accepted (two bodies face to face 0.26 m apart, a
    body sideways in a slot narrower than its disk); one whose bodies overlap is refused, naming the pair or the
    wall."""
    params = PhysicsParams(body_depth_m=0.25)
    face = CrowdState.create(np.array([[0.0, 0.0], [0.26, 0.0]]), heading_rad=np.array([0.0, np.pi]), radius_m=R,
                             overlap_tolerance_m=1.0)
    Simulator(face, params=params)
    with pytest.raises(Exception, match="overlap"):
        Simulator(face)  # as disks they overlap by 0.2 m
    apart = CrowdState.create(np.array([[0.0, 0.0], [0.24, 0.0]]), heading_rad=np.array([0.0, np.pi]), radius_m=R,
                              overlap_tolerance_m=1.0)
    with pytest.raises(Exception, match="pedestrians 0 and 1 overlap by 0.01 m"):
        Simulator(apart, params=params)
    walls = np.array([[-0.13, -3.0, -0.13, 3.0], [0.13, -3.0, 0.13, 3.0]])
    Simulator(CrowdState.create(np.array([[0.0, 0.0]]), radius_m=R), walls=walls, params=params)
    with pytest.raises(Exception, match="overlaps wall segment"):
        Simulator(CrowdState.create(np.array([[0.0, 0.0]]), heading_rad=np.pi / 2, radius_m=R), walls=walls,
                  params=params)
