"""The shipped human policy (baselines/trained/human_juelich.npz, trained by crowd-imitate from the Jülich corridor
recordings): loadable by name like the other shipped policies, acting as background pedestrians of the environment
and through the evaluation harness (crowd-evaluate) and the scorecard's runner."""
from __future__ import annotations

import numpy as np

from baselines.reference_policies import as_policy
from baselines.trained import list_trained, load_trained
from crowd_env.envs import crowd_v0
from crowd_env.experiments.running.evaluation import evaluate
from crowd_env.experiments.training.human_imitation import HUMAN_POLICY_NAME, TRAINING_RUNS, VALIDATION_RUNS


def test_the_human_policy_is_shipped_with_its_provenance():
    assert HUMAN_POLICY_NAME in list_trained()
    policy = load_trained(HUMAN_POLICY_NAME)
    meta = policy.file.meta
    assert meta["training_runs"] == list(TRAINING_RUNS) and meta["validation_runs"] == list(VALIDATION_RUNS)
    assert "Jülich UO corridor recordings" in meta["data"] and policy.file.output == "clip_box"
    assert policy.env_overrides["observation_frame"] == "egocentric"
    assert "travel_time" not in policy.env_overrides["observation_components"]


def test_human_background_pedestrians_walk_to_the_exit_in_the_environment():
    env = crowd_v0.parallel_env(scenario="seyfried_bottleneck", scenario_options={"n_pedestrians": 12},
                                controlled=2, background_policy=HUMAN_POLICY_NAME, frame_skip=10)
    obs, _ = env.reset(seed=0)
    start = {a: p[0] for a, p in env.positions_m.items()}
    for _ in range(30):  # 3 s, the two agents standing still
        obs, *_ = env.step({a: np.zeros(2) for a in env.agents})
    moved = [env.positions_m[a][0] - start[a] for a in env.positions_m if a not in env.agents]
    assert len(moved) >= 8 and np.mean(moved) > 1.0  # the Seyfried crowd walks towards +x, to the bottleneck


def test_the_evaluation_harness_runs_the_human_policy():
    results = evaluate({"human": as_policy(HUMAN_POLICY_NAME)}, [("seyfried_bottleneck", {"n_pedestrians": 10})],
                       seeds=(0,), max_time_s=20.0, progress=lambda *a: None)
    assert len(results) == 1 and results[0].policy == "human"
    assert results[0].n_evacuated >= 6
