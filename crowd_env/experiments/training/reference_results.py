"""Reference results: learned pedestrian policies against the calibrated model, on one task suite, one way.

The reference results (``crowd-reference-results``) trains and evaluates a documented set of policies on a documented set
of tasks and writes one results table with 95 % intervals, learning curves and the figures of the
documentation's results page (docs/validation/reference_results.md).

**Tasks** (:data:`TASKS`; ``--quick``: :data:`QUICK_TASKS`, the same code path with tiny crowds and budgets):
the Seyfried bottleneck (b = 1.0 m, N = 60) with everybody controlled; the same bottleneck with a few
learners among a calibrated crowd; the bidirectional corridor; the room with a pillar. Learners decide
every 0.1 s (``frame_skip=10``) with the default observation and action bound.

**Policies** (:data:`POLICIES`): the calibrated model (``baseline``: decisions every 0.01 s with its own
action bound, ``baselines.reference_policies.CalibratedPolicy``), ``random``, ``zero``, ``ppo`` (one network
shared by all learners, Stable-Baselines3), ``mappo`` (TorchRL, centralised critic on ``state()``) and
``bc`` (behaviour cloning of the calibrated model's intents, :mod:`crowd_env.experiments.training.imitation`). The
learned ones are trained with ``train_seeds`` and saved as :mod:`policy files
<crowd_env.envs.policy_files>`; every policy is evaluated on the same ``eval_seeds`` (unseen in
training: training and demonstrations use other seeds).

**Measures** per episode: the evaluation harness's (:mod:`crowd_env.experiments.running.evaluation`: evacuation,
J_s (NaN for an episode that did not finish: never a flow figure from a stalled run), mean speed, density
in front of the bottleneck, number and size of contact percussions, smallest gap, per-agent return), and
per trained policy its training cost (agent steps, wall time, one core each).

**Statistics**: per (task, policy) the mean over all evaluation episodes, with a 95 % interval from a
two-level percentile bootstrap (:func:`bootstrap_interval`): resample the training seeds, then the
evaluation episodes within each, 2000 times; for policies without training one level (the episodes).

**Resumable and distributed**: every training run and every evaluation cell is one task on a
:mod:`backend <crowd_env.experiments.running.backends>` (Ray, also a cluster by ``address``, a process pool, or
serial: the same executor as the calibration), written atomically to ``out`` when it finishes; a rerun
skips what is there, and a folder made with another plan is refused.
"""
from __future__ import annotations

import csv
import json
import math
import os
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from crowd_env.errors import InputError, RunStoreError

from ...walking.model import ModelParams
from ...core.checks import check_integer
from ...envs.crowd_v0 import decisions_for_time
from ..running.evaluation import DEFAULT_POLICY_RESOLVER, ScenarioSpec, evaluate, import_object
from crowd_env.files import copy_atomic, save_figure_atomic, write_json_atomic
from ..output.tables import format_table

__all__ = ["Task", "TASKS", "QUICK_TASKS", "POLICIES", "LEARNED", "BUDGETS", "QUICK_BUDGETS", "ReferencePlan",
           "make_plan", "run_reference_results", "bootstrap_interval", "summarize_cells", "format_results", "MEASURES",
           "train_one", "evaluate_one", "video_one", "video_path", "video_task", "learning_curves",
           "plot_learning_curves", "ship_policies", "compute_seconds", "target_checks", "format_checks",
           "algorithm_and_reward"]

POLICIES = ("baseline", "random", "zero", "ppo", "mappo", "bc", "ppo_le", "mappo_le")
LEARNED = ("ppo", "mappo", "bc", "ppo_le", "mappo_le")
# the learned policies trained with another reward than the default (crowd_env.envs.rewards.REWARDS): the
# algorithm they run and the reward's name
TRAINED_WITH = {"ppo_le": ("ppo", "least_effort"), "mappo_le": ("mappo", "least_effort")}
LEARNER_OPTIONS = {"frame_skip": 10}

# the least-effort policies' mean speed in the corridors: around the reward's optimum sqrt(e_s / e_w) = 1.33 m/s
LEAST_EFFORT_SPEED_M_S = (1.1, 1.5)
CORRIDOR_TASKS = ("corridor_bidirectional", "corridor_periodic", "counterflow_periodic")


def algorithm_and_reward(policy: str) -> tuple:
    """The trainer a learned policy runs and the name of the reward it is trained with (:data:`TRAINED_WITH`,
    else its own name and ``"default"``)."""
    return TRAINED_WITH.get(policy, (policy, "default"))


@dataclass(frozen=True)
class Task:
    """One reference-results task: the environment options of its learners (``env_config``) and the evaluation's time
    limit. ``max_steps`` of the environment follows from ``max_time_s``."""

    name: str
    description: str
    env_config: dict
    max_time_s: float

    def learner_config(self) -> dict:
        dt_decision = ModelParams().dt_s * self.env_config.get("frame_skip", 1)
        return {**self.env_config, "max_steps": decisions_for_time(self.max_time_s, dt_decision)}


def _bottleneck(n: int, controlled="all") -> dict:
    return {"scenario": "seyfried_bottleneck", "scenario_options": {"width_m": 1.0, "n_pedestrians": n},
            "controlled": controlled, **LEARNER_OPTIONS}


def _periodic(density_per_m2: float, westbound_fraction: float) -> dict:
    return {"scenario": "periodic_corridor", "scenario_options": {"length_m": 20.0, "width_m": 1.8,
            "density_per_m2": density_per_m2, "westbound_fraction": westbound_fraction}, "controlled": "all",
            **LEARNER_OPTIONS}


TASKS = {
    "bottleneck": Task("bottleneck", "Seyfried bottleneck, b = 1.0 m, N = 60, all controlled", _bottleneck(60), 90.0),
    "bottleneck_learners": Task("bottleneck_learners", "the same bottleneck, 6 learners among 54 calibrated pedestrians",
                                _bottleneck(60, controlled=6), 90.0),
    "corridor_bidirectional": Task("corridor_bidirectional", "bidirectional corridor, 20 pedestrians, all controlled",
                                   {"scenario": "corridor_bidirectional", "controlled": "all", **LEARNER_OPTIONS}, 60.0),
    "room_pillar": Task("room_pillar", "room with a pillar before the door, 30 pedestrians, all controlled",
                        {"scenario": "room_pillar", "controlled": "all", **LEARNER_OPTIONS}, 60.0),
    "corridor_periodic": Task("corridor_periodic", "periodic corridor 20 m x 1.8 m, 18 pedestrians (0.5 /m²) walking "
                              "east, all controlled", _periodic(0.5, 0.0), 60.0),
    "counterflow_periodic": Task("counterflow_periodic", "periodic corridor 20 m x 1.8 m, 36 pedestrians (1 /m²), "
                                 "half walking each way, all controlled", _periodic(1.0, 0.5), 60.0),
}
QUICK_TASKS = {
    "bottleneck": Task("bottleneck", "Seyfried bottleneck, b = 1.0 m, N = 8, all controlled (quick)", _bottleneck(8),
                       20.0),
}
# Training budgets: PPO timesteps (agent steps), MAPPO environment steps (frames), BC demonstration seeds
BUDGETS = {"ppo_timesteps": 2_000_000, "mappo_frames": 20_000, "bc_demo_seeds": 10, "bc_epochs": 15,
           "bc_dagger_rounds": 3}
QUICK_BUDGETS = {"ppo_timesteps": 512, "mappo_frames": 40, "bc_demo_seeds": 1, "bc_epochs": 2, "bc_dagger_rounds": 1}
ZERO_ALLOWED = ("bc_dagger_rounds",)  # 0: plain behaviour cloning
VIDEO_FPS, VIDEO_QUALITY = 5.0, 4.0  # the videos: a frame every 0.2 s in real time; about 3 MB for six
MEASURES = (
    ("evacuated_fraction", "evacuated", "{:.0%}"),
    ("evacuation_time_s", "evac. time (s)", "{:.1f}"),
    ("specific_flow_per_m_s", "J_s (1/m/s)", "{:.2f}"),
    ("mean_speed_m_s", "mean speed (m/s)", "{:.2f}"),
    ("density_front_per_m2", "density in front (1/m²)", "{:.2f}"),
    ("n_percussions", "percussions", "{:.0f}"),
    ("mean_percussion_kg_m_s", "mean percussion (kg m/s)", "{:.2f}"),
    ("min_gap_m", "min gap (mm)", "mm"),
    ("mean_return", "return per agent", "{:.2f}"),
    ("lane_order", "lane order", "{:.2f}"),
)


@dataclass
class ReferencePlan:
    """What a reference-results run does: tasks, policies, seeds and budgets (kept in ``out/plan.json``)."""

    tasks: dict
    policies: tuple = POLICIES
    train_seeds: tuple = (0, 1, 2)
    eval_seeds: tuple = tuple(range(10))
    budgets: dict = field(default_factory=lambda: dict(BUDGETS))
    resolver: str = DEFAULT_POLICY_RESOLVER
    quick: bool = False

    def to_dict(self) -> dict:
        return {"tasks": {k: asdict(t) for k, t in self.tasks.items()}, "policies": list(self.policies),
                "train_seeds": list(self.train_seeds), "eval_seeds": list(self.eval_seeds), "budgets": self.budgets,
                "resolver": self.resolver, "quick": self.quick}


def make_plan(*, quick: bool = False, tasks=None, policies=None, train_seeds=None, eval_seeds=None,
              budgets: dict | None = None) -> ReferencePlan:
    """The plan, checked: unknown tasks or policies, no seeds, an evaluation seed used in training, or a budget
    that is not a positive integer raise :class:`~crowd_env.errors.InputError` naming them."""
    known = QUICK_TASKS if quick else TASKS
    names = list(tasks) if tasks else list(known)
    bad = [t for t in names if t not in known]
    if bad:
        raise InputError(f"unknown reference-results task(s) {bad}; the {'quick ' if quick else ''}tasks are {list(known)}")
    pols = tuple(policies) if policies else POLICIES
    bad = [p for p in pols if p not in POLICIES]
    if bad:
        raise InputError(f"unknown reference-results policy(ies) {bad}; choose from {list(POLICIES)}")
    train = tuple(int(s) for s in (train_seeds if train_seeds is not None else ((0, 1) if quick else (0, 1, 2))))
    evals = tuple(int(s) for s in (eval_seeds if eval_seeds is not None else ((0, 1) if quick else range(10))))
    if not evals or (any(p in LEARNED for p in pols) and not train):
        raise InputError("the reference results need at least one evaluation seed, and one training seed for learned policies")
    b = dict(QUICK_BUDGETS if quick else BUDGETS)
    for k, v in (budgets or {}).items():
        if k not in b:
            raise InputError(f"unknown budget {k!r}; the budgets are {list(b)}")
        b[k] = v
    for k, v in b.items():
        least = 0 if k in ZERO_ALLOWED else 1
        check_integer(f"budget {k}", v, error=InputError, minimum=least)
    if b["bc_demo_seeds"] > 100 or b["bc_dagger_rounds"] > 9:  # each round's seeds in its own hundred
        raise InputError(f"at most 100 demonstration seeds and 9 DAgger rounds, got {b['bc_demo_seeds']} and "
                         f"{b['bc_dagger_rounds']}")
    overlap = set(evals) & _seeds_used_in_training(train, b["bc_demo_seeds"], b["bc_dagger_rounds"])
    if overlap:
        raise InputError(f"evaluation seeds {sorted(overlap)} are also training seeds")
    return ReferencePlan({n: known[n] for n in names}, pols, train, evals, b, quick=quick)


def _train_env_seed(seed: int) -> int:
    return 10_000 + 1_000 * int(seed)  # the seeds of training episodes start here (never an evaluation seed)


def _demo_seeds(seed: int, n: int, round_: int = 0) -> list:
    """The demonstration seeds of training seed ``seed``'s behaviour cloning, round ``round_`` (0: the teacher's
    demonstrations; then the DAgger rounds)."""
    return [20_000 + 1_000 * int(seed) + 100 * int(round_) + i for i in range(int(n))]


def _seeds_used_in_training(train_seeds, n_demo: int, n_rounds: int = 0) -> set:
    """Every episode seed a training run sets: the training copies (PPO's two, MAPPO's first), the trainers'
    own evaluation episodes and the demonstrations of every round, for each training seed."""
    out = set()
    for s in train_seeds:
        base = _train_env_seed(s)
        out |= {base, base + 1, base + 500}
        for r in range(n_rounds + 1):
            out |= set(_demo_seeds(s, n_demo, r))
    return out


# -- the two kinds of work unit ------------------------------------------------------------------------------

def train_dir(out: str, task: str, algorithm: str, seed: int) -> str:
    return os.path.join(out, "train", task, algorithm, f"seed{seed}")


def eval_path(out: str, task: str, policy: str, seed) -> str:
    return os.path.join(out, "eval", task, f"{policy}_seed{seed}.json" if seed is not None else f"{policy}.json")


def train_one(job: dict) -> dict:
    """Train one policy (``job``: task, algorithm, seed, budgets, out, resolver) and write its policy file
    ``policy.npz`` and ``cost.json`` in its folder; resumes a training run a kill interrupted."""
    from ...envs.policy_files import from_torchrl, save_policy_file
    from .conversion import sb3_policy_file

    resolve = import_object(job["resolver"])
    task = Task(**job["task"])
    cfg = task.learner_config()
    folder = job["dir"]
    seed, name, budgets = int(job["seed"]), job["algorithm"], job["budgets"]
    algo, reward = algorithm_and_reward(name)
    if reward != "default":
        cfg["reward_terms"] = reward
    quiet = lambda *a, **k: None  # noqa: E731
    t0 = time.perf_counter()
    resume = os.path.isdir(os.path.join(folder, "checkpoints"))
    if algo == "ppo":
        from . import ppo as training
        summary = training.train(cfg, int(budgets["ppo_timesteps"]), folder, resolve=resolve, seed=_train_env_seed(seed),
                                 copies=2, eval_seeds=(_train_env_seed(seed) + 500,), resume=resume, progress=quiet,
                                 checkpoint_every=max(10_000, int(budgets["ppo_timesteps"]) // 10))
        policy = sb3_policy_file(os.path.join(folder, "model.zip"), env_config=cfg)  # read without unpickling
        agent_steps = int(summary["timesteps"])
    elif algo == "mappo":
        from . import marl
        summary = marl.train(cfg, int(budgets["mappo_frames"]), folder, algorithm="mappo", resolve=resolve,
                             seed=_train_env_seed(seed), eval_seeds=(_train_env_seed(seed) + 500,), resume=resume,
                             progress=quiet)
        policy = from_torchrl(marl.load_policy(folder), env_config=cfg)
        agent_steps = int(summary["agent_steps"])
    elif algo == "bc":
        from .imitation import train_behaviour_cloning

        rounds = [_demo_seeds(seed, budgets["bc_demo_seeds"], r) for r in range(int(budgets["bc_dagger_rounds"]) + 1)]
        summary = train_behaviour_cloning(cfg, folder, teacher=resolve("baseline"), seed=seed, demo_seeds=rounds[0],
                                          dagger_seeds=rounds[1:], epochs=int(budgets["bc_epochs"]),
                                          max_time_s=task.max_time_s, progress=quiet)
        agent_steps = int(summary["agent_steps"])
        policy = None  # written by train_behaviour_cloning
    else:
        raise InputError(f"not a learned policy: {name!r}")
    if policy is not None:
        policy.meta.update({"algorithm": algo, "reward": reward, "task": task.name, "seed": seed})
        save_policy_file(policy, os.path.join(folder, "policy.npz"))
    cost = {"algorithm": name, "task": task.name, "seed": seed, "agent_steps": agent_steps,
            "train_wall_s": float(summary.get("train_wall_s", float("nan"))),
            "total_wall_s": time.perf_counter() - t0, "cores": 1}
    write_json_atomic(os.path.join(folder, "cost.json"), cost)
    return cost


def _scenario_and_options(task: "Task") -> tuple:
    """The task's scenario (a :class:`ScenarioSpec` labelled with the task's name) and its other env options."""
    cfg = dict(task.env_config)
    return ScenarioSpec(cfg.pop("scenario"), cfg.pop("scenario_options", None), label=task.name), cfg


def evaluate_one(job: dict) -> list:
    """Evaluate one policy (``job``: task, policy, its file for a learned one, eval seeds, resolver) on every
    evaluation seed; writes and returns the episodes' metrics (dicts)."""
    task = Task(**job["task"])
    label = job["policy"]
    scenario, cfg = _scenario_and_options(task)
    episodes = evaluate({label: job["policy_file"] or label}, [scenario], [int(s) for s in job["eval_seeds"]],
                        env_options=cfg, max_time_s=task.max_time_s, progress=None,
                        resolve=import_object(job["resolver"]))
    rows = [asdict(m) for m in episodes]
    write_json_atomic(job["out"], {"task": task.name, "policy": label, "train_seed": job["train_seed"], "episodes": rows})
    return rows


def video_path(out: str, task: str, policy: str) -> str:
    return os.path.join(out, "videos", f"{task}_{policy}.mp4")


def video_one(job: dict) -> dict:
    """Record one episode of one policy (``job``: task, policy, its file for a learned one, the evaluation
    seed, resolver, out) as an MP4 in real time at :data:`VIDEO_FPS` frames per second
    (:func:`crowd_env.experiments.output.video.record_rollout`: the evaluation harness's episode, percussions drawn;
    written under a temporary name and renamed, so a killed unit leaves no video); returns what was written
    and the episode's figures."""
    from ..output.video import record_rollout

    task = Task(**job["task"])
    scenario, cfg = _scenario_and_options(task)
    seed = int(job["seed"])
    t0 = time.perf_counter()
    metrics, info = record_rollout(job["policy_file"] or job["policy"], job["out"], scenario, seed, env_options=cfg,
                                   max_time_s=task.max_time_s, resolver=job["resolver"], fps=VIDEO_FPS,
                                   quality=VIDEO_QUALITY, label=f"{job['policy']}, {task.name}, evaluation seed {seed}")
    value = {"path": job["out"], "n_frames": info.n_frames, "fps": info.fps, "n_evacuated": metrics.n_evacuated,
             "n_pedestrians": metrics.n_pedestrians, "simulated_time_s": metrics.simulated_time_s,
             "wall_s": time.perf_counter() - t0}
    write_json_atomic(job["out"][:-len(".mp4")] + ".json", value)
    return value


# -- running the plan ----------------------------------------------------------------------------------------

def _check_folder(out: str, plan: ReferencePlan) -> None:
    path = os.path.join(out, "plan.json")
    want = json.loads(json.dumps(plan.to_dict()))  # as it reads back (tuples as lists)
    if os.path.exists(path):
        with open(path) as fh:
            have = json.load(fh)
        if have != want:
            diff = sorted(k for k in set(have) | set(want) if have.get(k) != want.get(k))
            raise RunStoreError(f"{out} holds reference results of another plan (differs in {diff}); use another --out")
    else:
        os.makedirs(out, exist_ok=True)
        write_json_atomic(path, want)


def _done_training(folder: str) -> bool:
    return os.path.exists(os.path.join(folder, "policy.npz")) and os.path.exists(os.path.join(folder, "cost.json"))


def _run_units(backend, fn, jobs, failed: list, progress, what, report) -> None:
    """Run ``fn`` on every job on ``backend``; ``progress`` names each finished one (``what(job)``:
    ``report(value)``), ``failed`` collects the others with their error."""
    for job, ok, value in backend.imap_unordered(fn, jobs):
        if ok:
            progress(f"{what(job)}: {report(value)}")
        else:
            failed.append(f"{what(job)}: {value}")


def _nanmean(values) -> float:
    v = np.asarray(values, dtype=float)
    return float(np.nanmean(v)) if np.isfinite(v).any() else float("nan")


def video_task(plan: "ReferencePlan") -> str:
    """The task the videos show: the all-controlled bottleneck when the plan has it, else its first task."""
    return "bottleneck" if "bottleneck" in plan.tasks else next(iter(plan.tasks))


def run_reference_results(plan: ReferencePlan, out: str, *, backend=None, progress=print, videos: bool = True) -> dict:
    """Run ``plan`` into ``out`` (resuming what is there) on ``backend`` (a :mod:`backends
    <crowd_env.experiments.running.backends>` executor; default serial): train, then evaluate, then (``videos``)
    record one episode of each policy on :func:`video_task` (the first evaluation seed; a learned policy's
    first training seed) to ``out/videos/<task>_<policy>.mp4``, then summarise. Returns the results (also
    ``out/results.json``); a failed unit is named in a :class:`~crowd_env.errors.BackendError` after the
    others finished, and is retried by the next run. Videos need the ``video`` extra, checked first."""
    from ..running.backends import BackendError, SerialBackend

    backend = backend or SerialBackend()
    progress = progress or (lambda *a: None)
    if videos:
        from ..output.video import check_video_path

        os.makedirs(os.path.join(out, "videos"), exist_ok=True)
        check_video_path(video_path(out, "task", "policy"))  # the writer is installed, before any work
    _check_folder(out, plan)
    t0 = time.perf_counter()
    jobs = [{"task": asdict(t), "algorithm": a, "seed": s, "budgets": plan.budgets, "resolver": plan.resolver,
             "dir": train_dir(out, t.name, a, s)}
            for t in plan.tasks.values() for a in plan.policies if a in LEARNED for s in plan.train_seeds]
    todo = [j for j in jobs if not _done_training(j["dir"])]
    failed = []
    _run_units(backend, train_one, todo, failed, progress,
               lambda j: f"train {j['task']['name']} {j['algorithm']} seed {j['seed']}",
               lambda v: f"{v['agent_steps']} agent steps, {v['total_wall_s']:.0f} s")
    evals = []
    for t in plan.tasks.values():
        for p in plan.policies:
            for s in (plan.train_seeds if p in LEARNED else (None,)):
                pf = os.path.join(train_dir(out, t.name, p, s), "policy.npz") if p in LEARNED else None
                if pf is not None and not os.path.exists(pf):
                    continue  # its training failed: named above
                evals.append({"task": asdict(t), "policy": p, "policy_file": pf, "train_seed": s,
                              "eval_seeds": list(plan.eval_seeds), "resolver": plan.resolver,
                              "out": eval_path(out, t.name, p, s)})
    todo = [j for j in evals if not os.path.exists(j["out"])]
    _run_units(backend, evaluate_one, todo, failed, progress,
               lambda j: f"evaluate {j['task']['name']} {j['policy']}" + (
                   f" (trained with seed {j['train_seed']})" if j["train_seed"] is not None else ""),
               lambda v: f"{len(v)} episodes, J_s {_nanmean([r['specific_flow_per_m_s'] for r in v]):.2f}")
    if videos:
        t, first = plan.tasks[video_task(plan)], plan.train_seeds[0]
        shots = [{"task": asdict(t), "policy": p, "seed": plan.eval_seeds[0], "resolver": plan.resolver,
                  "policy_file": os.path.join(train_dir(out, t.name, p, first), "policy.npz") if p in LEARNED else None,
                  "out": video_path(out, t.name, p)} for p in plan.policies]
        todo = [j for j in shots if not os.path.exists(j["out"])
                and (j["policy_file"] is None or os.path.exists(j["policy_file"]))]
        _run_units(backend, video_one, todo, failed, progress, lambda j: f"video {j['task']['name']} {j['policy']}",
                   lambda v: f"{v['path']} ({v['n_frames']} frames)")
    if failed:
        raise BackendError(f"{len(failed)} reference-results unit(s) failed (rerun to retry them):\n" + "\n".join(failed))
    results = summarize_cells(out, plan)
    results["wall_s_this_run"] = time.perf_counter() - t0
    write_json_atomic(os.path.join(out, "results.json"), results)
    return results


# -- statistics and the results table ------------------------------------------------------------------------

def bootstrap_interval(groups, *, n_resamples: int = 2000, confidence: float = 0.95, seed: int = 0) -> tuple:
    """``(mean, low, high)`` of the values in ``groups`` (a list of 1-D arrays, one per training seed; NaN values
    left out): the mean over all values, and the percentile interval of a two-level bootstrap (resample the
    groups with replacement, then the values within each chosen group). One group: the plain percentile
    bootstrap of the mean. NaN when no value is finite; the interval is (mean, mean) for a single value."""
    groups = [np.asarray(g, float)[np.isfinite(np.asarray(g, float))] for g in groups]
    groups = [g for g in groups if g.size]
    if not groups:
        return float("nan"), float("nan"), float("nan")
    mean = float(np.mean(np.concatenate(groups)))
    rng = np.random.default_rng(seed)
    stats = np.empty(n_resamples)
    for i in range(n_resamples):
        picked = [groups[j] for j in rng.integers(0, len(groups), len(groups))]
        stats[i] = np.mean(np.concatenate([g[rng.integers(0, g.size, g.size)] for g in picked]))
    alpha = (1.0 - confidence) / 2.0
    lo, hi = np.quantile(stats, [alpha, 1.0 - alpha])
    return mean, float(min(lo, mean)), float(max(hi, mean))


def _episode_values(row: dict, key: str) -> float:
    if key == "evacuated_fraction":
        return row["n_evacuated"] / row["n_pedestrians"]
    return float(row[key]) if row.get(key) is not None else float("nan")


def summarize_cells(out: str, plan: ReferencePlan) -> dict:
    """Per (task, policy): every measure's mean and 95 % interval over its episodes (:func:`bootstrap_interval`),
    the number of episodes, complete and stalled ones, and for learned policies the training cost."""
    cells = []
    for t in plan.tasks.values():
        for p in plan.policies:
            seeds = plan.train_seeds if p in LEARNED else (None,)
            groups = []
            for s in seeds:
                path = eval_path(out, t.name, p, s)
                if os.path.exists(path):
                    with open(path) as fh:
                        groups.append(json.load(fh)["episodes"])
            if not groups:
                continue
            cell = {"task": t.name, "policy": p, "n_episodes": sum(len(g) for g in groups),
                    "n_complete": sum(bool(r["complete"]) for g in groups for r in g),
                    "n_stalled": sum(bool(r["stalled"]) for g in groups for r in g), "measures": {}}
            for key, _, _ in MEASURES:
                vals = [[_episode_values(r, key) for r in g] for g in groups]
                m, lo, hi = bootstrap_interval(vals)
                cell["measures"][key] = {"mean": _num(m), "low": _num(lo), "high": _num(hi),
                                         "n": int(sum(np.isfinite(v).sum() for v in map(np.asarray, vals)))}
            if p in LEARNED:
                costs = []
                for s in seeds:
                    path = os.path.join(train_dir(out, t.name, p, s), "cost.json")
                    if os.path.exists(path):
                        with open(path) as fh:
                            costs.append(json.load(fh))
                cell["training"] = {"runs": len(costs), "agent_steps": int(np.mean([c["agent_steps"] for c in costs])),
                                    "wall_s": float(np.mean([c["total_wall_s"] for c in costs])), "cores": 1}
            cells.append(cell)
    return {"plan": plan.to_dict(), "cells": cells, "compute_s": compute_seconds(out, plan)}


def compute_seconds(out: str, plan: ReferencePlan) -> dict:
    """The work of the run so far in core-seconds (each unit runs on one core), per phase: training (the
    training runs' wall times), evaluation (the episodes' wall times) and videos; ``total``. On k cores with k
    workers the run takes about total / k, whatever the number of sessions it was resumed in."""
    train = evaluation = videos = 0.0
    for t in plan.tasks.values():
        for p in plan.policies:
            for s in (plan.train_seeds if p in LEARNED else (None,)):
                if s is not None and os.path.exists(os.path.join(train_dir(out, t.name, p, s), "cost.json")):
                    with open(os.path.join(train_dir(out, t.name, p, s), "cost.json")) as fh:
                        train += float(json.load(fh)["total_wall_s"])
                if os.path.exists(eval_path(out, t.name, p, s)):
                    with open(eval_path(out, t.name, p, s)) as fh:
                        evaluation += sum(float(r["wall_time_s"]) for r in json.load(fh)["episodes"])
            cost = video_path(out, t.name, p)[:-len(".mp4")] + ".json"
            if os.path.exists(cost):
                with open(cost) as fh:
                    videos += float(json.load(fh)["wall_s"])
    return {"training": train, "evaluation": evaluation, "videos": videos, "total": train + evaluation + videos}


def target_checks(results: dict) -> list:
    """The reference results' targets on its results, one row each (``check``, ``task``, ``policy``, ``measured``,
    ``target``, ``holds``): every policy learned with the default reward returns more than random on its task
    with non-overlapping 95 % intervals (the returns are the default reward's); the behaviour clone's J_s within
    10 % of the calibrated model's and its number of percussions within a factor 2, on every task where both
    have a J_s; the least-effort policies' mean speed within :data:`LEAST_EFFORT_SPEED_M_S` in the corridors
    (:data:`CORRIDOR_TASKS`). A cell that is missing is not checked."""
    by = {(c["task"], c["policy"]): c["measures"] for c in results["cells"]}
    rows = []
    for (task, policy), m in by.items():
        rand = by.get((task, "random"))
        if policy in TRAINED_WITH and task in CORRIDOR_TASKS and m["mean_speed_m_s"]["mean"] is not None:
            lo, hi = LEAST_EFFORT_SPEED_M_S
            v = m["mean_speed_m_s"]["mean"]
            rows.append({"check": "least-effort mean speed", "task": task, "policy": policy,
                         "measured": f"{v:.2f} m/s", "target": f"{lo:g}-{hi:g} m/s", "holds": bool(lo <= v <= hi)})
        if policy in LEARNED and policy not in TRAINED_WITH and rand is not None:
            r, q = m["mean_return"], rand["mean_return"]
            holds = None not in (r["low"], q["high"]) and r["low"] > q["high"]
            rows.append({"check": "return above random, intervals apart", "task": task, "policy": policy,
                         "measured": f"{_fmt('', '{:.2f}', r['low'])} > {_fmt('', '{:.2f}', q['high'])}",
                         "target": "low(policy) > high(random)", "holds": bool(holds)})
        base = by.get((task, "baseline"))
        if policy == "bc" and base is not None and base["specific_flow_per_m_s"]["mean"] is not None:
            js, jb = m["specific_flow_per_m_s"]["mean"], base["specific_flow_per_m_s"]["mean"]
            ratio = js / jb if js is not None else float("nan")
            rows.append({"check": "behaviour clone's J_s", "task": task, "policy": policy,
                         "measured": f"{ratio:.3f} x calibrated", "target": "within 10 %",
                         "holds": bool(abs(ratio - 1.0) <= 0.10)})
            n, nb = m["n_percussions"]["mean"], base["n_percussions"]["mean"]
            ratio = n / nb if n is not None and nb else float("nan")
            rows.append({"check": "behaviour clone's percussions", "task": task, "policy": policy,
                         "measured": f"{ratio:.2f} x calibrated", "target": "within a factor 2",
                         "holds": bool(0.5 <= ratio <= 2.0)})
    return rows


def format_checks(rows: list, *, markdown: bool = False) -> str:
    """:func:`target_checks` as a table."""
    head = ["check", "task", "policy", "measured", "target", "holds"]
    return format_table(head, [[r[k] if k != "holds" else ("yes" if r[k] else "NO") for k in head] for r in rows],
                        markdown=markdown)


def _num(v: float):
    """A finite float, or None (JSON null) for NaN: results.json stays strict JSON."""
    return float(v) if math.isfinite(v) else None


def _fmt(key: str, fmt: str, v) -> str:
    if v is None or not math.isfinite(v):
        return "nan"
    return f"{v * 1e3:.1f}" if fmt == "mm" else fmt.format(v)


def format_results(results: dict, *, markdown: bool = False) -> str:
    """The results table: per task and policy every measure as ``mean [low, high]`` (95 %), episodes complete /
    stalled, and the training cost."""
    head = ["task", "policy", "complete", "stalled"] + [label for _, label, _ in MEASURES] + ["training"]
    rows = []
    for c in results["cells"]:
        row = [c["task"], c["policy"], f"{c['n_complete']}/{c['n_episodes']}", f"{c['n_stalled']}/{c['n_episodes']}"]
        for key, _, fmt in MEASURES:
            m = c["measures"][key]
            cell = _fmt(key, fmt, m["mean"])
            if m["mean"] is not None:
                cell += f" [{_fmt(key, fmt, m['low'])}, {_fmt(key, fmt, m['high'])}]"
            if m["n"] < c["n_episodes"]:
                cell += f" ({m['n']} of {c['n_episodes']})"
            row.append(cell)
        tr = c.get("training")
        row.append(f"{tr['agent_steps']:,} agent steps, {tr['wall_s']:.0f} s" if tr else "-")
        rows.append(row)
    return format_table(head, rows, markdown=markdown)


# -- figures and shipping ------------------------------------------------------------------------------------

def learning_curves(out: str, plan: ReferencePlan) -> dict:
    """``{(task, algorithm): [(agent_steps (k,), episode return (k,)) per training seed]}`` from the training
    folders: PPO's ``learning_curve.csv`` (per finished episode of one agent) and MAPPO's ``progress.csv``
    (mean per-agent return of the episodes ended in each iteration), in the reward each was trained with
    (:data:`TRAINED_WITH`); BC has no return curve (its ``progress.csv`` holds the imitation loss)."""
    curves = {}
    for t in plan.tasks.values():
        for name in plan.policies:
            algo, _ = algorithm_and_reward(name)
            if algo not in ("ppo", "mappo"):
                continue
            for s in plan.train_seeds:
                folder = train_dir(out, t.name, name, s)
                if algo == "ppo":
                    path = os.path.join(folder, "learning_curve.csv")
                    if not os.path.exists(path):
                        continue
                    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
                    x, y = (data[:, 0], data[:, 1]) if data.size else (np.zeros(0), np.zeros(0))
                else:
                    path = os.path.join(folder, "progress.csv")
                    if not os.path.exists(path):
                        continue
                    with open(path) as fh:
                        rows = list(csv.DictReader(fh))
                    x = np.cumsum([float(r["agent_steps"]) for r in rows])
                    y = np.array([float(r["mean_episode_return"]) for r in rows])
                curves.setdefault((t.name, name), []).append((x, y))
    return curves


_COLOURS = {"ppo": "tab:blue", "mappo": "tab:orange", "baseline": "black", "random": "tab:red", "zero": "tab:grey",
            "bc": "tab:green", "ppo_le": "tab:purple", "mappo_le": "tab:brown"}


def plot_learning_curves(out: str, plan: ReferencePlan, results: dict, path: str) -> str:
    """One panel per task: the PPO and MAPPO training returns (running mean per seed) against agent steps,
    with the evaluation returns of the policies without training as horizontal lines (all in the default
    reward; the learned ones' evaluation in the default reward too); below, when the plan has them, the
    least-effort policies' training returns, in their own reward."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    curves = learning_curves(out, plan)
    tasks = list(plan.tasks)
    rows = [("ppo", "mappo"), tuple(p for p in plan.policies if p in TRAINED_WITH)]
    rows = [r for r in rows if r]
    fig = Figure(figsize=(5.0 * len(tasks), 3.8 * len(rows)))
    FigureCanvasAgg(fig)
    for row, algos in enumerate(rows):
        for i, name in enumerate(tasks):
            ax = fig.add_subplot(len(rows), len(tasks), row * len(tasks) + i + 1)
            for algo in algos:
                for k, (x, y) in enumerate(curves.get((name, algo), [])):
                    finite = np.isfinite(y)
                    x, y = x[finite], y[finite]
                    if y.size == 0:
                        continue
                    w = max(1, y.size // 20)
                    smooth = np.convolve(y, np.ones(w) / w, mode="valid")
                    ax.plot(x[w - 1:], smooth, color=_COLOURS[algo], lw=1.2,
                            label=f"{algo} (training)" if k == 0 else None)
            for c in results["cells"] if row == 0 else ():
                m = c["measures"]["mean_return"]
                if c["task"] == name and c["policy"] not in TRAINED_WITH and m["mean"] is not None:
                    ax.axhline(m["mean"], color=_COLOURS[c["policy"]], ls="--", lw=0.9,
                               label=f"{c['policy']} (evaluation)")
            ax.set_title(name, fontsize=9)
            ax.set_xlabel("agent steps of training")
            ax.set_ylabel("per-agent episode return" + (" (least effort)" if row else ""))
            ax.legend(fontsize=6)
    fig.tight_layout()
    return save_figure_atomic(fig, path, dpi=100)


def ship_policies(out: str, plan: ReferencePlan, dest: str, *, seed: int | None = None) -> list:
    """Copy the learned policies trained with ``seed`` (default: the plan's first training seed) into ``dest``
    as ``<task>_<algorithm>.npz`` (the shipped reference policies); returns the paths."""
    seed = plan.train_seeds[0] if seed is None else int(seed)
    os.makedirs(dest, exist_ok=True)
    paths = []
    for t in plan.tasks.values():
        for algo in plan.policies:
            if algo not in LEARNED:
                continue
            src = os.path.join(train_dir(out, t.name, algo, seed), "policy.npz")
            if not os.path.exists(src):
                raise RunStoreError(f"no trained {algo} policy for task {t.name} with seed {seed} in {out}")
            paths.append(copy_atomic(src, os.path.join(dest, f"{t.name}_{algo}.npz")))
    return paths
