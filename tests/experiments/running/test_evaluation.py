"""The evaluation harness (crowd_env.experiments.running.evaluation): the calibrated baseline's metrics through it,
and scenarios given by name and options."""
import numpy as np

from baselines.reference_policies import CalibratedPolicy, ZeroIntentPolicy, as_policy
from crowd_env.experiments.running.evaluation import ScenarioSpec, evaluate, run_episode


def test_evaluation_harness_takes_scenario_name_and_options():
    res = run_episode(as_policy("baseline"), ScenarioSpec("corridor_bidirectional", {"n_per_direction": 3}), seed=0,
                      max_time_s=30.0)
    assert res.scenario == "corridor_bidirectional(n_per_direction=3)"
    assert res.n_evacuated == res.n_pedestrians == 6 and np.isfinite(res.evacuation_time_s)
    assert res.min_gap_m > -1e-3
    assert np.isfinite(res.flow_per_s) and np.isnan(res.specific_flow_per_m_s)  # "middle" line, no width
    (room,) = evaluate(["baseline"], [("room_pillar", {"n_pedestrians": 8})], seeds=[1], max_time_s=30.0,
                       progress=None, resolve=as_policy)
    assert room.n_evacuated == 8 and room.specific_flow_per_m_s > 0  # J_s at the "door" line, b = door width


def test_harness_baseline_metrics_match_simulator():
    """The calibrated baseline through the harness evacuates everybody with a plausible specific flow;
    the metrics are the same across repeated runs (deterministic) and random/zero policies are worse."""
    spec = ScenarioSpec("seyfried_bottleneck", {"n_pedestrians": 10, "seed": 0})
    r1 = run_episode(as_policy("baseline"), spec, 0, max_time_s=40.0)
    r2 = run_episode(CalibratedPolicy(), spec, 0, max_time_s=40.0)
    assert r1 == r2.__class__(**{**r2.__dict__, "wall_time_s": r1.wall_time_s})
    assert r1.n_evacuated == 10 and np.isfinite(r1.evacuation_time_s)
    assert 0.5 < r1.specific_flow_per_m_s < 3.0
    assert r1.min_gap_m > -1e-3 and r1.mean_speed_m_s > 0.3
    z = run_episode(ZeroIntentPolicy(), spec, 0, max_time_s=2.0)
    assert z.n_evacuated == 0 and np.isnan(z.evacuation_time_s) and z.mean_return < r1.mean_return


def test_learners_among_a_crowd_are_measured_until_the_whole_crowd_has_left():
    """With some pedestrians as agents the episode goes on after they leave (CrowdParallelEnv.step_background):
    the calibrated model as the agents' policy then gives exactly the all-calibrated crowd's measures (the
    same model at the same decision interval), whichever pedestrians are the agents."""
    spec = ScenarioSpec("seyfried_bottleneck", {"n_pedestrians": 10, "seed": 0})
    everyone = run_episode(as_policy("baseline"), spec, 0, max_time_s=40.0)
    for controlled in ([0, 1, 2], [7]):
        some = run_episode(as_policy("baseline"), spec, 0, env_options={"controlled": controlled}, max_time_s=40.0)
        assert some.complete and some.n_evacuated == 10
        for key in ("evacuation_time_s", "specific_flow_per_m_s", "n_percussions", "min_gap_m", "mean_speed_m_s"):
            assert getattr(some, key) == getattr(everyone, key), key


def test_episode_setup_and_recorded_config_give_the_problem_a_policy_was_trained_on(tmp_path):
    import json

    from crowd_env.experiments.running.evaluation import episode_setup, recorded_env_config

    config = {"scenario": "seyfried_bottleneck", "scenario_options": {"width_m": 1.0, "n_pedestrians": 10},
              "controlled": "all", "frame_skip": 10, "max_steps": 100, "n_neighbors": 6, "n_rays": 8,
              "reseed_scenario": None, "observation_frame": "egocentric"}
    spec, options, max_time = episode_setup(config)
    assert spec.scenario == "seyfried_bottleneck" and spec.scenario_options == config["scenario_options"]
    assert max_time == 10.0  # 100 decisions of 10 steps of 0.01 s
    assert options == {k: v for k, v in config.items() if k not in ("scenario", "scenario_options", "max_steps")}
    assert recorded_env_config(tmp_path / "model.zip") == (None, None)
    (tmp_path / "env_config.json").write_text(json.dumps(config))
    for where in (tmp_path / "model.zip", tmp_path):  # beside a model file, or in its run folder
        cfg, path = recorded_env_config(where)
        assert cfg == config and path == str(tmp_path / "env_config.json")


def test_summaries_carry_bootstrap_intervals_of_the_means():
    from crowd_env.experiments.output.evaluation_report import format_intervals
    from crowd_env.experiments.running.evaluation import EpisodeMetrics, confidence_interval, summarize

    lo, hi = confidence_interval([1.0, 2.0, 3.0, 4.0])
    assert 1.0 <= lo < 2.5 < hi <= 4.0
    assert confidence_interval([2.0, float("nan")]) == (2.0, 2.0)
    assert all(np.isnan(confidence_interval([])))
    assert confidence_interval([1.0, 5.0, 2.0]) == confidence_interval([1.0, 5.0, 2.0])  # reproducible
    base = dict(policy="p", scenario="s", seed=0, n_pedestrians=2, n_evacuated=2, simulated_time_s=1.0, evacuation_time_s=1.0,
                specific_flow_per_m_s=1.0, flow_per_s=1.0, mean_speed_m_s=1.0, n_percussions=0,
                mean_percussion_kg_m_s=0.0, min_gap_m=0.1, wall_time_s=0.0)
    rows = summarize([EpisodeMetrics(**base, mean_return=r) for r in (1.0, 2.0, 3.0)])
    assert rows[0]["mean_return_ci_low"] < rows[0]["mean_return"] < rows[0]["mean_return_ci_high"]
    table = format_intervals(rows)
    assert f"{rows[0]['mean_return_ci_low']:.3f}..{rows[0]['mean_return_ci_high']:.3f}" in table


def test_the_harness_measures_an_episode_as_the_runner_measures_the_same_run():
    """The calibrated baseline through the harness runs the runner's crowd to the bit (CalibratedPolicy), and the
    harness measures it with the runner's own kernels (measure_step): the same flow, exit time, smallest gap and
    density in front, to the bit."""
    from crowd_env.experiments.running.runner import run_scenario
    from crowd_env.scenarios import make_scenario
    from crowd_env.walking.agent import SocialForceAgent

    sc = make_scenario("seyfried_bottleneck", n_pedestrians=10, seed=0)
    run = run_scenario(sc, SocialForceAgent(sc.navigation()), max_time_s=40.0, density_areas=("front",),
                       lane_area=None)
    ep = run_episode(as_policy("baseline"), ScenarioSpec("seyfried_bottleneck", {"n_pedestrians": 10, "seed": 0}), 0,
                     max_time_s=40.0)
    assert run.complete and ep.complete and ep.n_evacuated == run.n_evacuated == 10
    assert ep.specific_flow_per_m_s == run.specific_flow_per_m_s and ep.flow_per_s == run.flow_per_s
    assert ep.evacuation_time_s == run.evacuation_time_s and ep.min_gap_m == run.min_gap_m
    assert ep.density_front_per_m2 == run.mean_density_per_m2("front", "passages") > 0.0
