"""Training pipeline (SB3 PPO on the native vector env or SuperSuit): agent deaths in the SuperSuit pipeline, the two
vectorisers training to comparable returns, a smoke training whose model
runs through the evaluation harness and command, and SB3Policy's check of the observations. (The harness
alone: tests/experiments/running/test_evaluation.py.)"""
import json
import os
import warnings

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
pytest.importorskip("supersuit")

import supersuit as ss  # noqa: E402

from baselines.reference_policies import CallablePolicy, RandomPolicy, SB3Policy, as_policy  # noqa: E402
from crowd_env.envs import crowd_v0  # noqa: E402
from crowd_env.experiments.output.evaluation_report import format_table, plot_results  # noqa: E402
from crowd_env.experiments.running.evaluation import ScenarioSpec, evaluate, run_episode, summarize  # noqa: E402
from crowd_env.experiments.training.ppo import TrainingError, make_vec_env, train  # noqa: E402
from tests.conftest import load_script  # noqa: E402

TINY = {"scenario": "seyfried_bottleneck", "scenario_options": {"n_pedestrians": 6, "width_m": 1.0},
        "controlled": "all", "frame_skip": 10, "max_steps": 30, "n_neighbors": 6, "n_rays": 8}

def test_supersuit_vector_pipeline_with_agent_deaths():
    """black_death_v3 + pettingzoo_env_to_vec_env_v1 survive agents leaving mid-episode and the
    extra step({}) after the last one left; the vector env auto-resets."""
    env = crowd_v0.parallel_env(scenario_options={"n_pedestrians": 4}, frame_skip=20, max_steps=60)
    vec = ss.pettingzoo_env_to_vec_env_v1(ss.black_death_v3(env))
    vec = ss.concat_vec_envs_v1(vec, 1, num_cpus=0, base_class="stable_baselines3")
    obs = vec.reset()
    assert obs.shape == (4, env.observation_space("ped_0").shape[0])
    ed = env.observation_layout["desired_direction"]
    finished = 0
    for _ in range(80):
        obs, rew, dones, infos = vec.step(np.clip(2.0 * obs[:, ed], -2.5, 2.5))
        assert obs.shape[0] == 4 and np.all(np.isfinite(rew))
        if dones.all():
            finished += 1
            break
    assert finished == 1


def test_ppo_smoke_training_saves_model_and_curve(tmp_path):
    out = str(tmp_path / "ppo")
    summary = train(TINY, timesteps=600, out=out, resolve=as_policy, seed=0, copies=1, n_steps=64, batch_size=64,
                    n_epochs=2, eval_seeds=(5,), progress=lambda *a: None)
    for name in ("model.zip", "env_config.json", "learning_curve.csv", "learning_curve.png", "summary.json"):
        assert os.path.exists(os.path.join(out, name)), name
    assert summary["timesteps"] >= 600
    assert np.isfinite(summary["random"]["mean_return"]) and np.isfinite(summary["trained"]["mean_return"])
    with open(os.path.join(out, "learning_curve.csv")) as fh:
        assert fh.readline().strip() == "timestep,episode_return,episode_length"
    with open(os.path.join(out, "env_config.json")) as fh:
        assert json.load(fh)["frame_skip"] == 10

    # the saved model loads and runs through the evaluation harness next to the other policies
    model_path = os.path.join(out, "model.zip")
    env_options = {k: TINY[k] for k in ("frame_skip", "n_neighbors", "n_rays")}
    results = evaluate({"ppo": model_path, "random": RandomPolicy(0), "zero": "zero",
                        "walk": CallablePolicy(lambda o: 1.2 * o[:, 4:6])},
                       [ScenarioSpec("seyfried_bottleneck", {"n_pedestrians": 6})], seeds=(0,),
                       env_options=env_options, max_time_s=3.0, progress=None, resolve=as_policy)
    assert [r.policy for r in results] == ["ppo", "random", "zero", "walk"]
    table = format_table(summarize(results))
    assert "ppo" in table and "J_s" in table
    png = tmp_path / "metrics.png"
    plot_results(results, str(png))
    assert png.stat().st_size > 1000

    # and through the command-line evaluation script
    ev = load_script("evaluate")
    rc = ev.main(["--model", model_path, "--policies", "zero", "--seeds", "0", "--max-time", "1.0",
                  "--scenario-option", "n_pedestrians=6", "--out", str(tmp_path / "eval")])
    assert rc == 0 and (tmp_path / "eval" / "results.csv").exists()


def test_a_resume_loads_only_checkpoints_this_account_signed(tmp_path, monkeypatch):
    """crowd-train-ppo's checkpoints are SB3 archives (pickles): each index entry carries their digest under this
    account's key and a resume checks it before loading. A checkpoint altered to hold a code-running pickle, or a
    folder signed under another key, is refused (UntrustedFileError) and nothing runs; the folder as written
    resumes."""
    from crowd_env.errors import UntrustedFileError
    from crowd_env.files import SECRET_FILE_ENV
    from tests.conftest import plant_in_sb3_archive

    out, flag = tmp_path / "ppo", tmp_path / "ran.flag"
    kw = dict(resolve=as_policy, seed=0, copies=1, n_steps=32, batch_size=64, n_epochs=1, eval_seeds=(5,),
              checkpoint_every=32, progress=lambda *a: None)
    train(TINY, timesteps=100, out=str(out), **kw)
    latest = json.loads((out / "checkpoints" / "index.json").read_text())["checkpoints"][-1]
    archive = out / "checkpoints" / latest["model"]
    written = archive.read_bytes()
    plant_in_sb3_archive(archive, flag)
    with pytest.raises(UntrustedFileError, match=r"ppo_\d+_steps.zip do not match their digest.*delete .*checkpoints"):
        train(TINY, timesteps=400, out=str(out), resume=True, **kw)
    assert not flag.exists()
    archive.write_bytes(written)
    key = os.environ[SECRET_FILE_ENV]
    monkeypatch.setenv(SECRET_FILE_ENV, str(tmp_path / "someone_else.key"))
    with pytest.raises(UntrustedFileError, match="do not match their digest"):
        train(TINY, timesteps=400, out=str(out), resume=True, **kw)
    monkeypatch.setenv(SECRET_FILE_ENV, key)
    more = train(TINY, timesteps=400, out=str(out), resume=True, **kw)
    assert more["resumed_from_timesteps"] == latest["timesteps"] and more["timesteps"] >= 400


def test_sb3_policy_rejects_mismatched_observations(tmp_path):
    from stable_baselines3 import PPO

    env = crowd_v0.parallel_env(**{**TINY, "n_neighbors": 2})
    vec = ss.concat_vec_envs_v1(ss.pettingzoo_env_to_vec_env_v1(ss.black_death_v3(env)), 1, num_cpus=0,
                                base_class="stable_baselines3")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = PPO("MlpPolicy", vec, n_steps=16, batch_size=16, device="cpu")
    with pytest.raises(ValueError, match="expects observations of shape"):
        run_episode(SB3Policy(model), ScenarioSpec("seyfried_bottleneck", {"n_pedestrians": 6}), 0,
                    env_options={"n_neighbors": 6}, max_time_s=0.5)


def test_native_and_supersuit_vectorisers_train_to_comparable_returns(tmp_path):
    """The same PPO on the same problem through either vectoriser: both learn (seed-mean evaluation return far
    above the random policy's) and end within 1.5 of each other (measured: native 2.9, SuperSuit 3.6, random
    -4.6 over seeds 0-2 at 60k timesteps, about 6 s per run)."""
    cfg = {**TINY, "scenario_options": {"n_pedestrians": 10, "width_m": 1.0}, "max_steps": 100}
    means = {}
    for vectoriser in ("native", "supersuit"):
        runs = [train(cfg, timesteps=60_000, out=str(tmp_path / f"{vectoriser}_{seed}"), resolve=as_policy, seed=seed,
                      copies=2, n_steps=128, batch_size=256, n_epochs=5, eval_seeds=(1000, 1001, 1002),
                      vectoriser=vectoriser, progress=lambda *a: None) for seed in (0, 1, 2)]
        random_return = runs[0]["random"]["mean_return"]
        means[vectoriser] = float(np.mean([r["trained"]["mean_return"] for r in runs]))
        assert means[vectoriser] > random_return + 5.0, (vectoriser, means[vectoriser], random_return)
    assert abs(means["native"] - means["supersuit"]) < 1.5, means


def test_training_on_worker_processes_gives_the_same_model(tmp_path):
    """The native vectoriser's copies stepped in two processes give bitwise the serial observations, so PPO
    (one torch thread, same seed) ends with the same weights and the same evaluation."""
    import torch

    kwargs = dict(timesteps=512, resolve=as_policy, seed=0, copies=2, n_steps=64, batch_size=64, n_epochs=2,
                  eval_seeds=(5,), progress=lambda *a: None)
    serial = train(TINY, out=str(tmp_path / "w1"), workers=1, **kwargs)
    parallel = train(TINY, out=str(tmp_path / "w2"), workers=2, **kwargs)
    assert parallel["workers"] == 2 and serial["trained"] == parallel["trained"]
    from stable_baselines3 import PPO

    a = PPO.load(str(tmp_path / "w1" / "model.zip"), device="cpu").policy.state_dict()
    b = PPO.load(str(tmp_path / "w2" / "model.zip"), device="cpu").policy.state_dict()
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


def test_workers_need_the_native_vectoriser():
    with pytest.raises(TrainingError, match="workers = 2 needs the native vectoriser"):
        make_vec_env(TINY, copies=2, vectoriser="supersuit", workers=2)
