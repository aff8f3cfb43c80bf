"""RLlib PPO with one shared module (crowd_env.experiments.training.rllib, crowd-train-rllib): a smoke training on a
room where agents leave at different times, the saved policy reloaded, resume, and the refusals (an
unreachable cluster, checkpoints without --resume, other environment options, a checkpoint altered since it was
signed)."""
import csv
import glob
import json
import os
import pickle
import subprocess
import sys
import time

import numpy as np
import pytest

pytest.importorskip("ray.rllib")

import ray  # noqa: E402

from baselines.reference_policies import as_policy  # noqa: E402
from crowd_env.envs import crowd_v0  # noqa: E402
from crowd_env.errors import BackendError, TrainingError, UntrustedFileError  # noqa: E402
from crowd_env.experiments.training import rllib  # noqa: E402
from tests.conftest import ROOT, CodeRunningPayload, load_script  # noqa: E402
from tests.experiments.training.test_marl import N, TINY  # noqa: E402

SMALL = {"train_batch_size": 200, "minibatch_size": 100, "num_epochs": 2, "eval_seeds": (5,), "num_env_runners": 0,
         "progress": lambda *a: None}


@pytest.fixture(scope="module")
def local_ray():
    """One local Ray for the module (train() joins it instead of starting its own)."""
    started = not ray.is_initialized()
    if started:
        ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    if started:
        ray.shutdown()


def test_unreachable_cluster_is_refused_fast(tmp_path):
    t0 = time.perf_counter()
    with pytest.raises(BackendError, match="cannot reach the Ray cluster"):
        rllib.train(TINY, 200, str(tmp_path / "r"), resolve=as_policy, address="127.0.0.1:1", **SMALL)
    with pytest.raises(BackendError, match="host:port"):
        rllib.train(TINY, 200, str(tmp_path / "r"), resolve=as_policy, address="nowhere", **SMALL)
    assert time.perf_counter() - t0 < 10.0
    assert not (tmp_path / "r").exists()  # refused before anything was written
    cmd = load_script("train_rllib")
    with pytest.raises(SystemExit, match="cannot reach the Ray cluster"):
        cmd.main(["--address", "127.0.0.1:1", "--connect-timeout", "1", "--out", str(tmp_path / "c")])


def test_rllib_smoke_training_reload_and_resume(tmp_path, local_ray):
    from ray.rllib.core.rl_module.rl_module import RLModule

    out = str(tmp_path / "rllib")
    summary = rllib.train(TINY, 400, out, resolve=as_policy, **SMALL)
    for name in ("progress.csv", "policy.json", "policy", "env_config.json", "summary.json", "checkpoints/index.json"):
        assert os.path.exists(os.path.join(out, name)), name
    with open(os.path.join(out, "progress.csv")) as fh:
        rows = list(csv.DictReader(fh))
    assert tuple(rows[0]) == rllib.CSV_COLUMNS and [int(r["iteration"]) for r in rows] == [1, 2]
    assert all(np.isfinite(float(r[k])) for r in rows for k in ("policy_loss", "vf_loss", "mean_episode_return"))
    # agents left mid-episode: fewer agent steps than environment steps x agents
    assert summary["env_steps"] == 400 and 0 < summary["agent_steps"] < summary["env_steps"] * N
    assert np.isfinite(summary["random"]["mean_return"]) and np.isfinite(summary["trained"]["mean_return"])

    # the saved policy is the trained module: same actions as the module of the final algorithm checkpoint
    policy = rllib.load_policy(out)
    with open(os.path.join(out, "checkpoints", "index.json")) as fh:
        latest = json.load(fh)["checkpoints"][-1]["model"]
    module = RLModule.from_checkpoint(os.path.join(out, "checkpoints", latest, "learner_group", "learner",
                                                   "rl_module", rllib.MODULE_ID))
    final = rllib.RLlibPolicy(module, policy.obs_dim, policy.low, policy.high)
    obs = np.random.default_rng(0).uniform(-1, 1, (N, policy.obs_dim)).astype(np.float32)
    np.testing.assert_allclose(policy.actions(obs), final.actions(obs), atol=1e-6)
    resolved = as_policy(out, name="rllib_run")  # crowd-evaluate --policies DIR
    assert resolved.name == "rllib_run"
    np.testing.assert_allclose(resolved.actions(obs), policy.actions(obs), atol=0)
    env = crowd_v0.parallel_env(**TINY)
    o, _ = env.reset(seed=0)
    acts = policy.act(env, o)
    assert set(acts) == set(env.agents) and all(env.action_space(a).contains(v) for a, v in acts.items())
    with pytest.raises(TrainingError, match="expects observations of 45 entries"):
        policy.reset(crowd_v0.parallel_env(**{**TINY, "n_neighbors": 2}), 0)

    with pytest.raises(TrainingError, match="--resume"):
        rllib.train(TINY, 600, out, resolve=as_policy, **SMALL)
    with pytest.raises(TrainingError, match="max_steps"):
        rllib.train({**TINY, "max_steps": 20}, 600, out, resolve=as_policy, resume=True, **SMALL)

    # RLlib's checkpoints hold pickles: with its pickles replaced by a code-running one the latest checkpoint no
    # longer matches its digest (this account's key), and the resume is refused before RLlib reads any of it
    folder = os.path.join(out, "checkpoints", latest)
    kept = {p: open(p, "rb").read() for p in glob.glob(os.path.join(folder, "**", "*.pkl"), recursive=True)}
    assert kept
    flag = tmp_path / "ran.flag"
    for p in kept:
        with open(p, "wb") as fh:
            pickle.dump(CodeRunningPayload(flag), fh)
    with pytest.raises(UntrustedFileError, match=f"{latest} do not match their digest"):
        rllib.train(TINY, 600, out, resolve=as_policy, resume=True, **SMALL)
    assert not flag.exists()
    for p, blob in kept.items():
        with open(p, "wb") as fh:
            fh.write(blob)
    more = rllib.train(TINY, 600, out, resolve=as_policy, resume=True, **SMALL)
    assert more["resumed_from_env_steps"] == 400 and more["env_steps"] == 600 and more["iterations"] == 3
    with open(os.path.join(out, "checkpoints", "index.json")) as fh:
        assert [e["timesteps"] for e in json.load(fh)["checkpoints"]] == [200, 400, 600]


def test_command_help_and_bad_input(tmp_path):
    cmd = load_script("train_rllib")
    with pytest.raises(SystemExit) as info:
        cmd.main(["--help"])
    assert info.value.code == 0
    with pytest.raises(SystemExit, match="timesteps must be an integer >= 1"):
        cmd.main(["--timesteps", "0", "--out", str(tmp_path / "x")])
    with pytest.raises(TrainingError, match="no saved RLlib policy"):
        rllib.load_policy(str(tmp_path))


HEAD = """
import sys, ray
ctx = ray.init(num_cpus=2, include_dashboard=False)
print(ctx.address_info["gcs_address"], flush=True)
sys.stdin.read()  # until the test closes stdin
ray.shutdown()
"""


@pytest.mark.slow
def test_training_on_a_running_cluster(tmp_path):
    """--address joins a running Ray instance (another process's, standing in for a cluster head) through the
    same code path, with one remote EnvRunner sampling; token authentication is off on both sides."""
    env = {**os.environ, "RAY_AUTH_MODE": "disabled"}
    env.pop("RAY_ADDRESS", None)
    head = subprocess.Popen([sys.executable, "-c", HEAD], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                            env=env)
    try:
        address = head.stdout.readline().strip()
        assert ":" in address, address
        room = TINY["scenario_options"]
        out = tmp_path / "cluster"
        args = [sys.executable, str(ROOT / "scripts" / "train_rllib.py"), "--address", address, "--num-env-runners",
                "1", "--timesteps", "400", "--train-batch-size", "200", "--minibatch-size", "100", "--num-epochs", "2",
                "--scenario", "polygon", "--max-steps", "30", "--eval-seeds", "5", "--out", str(out)]
        for key in ("walkable_area", "exits", "spawn_area", "n_pedestrians"):
            args += ["--scenario-option", f"{key}={json.dumps(room[key])}"]
        run = subprocess.run(args, capture_output=True, text=True, env=env, timeout=300, cwd=ROOT)
        assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-4000:]
        summary = json.loads((out / "summary.json").read_text())
        assert summary["address"] == address and summary["cluster_cpus"] == 2 and summary["num_env_runners"] == 1
        assert summary["env_steps"] == 400 and 0 < summary["agent_steps"] < 400 * N
    finally:
        head.stdin.close()
        try:
            head.wait(timeout=60)
        except subprocess.TimeoutExpired:
            head.kill()
