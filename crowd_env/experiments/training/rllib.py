"""PPO through RLlib (Ray): one policy shared by every controlled pedestrian, locally or on a Ray cluster.

The PettingZoo parallel environment (:mod:`crowd_env.envs.crowd_v0`) is registered with RLlib as
``"crowd_v0"`` through ``ParallelPettingZooEnv``; ``policy_mapping_fn`` maps every agent to the one
module ``"shared"``, so every pedestrian's experience trains the same network (RLlib's default PPO
module: separate policy and value MLPs on the agent's own observation, a diagonal Gaussian whose
actions are scaled to the action Box, ``normalize_actions``). RLlib's new API stack (RLModule, Learner,
EnvRunner, the default in Ray 2.60) records agents that leave: a pedestrian's single-agent episode
ends on the step it leaves (``terminated``), the others go on, and the episode ends when none is left;
when the last ones are truncated while others left, RLlib declares the episode terminated.

Where it runs: :class:`~crowd_env.experiments.running.backends.RayBackend` starts Ray locally
(``num_cpus``) or, with ``address`` (``host:port``, ``ray://host:port`` or ``auto``), joins a running
cluster through the same code path, after :func:`~crowd_env.experiments.running.backends.check_reachable` has
refused an unreachable address within seconds. ``num_env_runners`` remote EnvRunners sample in
parallel (0: sampling in the driver); cluster nodes need ``crowd_env`` installed.

Outputs of :func:`train` in ``out``: ``progress.csv`` (one row per iteration, :data:`CSV_COLUMNS`,
also printed; returns and lengths are RLlib's running means over the last episodes, per agent),
``policy/`` (the trained RLModule; :func:`load_policy` makes it a policy of the evaluation harness),
``policy.json`` (its action bounds and observation size), ``env_config.json``, ``summary.json`` (mean
per-agent episode return of the random policy and of the trained one, deterministic, on the same
evaluation seeds, through :mod:`crowd_env.experiments.running.evaluation`) and ``checkpoints/`` (RLlib
algorithm checkpoints, ``index.json`` written last: ``resume`` continues from the latest; a folder with
checkpoints is refused without it, and resuming with other environment options is refused, by
:func:`crowd_env.experiments.training.ppo.check_resume`; each checkpoint's index entry carries the digest of its
files under this account's key, and one without a matching digest is never restored:
:func:`~crowd_env.experiments.training.ppo.check_checkpoint`). ``policy/`` is RLlib's own format, which holds
pickles: load a run folder only from a source you trust.

Needs the ``marl`` extra (``ray[rllib]``), imported inside the functions. Command line:
``crowd-train-rllib``; docs/training.md compares it with the other training stacks.
"""
from __future__ import annotations

import importlib.util
import json
import os
import shutil
import time

import numpy as np

from ...core.checks import check_integer
from ...envs import crowd_v0
from crowd_env.errors import MissingDependencyError, TrainingError
from ..running.backends import RayBackend, check_reachable
from crowd_env.files import write_json_atomic
from .ppo import (SharedPolicy, begin_run, check_checkpoint, evaluate_trained, read_checkpoints, sign_checkpoint,
                  write_progress)

__all__ = ["ENV_NAME", "MODULE_ID", "CSV_COLUMNS", "DEFAULT_PPO", "RLlibPolicy", "env_creator", "ppo_config",
           "load_policy", "train"]

ENV_NAME = "crowd_v0"
MODULE_ID = "shared"
CSV_COLUMNS = ("iteration", "env_steps", "agent_steps", "episodes", "mean_episode_return", "mean_episode_length",
               "policy_loss", "vf_loss", "entropy", "total_loss", "wall_s")
DEFAULT_PPO = {"train_batch_size": 2000, "minibatch_size": 500, "num_epochs": 10, "learning_rate": 3e-4,
               "gamma": 0.99, "lambda_": 0.95, "entropy_coeff": 1e-3, "hidden": (64, 64)}
POLICY_FORMAT = "crowd_env.rllib.policy/1"


def _require():
    if importlib.util.find_spec("ray") is None or importlib.util.find_spec("ray.rllib") is None:
        raise MissingDependencyError("RLlib training needs the 'marl' extra (ray[rllib]): pip install 'crowd_env[marl]'")


def env_creator(config: dict):
    """RLlib's environment: ``ParallelPettingZooEnv(crowd_v0.parallel_env(**config))``."""
    from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv

    return ParallelPettingZooEnv(crowd_v0.parallel_env(**dict(config)))


def _map_to_shared(agent_id, episode, **kwargs):
    return MODULE_ID


def ppo_config(env_config: dict, *, seed: int = 0, num_env_runners: int = 0,
               train_batch_size: int = DEFAULT_PPO["train_batch_size"],
               minibatch_size: int = DEFAULT_PPO["minibatch_size"], num_epochs: int = DEFAULT_PPO["num_epochs"],
               learning_rate: float = DEFAULT_PPO["learning_rate"], gamma: float = DEFAULT_PPO["gamma"],
               lambda_: float = DEFAULT_PPO["lambda_"], entropy_coeff: float = DEFAULT_PPO["entropy_coeff"],
               hidden=DEFAULT_PPO["hidden"]):
    """The ``PPOConfig``: the registered crowd environment, every agent on module ``"shared"``."""
    _require()
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig
    from ray.tune.registry import register_env

    register_env(ENV_NAME, env_creator)
    return (PPOConfig()
            .environment(ENV_NAME, env_config=dict(env_config))
            .multi_agent(policies={MODULE_ID}, policy_mapping_fn=_map_to_shared)
            .env_runners(num_env_runners=int(num_env_runners))
            .rl_module(model_config=DefaultModelConfig(fcnet_hiddens=list(hidden)))
            .training(train_batch_size_per_learner=int(train_batch_size), minibatch_size=int(minibatch_size),
                      num_epochs=int(num_epochs), lr=float(learning_rate), gamma=float(gamma), lambda_=float(lambda_),
                      entropy_coeff=float(entropy_coeff))
            .debugging(seed=int(seed)))


class RLlibPolicy(SharedPolicy):
    """A trained RLlib module as a policy of the evaluation harness (``act(env, observations)``): the
    deterministic action (the Gaussian's mean) scaled to the action Box as RLlib's EnvRunner does
    (``normalize_actions``: [-1, 1] -> [low, high], then clipped), for every live agent in one batch."""

    def __init__(self, module, obs_dim: int, low, high, normalize_actions: bool = True, name: str = "rllib_ppo"):
        self.module = module
        self.obs_dim = int(obs_dim)
        self.low = np.asarray(low, dtype=np.float32)
        self.high = np.asarray(high, dtype=np.float32)
        self.normalize_actions = bool(normalize_actions)
        self.name = name

    def actions(self, observations: np.ndarray) -> np.ndarray:
        """Deterministic actions (n, 2) float32 for observations (n, obs_dim)."""
        import torch

        with torch.no_grad():
            out = self.module.forward_inference({"obs": torch.as_tensor(np.asarray(observations, dtype=np.float32))})
            dist = self.module.get_inference_action_dist_cls().from_logits(out["action_dist_inputs"])
            a = dist.to_deterministic().sample().numpy().astype(np.float32)
        if self.normalize_actions:
            a = self.low + (np.clip(a, -1.0, 1.0) + 1.0) * (self.high - self.low) / 2.0
        return np.clip(a, self.low, self.high)


def load_policy(path: str, name: str | None = None) -> RLlibPolicy:
    """The policy saved by :func:`train` (``path``: the run folder, holding ``policy/`` and ``policy.json``).
    RLlib's checkpoint holds pickles, which run code when loaded: load only run folders you trust."""
    _require()
    from ray.rllib.core.rl_module.rl_module import RLModule

    meta_path = os.path.join(path, "policy.json")
    if not os.path.exists(meta_path):
        raise TrainingError(f"no saved RLlib policy in {path} (policy.json missing)")
    with open(meta_path) as fh:
        meta = json.load(fh)
    if meta.get("format") != POLICY_FORMAT:
        raise TrainingError(f"{meta_path} is not a policy saved by crowd_env.experiments.training.rllib")
    module = RLModule.from_checkpoint(os.path.join(path, "policy"))
    return RLlibPolicy(module, meta["obs_dim"], meta["low"], meta["high"], meta["normalize_actions"],
                       name=name or "rllib_ppo")


def _row(result: dict, iteration: int, wall_s: float) -> dict:
    runners = result.get("env_runners", {})
    learner = result.get("learners", {}).get(MODULE_ID, {})
    per_agent = runners.get("agent_episode_returns_mean") or {}
    agent_steps = runners.get("num_agent_steps_sampled") or {}
    nan = float("nan")
    return {"iteration": iteration, "env_steps": int(result.get("num_env_steps_sampled_lifetime", 0)),
            "agent_steps": int(sum(agent_steps.values())) if isinstance(agent_steps, dict) else int(agent_steps),
            "episodes": int(runners.get("num_episodes", 0)),
            "mean_episode_return": float(np.mean(list(per_agent.values()))) if per_agent else nan,
            "mean_episode_length": float(runners.get("episode_len_mean", nan)),
            "policy_loss": float(learner.get("policy_loss", nan)), "vf_loss": float(learner.get("vf_loss", nan)),
            "entropy": float(learner.get("entropy", nan)), "total_loss": float(learner.get("total_loss", nan)),
            "wall_s": wall_s}


def _save_checkpoint(algo, out: str, env_steps: int, iteration: int, rows) -> None:
    entries = read_checkpoints(out)
    if entries and entries[-1]["timesteps"] >= env_steps:
        return
    name = f"iter_{iteration:06d}"
    folder = os.path.join(out, "checkpoints")
    os.makedirs(folder, exist_ok=True)
    tmp = os.path.join(folder, name + ".tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    algo.save_to_path(os.path.abspath(tmp))
    write_json_atomic(os.path.join(tmp, "progress.json"), rows)
    shutil.rmtree(os.path.join(folder, name), ignore_errors=True)
    os.replace(tmp, os.path.join(folder, name))
    entry = sign_checkpoint(out, {"timesteps": env_steps, "model": name, "iteration": iteration})
    write_json_atomic(os.path.join(folder, "index.json"), {"checkpoints": entries + [entry]})


def train(env_config: dict, timesteps: int, out: str, *, resolve, address: str | None = None,
          num_cpus: int | None = None, num_env_runners: int = 0, seed: int = 0,
          train_batch_size: int = DEFAULT_PPO["train_batch_size"], minibatch_size: int = DEFAULT_PPO["minibatch_size"],
          num_epochs: int = DEFAULT_PPO["num_epochs"], learning_rate: float = DEFAULT_PPO["learning_rate"],
          gamma: float = DEFAULT_PPO["gamma"], lambda_: float = DEFAULT_PPO["lambda_"],
          entropy_coeff: float = DEFAULT_PPO["entropy_coeff"], hidden=DEFAULT_PPO["hidden"],
          eval_seeds=(1000, 1001, 1002), checkpoint_every: int = 1, resume: bool = False,
          connect_timeout_s: float = 5.0, progress=print) -> dict:
    """Train RLlib PPO for ``timesteps`` environment steps (sampled, in all); returns the summary (also
    written to ``out/summary.json``); see the module docstring for the outputs.

    ``resolve(spec, name=None) -> policy`` makes the random policy of the comparison (``resolve("random")``).
    ``address``: None starts Ray locally with ``num_cpus`` (default ``num_env_runners + 1``), otherwise
    joins that cluster (an unreachable one raises :class:`~crowd_env.errors.BackendError` within
    ``connect_timeout_s``). A checkpoint is written every ``checkpoint_every`` iterations (0: only at the
    end); ``resume`` continues from the latest one.
    """
    for name, value in (("timesteps", timesteps), ("train_batch_size", train_batch_size),
                        ("minibatch_size", minibatch_size), ("num_epochs", num_epochs)):
        check_integer(name, value, error=TrainingError, minimum=1)
    if checkpoint_every < 0 or num_env_runners < 0:
        raise TrainingError(f"checkpoint_every and num_env_runners must be >= 0, got {checkpoint_every!r} and "
                            f"{num_env_runners!r}")
    if address is not None:
        check_reachable(address, connect_timeout_s)  # before anything else: fail in seconds
    _require()
    policy_meta = _policy_meta(env_config)
    t0 = time.perf_counter()
    entries, before = begin_run(out, env_config, resume=resume, resolve=resolve, eval_seeds=eval_seeds, seed=seed,
                                progress=progress)

    config = ppo_config(env_config, seed=seed, num_env_runners=num_env_runners, train_batch_size=train_batch_size,
                        minibatch_size=minibatch_size, num_epochs=num_epochs, learning_rate=learning_rate, gamma=gamma,
                        lambda_=lambda_, entropy_coeff=entropy_coeff, hidden=hidden)
    local_cpus = num_cpus if num_cpus is not None else int(num_env_runners) + 1
    with RayBackend(address=address, num_cpus=None if address else local_cpus,
                    connect_timeout_s=connect_timeout_s) as backend:
        algo = config.build_algo()
        rows, start = _restore(algo, out, entries, progress)
        t1 = time.perf_counter()
        env_steps, iteration = _iterate(algo, out, rows, start, timesteps, checkpoint_every, progress)
        if rows:
            _save_checkpoint(algo, out, env_steps, iteration, rows)
        train_s = time.perf_counter() - t1
        write_progress(out, rows, CSV_COLUMNS)
        module = algo.get_module(MODULE_ID)
        policy_dir = os.path.join(out, "policy")
        shutil.rmtree(policy_dir, ignore_errors=True)
        module.save_to_path(os.path.abspath(policy_dir))
        write_json_atomic(os.path.join(out, "policy.json"),
                           {**policy_meta, "normalize_actions": bool(config.normalize_actions), "module_id": MODULE_ID})
        cluster_cpus = backend.n_workers
        algo.stop()

    trained = load_policy(out, name="rllib_ppo")
    after = evaluate_trained(trained, env_config, eval_seeds, progress)
    summary = {"algorithm": "rllib_ppo", "env_steps": env_steps, "resumed_from_env_steps": start,
               "agent_steps": int(sum(r["agent_steps"] for r in rows)), "iterations": iteration,
               "train_wall_s": train_s, "total_wall_s": time.perf_counter() - t0, "random": before, "trained": after,
               "improvement": after["mean_return"] - before["mean_return"], "env_config": env_config,
               "eval_seeds": list(eval_seeds), "seed": seed, "address": address, "cluster_cpus": cluster_cpus,
               "num_env_runners": num_env_runners,
               "ppo": {"train_batch_size": train_batch_size, "minibatch_size": minibatch_size, "num_epochs": num_epochs,
                       "learning_rate": learning_rate, "gamma": gamma, "lambda_": lambda_,
                       "entropy_coeff": entropy_coeff, "hidden": list(hidden)}}
    write_json_atomic(os.path.join(out, "summary.json"), summary)
    return summary


def _iterate(algo, out: str, rows: list, start: int, timesteps: int, checkpoint_every: int, progress) -> tuple:
    """RLlib training iterations until ``timesteps`` environment steps, each a row appended to ``rows`` and
    ``out/progress.csv``, a checkpoint every ``checkpoint_every``; (environment steps, iterations) done."""
    env_steps = start
    iteration = rows[-1]["iteration"] if rows else 0
    while env_steps < timesteps:
        t_iter = time.perf_counter()
        result = algo.train()
        iteration += 1
        row = _row(result, iteration, time.perf_counter() - t_iter)
        env_steps = row["env_steps"]
        rows.append(row)
        write_progress(out, rows, CSV_COLUMNS)
        progress(f"iter {iteration:4d} | env steps {env_steps:8d} | episodes {row['episodes']:3d} | return "
                 f"{row['mean_episode_return']:8.3f} | length {row['mean_episode_length']:6.1f} | loss pi "
                 f"{row['policy_loss']:+.4f} v {row['vf_loss']:.4f} | entropy {row['entropy']:.3f}")
        if checkpoint_every and iteration % checkpoint_every == 0:
            _save_checkpoint(algo, out, env_steps, iteration, rows)
    return env_steps, iteration


def _policy_meta(env_config: dict) -> dict:
    """The policy file's description from a probe environment (bad options fail here, not inside a Ray actor)."""
    probe = crowd_v0.parallel_env(**env_config)
    agent = probe.possible_agents[0]
    return {"format": POLICY_FORMAT, "obs_dim": int(probe.observation_space(agent).shape[0]),
            "low": probe.action_space(agent).low.tolist(), "high": probe.action_space(agent).high.tolist()}


def _restore(algo, out: str, entries: list, progress) -> tuple:
    """(progress rows, environment steps done): ``algo`` restored from the latest checkpoint of ``entries``, or
    ([], 0) for a fresh run."""
    if not entries:
        return [], 0
    path = os.path.join(out, "checkpoints", entries[-1]["model"])
    check_checkpoint(out, entries[-1])  # RLlib's checkpoints hold pickles: restored only when this account wrote them
    algo.restore_from_path(os.path.abspath(path))
    with open(os.path.join(path, "progress.json")) as fh:
        rows = json.load(fh)
    start = int(entries[-1]["timesteps"])
    progress(f"resuming from the checkpoint at {start} environment steps (iteration {rows[-1]['iteration']})")
    return rows, start
