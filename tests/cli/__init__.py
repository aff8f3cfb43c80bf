"""The command lines' tests; :func:`save_tiny_model` serves those that need a saved model with its recorded
configuration."""
from __future__ import annotations

import json


def save_tiny_model(folder, env_config: dict):
    """An untrained SB3 PPO model of ``env_config``'s environment saved as ``folder/model.zip``, with the
    ``env_config.json`` a training command writes beside it; returns the model's path (needs stable-baselines3)."""
    import warnings

    from stable_baselines3 import PPO

    from crowd_env.envs.sb3 import sb3_vec_env

    folder.mkdir(parents=True, exist_ok=True)
    (folder / "env_config.json").write_text(json.dumps(env_config))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        PPO("MlpPolicy", sb3_vec_env(1, seed=0, **env_config), n_steps=8, batch_size=8, device="cpu").save(
            str(folder / "model.zip"))
    return folder / "model.zip"
