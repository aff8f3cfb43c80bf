"""MAPPO / IPPO through TorchRL (crowd_env.experiments.training.marl, crowd-train-mappo): agents leaving at different
times through TorchRL's PettingZoo wrapper, the reward terms as info tensors, per-agent GAE, smoke trainings with
reload and resume, bad input."""
import csv
import json
import os

import numpy as np
import pytest

pytest.importorskip("torchrl")
pytest.importorskip("tensordict")

import torch  # noqa: E402
from tensordict.nn import TensorDictModule  # noqa: E402
from torchrl.envs.utils import ExplorationType, set_exploration_type  # noqa: E402

from baselines.reference_policies import as_policy  # noqa: E402
from crowd_env.envs import crowd_v0  # noqa: E402
from crowd_env.errors import TrainingError  # noqa: E402
from crowd_env.experiments.training import marl  # noqa: E402
from tests.conftest import load_script  # noqa: E402

# A 1.6 m x 2 m room whose whole right side is the exit, pedestrians spawned in its right half: agents
# leave at different times even under random actions, the others are truncated after 30 decisions.
ROOM = {"walkable_area": [[0, 0], [1.6, 0], [1.6, 2.0], [0, 2.0]], "exits": [[[1.6, 0.0], [1.6, 2.0]]],
        "spawn_area": [[0.8, 0], [1.6, 0], [1.6, 2.0], [0.8, 2.0]], "n_pedestrians": 4}
TINY = {"scenario": "polygon", "scenario_options": ROOM, "controlled": "all", "frame_skip": 10, "max_steps": 30}
N = ROOM["n_pedestrians"]
SMALL = {"frames_per_batch": 200, "num_epochs": 2, "minibatch_size": 128, "eval_seeds": (5,),
         "progress": lambda *a: None}


def _walker(env, speed=0.6):
    """Walk along the desired direction e_d (a scripted TensorDict policy)."""
    ed = crowd_v0.parallel_env(**TINY).observation_layout["desired_direction"]
    return TensorDictModule(lambda o: speed * o[..., ed], in_keys=[("agents", "observation")],
                            out_keys=[("agents", "action")])


def test_agents_leaving_at_different_times_run_through_the_wrapper():
    """Masks, per-agent done flags and episode returns while pedestrians leave one by one; the rewards are
    those of the plain PettingZoo environment with the same seed and actions."""
    env = marl.make_env(TINY, state=True, seed=3)
    td = env.rollout(100, policy=_walker(env))
    mask = td["agents", "mask"].numpy()                      # [T, n]: acting at t
    done = td["next", "agents", "done"].squeeze(-1).numpy()  # [T, n]
    assert bool(td["next", "done"][-1]) and not td["next", "done"][:-1].any()  # the episode ends when all are done
    steps = mask.sum(axis=0)
    assert len(set(steps.tolist())) >= 2, steps  # agents left at different times
    for j in range(N):  # alive, then gone for good; done from the step it leaves on
        k = int(steps[j])
        assert mask[:k, j].all() and not mask[k:, j].any()
        assert not done[:k - 1, j].any() and done[k - 1:, j].all()
    reward = td["next", "agents", "reward"].squeeze(-1).numpy()
    assert np.all(reward[~mask] == 0.0)
    returns = td["next", "agents", "episode_reward"][-1].squeeze(-1).numpy()
    np.testing.assert_allclose(returns, reward.sum(axis=0), rtol=1e-5)
    assert td["state"].shape == (len(mask), crowd_v0.parallel_env(**TINY).state_space.shape[0])

    # The same episode on the plain environment (the wrapper's seed resets it once when made).
    base = crowd_v0.parallel_env(**TINY)
    base.reset(seed=3)
    obs, _ = base.reset()
    ed = base.observation_layout["desired_direction"]
    direct = dict.fromkeys(base.possible_agents, 0.0)
    while base.agents:
        obs, rew, *_ = base.step({a: (0.6 * obs[a][ed]).astype(np.float32) for a in base.agents})
        for a, r in rew.items():
            direct[a] += r
    np.testing.assert_allclose(returns, [direct[a] for a in base.possible_agents], rtol=1e-5)


@pytest.mark.parametrize("terms", [False, True])
def test_the_reward_terms_reach_torchrl_as_tensors_only_when_asked_for(terms):
    """``reward_terms_in_infos=True``: TorchRL's wrapper turns each agent's list of floats into
    ``("agents", "info", "reward_terms")`` [n, T], summing to the reward while the agent acts (float32); without
    it the info has no such key."""
    env = marl.make_env({**TINY, "reward_terms_in_infos": terms}, seed=3)
    td = env.rollout(12, policy=_walker(env))
    info = td["next", "agents", "info"]
    assert ("reward_terms" in info.keys()) is terms
    if terms:
        parts = info["reward_terms"].numpy()
        assert parts.shape == (len(td), N, 4)
        acting = td["agents", "mask"].numpy()
        reward = td["next", "agents", "reward"].squeeze(-1).numpy()
        np.testing.assert_allclose(parts.sum(axis=-1)[acting], reward[acting], rtol=1e-5, atol=1e-6)
        assert np.abs(parts[acting]).sum() > 0


def test_gae_is_per_agent_and_stops_at_each_agents_exit():
    env = marl.make_env(TINY, state=True, seed=3)
    td = env.rollout(100, policy=_walker(env))
    actor, critic = marl.build_networks(env, "mappo")
    _, gae = marl.make_loss(actor, critic, gamma=0.9, lmbda=0.8)
    with torch.no_grad():
        gae(td)
    g = lambda *k: td[k].squeeze(-1).numpy()  # noqa: E731
    r, v, v1 = g("next", "agents", "reward"), g("agents", "state_value"), g("next", "agents", "state_value")
    d, term = g("next", "agents", "done"), g("next", "agents", "terminated")
    ref, acc = np.zeros_like(r), np.zeros(r.shape[1])
    for t in reversed(range(r.shape[0])):
        acc = r[t] + 0.9 * (1 - term[t]) * v1[t] - v[t] + 0.9 * 0.8 * (1 - d[t]) * acc
        ref[t] = acc
    np.testing.assert_allclose(g("agents", "advantage"), ref, atol=1e-5)
    td["agents", "action_log_prob"] = torch.zeros(td["agents", "mask"].shape)
    flat = marl.valid_transitions(td, state=True)
    assert flat.batch_size[0] == int(td["agents", "mask"].sum()) < td["agents", "mask"].numel()
    assert flat["state"].shape == (flat.batch_size[0], td["state"].shape[-1])


def test_the_critics_of_mappo_and_ippo():
    env = marl.make_env(TINY, state=True, seed=0)
    _, mappo_critic = marl.build_networks(env, "mappo")
    _, ippo_critic = marl.build_networks(env, "ippo")
    assert "state" in mappo_critic.in_keys and ("agents", "observation") in mappo_critic.in_keys
    assert ippo_critic.in_keys == [("agents", "observation")]
    td = env.reset()
    with torch.no_grad():
        a = mappo_critic(td.clone())["agents", "state_value"]
        td2 = td.clone()
        td2["state"] = td2["state"] + 1.0  # the centralised critic reads the global state
        b = mappo_critic(td2)["agents", "state_value"]
    assert a.shape == (N, 1) and not torch.allclose(a, b)


def _deterministic_actions(out, algorithm, obs):
    """Actions of the final checkpoint's actor through TorchRL's own deterministic exploration."""
    env = marl.make_env(TINY, state=algorithm == "mappo", seed=0)
    actor, _ = marl.build_networks(env, algorithm)
    with open(os.path.join(out, "checkpoints", "index.json")) as fh:
        latest = json.load(fh)["checkpoints"][-1]["model"]
    actor.load_state_dict(torch.load(os.path.join(out, "checkpoints", latest), weights_only=True)["actor"])
    td = env.reset()
    td["agents", "observation"] = torch.as_tensor(obs)
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        return actor(td)["agents", "action"].numpy()


def test_mappo_smoke_training_reload_and_resume(tmp_path):
    out = str(tmp_path / "mappo")
    summary = marl.train(TINY, 400, out, algorithm="mappo", resolve=as_policy, **SMALL)
    for name in ("progress.csv", "policy.pt", "env_config.json", "summary.json", "checkpoints/index.json"):
        assert os.path.exists(os.path.join(out, name)), name
    with open(os.path.join(out, "progress.csv")) as fh:
        rows = list(csv.DictReader(fh))
    assert tuple(rows[0]) == marl.CSV_COLUMNS and [int(r["iteration"]) for r in rows] == [1, 2]
    assert all(np.isfinite(float(r[k])) for r in rows for k in ("loss_objective", "loss_critic", "mean_episode_return"))
    # agents left mid-episode: fewer agent transitions than environment steps x agents were trained on
    assert summary["agent_steps"] < summary["frames"] * N
    assert summary["frames"] == 400 and np.isfinite(summary["random"]["mean_return"])
    assert np.isfinite(summary["trained"]["mean_return"])

    # the saved policy reloads and acts as the trained actor does (deterministically)
    policy = marl.load_policy(out)
    obs = np.random.default_rng(0).uniform(-1, 1, (N, policy.obs_dim)).astype(np.float32)
    np.testing.assert_allclose(policy.actions(obs), _deterministic_actions(out, "mappo", obs), atol=1e-6)
    env = crowd_v0.parallel_env(**TINY)
    o, _ = env.reset(seed=0)
    policy.reset(env, 0)
    acts = policy.act(env, o)
    assert set(acts) == set(env.agents) and all(env.action_space(a).contains(v) for a, v in acts.items())
    with pytest.raises(TrainingError, match="expects observations of 45 entries"):
        policy.reset(crowd_v0.parallel_env(**{**TINY, "n_neighbors": 2}), 0)
    # the evaluation's resolver (crowd-evaluate --policies DIR) loads the run folder and the file alike
    for spec in (out, os.path.join(out, "policy.pt")):
        resolved = as_policy(spec, name="mappo_run")
        assert resolved.name == "mappo_run"
        np.testing.assert_allclose(resolved.actions(obs), policy.actions(obs), atol=0)
    # the fresh policy as a policy file to share (crowd-convert-policy; env_config.json from the run folder): it acts
    # as the policy does to float32 rounding (numpy in float64 from the float32 weights, torch in float32)
    assert load_script("convert_policy").main([out, "--out", os.path.join(out, "shared.npz")]) == 0
    shared = as_policy(os.path.join(out, "shared.npz"))
    assert shared.file.env_config == TINY and shared.env_overrides == {"frame_skip": 10}
    np.testing.assert_allclose(shared.file.actions(obs), policy.actions(obs), rtol=1e-5, atol=2e-6)

    # refused: checkpoints without --resume, other environment options, the other algorithm
    with pytest.raises(TrainingError, match="--resume"):
        marl.train(TINY, 600, out, algorithm="mappo", resolve=as_policy, **SMALL)
    with pytest.raises(TrainingError, match="max_steps"):
        marl.train({**TINY, "max_steps": 20}, 600, out, algorithm="mappo", resolve=as_policy, resume=True, **SMALL)
    with pytest.raises(TrainingError, match="mappo checkpoints"):
        marl.train(TINY, 600, out, algorithm="ippo", resolve=as_policy, resume=True, **SMALL)

    # resume continues from the checkpoint at 400 frames
    more = marl.train(TINY, 600, out, algorithm="mappo", resolve=as_policy, resume=True, **SMALL)
    assert more["resumed_from_frames"] == 400 and more["frames"] == 600 and more["iterations"] == 3
    with open(os.path.join(out, "progress.csv")) as fh:
        assert [int(r["iteration"]) for r in csv.DictReader(fh)] == [1, 2, 3]
    with open(os.path.join(out, "checkpoints", "index.json")) as fh:
        assert [e["timesteps"] for e in json.load(fh)["checkpoints"]] == [200, 400, 600]


def test_ippo_command_smoke(tmp_path, capsys):
    out = tmp_path / "ippo"
    cmd = load_script("train_mappo")
    rc = cmd.main(["--algorithm", "ippo", "--frames", "200", "--frames-per-batch", "200", "--num-epochs", "1",
                   "--minibatch-size", "256", "--scenario", "polygon", "--scenario-option",
                   "walkable_area=" + json.dumps(ROOM["walkable_area"]), "--scenario-option",
                   "exits=" + json.dumps(ROOM["exits"]), "--scenario-option",
                   "spawn_area=" + json.dumps(ROOM["spawn_area"]), "--n-pedestrians", "4", "--max-steps", "30",
                   "--eval-seeds", "5", "--out", str(out)])
    text = capsys.readouterr().out
    assert rc == 0 and "iter    1" in text and "ippo: mean per-agent episode return" in text
    summary = json.loads((out / "summary.json").read_text())
    assert summary["algorithm"] == "ippo" and summary["env_config"]["scenario_options"] == ROOM
    assert marl.load_policy(str(out)).name == "ippo"


def test_bad_input_is_refused(tmp_path):
    with pytest.raises(TrainingError, match="unknown algorithm 'vdn'"):
        marl.train(TINY, 200, str(tmp_path / "x"), algorithm="vdn", resolve=as_policy)
    with pytest.raises(TrainingError, match="frames_per_batch"):
        marl.train(TINY, 200, str(tmp_path / "x"), algorithm="ippo", resolve=as_policy, frames_per_batch=0)
    with pytest.raises(TrainingError, match="no saved policy"):
        marl.load_policy(str(tmp_path))
    cmd = load_script("train_mappo")
    with pytest.raises(SystemExit) as info:
        cmd.main(["--algorithm", "vdn"])
    assert info.value.code == 2
    with pytest.raises(SystemExit, match="--scenario-option needs key=value"):
        cmd.main(["--scenario-option", "oops", "--out", str(tmp_path / "y")])
    with pytest.raises(SystemExit) as info:
        cmd.main(["--help"])
    assert info.value.code == 0
