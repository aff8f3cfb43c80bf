"""A pedestrian policy imitated from recorded people: behaviour cloning on the Jülich corridor recordings, then rounds
of drift correction in the simulator (Data as Demonstrator), resumable, on the one executor.

The data: the nine UO runs (:mod:`crowd_env.analysis.corridor_runs`, 16 frames/s), each replayed in its scenario
(``juelich_corridor``) into observation-action pairs (:mod:`.demonstrations`: the environment's observation of the
recorded state, the velocity over the next 0.1 s in the body frame; decisions whose neighbours the camera may have
missed are left out). :data:`TRAINING_RUNS` train; :data:`VALIDATION_RUNS` (one narrowed entrance, one narrowed
exit, each inside the range of the training runs of its kind: 1.0 m between 0.7 and 1.45 m, 0.95 m between 0.70 and
1.20 m) are never trained on and give the validation loss, the open-loop speed error and, in closed loop, the runs
the method was chosen on.

The stages (:func:`train_human_policy`), each stored under ``OUT`` as it ends, so that a stopped training resumes
after the last stage it finished (``resume=True``; a folder made with another configuration is refused):

1. ``demonstrations/<run>.npz``: every run's dataset (one task per run on the executor);
2. ``bc``: an MLP (:data:`DEFAULT_HUMAN_TRAINING` ``hidden``, tanh) fitted by mean squared error to the training
   runs' actions (Adam, minibatches, inputs scaled by the training data's mean and spread);
3. ``dad_<r>`` for r = 1 … ``dad_rounds``: the policy of the previous stage drives the recorded crowds of the
   training runs from recorded states, the waiting crowd behind the entrance included
   (:func:`~.recorded_rollouts.dad_rollouts` with ``spawn_newcomers``, one task per run), its decisions labelled
   with what brings each pedestrian back to its recording; the network is fitted further, for ``dad_epochs``, on
   the recordings and every round's rollouts together (DAgger's aggregation).

The defaults (:data:`DEFAULT_HUMAN_TRAINING`) are the ones chosen by closed-loop measurement on the validation runs
(docs/validation/human_policy.md): no own velocity in the observation (a clone that sees it copies it and stalls),
three rounds, the waiting crowd in the rollouts, the labels as velocities (``intent_gain`` 0).

Each stage writes ``checkpoints/<stage>.pt`` (the network, the optimiser, the progress so far; read back with
torch's weights-only loader) and ``policies/<stage>.npz`` (a :mod:`policy file <crowd_env.envs.policy_files>`,
output clipped to the action box), then ``checkpoints/index.json`` names it, written last. The last stage's policy
is also ``OUT/policy.npz``; ``progress.csv`` holds one row per epoch (the learning curves, drawn in
``learning_curves.png``); ``summary.json`` the
sizes, the wall and CPU times of each stage, and the open-loop speed error of every stage's policy and of the
calibrated agent on the validation runs' recorded states (:func:`open_loop_errors`).
"""
from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

from crowd_env.errors import TrainingError
from crowd_env.files import copy_atomic, write_atomic, write_json_atomic

from ...analysis.corridor_runs import recorded_uo_trajectories, uo_run, uo_scenario
from ...analysis.figures import pyplot, save_figure
from ...envs.background import FileObservationPolicy
from ...envs.policy_files import load_weights, save_policy_file
from ...walking.model import ModelParams
from ...walking.presets import get_preset
from ..running.backends import SerialBackend, run_all
from ..running.store import check_config
from .demonstrations import (DEFAULT_SMOOTHING_S, demonstrations_from_replay, load_demonstrations, policy_options,
                             replay_trajectories)
from .imitation import fit_epoch, mlp_network, network_policy_file
from .recorded_rollouts import DEFAULT_DAD, calibrated_actions, check_rollout_options, dad_rollouts

__all__ = ["TRAINING_RUNS", "VALIDATION_RUNS", "DEFAULT_HUMAN_TRAINING", "QUICK_HUMAN_TRAINING", "HUMAN_POLICY_NAME",
           "train_human_policy", "open_loop_errors", "human_training_config", "demonstrations_task",
           "dad_task", "rollout_params", "stage_names", "learning_curves_figure"]

HUMAN_POLICY_NAME = "human_juelich"
VALIDATION_RUNS = ("uo-100-180-180", "uo-180-180-095")
TRAINING_RUNS = ("uo-050-180-180", "uo-060-180-180", "uo-070-180-180", "uo-145-180-180", "uo-180-180-070",
                 "uo-180-180-120", "uo-180-180-180")
DEFAULT_HUMAN_TRAINING = {"hidden": [128, 128], "bc_epochs": 20, "dad_rounds": 3, "dad_epochs": 8, "batch_size": 512,
                          "learning_rate": 1e-3, "smoothing_s": DEFAULT_SMOOTHING_S, "seed": 0,
                          "dad": {**DEFAULT_DAD, "spawn_newcomers": True}, "policy": {"neighbor_radius_m": 3.0},
                          "radius_m": None, "body_depth_m": 0.0, "shoulder_turn_critical_ratio": 0.0}
# The same code path in seconds: two short runs, a few epochs, one round from a few starts (the default tests).
QUICK_HUMAN_TRAINING = {**DEFAULT_HUMAN_TRAINING, "hidden": [16, 16], "bc_epochs": 2, "dad_rounds": 1, "dad_epochs": 1,
                        "dad": {**DEFAULT_HUMAN_TRAINING["dad"], "horizon_s": 1.0, "start_every_s": 20.0},
                        "training_runs": ["uo-050-180-180"], "validation_runs": ["uo-060-180-180"]}


def human_training_config(config: dict | None = None, *, preset: str = "calibrated") -> dict:
    """The full configuration of a training (:data:`DEFAULT_HUMAN_TRAINING` with ``config`` on top, the runs,
    the policy's options checked, the physics of ``preset``): what ``OUT/config.json`` holds."""
    cfg = {**DEFAULT_HUMAN_TRAINING, "training_runs": list(TRAINING_RUNS), "validation_runs": list(VALIDATION_RUNS),
           **(config or {})}
    unknown = sorted(set(cfg) - set(DEFAULT_HUMAN_TRAINING) - {"training_runs", "validation_runs"})
    if unknown:
        raise TrainingError(f"unknown training option(s) {unknown}; known: {sorted(DEFAULT_HUMAN_TRAINING)}")
    overlap = sorted(set(cfg["training_runs"]) & set(cfg["validation_runs"]))
    if overlap or not cfg["training_runs"] or not cfg["validation_runs"]:
        raise TrainingError(f"training and validation runs must be disjoint and non-empty, got {cfg['training_runs']} "
                            f"and {cfg['validation_runs']}")
    for name in (*cfg["training_runs"], *cfg["validation_runs"]):
        uo_run(name)
    for key in ("bc_epochs", "dad_epochs", "batch_size", "dad_rounds"):
        if int(cfg[key]) != cfg[key] or cfg[key] < (0 if key == "dad_rounds" else 1):
            raise TrainingError(f"{key} must be an integer >= {0 if key == 'dad_rounds' else 1}, got {cfg[key]!r}")
    if not isinstance(cfg["dad"], dict) or set(cfg["dad"]) - set(DEFAULT_DAD):
        raise TrainingError(f"dad must be a dict of the rollouts' options {sorted(DEFAULT_DAD)}, got {cfg['dad']!r}")
    cfg["dad"] = {**DEFAULT_HUMAN_TRAINING["dad"], **cfg["dad"]}  # a partial dict changes only what it names
    check_rollout_options(**cfg["dad"])
    cfg["options"] = policy_options(cfg["policy"])
    physics = get_preset(preset)
    params = physics.params()
    cfg["params"] = {f: getattr(params, f) for f in ("dt_s", "rotation")}
    if cfg["radius_m"] is None:  # the body of the preset's physics
        cfg["radius_m"] = physics.radius_m
    if not (isinstance(cfg["radius_m"], (int, float)) and 0.0 < cfg["radius_m"] < 0.5):
        raise TrainingError(f"radius_m must be a body radius in m in (0, 0.5), got {cfg['radius_m']!r}")
    cfg["radius_m"] = float(cfg["radius_m"])
    depth = cfg.pop("body_depth_m")
    if isinstance(depth, bool) or not isinstance(depth, (int, float)) or not 0.0 <= depth < 2.0 * cfg["radius_m"]:
        raise TrainingError(f"body_depth_m must be 0 (the disk) or a depth in m below the body's width "
                            f"{2.0 * cfg['radius_m']:g} m, got {depth!r}")
    if depth > 0.0:  # bodies of three circles in the replays and the rollouts (a disk's configuration: no key)
        cfg["params"]["body_depth_m"] = float(depth)
    turn = cfg.pop("shoulder_turn_critical_ratio")
    if isinstance(turn, bool) or not isinstance(turn, (int, float)) or not 0.0 <= turn < 10.0:
        raise TrainingError(f"shoulder_turn_critical_ratio must be 0 (no turn) or Warren & Whang's critical ratio "
                            f"A/S in (0, 10), e.g. 1.3, got {turn!r}")
    if turn > 0.0:  # headings turned at narrow apertures in the replays and the rollouts (off: no key)
        cfg["params"]["shoulder_turn_critical_ratio"] = float(turn)
    cfg["preset"] = preset
    cfg["kind"] = "human_imitation"
    return cfg


def stage_names(cfg: dict) -> list:
    """The stages of a training: ``bc``, then ``dad_1`` … ``dad_R``."""
    return ["bc"] + [f"dad_{r}" for r in range(1, int(cfg["dad_rounds"]) + 1)]


def _replay(name: str, cfg: dict):
    body = {"radius_m": cfg["radius_m"]} if "radius_m" in cfg else {}  # a configuration stored before the option
    scenario = uo_scenario(name, **body)
    params = ModelParams(**cfg["params"])
    return scenario, replay_trajectories(recorded_uo_trajectories(name), scenario, options=cfg["options"],
                                         params=params, smoothing_s=cfg["smoothing_s"])


def demonstrations_task(task: dict) -> dict:
    """Executor task: the dataset of run ``task['run']`` written to ``task['path']`` (:mod:`.demonstrations`)."""
    scenario, replay = _replay(task["run"], task["config"])
    demos = demonstrations_from_replay(replay, scenario, task["config"]["options"],
                                       meta={"source": f"crowd_env.analysis.corridor_runs: {task['run']}",
                                             "scenario": "juelich_corridor", "run": task["run"]})
    demos.save(task["path"])
    return {"run": task["run"], "n_decisions": len(demos), "n_seen": int(demos.seen.sum())}


def rollout_params(cfg: dict) -> ModelParams:
    """The physics of a training's rollouts: its preset's, with the training's body depth (``body_depth_m``) and
    shoulder turn (``shoulder_turn_critical_ratio``)."""
    body = {k: cfg["params"][k] for k in ("body_depth_m", "shoulder_turn_critical_ratio") if k in cfg["params"]}
    return get_preset(cfg["preset"]).params(**body)


def dad_task(task: dict) -> dict:
    """Executor task: the labelled rollouts of the policy file ``task['policy']`` on run ``task['run']`` written to
    ``task['path']`` (:func:`~.recorded_rollouts.dad_rollouts`)."""
    cfg = task["config"]
    scenario, replay = _replay(task["run"], cfg)
    policy = FileObservationPolicy(task["policy"])
    demos = dad_rollouts(replay, scenario, policy, params=rollout_params(cfg), options=cfg["options"], **cfg["dad"])
    demos.save(task["path"])
    return {"run": task["run"], "n_decisions": len(demos)}


def _run_tasks(tasks: list, backend, fn) -> None:
    """Run the tasks whose output file is missing (a stopped stage resumes with the runs it had finished)."""
    todo = [t for t in tasks if not os.path.exists(t["path"])]
    if todo:
        run_all(todo, backend, fn)


class _Fitter:
    """The network, its optimiser and the input scaling, fitted stage after stage (:func:`train_human_policy`)."""

    def __init__(self, cfg: dict, x_train: np.ndarray, progress):
        import torch

        self.cfg, self.progress = cfg, progress
        torch.manual_seed(int(cfg["seed"]))
        self.mean = x_train.mean(0).astype(np.float64)
        std = x_train.std(0).astype(np.float64)
        std[std < 1e-6] = 1.0  # constant inputs (padding) pass through unscaled
        self.std = std
        self.net = mlp_network(x_train.shape[1], cfg["hidden"], 2)
        self.opt = torch.optim.Adam(self.net.parameters(), lr=float(cfg["learning_rate"]))
        self.gen = torch.Generator().manual_seed(int(cfg["seed"]))
        self.rows = []

    def state(self) -> dict:
        return {"net": self.net.state_dict(), "opt": self.opt.state_dict(), "gen": self.gen.get_state(),
                "mean": self.mean.tolist(), "std": self.std.tolist(), "rows": self.rows}

    def restore(self, saved: dict) -> None:
        self.net.load_state_dict(saved["net"])
        self.opt.load_state_dict(saved["opt"])
        self.gen.set_state(saved["gen"])
        self.mean, self.std = np.asarray(saved["mean"]), np.asarray(saved["std"])
        self.rows = list(saved["rows"])

    def fit(self, stage: str, train: tuple, validation: tuple, epochs: int) -> None:
        """``epochs`` epochs on ``train`` (observations, actions), each followed by the validation figures."""
        import torch

        x = np.concatenate([train[0], validation[0]])
        X = torch.as_tensor((x - self.mean) / self.std, dtype=torch.float32)
        Y = torch.as_tensor(np.concatenate([train[1], validation[1]]).astype(np.float32))
        n = train[0].shape[0]
        split = (torch.arange(n), torch.arange(n, x.shape[0]))
        for epoch in range(1, int(epochs) + 1):
            t0, c0 = time.perf_counter(), time.process_time()
            train_mse, val_mse = fit_epoch(self.net, self.opt, self.gen, X, Y, split, int(self.cfg["batch_size"]))
            with torch.no_grad():
                pred = self.net(X[split[1]]).numpy()
            speed_err = float(np.abs(np.hypot(*pred.T) - np.hypot(*validation[1].T)).mean())
            self.rows.append({"stage": stage, "epoch": epoch, "samples": n, "train_mse": train_mse,
                              "validation_mse": val_mse, "validation_speed_error_m_s": speed_err,
                              "wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0})
            self.progress(f"{stage} epoch {epoch:3d} | {n} samples | train mse {train_mse:.5f} | validation mse "
                          f"{val_mse:.5f} | validation speed error {speed_err:.4f} m/s")

    def policy_file(self, stage: str, cfg: dict):
        meta = {"algorithm": "behaviour cloning" if stage == "bc" else f"behaviour cloning + {stage[4:]} round(s) of "
                "Data as Demonstrator", "data": "Jülich UO corridor recordings (Zhang et al. 2011)",
                "training_runs": cfg["training_runs"], "validation_runs": cfg["validation_runs"], "stage": stage}
        return network_policy_file(self.net, self.mean, self.std, cfg["options"], meta, output="clip_box")


def _datasets(folder: Path, runs) -> tuple:
    """(observations, actions) of the seen decisions of ``runs``' datasets in ``folder``."""
    parts = [load_demonstrations(folder / f"{r}.npz") for r in runs]
    parts = [d.select(d.seen) for d in parts]
    return (np.concatenate([d.observation for d in parts]), np.concatenate([d.action for d in parts]))


def train_human_policy(out, *, config: dict | None = None, backend=None, resume: bool = False, preset: str = "calibrated",
                       progress=print) -> dict:
    """Train the policy (module docstring) into ``out``; returns the summary (also ``out/summary.json``). Without
    ``resume`` a folder holding checkpoints is refused; with it, the stages finished are loaded, not redone."""
    import torch

    out = Path(out)
    cfg = human_training_config(config, preset=preset)
    index_path = out / "checkpoints" / "index.json"
    if index_path.exists() and not resume:
        raise TrainingError(f"{out} holds checkpoints of a training: pass resume=True (--resume) to continue it, or "
                            "choose another folder")
    check_config(out, cfg)
    backend = backend or SerialBackend()
    torch.set_num_threads(1)
    done, timings = _index(index_path)
    demos = out / "demonstrations"
    demos.mkdir(parents=True, exist_ok=True)
    clock = _Clock()
    _run_tasks([{"run": r, "config": cfg, "path": str(demos / f"{r}.npz")}
                for r in (*cfg["training_runs"], *cfg["validation_runs"])], backend, demonstrations_task)
    timings.setdefault("demonstrations", clock.lap())
    train, validation = _datasets(demos, cfg["training_runs"]), _datasets(demos, cfg["validation_runs"])
    fitter = _Fitter(cfg, train[0], progress)
    if done:
        fitter.restore(load_weights(out / "checkpoints" / f"{done[-1]}.pt", "training checkpoint"))
    dad_parts = [_datasets(out / "dad" / s, cfg["training_runs"]) for s in done[1:]]
    for stage in stage_names(cfg)[len(done):]:
        clock.lap()
        if stage != "bc":
            dad_parts.append(_dad_round(out, cfg, stage, done[-1], backend))
        data = train if stage == "bc" else tuple(np.concatenate(c) for c in zip(train, *dad_parts))
        fitter.fit(stage, data, validation, cfg["bc_epochs"] if stage == "bc" else cfg["dad_epochs"])
        done.append(stage)
        timings[stage] = clock.lap()
        _save_stage(out, fitter, stage, done, timings, cfg)
    write_atomic(out / "progress.csv", _progress_csv(fitter.rows))
    learning_curves_figure(fitter.rows, out / "learning_curves.png")
    copy_atomic(out / "policies" / f"{done[-1]}.npz", out / "policy.npz")
    summary = _summary(out, cfg, fitter, timings)
    write_json_atomic(out / "summary.json", summary)
    return summary


class _Clock:
    """Wall and CPU seconds (this process) since the last lap."""

    def __init__(self):
        self.t, self.c = time.perf_counter(), time.process_time()

    def lap(self) -> dict:
        t, c = time.perf_counter(), time.process_time()
        lap = {"wall_s": t - self.t, "cpu_s": c - self.c}
        self.t, self.c = t, c
        return lap


def _index(index_path: Path) -> tuple:
    """(stages finished, their timings) from ``checkpoints/index.json`` (none yet: empty)."""
    if not index_path.exists():
        return [], {}
    import json

    index = json.loads(index_path.read_text())
    return list(index["stages"]), dict(index.get("timings", {}))


def _dad_round(out: Path, cfg: dict, stage: str, previous: str, backend) -> tuple:
    """The rollouts of round ``stage`` by the policy of stage ``previous`` (one task per training run)."""
    folder = out / "dad" / stage
    folder.mkdir(parents=True, exist_ok=True)
    policy = str(out / "policies" / f"{previous}.npz")
    _run_tasks([{"run": r, "config": cfg, "policy": policy, "path": str(folder / f"{r}.npz")}
                for r in cfg["training_runs"]], backend, dad_task)
    return _datasets(folder, cfg["training_runs"])


def _save_stage(out: Path, fitter: _Fitter, stage: str, stages: list, timings: dict, cfg: dict) -> None:
    import torch

    for sub in ("checkpoints", "policies"):
        (out / sub).mkdir(parents=True, exist_ok=True)
    path = out / "checkpoints" / f"{stage}.pt"
    tmp = path.with_suffix(".pt.tmp")
    torch.save(fitter.state(), tmp)
    os.replace(tmp, path)
    save_policy_file(fitter.policy_file(stage, cfg), str(out / "policies" / f"{stage}.npz"))
    write_json_atomic(out / "checkpoints" / "index.json", {"stages": stages, "timings": timings})


_PROGRESS_COLUMNS = ("stage", "epoch", "samples", "train_mse", "validation_mse", "validation_speed_error_m_s", "wall_s",
                     "cpu_s")


def _progress_csv(rows: list) -> str:
    return ",".join(_PROGRESS_COLUMNS) + "\n" + "".join(
        ",".join(str(r[c]) if isinstance(r[c], (str, int)) else f"{r[c]:.6g}" for c in _PROGRESS_COLUMNS) + "\n"
        for r in rows)


def learning_curves_figure(rows: list, path) -> Path:
    """The learning curves of :data:`_PROGRESS_COLUMNS` rows: the training and validation mean squared errors and
    the validation speed error against the epochs of all stages, each stage's first epoch marked."""
    plt = pyplot()
    fig, (ax, ax1) = plt.subplots(1, 2, figsize=(11, 4))
    x = np.arange(1, len(rows) + 1)
    ax.plot(x, [r["train_mse"] for r in rows], label="training runs (recordings and rollouts)")
    ax.plot(x, [r["validation_mse"] for r in rows], label="validation runs (recordings)")
    ax.set_yscale("log")
    ax.set_ylabel("mean squared error of the action ((m/s)²)")
    ax1.plot(x, [r["validation_speed_error_m_s"] for r in rows], color="C1")
    ax1.set_ylabel("validation speed error (m/s, per decision)")
    for a in (ax, ax1):
        for k, r in enumerate(rows):
            if r["epoch"] == 1:
                a.axvline(k + 1, color="0.8", lw=0.8)
                a.annotate(r["stage"], (k + 1, 1.0), xycoords=("data", "axes fraction"), fontsize=7, va="top")
        a.set_xlabel("epoch (all stages)")
    ax.legend(fontsize=7)
    return Path(save_figure(fig, Path(path)))


def open_loop_errors(out, cfg: dict, stages: list) -> dict:
    """The mean speed error (m/s, over the seen decisions, i.e. per pedestrian and decision interval) on each
    validation run's recorded states: of each stage's policy (its action against the recorded velocity over the
    next 0.1 s) and of the calibrated agent (its intent, desired speed 1.34 m/s), with the same means over the
    decisions where no two recorded disks overlap (``*_sparse``: states a disk crowd can be in)."""
    out = Path(out)
    params = rollout_params(cfg)
    table = {}
    for name in cfg["validation_runs"]:
        demos = load_demonstrations(out / "demonstrations" / f"{name}.npz")
        seen = demos.select(demos.seen)
        speed = np.hypot(*seen.action.T)
        scenario, replay = _replay(name, cfg)
        cal, sparse = _calibrated_speeds(replay, scenario, params, seen)
        row = {"decisions": len(seen), "sparse_decisions": int(sparse.sum()),
               "calibrated": float(np.abs(cal - speed).mean()),
               "calibrated_sparse": float(np.abs(cal - speed)[sparse].mean())}
        for stage in stages:
            pred = FileObservationPolicy(out / "policies" / f"{stage}.npz").actions(seen.observation)
            err = np.abs(np.hypot(*pred.T.astype(np.float64)) - speed)
            row[stage], row[f"{stage}_sparse"] = float(err.mean()), float(err[sparse].mean())
        table[name] = row
    return table


def _calibrated_speeds(replay, scenario, params, seen) -> tuple:
    """The calibrated agent's intent speeds at the decisions of ``seen``, and whether each decision's recorded
    crowd is free of overlapping disks around it (nobody within two radii)."""
    times = np.round(seen.time_s / replay.decision_dt_s).astype(np.int64)
    k_of = {round(t / replay.decision_dt_s): k for k, t in enumerate(replay.time_s)}
    col = {int(i): c for c, i in enumerate(replay.ids)}
    speeds = np.empty(len(seen))
    sparse = np.empty(len(seen), bool)
    radius = float(scenario.radius_m()[0])
    for step in np.unique(times):
        sel = np.flatnonzero(times == step)
        k = k_of[int(step)]
        rows = np.array([col[int(i)] for i in seen.pedestrian[sel]])
        speeds[sel] = np.hypot(*calibrated_actions(replay, scenario, params, k, rows).T)
        here = replay.position_m[k][replay.present[k]]
        d = np.hypot(*(here[None, :, :] - replay.position_m[k, rows][:, None, :]).transpose(2, 0, 1))
        sparse[sel] = np.sort(d, axis=1)[:, 1] >= 2.0 * radius if here.shape[0] > 1 else True
    return speeds, sparse


def _summary(out: Path, cfg: dict, fitter: _Fitter, timings: dict) -> dict:
    """What ``summary.json`` holds (module docstring); ``timings``: wall and CPU seconds of this process per stage,
    summed over the sessions of a resumed training."""
    stages = stage_names(cfg)
    sizes = {}
    for r in (*cfg["training_runs"], *cfg["validation_runs"]):
        d = load_demonstrations(out / "demonstrations" / f"{r}.npz")
        sizes[r] = {"decisions": len(d), "seen": int(d.seen.sum())}
    return {"config": cfg, "stages": stages, "datasets": sizes, "timings": timings,
            "wall_s": sum(t["wall_s"] for t in timings.values()),
            "cpu_s_this_process": sum(t["cpu_s"] for t in timings.values()),
            "final_validation_mse": fitter.rows[-1]["validation_mse"],
            "final_validation_speed_error_m_s": fitter.rows[-1]["validation_speed_error_m_s"],
            "open_loop": open_loop_errors(out, cfg, stages), "policy": str(out / "policy.npz")}
