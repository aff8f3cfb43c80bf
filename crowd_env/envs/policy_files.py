"""Trained policies as small files: one format for every learner, read and run with numpy alone.

A policy file (``.npz``) holds a multilayer perceptron that maps one agent's observation to its action,
plus what is needed to use it correctly: the environment options it was trained with (its observation
layout, decision interval and action bound), its training cost and where it came from. The same file is
written for a PPO policy (Stable-Baselines3), a MAPPO / IPPO actor (TorchRL) and a behaviour-cloned
network, so the evaluation, the reference results and the shipped reference policies (``baselines.trained``) load
them one way, without torch:

- ``x = (obs - obs_mean) / obs_std``, then hidden layers ``x = act(x W_i + b_i)`` (``act``: tanh or relu),
  then the output layer ``y = x W + b``;
- the action from ``y`` by ``output``: ``"clip_box"`` (SB3's deterministic action: the Gaussian mean,
  clipped to the action Box, as SB3's ``predict`` does), ``"tanh_box"`` (TorchRL's TanhNormal: the first
  half of ``y`` is the location, mapped into the Box by ``low + (high - low) (tanh(loc) + 1) / 2``) or
  ``"linear"`` (a regression: ``y`` itself; it must lie in the Box, which the environment checks).

:func:`from_sb3` and :func:`from_torchrl` convert trained models; tests check each against the framework's
own forward pass on the same observations (two independent implementations).

A policy file is data: it is read with ``allow_pickle=False``, so nothing in it runs. The ``.pt`` files of
``crowd-train-mappo`` are read with torch's weights-only loader (:func:`load_weights`), which refuses anything but
numbers, strings, lists, dicts and tensors before any of it runs.
"""
from __future__ import annotations

import json
import os
import pickle
import re
from dataclasses import dataclass, field

import numpy as np

from crowd_env.errors import PolicyError, UntrustedFileError

from crowd_env.files import write_npz_atomic

__all__ = ["POLICY_FILE_FORMAT", "OUTPUTS", "ACTIVATIONS", "MLPPolicyFile", "save_policy_file", "load_policy_file",
           "load_weights", "from_sb3", "from_torchrl"]

POLICY_FILE_FORMAT = "crowd_env.mlp_policy/1"
OUTPUTS = ("clip_box", "tanh_box", "linear")
ACTIVATIONS = ("tanh", "relu")


@dataclass
class MLPPolicyFile:
    """A shared per-agent MLP policy (see the module docstring for the forward pass).

    ``weights`` / ``biases``: one (in, out) matrix and (out,) vector per layer; ``low`` / ``high``: the action
    Box it was trained in; ``env_config``: the environment options of its training (observation layout,
    ``frame_skip``, ``action_max_m_s`` ...); ``meta``: algorithm, training cost, provenance."""

    weights: list
    biases: list
    activation: str
    output: str
    low: np.ndarray
    high: np.ndarray
    obs_mean: np.ndarray
    obs_std: np.ndarray
    env_config: dict = field(default_factory=dict)
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.activation not in ACTIVATIONS:
            raise PolicyError(f"activation must be one of {ACTIVATIONS}, got {self.activation!r}")
        if self.output not in OUTPUTS:
            raise PolicyError(f"output must be one of {OUTPUTS}, got {self.output!r}")
        self.weights = [np.asarray(w, np.float64) for w in self.weights]
        self.biases = [np.asarray(b, np.float64) for b in self.biases]
        if not self.weights or len(self.weights) != len(self.biases):
            raise PolicyError("a policy file needs one bias per weight matrix and at least one layer")
        for i, (w, b) in enumerate(zip(self.weights, self.biases)):
            if w.ndim != 2 or b.shape != (w.shape[1],) or (i and w.shape[0] != self.weights[i - 1].shape[1]):
                raise PolicyError(f"layer {i}: weight {w.shape} and bias {b.shape} do not chain")
        self.low = np.asarray(self.low, np.float64)
        self.high = np.asarray(self.high, np.float64)
        self.obs_mean = np.asarray(self.obs_mean, np.float64)
        self.obs_std = np.asarray(self.obs_std, np.float64)
        if self.obs_mean.shape != (self.obs_dim,) or self.obs_std.shape != (self.obs_dim,) or np.any(self.obs_std <= 0):
            raise PolicyError(f"obs_mean and obs_std must be ({self.obs_dim},) with obs_std > 0")
        want = 2 * self.action_dim if self.output == "tanh_box" else self.action_dim
        if self.weights[-1].shape[1] != want:
            raise PolicyError(f"output {self.output!r} needs {want} outputs for a {self.action_dim}-d action, the "
                              f"last layer has {self.weights[-1].shape[1]}")

    @property
    def obs_dim(self) -> int:
        return int(self.weights[0].shape[0])

    @property
    def action_dim(self) -> int:
        return int(self.low.shape[0])

    @property
    def n_parameters(self) -> int:
        return int(sum(w.size + b.size for w, b in zip(self.weights, self.biases)))

    def actions(self, observations) -> np.ndarray:
        """Deterministic actions (n, action_dim) float32 for observations (n, obs_dim)."""
        x = np.asarray(observations, np.float64)
        if x.ndim != 2 or x.shape[1] != self.obs_dim:
            raise PolicyError(f"the policy expects observations of shape (n, {self.obs_dim}), got {x.shape} (use "
                              "the n_neighbors / n_rays / observation_frame it was trained with: its env_config)")
        x = (x - self.obs_mean) / self.obs_std
        act = np.tanh if self.activation == "tanh" else (lambda v: np.maximum(v, 0.0))
        for w, b in zip(self.weights[:-1], self.biases[:-1]):
            x = act(x @ w + b)
        y = x @ self.weights[-1] + self.biases[-1]
        if self.output == "clip_box":
            y = np.clip(y, self.low, self.high)
        elif self.output == "tanh_box":
            y = self.low + (self.high - self.low) * (np.tanh(y[:, :self.action_dim]) + 1.0) / 2.0
        return y.astype(np.float32)


def save_policy_file(policy: MLPPolicyFile, path: str) -> str:
    """Write ``policy`` to ``path`` (``.npz``, compressed, written atomically: :func:`~crowd_env.files.write_npz_atomic`)."""
    meta = {"format": POLICY_FILE_FORMAT, "activation": policy.activation, "output": policy.output,
            "n_layers": len(policy.weights), "env_config": policy.env_config, "meta": policy.meta}
    arrays = {"low": policy.low, "high": policy.high, "obs_mean": policy.obs_mean, "obs_std": policy.obs_std}
    for i, (w, b) in enumerate(zip(policy.weights, policy.biases)):
        arrays[f"w{i}"] = w.astype(np.float32)
        arrays[f"b{i}"] = b.astype(np.float32)
    write_npz_atomic(path, meta, **arrays)
    return path


def load_policy_file(path: str) -> MLPPolicyFile:
    """The policy saved by :func:`save_policy_file`; :class:`~crowd_env.errors.PolicyError` naming the file when
    it is missing or not such a file."""
    if not os.path.isfile(path):
        raise PolicyError(f"no policy file at {path}")
    try:
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            if meta.get("format") != POLICY_FILE_FORMAT:
                raise PolicyError(f"{path} is a {meta.get('format')!r} file, not {POLICY_FILE_FORMAT!r}")
            n = int(meta["n_layers"])
            return MLPPolicyFile([data[f"w{i}"] for i in range(n)], [data[f"b{i}"] for i in range(n)],
                                 meta["activation"], meta["output"], data["low"], data["high"], data["obs_mean"],
                                 data["obs_std"], meta.get("env_config", {}), meta.get("meta", {}))
    except (OSError, ValueError, KeyError) as exc:
        raise PolicyError(f"{path} is not a crowd_env policy file: {exc}") from None


def load_weights(source, what: str):
    """What ``torch.save`` wrote to ``source`` (a path, or a file object read from one), read with torch's
    weights-only loader: numbers, strings, lists, dicts and tensors only (``what``: the kind of file, for the
    messages). Anything else in it, e.g. an object that would run code when unpickled, raises
    :class:`~crowd_env.errors.UntrustedFileError` naming the file and what it holds before any of it runs; what
    torch cannot read raises :class:`~crowd_env.errors.PolicyError`."""
    import torch

    name = getattr(source, "name", source)
    try:
        return torch.load(source, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as exc:
        found = re.search(r"GLOBAL (\S+)", str(exc))
        held = f"a reference to {found.group(1)}" if found else "objects other than data"
        raise UntrustedFileError(f"{name} holds {held}, not only the numbers, strings, lists, dicts and tensors of a "
                                 f"{what}: refused without running anything in it (load only files from sources "
                                 f"you trust; share policies as .npz: crowd-convert-policy)") from None
    except Exception as exc:  # torch raises RuntimeError, KeyError, EOFError ... for what is no torch file
        raise PolicyError(f"{name} is not a {what} (torch cannot read it: {type(exc).__name__}: {exc})") from None


def _linear_layers(modules) -> tuple:
    import torch

    weights, biases, acts = [], [], set()
    for m in modules:
        if isinstance(m, torch.nn.Linear):
            weights.append(m.weight.detach().cpu().numpy().T.copy())
            biases.append(m.bias.detach().cpu().numpy().copy())
        elif isinstance(m, torch.nn.Tanh):
            acts.add("tanh")
        elif isinstance(m, torch.nn.ReLU):
            acts.add("relu")
    if len(acts) > 1:
        raise PolicyError(f"mixed activations {sorted(acts)} cannot be stored")
    return weights, biases, (acts.pop() if acts else "tanh")


def from_sb3(model, *, env_config: dict, meta: dict | None = None) -> MLPPolicyFile:
    """The deterministic actor of an SB3 PPO ``MlpPolicy`` (policy branch of the MLP extractor, then the action
    head; no observation normalisation: crowd_env's training uses none)."""
    pol = model.policy
    w, b, act = _linear_layers(pol.mlp_extractor.policy_net.modules())
    head_w, head_b, _ = _linear_layers([pol.action_net])
    space = model.action_space
    d = int(np.prod(model.observation_space.shape))
    return MLPPolicyFile(w + head_w, b + head_b, act, "clip_box", space.low, space.high, np.zeros(d), np.ones(d),
                         dict(env_config), dict(meta or {}))


def from_torchrl(policy, *, env_config: dict, meta: dict | None = None) -> MLPPolicyFile:
    """The deterministic actor of a :class:`~crowd_env.experiments.training.marl.TorchRLPolicy` (its MLP; the
    location half of the output through the TanhNormal's map into the Box)."""
    mlp = policy.net[0]
    w, b, act = _linear_layers(mlp.modules())
    d = policy.obs_dim
    return MLPPolicyFile(w, b, act, "tanh_box", policy.low.numpy(), policy.high.numpy(), np.zeros(d), np.ones(d),
                         dict(env_config), dict(meta or {}))
