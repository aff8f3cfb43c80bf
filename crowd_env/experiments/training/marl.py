"""MAPPO and IPPO through TorchRL: one policy network shared by every controlled pedestrian.

The PettingZoo parallel environment (:mod:`crowd_env.envs.crowd_v0`) is wrapped by TorchRL's
``PettingZooWrapper`` with every agent in one group (``"agents"``, tensors ``[n_agents, ...]``),
``use_mask=True`` and ``done_on_any=False``: a pedestrian that leaves gets ``mask`` False, zero
observations and rewards and ``done`` True until the episode ends, which is when every agent is done
(its last reward and its ``terminated`` / ``truncated`` flag arrive on the step it leaves). The wrapper
is subclassed (:func:`make_env`) so that only the live agents' actions reach ``env.step`` (the crowd
environment refuses actions for agents that have left).

Networks (:func:`build_networks`), in the pattern of TorchRL's multi-agent PPO tutorial:

- the policy: an MLP from one agent's observation to the location and scale of a TanhNormal over the
  action Box, applied to each agent with the same weights (what ``MultiAgentMLP(share_params=True,
  centralised=False)`` computes; a plain MLP also takes the flat batches of per-agent transitions below);
- the critic, also shared over agents: ``ippo`` gives it the agent's own observation, V(o_i); ``mappo``
  the agent's observation and the environment's global state ``env.state()`` (fixed size,
  :mod:`crowd_env.envs.state`; TorchRL reads it as the ``"state"`` entry with ``return_state=True``),
  V(o_i, s): centralised training with decentralised execution, with the per-agent rewards of the
  environment each agent keeps its own value (the "agent-specific global state" of Yu et al. 2022).

Each iteration the ``Collector`` gathers ``frames_per_batch`` environment steps (each carries up to
n_agents transitions) with the stochastic policy; GAE is computed per agent on the ``[time, agent]``
batch (an agent's ``done`` stops its bootstrap); the transitions of live agents (``mask``) are flattened
into one batch and ``ClipPPOLoss`` (normalised advantages, entropy bonus) trains for ``num_epochs``
passes of shuffled minibatches. The agents that have left are thus never trained on and never bias the
advantage normalisation.

Outputs of :func:`train` in ``out``: ``progress.csv`` (one row per iteration, :data:`CSV_COLUMNS`,
also printed), ``policy.pt`` (the policy's weights and its shapes; :func:`load_policy` rebuilds it as a
policy of the evaluation harness), ``env_config.json``, ``summary.json`` (mean per-agent episode
return of the random policy and of the trained one, deterministic, on the same evaluation seeds, through
:mod:`crowd_env.experiments.running.evaluation`) and ``checkpoints/`` (networks, optimiser, progress, indexed
last and atomically as :mod:`crowd_env.experiments.training.ppo` does; ``resume`` continues from the latest).
Both are data only (numbers, strings, lists, dicts and tensors) and are read back with torch's weights-only
loader (:func:`~crowd_env.envs.policy_files.load_weights`): a ``.pt`` file holding anything else, e.g. an object that would run code when
unpickled, is refused (:class:`~crowd_env.errors.UntrustedFileError`) without anything in it running.

Needs the ``marl`` extra (torchrl, tensordict), imported inside the functions. Command line:
``crowd-train-mappo``; docs/training.md compares it with the other training stacks.
"""
from __future__ import annotations

import functools
import importlib.util
import io
import os
import time
import warnings

import numpy as np

from ...core.checks import check_integer
from ...envs import crowd_v0
from ...envs.policy_files import load_weights
from crowd_env.errors import MissingDependencyError, TrainingError
from crowd_env.files import write_atomic, write_json_atomic
from .ppo import SharedPolicy, begin_run, evaluate_trained, read_checkpoints, write_progress

__all__ = ["ALGORITHMS", "GROUP", "CSV_COLUMNS", "DEFAULT_PPO", "TorchRLPolicy", "check_algorithm", "make_env",
           "build_networks", "make_loss", "valid_transitions", "load_policy", "train"]

ALGORITHMS = ("mappo", "ippo")
GROUP = "agents"
CSV_COLUMNS = ("iteration", "frames", "agent_steps", "episodes", "mean_episode_return", "mean_episode_length",
               "loss_objective", "loss_critic", "loss_entropy", "entropy", "wall_s")
DEFAULT_PPO = {"frames_per_batch": 1000, "num_epochs": 10, "minibatch_size": 500, "learning_rate": 3e-4,
               "clip_epsilon": 0.2, "gamma": 0.99, "lmbda": 0.95, "entropy_coeff": 1e-3, "max_grad_norm": 1.0,
               "hidden": (64, 64)}
POLICY_FORMAT = "crowd_env.marl.policy/1"


def _require():
    missing = [name for name in ("torchrl", "tensordict") if importlib.util.find_spec(name) is None]
    if missing:
        raise MissingDependencyError(f"MAPPO/IPPO training needs the 'marl' extra (missing: {', '.join(missing)}): "
                                     "pip install 'crowd_env[marl]'")


def check_algorithm(algorithm: str) -> str:
    """``algorithm`` if it is one of :data:`ALGORITHMS`, else :class:`~crowd_env.errors.TrainingError`."""
    if algorithm not in ALGORITHMS:
        raise TrainingError(f"unknown algorithm {algorithm!r}: choose one of {list(ALGORITHMS)}")
    return algorithm


@functools.lru_cache(maxsize=None)
def _wrapper_class():
    from torchrl.envs.libs.pettingzoo import PettingZooWrapper

    class CrowdPettingZooWrapper(PettingZooWrapper):
        """TorchRL's PettingZoo wrapper sending actions of the live agents only."""

        def _step_parallel(self, tensordict):
            live = set(self._env.agents)
            actions = {}
            for group, agents in self.group_map.items():
                spec = self.input_spec["full_action_spec", group, "action"]
                values = spec.to_numpy(tensordict.get((group, "action")))
                for index, agent in enumerate(agents):
                    if agent in live:
                        actions[agent] = values[index]
            return self._env.step(actions)

    return CrowdPettingZooWrapper


def make_env(env_config: dict, *, state: bool = False, seed: int | None = None):
    """The TorchRL environment: the crowd environment in one agent group ``"agents"`` with masks, episode
    returns per agent (``("agents", "episode_reward")``) and the step count (``"step_count"``); with
    ``state`` also the global state ``"state"`` (``env.state()``, for MAPPO's critic)."""
    _require()
    from torchrl.envs import Compose, RewardSum, StepCounter, TransformedEnv

    base = crowd_v0.parallel_env(**env_config)
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="PettingZoo in TorchRL is tested")
        env = _wrapper_class()(base, return_state=state, group_map={GROUP: list(base.possible_agents)},
                               use_mask=True, categorical_actions=False, done_on_any=False, seed=seed)
    return TransformedEnv(env, Compose(RewardSum(in_keys=[(GROUP, "reward")], out_keys=[(GROUP, "episode_reward")]),
                                       StepCounter()))


def _actor_net(obs_dim: int, action_dim: int, hidden):
    import torch
    from tensordict.nn import NormalParamExtractor
    from torchrl.modules import MLP

    return torch.nn.Sequential(MLP(in_features=obs_dim, out_features=2 * action_dim, num_cells=list(hidden),
                                   activation_class=torch.nn.Tanh),
                               NormalParamExtractor())


def _critic_net(obs_dim: int, state_dim: int, hidden):
    """V(o_i) (``state_dim`` 0) or V(o_i, s): an MLP on the observation, concatenated with the state
    broadcast over the agent dimension when the batch has one."""
    import torch
    from torchrl.modules import MLP

    class Critic(torch.nn.Module):
        def __init__(self):
            super().__init__()
            self.mlp = MLP(in_features=obs_dim + state_dim, out_features=1, num_cells=list(hidden),
                           activation_class=torch.nn.Tanh)

        def forward(self, observation, state=None):
            if state is None:
                return self.mlp(observation)
            if state.dim() < observation.dim():  # [..., S] -> [..., n_agents, S]
                state = state.unsqueeze(-2).expand(*observation.shape[:-1], state.shape[-1])
            return self.mlp(torch.cat([observation, state], dim=-1))

    return Critic()


def build_networks(env, algorithm: str, hidden=DEFAULT_PPO["hidden"]):
    """``(actor, critic)`` TensorDict modules for ``env`` (from :func:`make_env`): the shared stochastic
    policy (TanhNormal over the action Box, writing ``("agents", "action")`` and its log-probability) and
    the shared critic (``("agents", "state_value")``) of ``algorithm`` (see the module docstring)."""
    check_algorithm(algorithm)
    import torch
    from tensordict.nn import TensorDictModule
    from torchrl.modules import ProbabilisticActor, TanhNormal

    obs_dim = env.observation_spec[GROUP, "observation"].shape[-1]
    action_spec = env.full_action_spec[GROUP, "action"]
    action_dim = action_spec.shape[-1]
    low, high = action_spec.space.low[0].clone(), action_spec.space.high[0].clone()
    net = _actor_net(obs_dim, action_dim, hidden)
    actor = ProbabilisticActor(
        TensorDictModule(net, in_keys=[(GROUP, "observation")], out_keys=[(GROUP, "loc"), (GROUP, "scale")]),
        spec=action_spec, in_keys=[(GROUP, "loc"), (GROUP, "scale")], out_keys=[(GROUP, "action")],
        distribution_class=TanhNormal, distribution_kwargs={"low": low, "high": high}, return_log_prob=True)
    if algorithm == "mappo":
        state_dim = env.observation_spec["state"].shape[-1]
        critic = TensorDictModule(_critic_net(obs_dim, state_dim, hidden), in_keys=[(GROUP, "observation"), "state"],
                                  out_keys=[(GROUP, "state_value")])
    else:
        critic = TensorDictModule(_critic_net(obs_dim, 0, hidden), in_keys=[(GROUP, "observation")],
                                  out_keys=[(GROUP, "state_value")])
    with torch.no_grad():  # initialise lazy shapes and check the keys once
        td = env.fake_tensordict()
        actor(td)
        critic(td)
    return actor, critic


def make_loss(actor, critic, *, gamma: float = DEFAULT_PPO["gamma"], lmbda: float = DEFAULT_PPO["lmbda"],
              clip_epsilon: float = DEFAULT_PPO["clip_epsilon"], entropy_coeff: float = DEFAULT_PPO["entropy_coeff"]):
    """``(loss, gae)``: ``ClipPPOLoss`` (normalised advantages, entropy bonus) on the flat batches of
    :func:`valid_transitions` and the ``GAE`` estimator on the ``[time, agent]`` batches of the collector,
    both reading the ``("agents", ...)`` entries (each agent's own reward, ``done`` and ``terminated``)."""
    from torchrl.objectives import ClipPPOLoss
    from torchrl.objectives.value import GAE

    loss = ClipPPOLoss(actor_network=actor, critic_network=critic, clip_epsilon=clip_epsilon, entropy_bonus=True,
                       entropy_coeff=entropy_coeff, normalize_advantage=True)
    keys = {"value": (GROUP, "state_value"), "advantage": (GROUP, "advantage"),
            "value_target": (GROUP, "value_target"), "reward": (GROUP, "reward"), "done": (GROUP, "done"),
            "terminated": (GROUP, "terminated")}
    loss.set_keys(action=(GROUP, "action"), sample_log_prob=(GROUP, "action_log_prob"), **keys)
    gae = GAE(gamma=gamma, lmbda=lmbda, value_network=critic, average_gae=False)
    gae.set_keys(**keys)
    return loss, gae


class TorchRLPolicy(SharedPolicy):
    """A trained shared policy as a policy of the evaluation harness (``act(env, observations)``):
    the deterministic action tanh(loc) scaled to the action Box, for every live agent in one batch."""

    def __init__(self, net, obs_dim: int, low, high, name: str = "marl", meta: dict | None = None):
        import torch

        self.net = net.eval()
        self.obs_dim = int(obs_dim)
        self.low = torch.as_tensor(low, dtype=torch.float32)
        self.high = torch.as_tensor(high, dtype=torch.float32)
        self.name = name
        self.meta = dict(meta or {})

    def actions(self, observations: np.ndarray) -> np.ndarray:
        """Deterministic actions (n, 2) float32 for observations (n, obs_dim)."""
        import torch
        from torchrl.modules import TanhNormal

        with torch.no_grad():
            loc, scale = self.net(torch.as_tensor(np.asarray(observations, dtype=np.float32)))
            action = TanhNormal(loc, scale, low=self.low, high=self.high).deterministic_sample
        return np.clip(action.numpy(), self.low.numpy(), self.high.numpy())


def _policy_payload(actor, algorithm: str, hidden, obs_dim: int, low, high) -> dict:
    net = actor.module[0].module  # ProbabilisticActor -> TensorDictModule -> Sequential(MLP, extractor)
    return {"format": POLICY_FORMAT, "algorithm": algorithm, "obs_dim": int(obs_dim), "hidden": list(hidden),
            "low": [float(v) for v in low], "high": [float(v) for v in high], "actor": net.state_dict()}


def _save_weights(path: str, payload: dict) -> None:
    """``payload`` (numbers, strings, lists, dicts, tensors) as ``torch.save`` writes it, atomically."""
    import torch

    buffer = io.BytesIO()
    torch.save(payload, buffer)
    write_atomic(path, buffer.getvalue())


def load_policy(path: str, name: str | None = None) -> TorchRLPolicy:
    """The policy saved by :func:`train`: ``path`` is its ``policy.pt`` or the run folder holding it. Read as
    data only (:func:`~crowd_env.envs.policy_files.load_weights`); a file of another kind raises :class:`~crowd_env.errors.TrainingError`."""
    _require()
    if os.path.isdir(path):
        path = os.path.join(path, "policy.pt")
    if not os.path.exists(path):
        raise TrainingError(f"no saved policy at {path}")
    payload = load_weights(path, "policy saved by crowd-train-mappo")
    if not isinstance(payload, dict) or payload.get("format") != POLICY_FORMAT:
        raise TrainingError(f"{path} is not a policy saved by crowd_env.experiments.training.marl (it holds "
                            f"{type(payload).__name__} without format {POLICY_FORMAT!r})")
    try:
        net = _actor_net(int(payload["obs_dim"]), len(payload["low"]), [int(h) for h in payload["hidden"]])
        net.load_state_dict(payload["actor"])
    except (KeyError, TypeError, ValueError, RuntimeError) as exc:
        raise TrainingError(f"{path} is a malformed {POLICY_FORMAT} policy: {type(exc).__name__}: {exc}") from None
    return TorchRLPolicy(net, payload["obs_dim"], payload["low"], payload["high"], name=name or payload["algorithm"],
                         meta={k: payload[k] for k in ("algorithm", "hidden")})


def _episode_stats(data) -> tuple:
    """``(count, mean per-agent return, mean length)`` of the episodes that ended in ``data`` (NaN if none)."""
    done = data["next", "done"].reshape(-1)
    if not bool(done.any()):
        return 0, float("nan"), float("nan")
    returns = data["next", GROUP, "episode_reward"][done]  # [episodes, n_agents, 1]
    lengths = data["next", "step_count"][done]
    return int(done.sum()), float(returns.mean()), float(lengths.float().mean())


def valid_transitions(data, state: bool):
    """The transitions of live agents as one flat batch (the agent dimension folded into the batch)."""
    from tensordict import TensorDict

    group = data[GROUP]
    t, n = group.batch_size
    keys = ["observation", "action", "action_log_prob", "advantage", "value_target", "state_value"]
    flat = TensorDict({GROUP: group.select(*keys).reshape(t * n)}, batch_size=[t * n])
    if state:
        s = data["state"]
        flat.set("state", s.unsqueeze(1).expand(t, n, s.shape[-1]).reshape(t * n, s.shape[-1]))
    return flat[group["mask"].reshape(-1)]


def _save_checkpoint(out: str, algorithm: str, frames: int, actor, critic, optim, rows) -> None:
    entries = read_checkpoints(out)
    if entries and entries[-1]["timesteps"] >= frames:
        return
    folder = os.path.join(out, "checkpoints")
    os.makedirs(folder, exist_ok=True)
    name = f"{algorithm}_{frames}_frames.pt"
    _save_weights(os.path.join(folder, name), {"algorithm": algorithm, "frames": frames, "actor": actor.state_dict(),
                                               "critic": critic.state_dict(), "optim": optim.state_dict(),
                                               "progress": rows})
    write_json_atomic(os.path.join(folder, "index.json"),
                       {"checkpoints": entries + [{"timesteps": frames, "model": name, "algorithm": algorithm}]})


def _resume(path: str, actor, critic, optim) -> list:
    """``actor``, ``critic`` and ``optim`` brought to the checkpoint at ``path`` (read as data only:
    :func:`~crowd_env.envs.policy_files.load_weights`); its progress rows. A malformed checkpoint raises :class:`~crowd_env.errors.TrainingError`."""
    ckpt = load_weights(path, "crowd-train-mappo checkpoint")
    try:
        actor.load_state_dict(ckpt["actor"])
        critic.load_state_dict(ckpt["critic"])
        optim.load_state_dict(ckpt["optim"])
        return [dict(row) for row in ckpt["progress"]]
    except (KeyError, TypeError, ValueError, RuntimeError) as exc:
        raise TrainingError(f"cannot resume from {path}: not a crowd-train-mappo checkpoint of these networks "
                            f"({type(exc).__name__}: {exc})") from None


def train(env_config: dict, frames: int, out: str, *, algorithm: str = "mappo", resolve, seed: int = 0,
          frames_per_batch: int = DEFAULT_PPO["frames_per_batch"], num_epochs: int = DEFAULT_PPO["num_epochs"],
          minibatch_size: int = DEFAULT_PPO["minibatch_size"], learning_rate: float = DEFAULT_PPO["learning_rate"],
          clip_epsilon: float = DEFAULT_PPO["clip_epsilon"], gamma: float = DEFAULT_PPO["gamma"],
          lmbda: float = DEFAULT_PPO["lmbda"], entropy_coeff: float = DEFAULT_PPO["entropy_coeff"],
          max_grad_norm: float = DEFAULT_PPO["max_grad_norm"], hidden=DEFAULT_PPO["hidden"],
          eval_seeds=(1000, 1001, 1002), threads: int = 1, checkpoint_every: int = 1, resume: bool = False,
          progress=print) -> dict:
    """Train ``algorithm`` (``"mappo"`` or ``"ippo"``) for ``frames`` environment steps; returns the summary
    (also written to ``out/summary.json``); see the module docstring for the outputs.

    ``resolve(spec, name=None) -> policy`` makes the random policy of the comparison (``resolve("random")``,
    e.g. ``baselines.reference_policies.as_policy``). A checkpoint is written every ``checkpoint_every``
    iterations (0: only at the end); ``resume`` continues from the latest one up to ``frames`` in all, a
    folder with checkpoints is refused without it, and with other environment options or another algorithm.
    """
    _check_train_arguments(algorithm, frames=frames, frames_per_batch=frames_per_batch, num_epochs=num_epochs,
                           minibatch_size=minibatch_size, checkpoint_every=checkpoint_every)
    _require()
    import torch

    torch.set_num_threads(max(1, int(threads)))
    previous = read_checkpoints(out)
    if resume and previous and previous[-1].get("algorithm", algorithm) != algorithm:
        raise TrainingError(f"cannot resume: {out} holds {previous[-1].get('algorithm')} checkpoints, not {algorithm}")
    t0 = time.perf_counter()
    entries, before = begin_run(out, env_config, resume=resume, resolve=resolve, eval_seeds=eval_seeds, seed=seed,
                                progress=progress)

    state = algorithm == "mappo"
    start = int(entries[-1]["timesteps"]) if entries else 0
    torch.manual_seed(seed + start)
    env = make_env(env_config, state=state, seed=seed + start)
    actor, critic = build_networks(env, algorithm, hidden)
    loss, gae = make_loss(actor, critic, gamma=gamma, lmbda=lmbda, clip_epsilon=clip_epsilon,
                          entropy_coeff=entropy_coeff)
    optim = torch.optim.Adam(loss.parameters(), lr=learning_rate)
    rows = []
    if entries:
        rows = _resume(os.path.join(out, "checkpoints", entries[-1]["model"]), actor, critic, optim)
        progress(f"resuming from the checkpoint at {start} frames")

    t1 = time.perf_counter()
    frames_done, iteration = _iterate(env, actor, critic, loss, gae, optim, rows, out, algorithm, start=start,
                                      frames=frames, frames_per_batch=frames_per_batch, state=state,
                                      num_epochs=num_epochs, minibatch_size=minibatch_size,
                                      max_grad_norm=max_grad_norm, checkpoint_every=checkpoint_every,
                                      progress=progress)
    train_s = time.perf_counter() - t1
    write_progress(out, rows, CSV_COLUMNS)

    obs_dim = env.observation_spec[GROUP, "observation"].shape[-1]
    space = env.full_action_spec[GROUP, "action"].space
    _save_weights(os.path.join(out, "policy.pt"),
                  _policy_payload(actor, algorithm, hidden, obs_dim, space.low[0].tolist(), space.high[0].tolist()))
    env.close()
    trained = load_policy(out, name=algorithm)
    after = evaluate_trained(trained, env_config, eval_seeds, progress)
    summary = {"algorithm": algorithm, "frames": frames_done, "resumed_from_frames": start,
               "agent_steps": int(sum(r["agent_steps"] for r in rows)), "iterations": iteration,
               "train_wall_s": train_s, "total_wall_s": time.perf_counter() - t0, "random": before, "trained": after,
               "improvement": after["mean_return"] - before["mean_return"], "env_config": env_config,
               "eval_seeds": list(eval_seeds), "seed": seed,
               "ppo": {"frames_per_batch": frames_per_batch, "num_epochs": num_epochs, "minibatch_size": minibatch_size,
                       "learning_rate": learning_rate, "clip_epsilon": clip_epsilon, "gamma": gamma, "lmbda": lmbda,
                       "entropy_coeff": entropy_coeff, "max_grad_norm": max_grad_norm, "hidden": list(hidden)}}
    write_json_atomic(os.path.join(out, "summary.json"), summary)
    return summary


def _iterate(env, actor, critic, loss, gae, optim, rows: list, out: str, algorithm: str, *, start: int, frames: int,
             frames_per_batch: int, state: bool, num_epochs: int, minibatch_size: int, max_grad_norm: float,
             checkpoint_every: int, progress) -> tuple:
    """Collect-and-update iterations from ``start`` to ``frames`` environment steps: GAE, clipped-PPO epochs, a row
    appended to ``rows`` and ``out/progress.csv``, a checkpoint every ``checkpoint_every`` and at the end;
    (frames done, iterations done)."""
    import torch
    from torchrl.collectors import Collector

    remaining = int(frames) - start
    frames_done = start
    iteration = rows[-1]["iteration"] if rows else 0
    if remaining <= 0:
        return frames_done, iteration
    batch = min(int(frames_per_batch), remaining)
    total = -(-remaining // batch) * batch
    collector = Collector(env, actor, frames_per_batch=batch, total_frames=total, device="cpu",
                          auto_register_policy_transforms=False)
    t_iter = time.perf_counter()
    for data in collector:
        with torch.no_grad():
            gae(data)
        episodes, ep_return, ep_length = _episode_stats(data)
        flat = valid_transitions(data, state)
        means = _ppo_update(loss, optim, flat, num_epochs, minibatch_size, max_grad_norm)
        collector.update_policy_weights_()
        frames_done += data.numel()
        iteration += 1
        row = {"iteration": iteration, "frames": frames_done, "agent_steps": int(flat.batch_size[0]),
               "episodes": episodes, "mean_episode_return": ep_return, "mean_episode_length": ep_length,
               **means, "wall_s": time.perf_counter() - t_iter}
        t_iter = time.perf_counter()  # wall_s: collection and update of the iteration
        rows.append(row)
        write_progress(out, rows, CSV_COLUMNS)
        progress(f"iter {iteration:4d} | frames {frames_done:8d} | episodes {episodes:3d} | return "
                 f"{ep_return:8.3f} | length {ep_length:6.1f} | loss pi {row['loss_objective']:+.4f} "
                 f"v {row['loss_critic']:.4f} ent {row['loss_entropy']:+.5f}")
        if checkpoint_every and iteration % checkpoint_every == 0:
            _save_checkpoint(out, algorithm, frames_done, actor, critic, optim, rows)
    collector.shutdown()
    _save_checkpoint(out, algorithm, frames_done, actor, critic, optim, rows)
    return frames_done, iteration


def _check_train_arguments(algorithm: str, *, checkpoint_every: int, **counts) -> None:
    """:class:`TrainingError` naming the argument: an unknown algorithm, a count below 1, checkpoint_every < 0."""
    check_algorithm(algorithm)
    for name, value in counts.items():
        check_integer(name, value, error=TrainingError, minimum=1)
    if checkpoint_every < 0:
        raise TrainingError(f"checkpoint_every must be >= 0, got {checkpoint_every!r}")


def _ppo_update(loss, optim, flat, num_epochs: int, minibatch_size: int, max_grad_norm: float) -> dict:
    """``num_epochs`` passes of clipped-PPO minibatch updates over the batch ``flat``, gradients clipped to
    ``max_grad_norm``; the mean of each loss term and of the entropy over the minibatches."""
    import torch

    n = flat.batch_size[0]
    sums = dict.fromkeys(("loss_objective", "loss_critic", "loss_entropy", "entropy"), 0.0)
    count = 0
    for _ in range(num_epochs):
        for idx in torch.randperm(n).split(int(minibatch_size)):
            parts = loss(flat[idx])
            total_loss = parts["loss_objective"] + parts["loss_critic"] + parts["loss_entropy"]
            optim.zero_grad()
            total_loss.backward()
            torch.nn.utils.clip_grad_norm_(loss.parameters(), max_grad_norm)
            optim.step()
            for key in sums:
                sums[key] += float(parts[key].detach())
            count += 1
    return {k: v / max(count, 1) for k, v in sums.items()}
