"""Which parameters run by default (docs/core.md): the Simulator without params runs ModelParams(), the paper's
literal set (the `paper` preset), while the environment and the commands' pipeline default to DEFAULT_PRESET."""
from __future__ import annotations

from crowd_env.walking import ModelParams
from crowd_env.walking.presets import DEFAULT_PRESET, get_preset
from crowd_env.experiments.validation.bottleneck import model_params
from crowd_env.scenarios import make_scenario


def test_the_simulator_without_params_runs_the_paper_parameters():
    scenario = make_scenario("seyfried_bottleneck", n_pedestrians=5, seed=0)
    sim = scenario.make_simulator()
    assert sim.params == ModelParams() == get_preset("paper").params()
    assert sim.params.social_strength_n == 790.0 and sim.params.social_range_m == 0.08


def test_the_environment_and_the_pipeline_default_to_the_calibrated_preset():
    from crowd_env.envs import crowd_v0

    assert DEFAULT_PRESET == "calibrated"
    calibrated = get_preset(DEFAULT_PRESET).params()
    assert calibrated != ModelParams()
    assert model_params() == calibrated
    assert model_params("paper", {"social_strength_n": 500.0}) == ModelParams(social_strength_n=500.0)
    env = crowd_v0.parallel_env(scenario="seyfried_bottleneck", scenario_options={"n_pedestrians": 5})
    env.reset(seed=0)
    assert env.sim.params == calibrated
