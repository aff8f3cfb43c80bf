"""Issue 4: the baseline agent, the key equivalence, and a reduced Seyfried 2009 reproduction."""
import csv
import json

import numpy as np
import pytest

from baselines import SocialForceAgent
from crowd_env.analysis.density import force_balance_jam_density_per_m2
from crowd_env.analysis.experiment import INSIDE_SPEED_RANGE_M_S, seyfried_2009
from crowd_env.cli.reproduce_bottleneck import main as reproduce
from crowd_env.core import Simulator
from crowd_env.walking import ModelParams
from crowd_env.experiments.running.runner import run_scenario
from crowd_env.scenarios import make_scenario


def _bottleneck(seed):
    """Seyfried's bottleneck at b = 1 m with N = 60, the paper's set-up (no navigation clearance)."""
    return make_scenario("seyfried_bottleneck", width_m=1.0, n_pedestrians=60, seed=seed, navigation_clearance_m=0.0)


@pytest.fixture(scope="module")
def scenario():
    return _bottleneck(0)


def test_key_equivalence_step_by_step(scenario):
    """Baseline intents u_d e_d + (τ/m) Σf give the same motion as the paper's model written with the
    social force as an external force (architecture.md, "The key equivalence").

    Checked one step at a time from the same state (B is reset to A's state before every step), so
    round-off differences between the two algebraically equal forms cannot compound chaotically.
    """
    agent = SocialForceAgent(scenario.navigation())
    sim_a = Simulator(scenario.make_state(), geometry=scenario.geometry)
    n_contact_steps = 0
    for _ in range(400):
        sim_b = Simulator(sim_a.state.copy(), geometry=scenario.geometry)
        intents, heading = agent(sim_a)
        result = sim_a.step(intents, desired_heading_rad=heading)
        n_contact_steps += result.contact_i.size > 0
        idx = sim_b.active_index
        e_d = agent.desired_direction(sim_b)
        st = sim_b.state
        pure = np.zeros((st.n, 2))
        pure[idx] = st.desired_speed_m_s[idx, None] * e_d
        force = np.zeros((st.n, 2))
        force[idx] = agent.social_force(sim_b, e_d)
        theta_d = st.heading_rad.copy()
        theta_d[idx] = np.arctan2(e_d[:, 1], e_d[:, 0])
        sim_b.step(pure, desired_heading_rad=theta_d, external_force_n=force)
        np.testing.assert_allclose(sim_a.state.velocity_m_s, sim_b.state.velocity_m_s, atol=1e-9)
        np.testing.assert_allclose(sim_a.state.position_m, sim_b.state.position_m, atol=1e-11)
        np.testing.assert_allclose(sim_a.state.heading_rad, sim_b.state.heading_rad, atol=1e-11)
    assert np.abs(sim_a.state.velocity_m_s).max() > 0.5  # they actually walked
    assert n_contact_steps > 10  # and collided: the impact and projection paths were exercised


def test_social_force_slows_the_flow():
    """Social repulsion holds the crowd back (paper Section 4.1.2): at b = 1 m, N = 60, seeds 0-5, the
    crowd without it passes faster while it passes (Eq. 22 over the passages made, mean over seeds, more
    than 10 % above the calibrated crowd's J_s; measured 2.32 against 1.82 1/(m s)), and without it the
    "more aggressive" crowd also clogs the door for good in some runs (the paper's "clogging
    phenomenon"; measured: 3 of 6, a stalled run being reported as such, not as a flow) while the
    crowd with it never does. A single seed decides nothing here: whether one given run clogs without
    the repulsion changes with the last bits of the arithmetic (seed 0 clogged on one machine and
    flowed on another)."""
    with_js, without_js, clogged = [], [], 0
    for seed in range(6):
        sc = _bottleneck(seed)
        agent = SocialForceAgent(sc.navigation())
        with_social = run_scenario(sc, agent, ModelParams(), max_time_s=120)
        without = run_scenario(sc, agent, ModelParams(social_forces=False), max_time_s=120)
        assert with_social.complete and not with_social.stalled, f"seed {seed}: the calibrated crowd stalled"
        assert without.complete or without.stalled, f"seed {seed}: ran out of time without a stall"
        with_js.append(with_social.specific_flow_per_m_s)
        without_js.append(without.partial_specific_flow_per_m_s)
        clogged += without.stalled
    assert np.mean(without_js) > 1.1 * np.mean(with_js), (without_js, with_js)
    assert 1 <= clogged < 6, clogged


def test_reduced_seyfried_n60_b1():
    """N = 60, b = 1.0 m, A = 790 N, B = 0.08 m (the paper preset), seeds 0-3: mean J_s within ±10 % of
    Seyfried's 1.901 1/(m s) (single seeds scatter by about ±12 %; 10-seed means are in the issue
    notes), everybody evacuated, no overlap beyond 1e-3 m."""
    runs = []
    for seed in range(4):
        sc = _bottleneck(seed)
        runs.append(run_scenario(sc, SocialForceAgent(sc.navigation()), ModelParams(), max_time_s=120))
    exp = seyfried_2009()
    js_exp = float(exp.specific_flow_per_m_s[exp.lookup(1.0, 60)[0]])
    assert all(r.n_evacuated == 60 and r.crossing_times_s.size == 60 and r.min_gap_m > -1e-3 for r in runs)
    assert abs(np.mean([r.specific_flow_per_m_s for r in runs]) / js_exp - 1.0) < 0.10
    # the jam in front is held apart by the social force: within 15 % of the force-balance density
    # (3.66 /m²), below the experiment's 4-6 /m²
    rho_front = np.mean([r.mean_density_per_m2("front") for r in runs])
    assert abs(rho_front / force_balance_jam_density_per_m2(790.0, 0.08) - 1.0) < 0.15
    assert rho_front < 4.0
    # continuity in the channel: the stationary passage rate per metre equals ρ_inside · v_inside, two
    # measurements made independently (passages of the line, counts and speeds in the channel area)
    for r in runs:
        rho_v = r.mean_density_per_m2("inside") * r.mean_speed_m_s("inside")
        assert abs(r.stationary_specific_flow_per_m_s() / rho_v - 1.0) < 0.03
    # Eq. 22's J_s mixes a stationary phase faster than the experiment (pedestrians cross the channel
    # at about their desired speeds, above the measured 0.94-1.22 m/s) with a slow draining tail
    stationary = np.mean([r.stationary_specific_flow_per_m_s() for r in runs])
    assert stationary > 1.25 * np.mean([r.specific_flow_per_m_s for r in runs])
    assert np.mean([r.mean_speed_m_s("inside") for r in runs]) > INSIDE_SPEED_RANGE_M_S[1] + 0.1


def test_reproduction_cli_resumes_and_guards_config(tmp_path):
    out = tmp_path / "run"
    args = ["--widths", "1.0", "--sizes", "20", "--seeds", "1", "--jobs", "1", "--out", str(out), "--no-figures"]
    assert reproduce(args) == 0
    rows = list(csv.DictReader(open(out / "results.csv")))
    assert len(rows) == 1
    for col in ("width_m", "n_pedestrians", "seed", "specific_flow_per_m_s", "flow_per_s", "evacuation_time_s",
                "n_evacuated", "min_gap_m"):
        assert col in rows[0]
    assert int(rows[0]["n_evacuated"]) == 20
    record = out / "runs" / "b1.000_n20_s0.json"
    stamp = record.stat().st_mtime_ns
    assert reproduce(args) == 0  # resumable: the finished run is not recomputed
    assert record.stat().st_mtime_ns == stamp
    assert json.loads(record.read_text())["n_pedestrians"] == 20
    with pytest.raises(SystemExit, match="different configuration"):
        reproduce(args + ["--A", "500"])
    with pytest.raises(SystemExit):
        reproduce(args + ["--param", "no_such_param=1"])


def test_state_does_not_alias_scenario_arrays(scenario):
    """Regression: two states made from one scenario must not share position buffers."""
    a = scenario.make_state()
    b = scenario.make_state()
    a.position_m[0] += 1.0
    assert not np.shares_memory(a.position_m, b.position_m)
    assert not np.shares_memory(a.position_m, scenario.position_m)
    assert b.position_m[0, 0] == scenario.position_m[0, 0]


def test_lone_pedestrian_is_not_steered_into_the_entrance_corner():
    """A lone pedestrian 0.6 m off-axis walks through the empty 1 m bottleneck almost as fast as on the
    axis with the configuration-space field; the point field steers it into the corner (much slower)."""
    from crowd_env.scenarios.bottleneck import BottleneckScenario

    def transit(y0, clearance):
        base = make_scenario("seyfried_bottleneck", width_m=1.0, n_pedestrians=1, seed=0)
        sc = BottleneckScenario(geometry=base.geometry, position_m=np.array([[-1.5, y0]]),
                                pedestrian_params={"radius_m": 0.23, "desired_speed_m_s": 1.34},
                                navigation_clearance_m=clearance)
        sim = Simulator(sc.make_state(), geometry=sc.geometry)
        agent = SocialForceAgent(sc.navigation())
        while sim.state.position_m[0, 0] < 1.4 and sim.time_s < 10.0:
            intents, heading = agent(sim)
            sim.step(intents, desired_heading_rad=heading)
        return sim.time_s

    on_axis = transit(0.0, 0.23)
    assert on_axis < 2.9 / 1.34 + 0.6
    assert transit(0.6, 0.23) < on_axis + 0.4
    assert transit(0.6, 0.0) > on_axis + 1.0


def test_presets_set_the_base_configuration_and_flags_override(tmp_path):
    from crowd_env.cli.reproduce_bottleneck import PRESETS, build_parser, config_of, model_params_from_args

    from crowd_env.walking.presets import DEFAULT_PRESET

    cal = PRESETS["calibrated"].model
    assert DEFAULT_PRESET == "calibrated"
    for argv, a, b, wall, clearance in (([], cal["social_strength_n"], cal["social_range_m"], 0.0, 0.23),
                                         (["--preset", "paper"], 790.0, 0.08, None, 0.0),
                                         (["--preset", "recalibrated"], 1150.0, 0.2, 0.0, 0.23),
                                         (["--preset", "recalibrated", "--A", "900", "--navigation-clearance", "0.1"],
                                          900.0, 0.2, 0.0, 0.1)):
        args = build_parser().parse_args(argv)
        config = config_of(args, model_params_from_args(args))
        assert config["params"]["social_strength_n"] == a and config["params"]["social_range_m"] == b
        assert config["params"]["wall_social_strength_n"] == wall
        assert config["geometry"]["navigation_clearance_m"] == clearance
    assert set(PRESETS) == {"calibrated", "joint", "paper", "recalibrated", "shoulders", "vision"}
    with pytest.raises(SystemExit):
        build_parser().parse_args(["--preset", "nonsense"])
    # the optional wall slowdown enters the configuration only when given (older run folders stay valid)
    assert "navigation_wall_slowdown" not in config_of(args, model_params_from_args(args))["geometry"]
    args = build_parser().parse_args(["--navigation-wall-slowdown", "0.5", "0.4"])
    assert config_of(args, model_params_from_args(args))["geometry"]["navigation_wall_slowdown"] == [0.5, 0.4]


def test_impossible_geometry_fails_before_the_output_folder_is_touched(tmp_path):
    out = tmp_path / "out"
    for argv, match in ((["--widths", "0.3"], "b = 0.3 m, N = 20: bottleneck width 0.3 m is not wider"),
                        (["--navigation-wall-slowdown", "0.5", "2"], "navigation_wall_slowdown: .*speed_factor")):
        with pytest.raises(SystemExit, match=match):
            reproduce(argv + ["--sizes", "20", "--seeds", "1", "--out", str(out)])
        assert not out.exists()


def test_a_damaged_run_record_and_a_step_too_small_are_one_line_errors(tmp_path):
    """Regression (issue 52): crowd-bottleneck over an emptied, truncated or '{}' run record, and with --param
    dt_s=1e-9 (10^11 steps a run), raised tracebacks; the second also wrote the folder and ran every worker."""
    out = tmp_path / "run"
    args = ["--widths", "1.0", "--sizes", "20", "--seeds", "1", "--jobs", "1", "--out", str(out), "--no-figures"]
    assert reproduce(args) == 0
    record = out / "runs" / "b1.000_n20_s0.json"
    text = record.read_text()
    for damaged, match in (("", "unreadable run record"), (text[:100], "unreadable run record"),
                           ("{}", "the run record lacks")):
        record.write_text(damaged)
        with pytest.raises(SystemExit, match=rf"^error: .*b1\.000_n20_s0\.json: {match}.*delete"):
            reproduce(args)
    other = tmp_path / "tiny_step"
    with pytest.raises(SystemExit, match=r"^error: max_time_s = 300 s at dt_s = 1e-09 s needs up to "
                                         r"300,000,000,000 steps, more than step_limit"):
        reproduce(["--quick", "--param", "dt_s=1e-9", "--out", str(other)])
    with pytest.raises(SystemExit, match=r"^error: --param dt_s = 5e-05 s is below the smallest time step"):
        reproduce(["--quick", "--param", "dt_s=5e-5", "--out", str(other)])  # within the step limit: 6e6 steps
    assert not other.exists()


def _run_with(a_n, b_m, clearance_m, wall_strength_n=None, seed=0, width_m=1.0, max_time_s=80.0, anisotropy=1.0):
    sc = make_scenario("seyfried_bottleneck", width_m=width_m, n_pedestrians=60, seed=seed,
                       navigation_clearance_m=clearance_m)
    params = ModelParams(social_strength_n=a_n, social_range_m=b_m, wall_social_strength_n=wall_strength_n,
                         social_anisotropy=anisotropy)
    return run_scenario(sc, SocialForceAgent(sc.navigation()), params, max_time_s=max_time_s)


def test_point_field_stalls_a_pair_beside_the_entrance_and_the_recalibrated_configuration_does_not():
    """With the literal point field (Eq. 11-13) and a large A·B (A = 752.5 N, B = 0.2 m), two pedestrians
    end up on either side of the entrance, each steered at its corner of the opening and repelled by
    the other (and the wall): they stand still for good (documented in PRESETS). Seeds 0-5 stalled
    6/6 runs with walls repelling socially, 3/6 with the point field and no wall force, 5/6 with the
    configuration-space field and the wall force, 0/6 with both changes (the recalibrated preset's
    structure). Which seeds stall in the partial cases shifts with the last bits of the solvers, so
    those assert that some seed of 0-3 stalls."""
    def stalls(clearance_m, wall_strength_n, seed):
        return _run_with(752.5, 0.2, clearance_m, wall_strength_n, seed=seed).n_evacuated < 60

    assert all(_run_with(752.5, 0.2, 0.0, seed=s).n_evacuated == 58 for s in (0, 1))  # point field, walls repel
    assert any(stalls(0.0, 0.0, s) for s in range(4))
    assert any(stalls(0.23, None, s) for s in range(4))
    assert not any(stalls(0.23, 0.0, s) for s in range(3))


def test_recalibrated_preset_n60_b1():
    """The recalibrated preset (A = 1150 N, B = 0.2 m, configuration-space field, no wall social force):
    mean J_s of 4 seeds within ±5 % of Seyfried's 1.901 1/(m s) at b = 1.0 m (single seeds scatter by
    ±12 %; 10-seed means are within ±5 % at all five widths, see the issue notes), everybody out, no
    overlap."""
    runs = [_run_with(1150.0, 0.2, 0.23, wall_strength_n=0.0, seed=seed) for seed in range(4)]
    exp = seyfried_2009()
    js_exp = float(exp.specific_flow_per_m_s[exp.lookup(1.0, 60)[0]])
    assert all(r.n_evacuated == 60 and r.min_gap_m > -1e-3 for r in runs)
    assert abs(np.mean([r.specific_flow_per_m_s for r in runs]) / js_exp - 1.0) < 0.05
    # B = 0.2 m keeps the jam looser: the front density follows the force balance (1.86 /m²) within 15 %
    rho_front = np.mean([r.mean_density_per_m2("front") for r in runs])
    assert abs(rho_front / force_balance_jam_density_per_m2(1150.0, 0.2) - 1.0) < 0.15


def test_discharge_is_pressure_driven(tmp_path):
    """README: the model's discharge rate falls as the crowd behind thins (N = 40, b = 1.0 m), unlike the
    experiment's capacity flow; fig15_discharge.png shows it. discharge_rate is exact on even passages."""
    from crowd_env.analysis.figures import discharge_figure, discharge_rate

    remaining, rate = discharge_rate(0.5 * np.arange(12), window=5)
    np.testing.assert_allclose(rate, 2.0)
    np.testing.assert_allclose(remaining, 12 - (np.arange(7) + 2.5))
    assert discharge_rate([1.0, 2.0], window=5)[0].size == 0
    sc = make_scenario("seyfried_bottleneck", width_m=1.0, n_pedestrians=40, seed=0, navigation_clearance_m=0.0)
    r = run_scenario(sc, SocialForceAgent(sc.navigation()), ModelParams(), max_time_s=120)
    remaining, rate = discharge_rate(r.crossing_times_s, window=5)
    third = rate.size // 3
    assert rate[:third].mean() > 1.5 * rate[-third:].mean()
    record = {"n_pedestrians": 40, "width_m": 1.0, "crossing_times_s": r.crossing_times_s.tolist()}
    path = discharge_figure([record], tmp_path / "fig15_discharge.png")
    assert path.exists() and path.stat().st_size > 1000


def test_small_groups_queue_along_the_front_wall_beside_the_entrance():
    """README (J_s for N = 20): the tail of a small group waits beside the entrance. Pedestrians from the
    sides of the holding section reach the front wall next to the opening (each aims at its corner,
    Eq. 11-13) and slide along it; they pass last. N = 20, b = 1.0 m, seeds 0-3: time spent against the
    front wall beside the opening (x in (-0.6, 0) m, |y| > b/2) by the first six and the last six to pass,
    and the passage rate of the first ten."""
    from crowd_env.analysis.flow import MeasurementLine, PassageCounter

    first, last, early_rates = [], [], []
    for seed in range(4):
        sc = make_scenario("seyfried_bottleneck", width_m=1.0, n_pedestrians=20, seed=seed, navigation_clearance_m=0.0)
        state = sc.make_state()
        sim = sc.make_simulator(state, ModelParams())
        agent = SocialForceAgent(sc.navigation())
        counter = PassageCounter(MeasurementLine(*np.asarray(sc.geometry.measurement_lines["bottleneck"])))
        beside_s = np.zeros(state.n)
        while state.active.any() and sim.time_s < 60.0:
            prev, t_prev = state.position_m.copy(), sim.time_s
            intents, heading = agent(sim)
            sim.step(intents, desired_heading_rad=heading)
            counter.update(prev, state.position_m, t_prev, sim.time_s, np.arange(state.n))
            x, y = state.position_m[:, 0], state.position_m[:, 1]
            beside_s[state.active & (x > -0.6) & (x < 0.0) & (np.abs(y) > 0.5)] += sim.params.dt_s
        assert len(counter) == 20
        times = np.sort(counter.times_s)
        early_rates.append(9.0 / (times[9] - times[0]))  # first ten passages, b = 1 m: per metre and second
        order = counter.ids[np.argsort(counter.times_s)]
        first.append(beside_s[order[:6]])
        last.append(beside_s[order[-6:]])
    assert np.mean(last) > 3.0 and np.mean(first) < 1.0
    # the first half passes at about the experiment's rate (N = 20 range 1.77-2.31 /(m s); measured
    # 1.73-2.00 per seed), far above the whole run's J_s (about 1.1 here)
    assert np.mean(early_rates) > 1.6, early_rates
    assert np.mean(np.concatenate(last) > 4.0) >= 0.4  # 14 of the 24 wait there over 4 s


def test_wall_repulsion_sets_the_lanes_at_the_paper_point():
    """README: at the paper's point (A = 790 N, B = 0.08 m) the lane pattern in the channel follows the
    social force of the walls, which the paper leaves open. At b = 1.2 m (3 seeds): walls repelling like
    pedestrians (the `paper` preset) squeeze a central file between the two side lanes; without wall
    repulsion the traffic runs along both walls, two lanes and nothing in the middle."""
    from crowd_env.analysis.lanes import detect_lanes

    def lanes(wall_strength_n):
        y = np.concatenate([_run_with(790.0, 0.08, 0.0, wall_strength_n, seed=s, width_m=1.2).lateral_positions_m
                            for s in range(3)])
        edges = np.arange(-0.6, 0.6 + 1e-9, 0.01)
        counts, _ = np.histogram(y, bins=edges)
        return detect_lanes(0.5 * (edges[:-1] + edges[1:]), counts / counts.sum()).peak_positions_m

    with_walls, without = lanes(None), lanes(0.0)
    assert np.abs(with_walls).min() < 0.05 and with_walls.size == 3, with_walls
    assert without.size == 2 and np.all(np.abs(without) > 0.6 - 0.23 - 0.04), without


def test_anisotropy_slows_the_channel_and_lowers_the_flow():
    """README ("The slope of J(b) is not the anisotropy's"): at the paper's point, weighting neighbours
    behind by λ = 0.5 instead of 1 slows the pedestrians inside the channel (4 seeds: 1.26 against
    1.44 m/s at b = 1 m) and lowers J_s (1.30 against 1.81 /(m s)); one seed here."""
    isotropic = _run_with(790.0, 0.08, 0.0)
    anisotropic = _run_with(790.0, 0.08, 0.0, anisotropy=0.5)
    assert anisotropic.n_evacuated == isotropic.n_evacuated == 60
    assert anisotropic.mean_speed_m_s("inside") < isotropic.mean_speed_m_s("inside") - 0.08
    assert anisotropic.specific_flow_per_m_s < 0.85 * isotropic.specific_flow_per_m_s
