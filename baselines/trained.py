"""Trained reference policies shipped with crowd_env, loadable by name without training.

Each is a :mod:`policy file <crowd_env.envs.policy_files>` in ``baselines/trained/`` (``<name>.npz``),
written by ``crowd-reference-results`` (docs/validation/reference_results.md: how each was trained, on which task, and
how it compares with the calibrated model). A file policy acts with the environment options it was
trained with (observation layout, decision interval, action bound), which it names in ``env_overrides``
so the evaluation harness applies them::

    from baselines.trained import load_trained, list_trained
    policy = load_trained("bottleneck_bc")       # also: as_policy("bottleneck_bc"), crowd-evaluate --policy
    env = crowd_v0.parallel_env(controlled=6, background_policy="bottleneck_ppo")  # the others: a trained policy

The environment finds :func:`background_policy` through the ``crowd_env_background_policies`` entry point
(``pyproject.toml``), so that crowd_env never imports this package.

Inference is numpy only (no torch).
"""
from __future__ import annotations

import os

from crowd_env.envs.background import FileObservationPolicy
from crowd_env.errors import NotFoundError

from .policy import EnvPolicy, stack_observations

__all__ = ["FilePolicy", "TRAINED_DIR", "list_trained", "load_trained", "file_policy", "background_policy"]

TRAINED_DIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "trained")


class FilePolicy(FileObservationPolicy, EnvPolicy):
    """A policy file's MLP shared by all live agents, one batched forward pass per decision: the environment's
    :class:`~crowd_env.envs.background.FileObservationPolicy` with the agent interface (:meth:`reset`, :meth:`act`)."""

    def reset(self, env, seed=None) -> None:
        have = env.observation_space(env.possible_agents[0]).shape
        if tuple(have) != (self.obs_dim,):
            raise ValueError(f"policy {self.name!r} expects observations of size {self.obs_dim}, the environment "
                             f"gives {have} (use its options: {self.env_overrides})")

    def act(self, env, observations) -> dict:
        if not env.agents:
            return {}
        return dict(zip(env.agents, self.file.actions(stack_observations(env, observations))))


def list_trained() -> list:
    """Names of the shipped trained policies (``baselines/trained/<name>.npz``)."""
    if not os.path.isdir(TRAINED_DIR):
        return []
    return sorted(f[:-4] for f in os.listdir(TRAINED_DIR) if f.endswith(".npz"))


def load_trained(name: str) -> FilePolicy:
    """The shipped policy ``name`` (see :func:`list_trained`); ``ValueError`` naming the shipped ones otherwise."""
    path = os.path.join(TRAINED_DIR, f"{name}.npz")
    if not os.path.isfile(path):
        raise ValueError(f"no shipped trained policy {name!r}; shipped: {', '.join(list_trained()) or 'none'}")
    return FilePolicy(path, name=name)


def file_policy(spec: str, name: str | None = None) -> FilePolicy | None:
    """The policy of a shipped trained policy's name or of a policy file (``.npz``), named ``name`` when
    given; None for anything else."""
    if spec in list_trained():
        p = load_trained(spec)
        p.name = name or p.name
        return p
    if spec.endswith(".npz"):
        return FilePolicy(spec, name=name)
    return None


def background_policy(spec: str) -> FilePolicy:
    """The environment's loader of named background policies (entry point ``crowd_env_background_policies``):
    :func:`file_policy`; :class:`~crowd_env.errors.NotFoundError` (a ``LookupError``) naming the shipped ones
    for anything else."""
    p = file_policy(spec)
    if p is not None:
        return p
    raise NotFoundError(f"not a shipped trained policy ({', '.join(list_trained()) or 'none shipped'}) nor a "
                      f"policy file (.npz): {spec!r}")
