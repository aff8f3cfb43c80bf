"""Periodicity along x (crowd_env.core.periodic, the periodic corridor): the minimum image in the neighbour grid,
the contacts, hand links and the step; a contact across the seam is the same contact as away from it; positions
stay in [0, L); the fused and the staged step agree to the bit; a non-periodic run is unchanged."""
import numpy as np
import pytest
from shapely.geometry import box

from crowd_env.core import CrowdState, Simulator
from crowd_env.core.geometry import PERIODIC_WALL_EXTENSION_M, Geometry, GeometryError
from crowd_env.core.neighbors import grid_k_nearest, grid_pairs, grid_pairs_around
from crowd_env.core.params import ParameterError
from crowd_env.core.periodic import minimum_image_dx, wrap_positions, wrap_x
from crowd_env.walking.presets import DEFAULT_PRESET, get_preset
from crowd_env.core.state import StateError

L = 10.0


def _brute_pairs(pos, index, radius, period):
    """Pairs of rows into ``index`` within ``radius`` at their nearest image (all pairs tested)."""
    p = pos[index]
    dx = p[:, None, 0] - p[None, :, 0]
    dx -= period * np.floor(dx / period + 0.5)
    d = np.hypot(dx, p[:, None, 1] - p[None, :, 1])
    ii, jj = np.nonzero(np.triu(d <= radius, k=1))
    return sorted(zip(ii.tolist(), jj.tolist())), d


def test_minimum_image_and_wrap():
    """dx − L round(dx / L) and x mod L, scalars and arrays; period 0 leaves values as they are."""
    assert minimum_image_dx(9.5, L) == pytest.approx(-0.5)
    assert minimum_image_dx(-9.5, L) == pytest.approx(0.5)
    assert minimum_image_dx(3.0, L) == 3.0 and minimum_image_dx(9.5, 0.0) == 9.5
    assert wrap_x(-0.25, L) == pytest.approx(9.75) and wrap_x(10.0, L) == 0.0 and wrap_x(23.0, L) == pytest.approx(3.0)
    assert 0.0 <= wrap_x(-1e-17, L) < L  # a tiny negative x rounds to L: brought back to 0
    assert wrap_x(-3.0, 0.0) == -3.0
    np.testing.assert_allclose(minimum_image_dx(np.array([9.5, -0.2, 4.9]), L), [-0.5, -0.2, 4.9])
    pos = np.array([[-1.0, 2.0], [12.5, 0.0]])
    wrap_positions(pos, L)
    np.testing.assert_allclose(pos, [[9.0, 2.0], [2.5, 0.0]])


@pytest.mark.parametrize("period, radius", [(L, 0.6), (L, 4.0), (1.5, 0.6), (0.9, 0.6)])
def test_periodic_grid_pairs_match_brute_force(period, radius):
    """Every pair within the radius at its nearest image exactly once, across the seam too, also with a grid
    of one or two columns (L < 3 × radius); the pairs around a few rows and the k nearest likewise."""
    rng = np.random.default_rng(3)
    pos = np.column_stack([rng.uniform(0.0, period, 300), rng.uniform(0.0, 3.0, 300)])
    pos[:5, 0] = [0.0, period - 1e-12, 1e-9, 0.5 * period, np.nextafter(period, 0.0)]  # on and beside the seam
    index = np.sort(rng.choice(300, 240, replace=False)).astype(np.int64)
    index[:3] = [0, 1, 2]
    index = np.unique(index)
    got = grid_pairs(pos, index, radius, period)
    want, d = _brute_pairs(pos, index, radius, period)
    assert np.all(got[:, 0] < got[:, 1])
    assert sorted(map(tuple, got.tolist())) == want
    rows = np.array([0, 1, 7, 40], np.int64)
    around = sorted(map(tuple, grid_pairs_around(pos, index, rows, radius, period).tolist()))
    assert around == [p for p in want if p[0] in rows or p[1] in rows]
    k = 5
    near = grid_k_nearest(pos, index, index[:50], k, radius, period)
    for a in range(50):
        others = np.flatnonzero((np.arange(index.size) != a) & (d[a] <= radius))
        expect = np.sort(d[a, others])[:k]
        found = near[a][near[a] >= 0]
        np.testing.assert_allclose(np.sort(d[a, found]), expect, rtol=0, atol=1e-12)


def test_non_periodic_grid_unchanged():
    """period 0 (the default) is the plain grid: the same pairs in the same order as without the argument."""
    rng = np.random.default_rng(5)
    pos = rng.uniform(0, 20, (500, 2))
    index = np.arange(500, dtype=np.int64)
    np.testing.assert_array_equal(grid_pairs(pos, index, 0.7), grid_pairs(pos, index, 0.7, 0.0))
    far = grid_pairs(pos, index, 0.7, 20.0)  # periodic: the pairs across the seam come on top
    assert len(far) > len(grid_pairs(pos, index, 0.7))


def _simulator(position, velocity, period=L, links=None, offsets=None, params=None):
    st = CrowdState.create(position, velocity_m_s=velocity, radius_m=0.23, heading_rad=0.0,
                           desired_speed_m_s=1.3, links=links, link_offsets_m=offsets)
    return Simulator(st, walls=np.zeros((0, 4)), params=params or get_preset(DEFAULT_PRESET).params(), period_m=period)


def _collide(position, velocity, shift, n_steps=6, **kw):
    """Run the disks ``position`` (around x = L/2) moved by ``shift`` along x (wrapped) for ``n_steps`` steps with
    their start velocities as intents; returns (positions moved back, velocities, ω, headings, impact steps)."""
    pos = np.array(position, dtype=float)
    pos[:, 0] += shift
    sim = _simulator(pos, velocity, **kw)
    assert np.all((sim.state.position_m[:, 0] >= 0) & (sim.state.position_m[:, 0] < L))
    intents = np.array(velocity, dtype=float)
    impacts = 0
    for _ in range(n_steps):
        r = sim.step(intents)
        impacts += r.n_impact_clusters > 0
        assert np.all((sim.state.position_m[:, 0] >= 0) & (sim.state.position_m[:, 0] < L))
    st = sim.state
    back = st.position_m.copy()
    back[:, 0] = minimum_image_dx(back[:, 0] - shift - np.asarray(position)[:, 0], L) + np.asarray(position)[:, 0]
    return back, st.velocity_m_s.copy(), st.angular_velocity_rad_s.copy(), st.heading_rad.copy(), impacts, sim


def _assert_same_collision(a, b):
    """Positions and velocities to 1e-12, spins and headings to 1e-11: the shifted coordinates differ from the
    original ones by their rounding (1e-15 m at x ≈ 5-10 m), which the spin of an oblique multi-contact impact
    amplifies most (5e-12 rad/s of 1.4 rad/s after the impacts of the linked cluster)."""
    for name, x, y, tol in zip(("position", "velocity", "angular velocity", "heading"), a[:4], b[:4],
                               (1e-12, 1e-12, 1e-11, 1e-11)):
        np.testing.assert_allclose(x, y, rtol=0, atol=tol, err_msg=name)
    assert a[4] == b[4] > 0


PAIR = ([[0.5 * L - 0.245, 1.0], [0.5 * L + 0.245, 1.06]], [[1.2, 0.1], [-1.0, 0.0]])
CLUSTER = ([[0.5 * L - 0.47, 1.0], [0.5 * L, 1.02], [0.5 * L + 0.47, 1.0], [0.5 * L + 0.02, 0.53]],
           [[1.0, 0.1], [0.0, -0.4], [-1.1, 0.0], [0.1, 0.8]])


def _straddles(position, shift):
    """The disks ``position`` moved by ``shift`` and wrapped lie on both sides of the seam."""
    x = np.array([wrap_x(p[0] + shift, L) for p in position])
    return x.min() < 0.5 and x.max() > L - 0.8


@pytest.mark.parametrize("shift", [-0.5 * L, -0.5 * L - 0.245, -0.5 * L + 0.2, 0.5 * L - 1e-13])
def test_pair_collides_across_the_seam_as_away_from_it(shift):
    """Two disks colliding obliquely at x ≈ L/2 and the same two across the seam x = 0 ≡ L (one on each side;
    one of them exactly on x = 0; both 1e-13 m to the left): the same impacts, post-impact velocities, spins
    and positions to 1e-12."""
    assert _straddles(PAIR[0], shift)
    away = _collide(*PAIR, 0.0)
    seam = _collide(*PAIR, shift)
    _assert_same_collision(away, seam)
    assert np.abs(away[1] - np.asarray(PAIR[1])).max() > 0.5  # an impact changed the velocities


@pytest.mark.parametrize("shift", [-0.5 * L, -0.5 * L + 0.3, -0.5 * L - 0.3])
def test_cluster_with_hand_link_across_the_seam(shift):
    """A cluster of four disks pushed together, two of them holding hands (K_v, Eq. 2), straddling the seam:
    the same multi-contact impacts (one cluster of four) and link rows as away from it, to 1e-12."""
    kw = dict(links=[[0, 1]], offsets=[[0.0, 0.23, 0.0, -0.23]])
    assert _straddles(CLUSTER[0], shift)
    away = _collide(*CLUSTER, 0.0, n_steps=8, **kw)
    seam = _collide(*CLUSTER, shift, n_steps=8, **kw)
    _assert_same_collision(away, seam)


def test_dense_periodic_run_keeps_gaps_and_positions():
    """A dense crowd (3.5 /m², a fifth walking west) in a periodic 8 m strip for 3 s, stepped from Python with the
    calibrated agent: every gap, pairs across the seam included, ≥ −1e-9 m after every step (checked by brute
    force at the nearest image), every x in [0, L), and pedestrians do cross the seam."""
    from crowd_env.scenarios import make_scenario
    from crowd_env.walking.agent import SocialForceAgent

    sc = make_scenario("periodic_corridor", length_m=8.0, width_m=1.8, density_per_m2=3.5, westbound_fraction=0.2,
                       seed=2)
    sim = sc.make_simulator()
    agent = SocialForceAgent(sc.navigation())
    st = sim.state
    start = st.position_m[:, 0].copy()
    crossed = np.zeros(st.n, bool)
    for _ in range(300):
        before = st.position_m[:, 0].copy()
        intents, heading = agent(sim)
        sim.step(intents, desired_heading_rad=heading)
        x = st.position_m[:, 0]
        assert np.all((x >= 0.0) & (x < 8.0))
        crossed |= np.abs(x - before) > 4.0
        _, d = _brute_pairs(st.position_m, np.arange(st.n), 1.0, 8.0)
        gap = d - 2 * 0.23 + np.eye(st.n) * 10
        assert gap.min() >= -1e-9
        assert sim.min_gap_m() >= -1e-9
    assert crossed.sum() > 5 and not np.array_equal(start, st.position_m[:, 0])


def test_fused_and_staged_periodic_steps_agree_bitwise():
    """The fused step and the staged step (profile=True) of a dense bidirectional periodic crowd: the same
    states, contacts and gaps to the bit, re-detections and contacts across the seam included."""
    from crowd_env.scenarios import make_scenario
    from crowd_env.walking.agent import SocialForceAgent

    sc = make_scenario("periodic_corridor", length_m=8.0, density_per_m2=3.0, westbound_fraction=0.5, seed=1)
    fused, staged = sc.make_simulator(), sc.make_simulator()
    staged.profile = True
    agent = SocialForceAgent(sc.navigation())
    seam_contacts = 0
    for _ in range(250):
        intents, heading = agent(fused)
        ra = fused.step(intents, desired_heading_rad=heading)
        intents, heading = agent(staged)
        rb = staged.step(intents, desired_heading_rad=heading)
        for name in ("position_m", "velocity_m_s", "heading_rad", "angular_velocity_rad_s"):
            assert np.array_equal(getattr(fused.state, name), getattr(staged.state, name)), name
        for name in ("contact_i", "contact_j", "percussion_normal", "percussion_tangent"):
            assert np.array_equal(getattr(ra, name), getattr(rb, name)), name
        assert ra.min_gap_m == rb.min_gap_m
        pair = ra.contact_j >= 0
        x = fused.state.position_m[:, 0]
        seam_contacts += int((np.abs(x[ra.contact_i[pair]] - x[ra.contact_j[pair]]) > 4.0).sum())
    assert fused.n_staged_steps == 0 and staged.n_staged_steps == 250
    assert fused.n_redetections == staged.n_redetections > 0 and seam_contacts > 0


def test_periodic_geometry():
    """Geometry(period_x_m=L): no exits, side walls prolonged 1 m beyond the seam, no end walls; pickled with
    it; a non-periodic area, a wrong span or exits raise naming the problem."""
    import pickle

    g = Geometry(box(0, -0.9, 12, 0.9), exits=(), period_x_m=12.0)
    assert g.period_x_m == 12.0 and g.exits == ()
    walls = np.sort(g.walls.reshape(-1, 2, 2), axis=1)
    np.testing.assert_allclose(sorted(walls.tolist()), [[[-PERIODIC_WALL_EXTENSION_M, -0.9], [13.0, -0.9]],
                                                        [[-PERIODIC_WALL_EXTENSION_M, 0.9], [13.0, 0.9]]])
    assert pickle.loads(pickle.dumps(g)).period_x_m == 12.0
    assert Geometry(box(0, 0, 3, 3), exits=[box(2, 0, 3, 3)]).period_x_m == 0.0
    with pytest.raises(GeometryError, match="no exits"):
        Geometry(box(0, 0, 12, 1), exits=[box(5, 0, 6, 1)], period_x_m=12.0)
    with pytest.raises(GeometryError, match="span x from 0 to period_x_m"):
        Geometry(box(0, 0, 12, 1), exits=(), period_x_m=10.0)
    with pytest.raises(GeometryError, match="not periodic"):
        Geometry([(0, 0), (12, 0), (12, 2), (0, 1)], exits=(), period_x_m=12.0)
    with pytest.raises(GeometryError, match="period_x_m"):
        Geometry(box(0, 0, 12, 1), exits=(), period_x_m=-1.0)
    with pytest.raises(GeometryError, match="no exit"):
        Geometry(box(0, 0, 12, 1), exits=())


def test_simulator_period_checks():
    """Simulator.period_m comes from the geometry; start positions are wrapped into [0, L); an overlap across
    the seam, a period too short for the interactions or one contradicting the geometry raise."""
    g = Geometry(box(0, -0.9, 12, 0.9), exits=(), period_x_m=12.0)
    st = CrowdState.create([[12.5, 0.0], [3.0, 0.0]], radius_m=0.23)
    sim = Simulator(st, geometry=g)
    assert sim.period_m == 12.0 and sim.state.position_m[0, 0] == pytest.approx(0.5)
    assert Simulator(CrowdState.create([[1.0, 0.0]]), walls=np.zeros((0, 4))).period_m == 0.0
    with pytest.raises(StateError, match="overlap.*period"):
        Simulator(CrowdState.create([[0.1, 0.0], [11.8, 0.0]], radius_m=0.23), geometry=g)
    with pytest.raises(ParameterError, match="period_m = 2 m must exceed"):
        Simulator(CrowdState.create([[1.0, 0.0]], radius_m=0.23), walls=np.zeros((0, 4)), period_m=2.0)
    with pytest.raises(ParameterError, match="differs"):
        Simulator(CrowdState.create([[1.0, 0.0]]), geometry=g, period_m=10.0)
    with pytest.raises(ParameterError, match="period_m"):
        Simulator(CrowdState.create([[1.0, 0.0]]), walls=np.zeros((0, 4)), period_m=float("nan"))


def test_min_gap_sees_the_seam():
    """Simulator.min_gap_m, and min_gap_m / first_overlap of crowd_env.core.state (the soak's checks) with a
    period, measure pairs across the seam at their nearest image."""
    from crowd_env.core.state import first_overlap, min_gap_m

    sim = _simulator([[0.1, 0.0], [L - 0.37, 0.0]], [[0.0, 0.0], [0.0, 0.0]])
    assert sim.min_gap_m() == pytest.approx(0.47 - 0.46, abs=1e-12)
    pos, rad = np.array([[0.1, 0.0], [L - 0.3, 0.0]]), np.full(2, 0.23)
    assert min_gap_m(pos, rad) > 9.0 and first_overlap(pos, rad) is None
    assert min_gap_m(pos, rad, L) == pytest.approx(-0.06) and first_overlap(pos, rad, 0.0, L)[2] == pytest.approx(0.06)
