"""The cold-start compilation on two cores (crowd_env.experiments.running.warm_up): with the rollout cached it does
nothing, and its two halves run (they load from the cache here; the cold speed-up is measured by the README's main
job on a fresh machine, see docs/performance.md)."""
from __future__ import annotations

from crowd_env.core.presets import DEFAULT_PRESET, get_preset
from crowd_env.experiments.running import warm_up
from crowd_env.experiments.running.runner import run_scenario
from crowd_env.scenarios import make_scenario
from crowd_env.walking.agent import SocialForceAgent


def test_a_cached_rollout_starts_no_helper(monkeypatch):
    params = get_preset(DEFAULT_PRESET).params()
    scenario = make_scenario("seyfried_bottleneck", n_pedestrians=4, width_m=1.0, seed=0)
    run_scenario(scenario, SocialForceAgent(scenario.navigation()), params, max_time_s=1.0)  # the rollout is cached
    assert warm_up.rollout_cached()
    monkeypatch.setattr(warm_up.subprocess, "Popen", lambda *a, **k: (_ for _ in ()).throw(AssertionError("started")))
    assert warm_up.compile_in_parallel(params) is False


def test_the_helper_s_half_and_this_process_s_half_run(monkeypatch):
    params = get_preset(DEFAULT_PRESET).params()
    warm_up.compile_core(params)
    warm_up.compile_walking(params)
    monkeypatch.setattr(warm_up, "rollout_cached", lambda: False)  # as on a cold cache: the helper starts, and waits
    monkeypatch.setattr(warm_up.os, "cpu_count", lambda: 2)
    assert warm_up.compile_in_parallel(params) is True
