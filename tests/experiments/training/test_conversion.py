"""Trained models as policy files (crowd_env.experiments.training.conversion, crowd-convert-policy): an SB3 archive
read without unpickling gives the policy file SB3's own loader does, to the bit, and acts as SB3's ``predict`` to
float32 rounding; a MAPPO policy.pt converts likewise; options that do not fit the model are refused."""
import json
import os

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from stable_baselines3 import PPO  # noqa: E402

from crowd_env.envs.policy_files import from_sb3, load_policy_file  # noqa: E402
from crowd_env.envs.sb3 import sb3_vec_env  # noqa: E402
from crowd_env.errors import PolicyError, UntrustedFileError  # noqa: E402
from crowd_env.experiments.training.conversion import convert_policy, sb3_policy_file  # noqa: E402
from tests.conftest import load_script, plant_in_sb3_archive  # noqa: E402

TINY = {"scenario": "seyfried_bottleneck", "scenario_options": {"n_pedestrians": 4, "width_m": 1.0},
        "controlled": "all", "frame_skip": 10, "max_steps": 20, "n_neighbors": 3, "n_rays": 4,
        "action_max_m_s": 1.7}


def _saved_model(folder, activation=None):
    """An SB3 PPO MlpPolicy (32-32, untrained: random weights, the action head's scaled up from SB3's 0.01 gain so
    that some actions pass the bound) on TINY, saved as crowd-train-ppo saves one: ``model.zip`` with
    ``env_config.json`` beside it."""
    import torch

    torch.manual_seed(0)
    kwargs = {"net_arch": [32, 32], **({"activation_fn": activation} if activation else {})}
    model = PPO("MlpPolicy", sb3_vec_env(1, seed=0, **TINY), n_steps=16, batch_size=16, device="cpu",
                policy_kwargs=kwargs)
    with torch.no_grad():
        model.policy.action_net.weight.mul_(100.0)
    os.makedirs(folder, exist_ok=True)
    model.save(os.path.join(folder, "model.zip"))
    with open(os.path.join(folder, "env_config.json"), "w") as fh:
        json.dump(TINY, fh)
    return model, os.path.join(folder, "model.zip")


def _observations(obs_dim):
    """Observations at several scales: the large ones drive the Gaussian's mean past the action bound (clipped)."""
    rng = np.random.default_rng(1)
    return (rng.normal(size=(60, obs_dim)) * np.repeat([0.3, 1.0, 10.0, 100.0], 15)[:, None]).astype(np.float32)


@pytest.mark.parametrize("activation", [None, "relu"])
def test_a_converted_sb3_model_acts_as_sb3_does(tmp_path, activation):
    import torch

    model, path = _saved_model(str(tmp_path / "ppo"), torch.nn.ReLU if activation else None)
    read = sb3_policy_file(path, env_config=TINY)
    loaded = from_sb3(PPO.load(path, device="cpu"), env_config=TINY)  # SB3's own loader (unpickles the archive)
    assert read.activation == loaded.activation == (activation or "tanh")
    for a, b in zip(read.weights + read.biases + [read.low, read.high], loaded.weights + loaded.biases
                    + [loaded.low, loaded.high]):
        assert np.array_equal(a, b)  # the same numbers to the bit: the archive read without unpickling
    obs = _observations(read.obs_dim)
    out = tmp_path / "policy.npz"
    assert load_script("convert_policy").main([path, "--out", str(out)]) == 0
    shared = load_policy_file(str(out))
    assert shared.env_config == TINY and shared.meta == {"algorithm": "sb3", "converted_from": "model.zip"}
    # float32 weights are stored as float32: the file acts as the converted policy to the bit
    assert np.array_equal(shared.actions(obs), read.actions(obs))
    sb3 = model.predict(obs, deterministic=True)[0]
    assert np.any(np.abs(sb3) == 1.7) and np.any(np.abs(sb3) < 1.7)  # clipped and free actions both compared
    # to float32 rounding, not to the bit: the file computes in float64 from the float32 weights, SB3 in float32
    # throughout (sums of 26-32 products per layer, actions up to 1.7 m/s: measured at most 2.6e-6 m/s apart)
    np.testing.assert_allclose(shared.actions(obs), sb3, rtol=0, atol=1e-5)


def test_an_sb3_archive_is_read_without_unpickling(tmp_path):
    """A code-running pickle in the archive's ``data`` (where SB3 keeps the spaces and the policy class) is never
    run by the conversion, while PPO.load runs it; only policy.pth is read, through the weights-only loader,
    which refuses a payload planted there."""
    _, path = _saved_model(str(tmp_path / "ppo"))
    flag = tmp_path / "ran.flag"
    plant_in_sb3_archive(path, flag)
    assert sb3_policy_file(path, env_config=TINY).obs_dim > 0
    assert not flag.exists()
    try:  # SB3's own loader runs it (why the docs say to load SB3 models only from sources you trust)
        PPO.load(path, device="cpu")
    except Exception:
        pass  # what the payload returned is no policy class
    assert flag.exists()
    flag.unlink()
    plant_in_sb3_archive(path, flag, "policy.pth")
    with pytest.raises(UntrustedFileError, match=r"model.zip \(policy.pth\) holds a reference to \w*\.open"):
        sb3_policy_file(path, env_config=TINY)
    assert not flag.exists()


def test_a_mappo_policy_converts_and_acts_as_before(tmp_path):
    pytest.importorskip("torchrl")
    import torch

    from crowd_env.experiments.training import marl

    torch.manual_seed(0)
    env = marl.make_env(TINY, seed=0)
    actor, _ = marl.build_networks(env, "ippo", hidden=(16, 16))
    space = env.full_action_spec[marl.GROUP, "action"].space
    obs_dim = env.observation_spec[marl.GROUP, "observation"].shape[-1]
    folder = tmp_path / "mappo"
    folder.mkdir()
    marl._save_weights(str(folder / "policy.pt"), marl._policy_payload(actor, "ippo", (16, 16), obs_dim,
                                                                        space.low[0].tolist(), space.high[0].tolist()))
    (folder / "env_config.json").write_text(json.dumps(TINY))
    policy = convert_policy(str(folder), str(tmp_path / "p.npz"))
    assert policy.meta["algorithm"] == "ippo" and policy.output == "tanh_box"
    obs = _observations(obs_dim)
    trained = marl.load_policy(str(folder))
    np.testing.assert_allclose(load_policy_file(str(tmp_path / "p.npz")).actions(obs), trained.actions(obs),
                               rtol=1e-5, atol=2e-6)


def test_options_that_do_not_fit_the_model_are_refused(tmp_path):
    _, path = _saved_model(str(tmp_path / "ppo"))
    with pytest.raises(PolicyError, match=r"takes observations of 26 entries, the environment of its env_config gives 2\d"):
        sb3_policy_file(path, env_config={**TINY, "n_neighbors": 2})
    with pytest.raises(PolicyError, match=r"was trained with actions in \[\[-1.7 -1.7\]"):
        sb3_policy_file(path, env_config={**TINY, "action_max_m_s": 2.5})
    os.remove(tmp_path / "ppo" / "env_config.json")
    with pytest.raises(PolicyError, match="no env_config.json beside .*model.zip: give the environment options"):
        convert_policy(path, str(tmp_path / "p.npz"))
    cmd = load_script("convert_policy")
    (tmp_path / "cfg.json").write_text(json.dumps(TINY))
    assert cmd.main([path, "--env-config", str(tmp_path / "cfg.json"), "--out", str(tmp_path / "p.npz")]) == 0
    with pytest.raises(SystemExit, match="--out must name a .npz file"):
        cmd.main([path, "--out", str(tmp_path / "p.zip")])
    (tmp_path / "junk.zip").write_bytes(b"not a zip")
    with pytest.raises(SystemExit, match="junk.zip is not a saved SB3 model"):
        cmd.main([str(tmp_path / "junk.zip"), "--env-config", str(tmp_path / "cfg.json"), "--out", str(tmp_path / "q.npz")])
    with pytest.raises(SystemExit, match="cannot convert"):
        cmd.main([str(tmp_path / "cfg.json"), "--env-config", str(tmp_path / "cfg.json"), "--out", str(tmp_path / "q.npz")])
