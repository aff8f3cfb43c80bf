"""Behaviour cloning: a network trained on the calibrated model's own intents, the bridge between the two worlds.

The calibrated eikonal + social-force agent (Kabalan et al. 2016, Eqs. 13-19) drives every controlled
pedestrian of the environment with the options it needs (``action_max_m_s=50``, ``heading_target=
"desired_direction"``, a decision every simulator step: ``baselines.reference_policies.CalibratedPolicy``'s
``env_overrides``). :func:`collect_demonstrations` records, every ``every`` steps, each live agent's
observation and the intent the model gave it; :func:`train_behaviour_cloning` fits a tanh MLP to those
pairs by mean squared error (Adam, minibatches, a held-out 10 % for the validation loss) and writes it
as a :mod:`policy file <crowd_env.envs.policy_files>` that acts with the same environment options.

A clone acts on the observation alone, which lacks two things the model uses: the pedestrian's own
desired speed (drawn per pedestrian, N(1.34, 0.26) m/s) and anything beyond the ``n_neighbors`` nearest
and the ``n_rays`` wall distances. How close it comes is the check on the chain (observation, action
bound, decision interval) that the reference results report (``crowd-reference-results``, docs/validation/reference_results.md).
"""
from __future__ import annotations

import os
import time

import numpy as np

from crowd_env.errors import TrainingError
from crowd_env.files import write_atomic, write_json_atomic

from ...core.checks import check_integer

from ...envs.crowd_v0 import DEFAULT_ACTION_MAX_M_S, CrowdParallelEnv, decisions_for_time
from ...envs.policy_files import MLPPolicyFile, save_policy_file

__all__ = ["collect_demonstrations", "train_behaviour_cloning", "DEFAULT_BC", "mlp_network", "fit_epoch",
           "network_policy_file"]

DEFAULT_BC = {"hidden": (128, 128), "epochs": 15, "batch_size": 512, "learning_rate": 1e-3, "every": 5,
              "validation_fraction": 0.1}


def demonstration_env_config(env_config: dict, teacher) -> dict:
    """``env_config`` with the teacher's ``env_overrides`` (the options it needs), every pedestrian controlled."""
    return {**env_config, **getattr(teacher, "env_overrides", {})}


def collect_demonstrations(env_config: dict, seeds, *, teacher, every: int = DEFAULT_BC["every"],
                           max_time_s: float = 90.0, driver=None) -> tuple:
    """``(observations (n, D) float32, intents (n, 2) float32, agent_steps)`` of ``teacher`` (a policy of the
    evaluation harness, e.g. the calibrated one) on ``env_config`` with the teacher's ``env_overrides``,
    one episode per seed, every live agent's pair every ``every`` decisions. ``agent_steps``: all agent
    decisions simulated (the collection's cost). With a ``driver`` (``driver(observations (n, D)) -> (n, 2)``,
    e.g. the clone) the driver's actions move the crowd and the teacher only labels the states it reaches
    (DAgger's collection)."""
    check_integer("every", every, error=TrainingError, minimum=1)
    seeds = list(seeds)
    if not seeds:
        raise TrainingError("collect_demonstrations needs at least one seed")
    cfg = demonstration_env_config(env_config, teacher)
    xs, ys, agent_steps = [], [], 0
    for seed in seeds:
        env = CrowdParallelEnv(**{k: v for k, v in cfg.items() if k != "max_steps"})
        env.max_steps = decisions_for_time(max_time_s, env.dt_s)
        obs, _ = env.reset(seed=int(seed))
        teacher.reset(env, int(seed))
        k = 0
        while env.agents:
            labelled = k % every == 0
            actions = teacher.act(env, obs) if driver is None or labelled else None
            if labelled:
                xs.append(np.stack([obs[a] for a in env.agents]))
                ys.append(np.stack([actions[a] for a in env.agents]))
            if driver is not None:
                actions = dict(zip(env.agents, driver(xs[-1] if labelled else np.stack([obs[a] for a in env.agents]))))
            agent_steps += len(env.agents)
            obs, *_ = env.step(actions)
            k += 1
        env.close()
    if not xs:
        raise TrainingError("the demonstrations hold no decision (did every episode end at once?)")
    return np.concatenate(xs).astype(np.float32), np.concatenate(ys).astype(np.float32), agent_steps


def train_behaviour_cloning(env_config: dict, out: str, *, teacher, seed: int = 0, demo_seeds=range(100, 110),
                            dagger_seeds=(), hidden=DEFAULT_BC["hidden"], epochs: int = DEFAULT_BC["epochs"],
                            batch_size: int = DEFAULT_BC["batch_size"],
                            learning_rate: float = DEFAULT_BC["learning_rate"], every: int = DEFAULT_BC["every"],
                            validation_fraction: float = DEFAULT_BC["validation_fraction"], threads: int = 1,
                            max_time_s: float = 90.0, progress=print) -> dict:
    """Collect the ``teacher``'s demonstrations on ``demo_seeds`` and fit the clone; then, for each list of
    seeds in ``dagger_seeds``, one DAgger round (Ross, Gordon & Bagnell 2011): the clone drives the crowd on
    those seeds, the teacher labels the states it reaches, and the clone is fitted again on everything
    gathered so far (the cure for compounding errors: a clone trained on the teacher's states alone meets
    states the teacher never visits, e.g. a jam it caused, and has no answer learned for them). Writes
    ``out/policy.npz`` (the policy file, acting with the teacher's environment options),
    ``out/progress.csv`` (round, epoch, training and validation loss) and ``out/summary.json`` (returned:
    losses, sizes, cost)."""
    import torch

    for name, value in (("epochs", epochs), ("batch_size", batch_size)):
        check_integer(name, value, error=TrainingError, minimum=1)
    if not 0.0 < validation_fraction < 1.0:
        raise TrainingError(f"validation_fraction must lie in (0, 1), got {validation_fraction!r}")
    rounds = [list(demo_seeds)] + [list(r) for r in dagger_seeds]
    torch.set_num_threads(max(1, int(threads)))
    os.makedirs(out, exist_ok=True)
    t0 = time.perf_counter()
    x, y, agent_steps = collect_demonstrations(env_config, rounds[0], teacher=teacher, every=every,
                                               max_time_s=max_time_s)
    collect_s = time.perf_counter() - t0
    samples = [int(x.shape[0])]
    rng = np.random.default_rng(seed)
    torch.manual_seed(seed)
    mean = x.mean(0).astype(np.float64)  # the first demonstrations' scaling, kept through the DAgger rounds
    std = x.std(0).astype(np.float64)
    std[std < 1e-6] = 1.0  # constant inputs (padding) pass through unscaled
    net = mlp_network(x.shape[1], hidden, y.shape[1])
    opt = torch.optim.Adam(net.parameters(), lr=learning_rate)
    gen = torch.Generator().manual_seed(seed)

    def clone(obs: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            return net(torch.as_tensor((obs - mean) / std, dtype=torch.float32)).numpy().astype(np.float64)

    rows = []
    train_s = 0.0
    for r, seeds_r in enumerate(rounds):
        if r:
            t = time.perf_counter()
            xr, yr, steps = collect_demonstrations(env_config, seeds_r, teacher=teacher, every=every,
                                                   max_time_s=max_time_s, driver=clone)
            collect_s += time.perf_counter() - t
            x, y, agent_steps = np.concatenate([x, xr]), np.concatenate([y, yr]), agent_steps + steps
            samples.append(int(xr.shape[0]))
        order = rng.permutation(x.shape[0])
        n_val = max(1, int(round(validation_fraction * x.shape[0])))
        X = torch.as_tensor((x - mean) / std, dtype=torch.float32)
        Y = torch.as_tensor(y)
        split = (torch.as_tensor(order[n_val:]), torch.as_tensor(order[:n_val]))
        t1 = time.perf_counter()
        for epoch in range(1, int(epochs) + 1):
            train_mse, val_loss = fit_epoch(net, opt, gen, X, Y, split, int(batch_size))
            rows.append({"round": r, "epoch": epoch, "train_mse": train_mse, "validation_mse": val_loss,
                         "wall_s": train_s + time.perf_counter() - t1})
            progress(f"bc round {r} epoch {epoch:3d} | train mse {train_mse:.5f} | validation mse {val_loss:.5f}")
        train_s += time.perf_counter() - t1
    write_atomic(os.path.join(out, "progress.csv"), "round,epoch,train_mse,validation_mse,wall_s\n" + "".join(
        f"{r['round']},{r['epoch']},{r['train_mse']:.6g},{r['validation_mse']:.6g},{r['wall_s']:.3f}\n" for r in rows))
    cfg = {k: v for k, v in demonstration_env_config(env_config, teacher).items() if k != "max_steps"}
    summary = {"algorithm": "bc", "teacher": getattr(teacher, "name", type(teacher).__name__),
               "demo_seeds": [int(s) for s in rounds[0]], "dagger_seeds": [[int(s) for s in r] for r in rounds[1:]],
               "every": int(every), "samples": int(x.shape[0]), "samples_per_round": samples,
               "agent_steps": int(agent_steps), "collect_wall_s": collect_s, "train_wall_s": train_s,
               "total_wall_s": time.perf_counter() - t0, "final_train_mse": rows[-1]["train_mse"],
               "final_validation_mse": rows[-1]["validation_mse"], "intent_rms_m_s": float(np.sqrt((y ** 2).mean())),
               "hidden": [int(h) for h in hidden], "epochs": int(epochs), "seed": int(seed), "env_config": cfg}
    _save_clone(net, mean, std, cfg, summary, out)
    return summary


def _save_clone(net, mean, std, cfg: dict, summary: dict, out: str) -> None:
    """``out/policy.npz`` (the clone as a policy file acting in the teacher's action box) and ``out/summary.json``."""
    policy = network_policy_file(net, mean, std, cfg,
                                 {k: summary[k] for k in ("algorithm", "teacher", "samples", "agent_steps", "seed")})
    save_policy_file(policy, os.path.join(out, "policy.npz"))
    write_json_atomic(os.path.join(out, "summary.json"), summary)


def network_policy_file(net, mean, std, cfg: dict, meta: dict, output: str = "linear") -> MLPPolicyFile:
    """The torch MLP ``net`` (:func:`mlp_network`) with the input scaling ``(obs − mean) / std`` as a policy file
    acting with the environment options ``cfg`` in its action box (``action_max_m_s``), its output read as
    ``output`` (:data:`~crowd_env.envs.policy_files.OUTPUTS`)."""
    import torch

    linears = [m for m in net if isinstance(m, torch.nn.Linear)]
    space_max = float(cfg.get("action_max_m_s", DEFAULT_ACTION_MAX_M_S))
    return MLPPolicyFile([m.weight.detach().numpy().T for m in linears], [m.bias.detach().numpy() for m in linears],
                         "tanh", output, [-space_max] * 2, [space_max] * 2, mean, std, cfg, meta)


def mlp_network(d_in: int, hidden, d_out: int):
    """A torch MLP: tanh hidden layers of the sizes ``hidden``, a linear output."""
    import torch

    layers, d = [], d_in
    for h in hidden:
        layers += [torch.nn.Linear(d, int(h)), torch.nn.Tanh()]
        d = int(h)
    return torch.nn.Sequential(*layers, torch.nn.Linear(d, d_out))


def fit_epoch(net, opt, gen, X, Y, split: tuple, batch_size: int) -> tuple:
    """One epoch of mean-squared-error minibatches over the training rows of ``split`` (train, validation
    indices), shuffled by ``gen``; (the epoch's mean training loss, the validation loss after it)."""
    import torch

    tr_t, val_t = split
    perm = tr_t[torch.randperm(tr_t.numel(), generator=gen)]
    total, count = 0.0, 0
    for start in range(0, perm.numel(), batch_size):
        i = perm[start:start + batch_size]
        loss = ((net(X[i]) - Y[i]) ** 2).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
        total += float(loss.detach()) * i.numel()
        count += i.numel()
    with torch.no_grad():
        val_loss = float(((net(X[val_t]) - Y[val_t]) ** 2).mean())
    return total / count, val_loss
