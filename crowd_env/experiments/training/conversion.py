"""Trained models as policy files (``.npz``), the format to share: arrays and JSON, read without running code.

An SB3 ``.zip`` holds pickles (SB3's own loader unpickles the spaces, the policy class and the schedules it
stores), so a model from someone else may run code when ``PPO.load`` reads it; a policy file
(:mod:`crowd_env.envs.policy_files`) holds the MLP's weights, the action bounds and the environment options the
policy was trained with (observation layout, decision interval, action bound), and nothing else.

:func:`sb3_policy_file` reads an SB3 ``MlpPolicy`` archive *without unpickling anything*: the weights from its
``policy.pth`` through torch's weights-only loader, the layers from their names and shapes, the activation from
the readable entry of ``policy_kwargs`` (SB3's default tanh when absent); the observation size and action bounds
are the environment's that ``env_config`` makes, checked against the weights and the bounds the archive records.
Its forward pass is SB3's deterministic ``predict`` (the Gaussian's mean clipped to the action Box).
:func:`convert_policy` writes the policy file of an SB3 ``.zip`` or of a ``crowd-train-mappo`` ``policy.pt`` (or
run folder; read as data only), with the ``env_config.json`` beside the model unless told otherwise. Command
line: ``crowd-convert-policy``.
"""
from __future__ import annotations

import io
import json
import os
import re
import zipfile

import numpy as np

from crowd_env.errors import PolicyError

from ...envs import crowd_v0
from ...envs.policy_files import MLPPolicyFile, from_torchrl, load_weights, save_policy_file
from ..running.evaluation import ENV_CONFIG_FILE, recorded_env_config

__all__ = ["SB3_ACTIVATIONS", "sb3_policy_file", "convert_policy"]

SB3_ACTIVATIONS = {"Tanh": "tanh", "ReLU": "relu"}  # torch.nn class name -> the policy file's activation
_HIDDEN = re.compile(r"mlp_extractor\.policy_net\.(\d+)\.(weight|bias)$")
_NOT_ACTING = ("log_std", "value_net.", "mlp_extractor.value_net.")  # the critic and the exploration noise


def _sb3_archive(path: str) -> tuple:
    """``(data, state dict)`` of the SB3 archive at ``path``: its ``data`` entry as JSON (the pickled parts stay
    base64 text) and ``policy.pth`` through the weights-only loader."""
    try:
        with zipfile.ZipFile(path) as archive:
            data = json.loads(archive.read("data"))
            buffer = io.BytesIO(archive.read("policy.pth"))
    except (OSError, KeyError, zipfile.BadZipFile, ValueError) as exc:
        raise PolicyError(f"{path} is not a saved SB3 model (a .zip with 'data' and 'policy.pth'): {exc}") from None
    buffer.name = f"{path} (policy.pth)"
    state = load_weights(buffer, "SB3 policy's state dict")
    if not isinstance(data, dict) or not isinstance(state, dict):
        raise PolicyError(f"{path} is not a saved SB3 model: its data or policy.pth is not a dict")
    return data, state


def _sb3_activation(data: dict, path: str) -> str:
    """The activation of the policy MLP: ``policy_kwargs['activation_fn']``'s class name, tanh when absent."""
    kwargs = data.get("policy_kwargs")
    kwargs = kwargs if isinstance(kwargs, dict) else {}
    if kwargs.get("squash_output") or data.get("use_sde"):
        raise PolicyError(f"{path}: a model trained with gSDE (use_sde) or squashed outputs has no policy-file form")
    named = kwargs.get("activation_fn")
    if named is None:
        return "tanh"  # SB3's ActorCriticPolicy default
    cls = re.search(r"(\w+)'?>?$", str(named)).group(1)
    if cls not in SB3_ACTIVATIONS:
        raise PolicyError(f"{path}: activation {named} has no policy-file form (one of {sorted(SB3_ACTIVATIONS)})")
    return SB3_ACTIVATIONS[cls]


def _sb3_layers(state: dict, path: str) -> tuple:
    """``(weights (in, out), biases)`` of the acting MLP: ``mlp_extractor.policy_net`` (a Linear at every even
    index, the activation between) and ``action_net``; any parameter of another network is refused."""
    hidden = {}
    for key, value in state.items():
        found = _HIDDEN.match(key)
        if found:
            hidden[int(found.group(1)), found.group(2)] = value
        elif not key.startswith(_NOT_ACTING) and not key.startswith("action_net."):
            raise PolicyError(f"{path}: parameter {key!r} is not one of an SB3 MlpPolicy with the flatten extractor "
                              "(an MLP policy branch and action_net): no policy-file form")
    index = sorted({i for i, _ in hidden})
    pairs = [(hidden.get((i, "weight")), hidden.get((i, "bias"))) for i in index]
    pairs.append((state.get("action_net.weight"), state.get("action_net.bias")))
    if index != list(range(0, 2 * len(index), 2)) or any(w is None or b is None for w, b in pairs):
        raise PolicyError(f"{path}: the policy network's layers {index} and action_net are not an SB3 MLP")
    try:
        return [w.numpy().T.copy() for w, _ in pairs], [b.numpy().copy() for _, b in pairs]
    except AttributeError:
        raise PolicyError(f"{path}: a weight of the policy network is not a tensor") from None


def _recorded_bounds(data: dict, key: str):
    """The bounds SB3 recorded in ``data[key]`` as text (``'[-2.5 -2.5]'``), or None when not readable."""
    space = data.get("action_space")
    try:
        return np.array(str(space[key]).strip("[]").split(), dtype=float)
    except (TypeError, KeyError, ValueError):
        return None


def _spaces(env_config: dict) -> tuple:
    """``(observation size, action Box low, high)`` of an agent of the environment ``env_config`` makes."""
    env = crowd_v0.parallel_env(**env_config)
    agent = env.possible_agents[0]
    space = env.action_space(agent)
    return int(env.observation_space(agent).shape[0]), space.low, space.high


def _check_fits(policy: MLPPolicyFile, obs_dim: int, path: str) -> None:
    if policy.obs_dim != obs_dim:
        raise PolicyError(f"{path} takes observations of {policy.obs_dim} entries, the environment of its env_config "
                          f"gives {obs_dim}: pass the environment options it was trained with")


def sb3_policy_file(path: str, *, env_config: dict, meta: dict | None = None) -> MLPPolicyFile:
    """The deterministic actor of the SB3 ``MlpPolicy`` (PPO, A2C) saved at ``path``, read without unpickling
    anything (module docstring), acting in the environment ``env_config`` describes (the options it was trained
    with: they give the observation size and action bounds, checked against the archive's). Raises
    :class:`~crowd_env.errors.PolicyError` for an archive without that form or options that do not fit it."""
    data, state = _sb3_archive(path)
    activation = _sb3_activation(data, path)
    weights, biases = _sb3_layers(state, path)
    obs_dim, low, high = _spaces(env_config)
    for recorded, have in ((_recorded_bounds(data, "low"), low), (_recorded_bounds(data, "high"), high)):
        if recorded is not None and (recorded.shape != have.shape or not np.allclose(recorded, have, rtol=1e-6)):
            raise PolicyError(f"{path} was trained with actions in [{_recorded_bounds(data, 'low')}, "
                              f"{_recorded_bounds(data, 'high')}], the environment of its env_config has [{low}, "
                              f"{high}]: pass the environment options it was trained with")
    policy = MLPPolicyFile(weights, biases, activation, "clip_box", low, high,
                           np.zeros(weights[0].shape[0]), np.ones(weights[0].shape[0]), dict(env_config), dict(meta or {}))
    _check_fits(policy, obs_dim, path)
    return policy


def convert_policy(model: str, out: str, *, env_config: dict | None = None) -> MLPPolicyFile:
    """Write the policy file (``.npz``) of ``model`` to ``out`` and return it: an SB3 ``.zip``
    (:func:`sb3_policy_file`) or a ``crowd-train-mappo`` ``policy.pt`` or run folder (read as data only:
    :func:`~crowd_env.experiments.training.marl.load_policy`). ``env_config``: the environment options it was
    trained with (None: the ``env_config.json`` beside the model, as the training commands write it)."""
    if env_config is None:
        env_config, _ = recorded_env_config(model)
        if env_config is None:
            raise PolicyError(f"no {ENV_CONFIG_FILE} beside {model}: give the environment options it was trained "
                              f"with (crowd-convert-policy --env-config FILE)")
    source = {"converted_from": os.path.basename(os.path.normpath(model))}
    if model.endswith(".zip"):
        policy = sb3_policy_file(model, env_config=env_config, meta={"algorithm": "sb3", **source})
    elif model.endswith(".pt") or os.path.exists(os.path.join(model, "policy.pt")):
        from .marl import load_policy

        trained = load_policy(model)
        policy = from_torchrl(trained, env_config=env_config, meta={"algorithm": trained.meta["algorithm"], **source})
        _check_fits(policy, _spaces(env_config)[0], model)
    else:
        raise PolicyError(f"cannot convert {model!r}: give an SB3 model (.zip) or a crowd-train-mappo policy.pt or "
                          "run folder")
    save_policy_file(policy, out)
    return policy
