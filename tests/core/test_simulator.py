"""The full time step (collision-problem.md, "Recommended time step"): analytic impacts through a
Simulator step, the heading's response (Eq. 20-21) and its time discretisation, conservation,
energy, permutation invariance, no overlap in pushing crowds, candidate re-detection, the dense and
sparse solver paths, the cvxpy path, hand links, exits and bad input."""
import math

import numpy as np
import pytest

from crowd_env.experiments.validation.collision import simulate_oblique_rotation
from crowd_env.core import CrowdState, ParameterError, Simulator, StateError
from crowd_env.walking import ModelParams
from crowd_env.core.params import PhysicsParams
from crowd_env.core.segments import GeometryError
from crowd_env.core.solvers import closed_form


def box(L):
    return [[0, 0, L, 0], [L, 0, L, L], [L, L, 0, L], [0, L, 0, 0]]


def lattice_crowd(n_side, spacing, origin=(0.3, 0.3), jitter=0.01, seed=0, **kw):
    rng = np.random.default_rng(seed)
    xs = origin[0] + spacing * np.arange(n_side)
    ys = origin[1] + spacing * np.arange(n_side)
    X, Y = np.meshgrid(xs, ys)
    pos = np.c_[X.ravel(), Y.ravel()] + rng.uniform(-jitter, jitter, (n_side * n_side, 2))
    return CrowdState.create(pos, rng=rng, **kw)


def towards(state, target, speed):
    d = np.asarray(target, float) - state.position_m
    return speed * d / np.linalg.norm(d, axis=1)[:, None]


def total_momenta(st):
    m = st.mass_kg
    p = (m[:, None] * st.velocity_m_s).sum(axis=0)
    x, u = st.position_m, st.velocity_m_s
    ang = float((m * (x[:, 0] * u[:, 1] - x[:, 1] * u[:, 0]) + st.inertia_kg_m2 * st.angular_velocity_rad_s).sum())
    return p, ang


# ---------------------------------------------------------------- Section 3.1 through a full step
@pytest.mark.parametrize("case", ["a", "b"])
@pytest.mark.parametrize("k_n", [1.0, 10.0, 30.0, 100.0, 1e3, 1e5])
def test_head_on_through_a_simulator_step(case, k_n):
    c = closed_form.PAPER_CASES[case]
    st = CrowdState.create([[0.0, 0.0], [0.46, 0.0]], velocity_m_s=[[c["u1"], 0.0], [c["u2"], 0.0]],
                           mass_kg=[c["m1"], c["m2"]], radius_m=0.23, tau_s=1e12)
    sim = Simulator(st, params=ModelParams(normal_dissipation_kg=k_n, rotation=False))
    res = sim.step(st.velocity_m_s.copy())  # intents = velocities: no driving force
    a1, a2 = closed_form.head_on_analytic(c["m1"], c["m2"], c["u1"], c["u2"], k_n)
    np.testing.assert_allclose(st.velocity_m_s, [[a1, 0.0], [a2, 0.0]], atol=1e-9)
    assert res.n_impact_clusters == 1 and res.contact_i.tolist() == [0]
    assert res.kinetic_energy_after_impact_j <= res.kinetic_energy_before_impact_j * (1 + 1e-12)
    assert sim.min_gap_m() >= -1e-12


def test_disk_bounces_off_a_wall_in_a_step():
    for k_n, m in ((10.0, 83.0), (1e3, 83.0), (1e5, 83.0)):
        st = CrowdState.create([[1.0, 0.23]], velocity_m_s=[[0.3, -1.0]], mass_kg=m, tau_s=1e12)
        sim = Simulator(st, walls=[[-5, 0, 5, 0]], params=ModelParams(normal_dissipation_kg=k_n))
        sim.step(st.velocity_m_s.copy())
        expect = -1.0 * (m - k_n) / (m + k_n) if k_n > m else 0.0
        np.testing.assert_allclose(st.velocity_m_s[0], [0.3, expect], atol=1e-12)
        assert st.position_m[0, 1] >= 0.23 - 1e-12


# ---------------------------------------------------------------- Section 3.2: heading after an oblique impact
def _rotation_error(dt, k=5.0, k_tg=1e3, t_end=3.0):
    t, theta, td0 = simulate_oblique_rotation(k_tg, k, dt_s=dt, t_end_s=t_end)
    return float(np.abs(theta - closed_form.theta_analytic(t, td0, k)).max()), theta, td0


def test_heading_converges_to_eq20_at_first_order():
    errs = [_rotation_error(dt)[0] for dt in (0.01, 0.005, 0.0025, 0.00125)]
    ratios = [errs[i] / errs[i + 1] for i in range(3)]
    assert all(1.8 < r < 2.2 for r in ratios), (errs, ratios)  # semi-implicit Euler: first order


def test_heading_tight_at_small_step_and_theta_max_eq21():
    for k in (0.5, 18.5):
        err, theta, td0 = _rotation_error(5e-4, k=k, t_end=2.0 / closed_form.natural_frequency(k))
        tmax = float(closed_form.theta_max(td0, k))
        assert td0 > 0.5  # the oblique impact spun the pedestrian
        assert err < 1e-3 * tmax
        assert theta.max() == pytest.approx(tmax, rel=1e-3)


def test_spin_after_impact_independent_of_kn_and_of_dt():
    spins = [simulate_oblique_rotation(1e3, 5.0, dt_s=dt, t_end_s=0.02, k_n=k_n)[2]
             for dt in (0.01, 0.002) for k_n in (2e3, 1e4, 1e6)]
    np.testing.assert_allclose(spins, spins[0], rtol=1e-9)
    assert spins[0] == pytest.approx(closed_form.oblique_spin(1e3)[0], rel=1e-12)


# ---------------------------------------------------------------- conservation and energy in full steps
def test_free_cluster_step_conserves_momenta():
    """No walls, no driving force, no heading spring: impacts and projection exchange momentum only."""
    rng = np.random.default_rng(5)
    st = lattice_crowd(5, 0.462, jitter=0.0008, seed=5, heading_stiffness=0.0, heading_damping=0.0,
                       velocity_m_s=rng.normal(0, 1, (25, 2)), angular_velocity_rad_s=rng.normal(0, 1, 25),
                       heading_rad=rng.uniform(-3, 3, 25), tau_s=1e12,
                       links=[[0, 1], [7, 12]], link_offsets_m=[[0, 0.25, 0, -0.25], [0.1, 0.2, -0.1, -0.2]])
    sim = Simulator(st, params=ModelParams(tangential_dissipation_kg=300.0, link_dissipation_kg_per_m2=1e3))
    for _ in range(30):
        p0, l0 = total_momenta(st)
        res = sim.step(st.velocity_m_s.copy())
        p1, l1 = total_momenta(st)
        scale = float((st.mass_kg * np.hypot(*st.velocity_m_s.T)).sum())
        assert np.abs(p1 - p0).max() <= 1e-10 * scale
        assert abs(l1 - l0) <= 1e-10 * scale * (1 + np.abs(st.position_m).max())
        assert res.kinetic_energy_after_impact_j <= res.kinetic_energy_before_impact_j * (1 + 1e-12) + 1e-12
        assert res.kinetic_energy_after_projection_j <= res.kinetic_energy_after_impact_j * (1 + 1e-12) + 1e-12
    assert res.n_impact_clusters >= 0


def _pushing_run(steps, n_side=6, L=3.3, seed=1, check_every=1, **cascade_kw):
    st = lattice_crowd(n_side, 0.5, seed=seed)
    sim = Simulator(st, walls=box(L), params=ModelParams())
    for k, v in cascade_kw.items():  # solver limits
        setattr(sim.cascade, k, v)
    worst = np.inf
    for s in range(steps):
        res = sim.step(towards(st, [L, L / 2], 1.5))
        assert res.kinetic_energy_after_impact_j <= res.kinetic_energy_before_impact_j * (1 + 1e-9) + 1e-9
        assert res.kinetic_energy_after_projection_j <= res.kinetic_energy_after_impact_j * (1 + 1e-9) + 1e-9
        if s % check_every == 0:
            worst = min(worst, sim.min_gap_m())
    r = st.radius_m
    inside = np.all((st.position_m >= r[:, None] - 1e-3) & (st.position_m <= L - r[:, None] + 1e-3))
    return sim, worst, inside


def test_pushing_crowd_never_overlaps_short():
    sim, worst, inside = _pushing_run(1500)
    assert worst >= -1e-3 and inside, worst


@pytest.mark.slow
def test_pushing_crowd_never_overlaps_10k_steps():
    sim, worst, inside = _pushing_run(10_000, n_side=7, L=3.8)
    assert worst >= -1e-3 and inside, worst


def test_jam_without_overlap_through_sparse_paths():
    """Force the sparse solvers (and their fallbacks) on a jam: still no overlap."""
    sim, worst, inside = _pushing_run(400, max_dense_rows=8, max_dense_bodies=6, max_dense_projection_rows=10)
    assert sim.n_sparse_solves > 50
    assert worst >= -1e-3 and inside, worst


def test_candidate_keys_are_unique_in_a_walled_jam(monkeypatch):
    """The large projection's contact keys (matched with np.isin(assume_unique=True) against the last
    step's active contacts and re-detected candidates) are unique: every pair and every pedestrian-wall
    segment contact appears once in a candidate list, walls and a corner included."""
    from crowd_env.core.solvers.cascade import SolverCascade

    seen = []
    project_large = SolverCascade._project_large

    def recording(self, vel, mass, c_a, c_b, con, h, lam_warm=None, keys=None):
        seen.append((keys.copy(), int((con["b"] < 0).sum())))
        return project_large(self, vel, mass, c_a, c_b, con, h, lam_warm, keys)

    monkeypatch.setattr(SolverCascade, "_project_large", recording)
    sim, worst, inside = _pushing_run(150, max_dense_projection_rows=10)
    assert len(seen) > 50 and sum(walls > 0 for _, walls in seen) > 50
    for keys, _ in seen:
        assert np.unique(keys).shape == keys.shape
    assert sim.cascade.n_working_set_solves + sim.cascade.n_alm_newton_steps > 0 and worst >= -1e-3 and inside


def test_dense_and_sparse_paths_give_the_same_steps():
    """Both paths are exact solvers of the same problems: identical trajectories to round-off
    (as long as neither falls back on the interior-point solver)."""
    runs = []
    for limits in ((400, 150, 200), (4, 3, 4)):
        st = lattice_crowd(5, 0.47, jitter=0.004, seed=3)
        sim = Simulator(st, walls=box(2.7), params=ModelParams(tangential_dissipation_kg=50.0))
        sim.cascade.max_dense_rows, sim.cascade.max_dense_bodies, sim.cascade.max_dense_projection_rows = limits
        for _ in range(25):
            sim.step(towards(st, [2.7, 1.35], 1.5))
        runs.append((st.position_m.copy(), st.velocity_m_s.copy(), sim.n_sparse_solves, sim.n_fallback_solves))
    assert runs[0][2] == 0 and runs[1][2] > 0 and runs[1][3] == 0
    np.testing.assert_allclose(runs[1][1], runs[0][1], atol=1e-8)
    np.testing.assert_allclose(runs[1][0], runs[0][0], atol=1e-10)


def test_redetection_after_a_push_through_a_chain():
    """Newton's cradle: disk 0 at 2 m/s hits a resting touching chain; the last disk leaves at
    ~2 m/s towards a resting disk 5 mm away, which was not a candidate with the pre-impact speeds
    (margin ε + 2h·0 = 1 mm). Without detecting again the two would overlap by ~15 mm."""
    r = 0.23
    xs = [0.0, 0.46, 0.92, 1.38, 1.38 + 0.46 + 0.005]
    st = CrowdState.create([[x, 0.0] for x in xs], velocity_m_s=[[2.0, 0.0]] + [[0.0, 0.0]] * 4, radius_m=r,
                           mass_kg=80.0, tau_s=1e12)
    sim = Simulator(st, params=ModelParams(rotation=False))
    sim.step(st.velocity_m_s.copy())
    assert sim.n_redetections >= 1
    assert sim.min_gap_m() >= -1e-12
    assert st.velocity_m_s[3, 0] < 2.0  # the last chain disk was stopped by its neighbour
    p = (st.mass_kg * st.velocity_m_s[:, 0]).sum()
    assert p == pytest.approx(160.0, rel=1e-12)


@pytest.mark.parametrize("last_gap_m, binds", [(0.006, False), (0.002, True)])
def test_redetection_after_the_projection_projects_again_only_if_a_new_candidate_binds(last_gap_m, binds):
    """Disk 0 at 2 m/s closes a 5 mm gap to a resting touching chain within the step: the projection
    (not an impact) sets the chain moving at 0.375 m/s, which makes its last disk a candidate for a
    resting disk ``last_gap_m`` away (not one with the pre-step speeds). At 6 mm the chain does not
    reach it within the step: the projected velocities stand (one projection). At 2 mm it binds:
    projected again over all candidates, the chain pushes that disk too. Momentum is conserved and
    nothing overlaps either way. The staged step (profiled, so that its projections can be counted) and the
    fused step, which runs the same re-detection loop compiled, agree to the bit."""
    r = 0.23
    xs = [0.0, 0.465, 0.925, 1.385, 1.845 + last_gap_m]

    def crowd():
        return CrowdState.create([[x, 0.0] for x in xs], velocity_m_s=[[2.0, 0.0]] + [[0.0, 0.0]] * 4, radius_m=r,
                                 mass_kg=80.0, tau_s=1e12)

    fused_state = crowd()
    fused = Simulator(fused_state, params=ModelParams(rotation=False))
    fused.step(fused_state.velocity_m_s.copy())
    assert fused.n_staged_steps == 0 and fused.n_redetections == 1
    st = crowd()
    sim = Simulator(st, params=ModelParams(rotation=False), profile=True)
    projections = []
    project = sim.cascade.project
    sim.cascade.project = lambda *args, **kwargs: projections.append(1) or project(*args, **kwargs)
    sim.step(st.velocity_m_s.copy())
    assert sim.n_staged_steps == 1
    assert sim.n_redetections == 1 and len(projections) == (2 if binds else 1)
    np.testing.assert_array_equal(st.velocity_m_s, fused_state.velocity_m_s)
    np.testing.assert_array_equal(st.position_m, fused_state.position_m)
    assert (st.velocity_m_s[4, 0] > 0.1) == binds
    if not binds:
        np.testing.assert_allclose(st.velocity_m_s[:, 0], [0.875, 0.375, 0.375, 0.375, 0.0], atol=1e-12)
    assert (st.mass_kg * st.velocity_m_s[:, 0]).sum() == pytest.approx(160.0, rel=1e-12)
    assert sim.min_gap_m() >= -1e-12


# ---------------------------------------------------------------- permutation invariance
@pytest.mark.parametrize("seed", [0, 1])
def test_step_is_permutation_invariant(seed):
    rng = np.random.default_rng(seed)
    base = lattice_crowd(6, 0.465, origin=(0.3, 0.3), jitter=0.003, seed=seed,
                         velocity_m_s=rng.normal(0, 1, (36, 2)), heading_rad=rng.uniform(-3, 3, 36),
                         angular_velocity_rad_s=rng.normal(0, 1, 36), mass_kg=rng.uniform(60, 90, 36),
                         links=[[0, 1], [10, 11]], link_offsets_m=[[0, 0.25, 0, -0.25]] * 2)
    intents = rng.normal(0, 1.3, (36, 2))
    perm = rng.permutation(36)
    inv = np.argsort(perm)
    params = ModelParams(tangential_dissipation_kg=40.0, link_dissipation_kg_per_m2=2e3)
    walls = box(3.1)
    a = base.copy()
    sim_a = Simulator(a, walls=walls, params=params)
    b = base.copy()
    for name in ("position_m", "heading_rad", "velocity_m_s", "angular_velocity_rad_s", "mass_kg", "inertia_kg_m2",
                 "radius_m", "desired_speed_m_s", "tau_s", "heading_stiffness", "heading_damping", "active"):
        setattr(b, name, getattr(b, name)[perm].copy())
    b.links = inv[base.links]
    sim_b = Simulator(b, walls=walls[::-1], params=params)  # walls reversed too
    for _ in range(5):
        ra = sim_a.step(intents)
        rb = sim_b.step(intents[perm])
        assert ra.n_impact_clusters == rb.n_impact_clusters
    for name in ("position_m", "velocity_m_s", "heading_rad", "angular_velocity_rad_s"):
        np.testing.assert_allclose(getattr(b, name), getattr(a, name)[perm], atol=1e-12, rtol=0, err_msg=name)


# ---------------------------------------------------------------- hand-holding in the simulator
def test_linked_pair_walking_apart_is_held_back():
    def run(k_v):
        st = CrowdState.create([[0.0, 0.0], [0.7, 0.0]], velocity_m_s=[[-1.0, 0.0], [1.0, 0.0]], tau_s=1e12,
                               heading_rad=[np.pi / 2, np.pi / 2], links=[[0, 1]],
                               link_offsets_m=[[0.0, -0.23, 0.0, 0.23]])  # right shoulder of 0, left of 1
        sim = Simulator(st, params=ModelParams(link_dissipation_kg_per_m2=k_v, rotation=False))
        sim.step(st.velocity_m_s.copy())
        return st.velocity_m_s[1, 0] - st.velocity_m_s[0, 0]
    free = run(0.0)
    weak = run(5.0)
    strong = run(1e5)
    assert free == pytest.approx(2.0)
    assert 0.0 < weak < free  # damped separation
    assert strong < 0.0  # stiff link: the pair bounces back together


# ---------------------------------------------------------------- reference solver path
def test_cvxpy_solver_path_matches_dual():
    def run(solver):
        rng = np.random.default_rng(11)
        st = lattice_crowd(3, 0.465, jitter=0.002, seed=11, velocity_m_s=rng.normal(0, 1, (9, 2)))
        sim = Simulator(st, walls=box(1.6), params=ModelParams(solver=solver, tangential_dissipation_kg=20.0))
        for _ in range(15):
            sim.step(towards(st, [1.6, 0.8], 1.2))
        return st.position_m.copy(), st.velocity_m_s.copy()
    pa, va = run("dual")
    pb, vb = run("cvxpy")
    np.testing.assert_allclose(vb, va, atol=1e-5)
    np.testing.assert_allclose(pb, pa, atol=1e-6)


# ---------------------------------------------------------------- exits, inactive pedestrians
def test_exit_removes_pedestrians_and_they_stop_interacting():
    st = CrowdState.create([[0.0, 0.0], [3.0, 0.0]], velocity_m_s=[[1.0, 0.0], [0.0, 0.0]])
    sim = Simulator(st, exit_test=lambda p: p[:, 0] > 0.005)
    res = sim.step(np.array([[1.0, 0.0], [0.0, 0.0]]))
    assert res.exited.tolist() == [0, 1]
    assert not st.active.any()
    frozen = st.position_m.copy()
    sim.step(np.zeros((2, 2)))
    np.testing.assert_array_equal(st.position_m, frozen)


def test_a_fused_step_without_contacts_or_exits_gives_empty_arrays_of_its_own():
    """The fused step hands no empty contact or exit arrays back from the compiled code (None, for speed):
    the result still holds arrays of the staged step's dtypes, writeable and new at every step."""
    st = CrowdState.create([[0.0, 0.0], [3.0, 0.0]])
    sim = Simulator(st, walls=np.zeros((0, 4)))
    first, second = (sim.step(np.array([[1.0, 0.0], [0.0, 0.0]])) for _ in range(2))
    assert first.timings_s.keys() == {"fused"}  # the path under test
    fields = ("contact_i", "contact_j", "contact_wall", "percussion_normal", "percussion_tangent", "exited")
    for name, dtype in zip(fields, (np.int64,) * 3 + (np.float64,) * 2 + (np.int64,)):
        a, b = getattr(first, name), getattr(second, name)
        assert a.shape == (0,) and a.dtype == dtype and a.flags.writeable and a is not b


def test_inactive_pedestrian_may_overlap_without_effect():
    st = CrowdState.create([[0.0, 0.0], [5.0, 0.0]])
    st.active[1] = False
    st.position_m[1] = [0.1, 0.0]  # on top of pedestrian 0, but gone
    sim = Simulator(st)
    sim.step(np.zeros((2, 2)))
    assert sim.min_gap_m() == math.inf


# ---------------------------------------------------------------- bad input
def test_bad_intents_and_forces_are_named():
    st = CrowdState.create([[0.0, 0.0], [1.0, 0.0]])
    sim = Simulator(st)
    with pytest.raises(ValueError, match=r"intents_m_s must have shape \(2, 2\)"):
        sim.step(np.zeros((3, 2)))
    with pytest.raises(ValueError, match=r"intents_m_s is not finite for pedestrian\(s\) \[1\]"):
        sim.step(np.array([[0.0, 0.0], [np.nan, 0.0]]))
    with pytest.raises(ValueError, match=r"intents_m_s is not finite for pedestrian\(s\) \[0\]"):
        sim.step(np.array([[np.inf, 0.0], [0.0, 0.0]]))
    with pytest.raises(ValueError, match="desired_heading_rad must have shape"):
        sim.step(np.zeros((2, 2)), desired_heading_rad=np.zeros(3))
    with pytest.raises(ValueError, match="external_force_n is not finite"):
        sim.step(np.zeros((2, 2)), external_force_n=np.array([[0.0, np.nan], [0.0, 0.0]]))
    assert sim.step_count == 0  # nothing advanced


def test_bad_simulator_construction():
    st = CrowdState.create([[1.0, 1.0]])
    with pytest.raises(StateError, match="state must be a CrowdState"):
        Simulator({"position_m": [[0, 0]]})
    with pytest.raises(ParameterError, match="params must be a ModelParams"):
        Simulator(st, params={"dt_s": 0.01})
    with pytest.raises(GeometryError, match="zero length"):
        Simulator(st, walls=[[0, 0, 0, 0]])
    with pytest.raises(GeometryError, match=r"shape \(S, 4\)"):
        Simulator(st, walls=[[0, 0, 1]])
    with pytest.raises(StateError, match=r"pedestrian 0 .* overlaps wall segment 0"):
        Simulator(st, walls=[[0, 1.1, 3, 1.1]])
    st.position_m[0] = [0.0, 0.0]
    st2 = CrowdState.create([[0.0, 0.0], [2.0, 0.0]])
    st2.position_m[1] = [0.2, 0.0]  # moved onto pedestrian 0 after creation
    with pytest.raises(StateError, match="pedestrians 0 and 1 overlap"):
        Simulator(st2)


# ---------------------------------------------------------------- the fused step
def _bottleneck_sims(steps, depth_m=0.0, **cascade_kw):
    from baselines.social_force import SocialForceAgent
    from crowd_env.scenarios import make_scenario

    sc = make_scenario("seyfried_bottleneck", width_m=0.8, n_pedestrians=60, seed=4)
    agent = SocialForceAgent(sc.navigation())
    physics = PhysicsParams(body_depth_m=depth_m)  # 0: the paper's disks; else three circles (crowd_env.core.body)
    sims = [Simulator(sc.make_state(rng=np.random.default_rng(4)), geometry=sc.geometry, profile=profile,
                      params=physics) for profile in (False, True)]
    for sim in sims:
        for k, v in cascade_kw.items():  # solver limits
            setattr(sim.cascade, k, v)
    for _ in range(steps):
        results = []
        for sim in sims:
            intents, heading = agent(sim)
            results.append(sim.step(intents, desired_heading_rad=heading))
        yield sims, results


# bodies of three circles form smaller clusters in these 6 s (at most 3 bodies): smaller limits hand them over
@pytest.mark.parametrize("limits, depth_m", [(None, 0.0), ((6, 4, 8), 0.0), (None, 0.28), ((3, 2, 4), 0.28)])
def test_fused_and_staged_steps_agree_bitwise(limits, depth_m):
    """The fused compiled step and the staged step call the same kernels: identical trajectories, step
    results and re-detection rounds, bit for bit, in a jammed bottleneck (with small solver limits, the
    fused step hands the large clusters to the staged path mid-run), with the paper's disks and with bodies of
    three circles."""
    kw = {} if limits is None else dict(zip(("max_dense_rows", "max_dense_bodies", "max_dense_projection_rows"),
                                            limits))
    for (fused, staged), (ra, rb) in _bottleneck_sims(600, depth_m, **kw):
        for name in ("position_m", "velocity_m_s", "heading_rad", "angular_velocity_rad_s", "active"):
            assert np.array_equal(getattr(fused.state, name), getattr(staged.state, name)), name
        for name in ("contact_i", "contact_j", "contact_wall", "percussion_normal", "percussion_tangent", "exited"):
            assert np.array_equal(getattr(ra, name), getattr(rb, name)), name
        assert ra.min_gap_m == rb.min_gap_m
        assert ra.kinetic_energy_after_projection_j == rb.kinetic_energy_after_projection_j
    assert staged.n_staged_steps == staged.step_count == 600
    assert fused.n_redetections == staged.n_redetections
    if limits is None:
        # the fused path carries every step, those needing a re-detection (speeds grown by impacts) too
        assert fused.n_staged_steps == 0 and fused.n_redetections > 0
    else:
        assert 0 < fused.n_staged_steps < fused.step_count and fused.n_sparse_solves > 0
    assert fused.min_gap_m() >= -1e-9


@pytest.mark.parametrize("depth_m, steps", [(0.0, 400), (0.28, 800)])  # bodies touch later: a longer run
def test_step_min_gap_matches_the_independent_check(depth_m, steps):
    """StepResult.min_gap_m (over contact candidates) equals Simulator.min_gap_m (all pairs and walls
    within 5 cm) whenever some gap is below the detection tolerance (disks, and bodies of three circles)."""
    checked = 0
    for (fused, _), (ra, _) in _bottleneck_sims(steps, depth_m):
        independent = fused.min_gap_m()
        if independent < fused.params.contact_tolerance_m:
            assert ra.min_gap_m == pytest.approx(independent, abs=1e-12)
            checked += 1
        else:
            assert ra.min_gap_m >= min(independent, 0.05) - 1e-12  # a subset of the pairs, or beyond 5 cm
    assert checked > 100


@pytest.mark.filterwarnings("ignore::crowd_env.core.timestep.TimeStepWarning")  # tau = h on purpose
def test_fast_pedestrian_cannot_step_over_a_thin_exit():
    """The exit test follows each centre's path within the step: a 1 cm deep exit crossed at 10 m/s
    (10 cm per step) still removes the pedestrian, and one passing beside the exit does not leave."""
    from shapely.geometry import box as sbox

    from crowd_env.core.geometry import Geometry

    geom = Geometry(sbox(0, 0, 6, 4), exits=[sbox(5.99, 1, 6.0, 3)])
    st = CrowdState.create([[5.5, 2.0], [3.0, 0.5]], radius_m=0.23, tau_s=0.01)  # tau = h: u* = u_int
    sim = Simulator(st, geometry=geom, params=ModelParams(rotation=False))
    left_at = None
    for k in range(20):
        res = sim.step([[10.0, 0.0], [1.0, 0.0]])
        if res.exited.size:
            assert res.exited.tolist() == [0] and left_at is None
            left_at = k
    assert left_at is not None and not st.active[0] and st.active[1]
