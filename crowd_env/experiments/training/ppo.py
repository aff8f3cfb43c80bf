"""Training one PPO policy shared by all controlled pedestrians (Stable-Baselines3).

Every controlled pedestrian of ``copies`` copies of the PettingZoo environment of the Kabalan et al.
(2016) model is one slot of a vector environment, so every pedestrian's experience trains the same
network. ``vectoriser="native"`` (default) uses the project's own
:class:`~crowd_env.envs.sb3.CrowdSB3VecEnv` (arrays, agents that leave become padding slots until their
copy resets, see :mod:`crowd_env.envs.vector`); ``"supersuit"`` the SuperSuit chain
``black_death_v3`` → ``pettingzoo_env_to_vec_env_v1`` → ``concat_vec_envs_v1(..., base_class=
"stable_baselines3")`` with a ``VecMonitor``, kept for comparison (``tests/experiments/training/test_ppo.py``
trains both). :func:`train` writes ``model.zip``,
``env_config.json``, ``learning_curve.csv`` / ``.png``, ``summary.json`` (mean per-agent episode return
of a random policy and of the trained one on the same evaluation seeds) and resumable checkpoints
(``checkpoints/``, indexed last and atomically, each entry with the digest of its files under this account's
key, checked before a resume loads them: :func:`check_checkpoint`). SB3's ``.zip`` archives hold pickles, which
run code when loaded: load ``model.zip`` only from a source you trust, and share a policy as ``.npz``
(``crowd-convert-policy``). Needs the ``train`` extra (torch, SB3; SuperSuit for its vectoriser),
imported inside the functions that use it. Command line: ``crowd-train-ppo``.
"""
from __future__ import annotations

from crowd_env.errors import CrowdEnvError, TrainingError

import json
import os
import time
import warnings

import numpy as np

from ...envs import crowd_v0
from ..running.evaluation import ENV_CONFIG_FILE, episode_setup, run_episode
from crowd_env.files import (check_files_digest, files_digest, save_figure_atomic, write_atomic, write_csv_atomic,
                             write_json_atomic)

__all__ = ["DEFAULT_SCENARIO_OPTIONS", "SharedPolicy", "TrainingError", "make_vec_env", "mean_return", "read_checkpoints",
           "save_checkpoint", "check_resume", "check_env_config", "begin_run", "evaluate_trained", "train", "write_curve",
           "progress_line", "checkpoint_files", "sign_checkpoint", "check_checkpoint"]

DEFAULT_SCENARIO_OPTIONS = {"width_m": 1.0, "n_pedestrians": 10}
VECTORISERS = ("native", "supersuit")


def make_vec_env(env_config: dict, copies: int = 1, seed: int | None = None, vectoriser: str = "native",
                 workers: int = 1):
    """SB3 VecEnv over all controlled agents of ``copies`` environments (copy i seeded ``seed + i``), stepped
    in ``workers`` processes (the native vectoriser only; see :mod:`crowd_env.envs.vector`)."""
    if vectoriser not in VECTORISERS:
        raise TrainingError(f"unknown vectoriser {vectoriser!r}; choose one of {VECTORISERS}")
    if vectoriser == "native":
        from ...envs.sb3 import sb3_vec_env

        return sb3_vec_env(copies, seed=seed, workers=workers, **env_config)
    if workers != 1:
        raise TrainingError(f"workers = {workers!r} needs the native vectoriser; the supersuit chain steps its copies "
                            "in this process")
    import supersuit as ss
    from stable_baselines3.common.vec_env import VecMonitor

    env = crowd_v0.parallel_env(**env_config)
    env = ss.black_death_v3(env)
    vec = ss.pettingzoo_env_to_vec_env_v1(env)
    vec = ss.concat_vec_envs_v1(vec, copies, num_cpus=0, base_class="stable_baselines3")
    if seed is not None:
        # Seed every copy (copy i gets seed + i); SB3's later unseeded resets continue these streams.
        vec.venv.reset(seed=seed)
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="The `render_mode` attribute is not defined")
        return VecMonitor(vec)


class SharedPolicy:
    """A trained policy shared by all agents, as a policy of the evaluation harness: subclasses give
    ``obs_dim``, ``name`` and ``actions(observations (n, obs_dim)) -> (n, 2)``; :meth:`act` runs it on every
    live agent in one batch, :meth:`reset` refuses an environment whose observations have another size."""

    obs_dim: int
    name: str

    def actions(self, observations: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def reset(self, env, seed=None) -> None:
        have = env.observation_space(env.possible_agents[0]).shape[0]
        if have != self.obs_dim:
            raise TrainingError(f"policy {self.name!r} expects observations of {self.obs_dim} entries, the environment "
                                f"gives {have} (use the environment options it was trained with: env_config.json)")

    def act(self, env, observations) -> dict:
        if not env.agents:
            return {}
        obs = np.stack([observations[a] for a in env.agents])
        return dict(zip(env.agents, self.actions(obs)))


def mean_return(policy, env_config: dict, seeds) -> dict:
    """Mean per-agent episode return (and evacuated fraction) of ``policy`` over ``seeds``."""
    spec, opts, max_time = episode_setup(env_config)  # the episodes the policy is trained on
    runs = [run_episode(policy, spec, s, env_options=opts, max_time_s=max_time) for s in seeds]
    return {"mean_return": float(np.mean([r.mean_return for r in runs])),
            "std_return": float(np.std([r.mean_return for r in runs])),
            "evacuated_fraction": float(np.mean([r.n_evacuated / r.n_pedestrians for r in runs])),
            "n_percussions": float(np.mean([r.n_percussions for r in runs]))}



def write_progress(out: str, rows, columns) -> None:
    """``out/progress.csv``: one row per training iteration, the fields ``columns`` (the TorchRL and RLlib runs)."""
    write_csv_atomic(os.path.join(out, "progress.csv"), columns, rows)


def read_checkpoints(out: str) -> list:
    """Checkpoint entries of ``out`` in order (``{"timesteps", "model", "vecnormalize"}``), [] if none."""
    path = os.path.join(out, "checkpoints", "index.json")
    if not os.path.exists(path):
        return []
    with open(path) as fh:
        return json.load(fh)["checkpoints"]


def checkpoint_files(out: str, entry: dict) -> list:
    """The files (or folders) of the checkpoint ``entry`` of ``out``: its model and, for SB3, VecNormalize's."""
    return [os.path.join(out, "checkpoints", entry[k]) for k in ("model", "vecnormalize") if entry.get(k)]


def sign_checkpoint(out: str, entry: dict) -> dict:
    """``entry`` with the digest of its files under this account's key (:func:`crowd_env.files.files_digest`),
    for the index: resuming checks it before any of them, which are pickles, is loaded."""
    return {**entry, "digest": files_digest(checkpoint_files(out, entry))}


def check_checkpoint(out: str, entry: dict) -> None:
    """Refuse (:class:`~crowd_env.errors.UntrustedFileError`) to resume from the checkpoint ``entry`` unless this
    account's crowd_env wrote its files (:func:`sign_checkpoint`): a training folder someone else shared, or one
    from before checkpoints were signed, is never unpickled."""
    check_files_digest(checkpoint_files(out, entry), entry.get("digest"),
                       f"to train afresh delete {os.path.join(out, 'checkpoints')} or choose another --out")


def save_checkpoint(model, out: str, curve: list) -> dict | None:
    """Save ``model`` (and VecNormalize statistics if any) and the curve; append to the index last, signed
    (:func:`sign_checkpoint`).

    Returns the new entry, or None when the latest checkpoint already has this step count."""
    entries = read_checkpoints(out)
    t = int(model.num_timesteps)
    if entries and entries[-1]["timesteps"] >= t:
        return None
    folder = os.path.join(out, "checkpoints")
    os.makedirs(folder, exist_ok=True)
    entry = {"timesteps": t, "model": f"ppo_{t}_steps.zip", "vecnormalize": None}
    model.save(os.path.join(folder, f"ppo_{t}_steps.tmp.zip"))
    os.replace(os.path.join(folder, f"ppo_{t}_steps.tmp.zip"), os.path.join(folder, entry["model"]))
    norm = model.get_vec_normalize_env()
    if norm is not None:
        entry["vecnormalize"] = f"vecnormalize_{t}_steps.pkl"
        norm.save(os.path.join(folder, entry["vecnormalize"] + ".tmp"))
        os.replace(os.path.join(folder, entry["vecnormalize"] + ".tmp"), os.path.join(folder, entry["vecnormalize"]))
    write_json_atomic(os.path.join(folder, "curve.json"), curve)
    entry = sign_checkpoint(out, entry)
    write_json_atomic(os.path.join(folder, "index.json"), {"checkpoints": entries + [entry]})
    return entry


def check_resume(out: str, env_config: dict, resume: bool) -> list:
    """The checkpoints to resume from; refuses a folder with checkpoints without ``resume`` or of another config."""
    entries = read_checkpoints(out)
    if entries and not resume:
        raise TrainingError(f"{out} holds checkpoints (latest at {entries[-1]['timesteps']} timesteps): pass "
                            "--resume to continue that run, or choose another --out")
    path = os.path.join(out, ENV_CONFIG_FILE)
    if resume and entries and os.path.exists(path):
        with open(path) as fh:
            old = json.load(fh)
        if old != json.loads(json.dumps(env_config)):
            diff = sorted(k for k in set(old) | set(env_config) if old.get(k) != env_config.get(k))
            raise TrainingError(f"cannot resume: {out} was trained with other environment options "
                                f"(differs in {diff})")
    return entries


def check_env_config(env_config: dict) -> None:
    """Build the environment ``env_config`` describes once, so that what it refuses (an unknown scenario option, a
    bottleneck narrower than a pedestrian, ...) is a :class:`~crowd_env.errors.TrainingError` naming it before a
    training command writes anything."""
    try:
        crowd_v0.parallel_env(**env_config).close()
    except CrowdEnvError as exc:
        raise TrainingError(f"the environment to train on cannot be built: {exc}") from None


def begin_run(out: str, env_config: dict, *, resume: bool, resolve, eval_seeds, seed: int, progress=print):
    """What every training command does first: check ``env_config`` (:func:`check_env_config`; nothing is written
    for one the environment refuses), refuse or accept ``out`` (:func:`check_resume`), write ``env_config.json``
    and score the random policy on ``eval_seeds`` (kept in ``random_eval.json`` and reused when a run resumes with
    the same seeds). Returns ``(checkpoint entries, random policy's mean_return dict)``."""
    check_env_config(env_config)
    os.makedirs(out, exist_ok=True)
    entries = check_resume(out, env_config, resume)
    write_json_atomic(os.path.join(out, ENV_CONFIG_FILE), env_config, indent=2)
    random_path = os.path.join(out, "random_eval.json")
    before = None
    if entries and os.path.exists(random_path):
        with open(random_path) as fh:
            saved = json.load(fh)
        before = saved["result"] if saved["eval_seeds"] == list(eval_seeds) and saved["seed"] == seed else None
    if before is None:
        before = mean_return(resolve("random"), env_config, eval_seeds)
        write_json_atomic(random_path, {"eval_seeds": list(eval_seeds), "seed": seed, "result": before})
    _report("random", before, progress)
    return entries, before


def evaluate_trained(policy, env_config: dict, eval_seeds, progress=print) -> dict:
    """The trained ``policy``'s :func:`mean_return` on ``eval_seeds``, reported like the random policy's."""
    after = mean_return(policy, env_config, eval_seeds)
    _report("trained", after, progress)
    return after


def _report(what: str, result: dict, progress) -> None:
    progress(f"{what} policy: mean per-agent episode return {result['mean_return']:.3f} "
             f"(evacuated {100 * result['evacuated_fraction']:.0f}%)")


def train(env_config: dict, timesteps: int, out: str, *, resolve, seed: int = 0, copies: int = 2, n_steps: int = 256,
          batch_size: int = 512, n_epochs: int = 10, learning_rate: float = 3e-4, gamma: float = 0.99,
          eval_seeds=(1000, 1001, 1002), threads: int = 1, verbose: int = 0, checkpoint_every: int = 10_000,
          resume: bool = False, vectoriser: str = "native", workers: int = 1, progress=print,
          progress_every_s: float = 10.0) -> dict:
    """Train, save and evaluate; returns the summary dict (also written to ``out/summary.json``).

    ``resolve(spec, name=None) -> policy`` makes the policies the summary compares
    (:func:`~crowd_env.experiments.running.evaluation.resolve_policy`): ``resolve("random")`` before training and
    ``resolve(model, name="ppo")`` for the trained SB3 model, e.g. ``baselines.reference_policies.as_policy``.

    ``checkpoint_every`` timesteps (0: only at the end) a checkpoint is saved under ``out/checkpoints``;
    ``resume`` continues from the latest one up to ``timesteps`` in all (see the module docstring).
    ``vectoriser``: ``"native"`` or ``"supersuit"`` (see the module docstring); ``workers``: processes that
    step the native vectoriser's copies (:func:`~crowd_env.envs.vector.vector_env`).

    ``progress(line)`` gets the random policy's score, then while training one line at the end of a rollout
    at most every ``progress_every_s`` seconds (:func:`progress_line`: timesteps done, elapsed and estimated
    remaining time, the mean return of the recent episodes), then the trained policy's score.
    """
    import torch
    from stable_baselines3.common.utils import set_random_seed

    torch.set_num_threads(max(1, int(threads)))
    t0 = time.perf_counter()
    entries, before = begin_run(out, env_config, resume=resume, resolve=resolve, eval_seeds=eval_seeds, seed=seed,
                                progress=progress)

    start = entries[-1]["timesteps"] if entries else 0
    set_random_seed(seed + start)  # python, numpy, torch
    vec = make_vec_env(env_config, copies, seed + start, vectoriser, workers)
    curve = []
    model = _model(entries, out, vec, curve, progress, n_steps=n_steps, batch_size=batch_size, n_epochs=n_epochs,
                   learning_rate=learning_rate, gamma=gamma, verbose=verbose)
    model.action_space.seed(seed + start)
    t1 = time.perf_counter()
    remaining = int(timesteps) - int(model.num_timesteps)
    try:
        if remaining > 0:  # with reset_num_timesteps=False SB3 counts total_timesteps on top of num_timesteps
            model.learn(total_timesteps=remaining, reset_num_timesteps=not entries,
                        callback=_callbacks(curve, out, start, timesteps, checkpoint_every, progress, progress_every_s))
        train_s = time.perf_counter() - t1
        model.save(os.path.join(out, "model.zip"))
    finally:
        vec.close()  # also stops worker processes when training fails

    after = evaluate_trained(resolve(model, name="ppo"), env_config, eval_seeds, progress)
    write_curve(curve, out, before["mean_return"], after["mean_return"])
    summary = {"timesteps": int(model.num_timesteps), "resumed_from_timesteps": start, "train_wall_s": train_s,
               "total_wall_s": time.perf_counter() - t0, "random": before, "trained": after,
               "improvement": after["mean_return"] - before["mean_return"], "env_config": env_config,
               "eval_seeds": list(eval_seeds), "seed": seed, "copies": copies, "vectoriser": vectoriser, "workers": workers,
               "ppo": {"n_steps": n_steps, "batch_size": batch_size, "n_epochs": n_epochs,
                       "learning_rate": learning_rate, "gamma": gamma}}
    write_json_atomic(os.path.join(out, "summary.json"), summary)
    return summary


def _model(entries: list, out: str, vec, curve: list, progress, **ppo):
    """The PPO model: loaded from the latest checkpoint of ``entries`` (its VecNormalize and learning curve too),
    or new with the ``ppo`` hyperparameters and a 64-64 MLP."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    if not entries:  # Not PPO(seed=...): SB3 would call vec.seed(), which SuperSuit's concatenated env lacks.
        return PPO("MlpPolicy", vec, device="cpu", policy_kwargs={"net_arch": [64, 64]}, **ppo)
    latest = entries[-1]
    folder = os.path.join(out, "checkpoints")
    check_checkpoint(out, latest)  # the files are pickles: loaded only when this account's crowd_env wrote them
    if latest["vecnormalize"]:
        vec = VecNormalize.load(os.path.join(folder, latest["vecnormalize"]), vec)
    model = PPO.load(os.path.join(folder, latest["model"]), env=vec, device="cpu")
    with open(os.path.join(folder, "curve.json")) as fh:
        curve.extend(tuple(c) for c in json.load(fh) if c[0] <= latest["timesteps"])
    progress(f"resuming from the checkpoint at {model.num_timesteps} timesteps")
    return model


def _callbacks(curve: list, out: str, start: int, timesteps: int, checkpoint_every: int, progress,
               progress_every_s: float) -> list:
    """SB3 callbacks: the learning curve (appended to ``curve``), checkpoints every ``checkpoint_every``
    timesteps and at the end, and a progress line after a rollout at most every ``progress_every_s`` s."""
    from stable_baselines3.common.callbacks import BaseCallback

    class Curve(BaseCallback):
        def _on_step(self) -> bool:
            for info in self.locals.get("infos", []):
                ep = info.get("episode")
                if ep is not None:
                    curve.append((self.num_timesteps, float(ep["r"]), int(ep["l"])))
            return True

    class Progress(BaseCallback):
        def _on_training_start(self) -> None:
            self.t0 = self.last = time.perf_counter()
            self.t_start = int(self.model.num_timesteps)
            progress(f"training PPO: {int(self.model.num_timesteps)} -> {int(timesteps)} timesteps (agent steps), "
                     f"{self.training_env.num_envs} agent slots, a line every {progress_every_s:g} s")

        def _on_rollout_end(self) -> None:
            now = time.perf_counter()
            if now - self.last >= progress_every_s:
                self.last = now
                progress(progress_line(int(self.model.num_timesteps), int(timesteps), self.t_start, now - self.t0,
                                       [c[1] for c in curve[-100:]]))

        def _on_step(self) -> bool:
            return True

    class Checkpoint(BaseCallback):
        """Saves when ``checkpoint_every`` timesteps have passed, at a rollout start (after the update)."""

        last_t = start

        def _on_rollout_start(self) -> None:
            if checkpoint_every > 0 and self.model.num_timesteps - self.last_t >= checkpoint_every:
                save_checkpoint(self.model, out, curve)
                self.last_t = self.model.num_timesteps

        def _on_step(self) -> bool:
            return True

        def _on_training_end(self) -> None:
            save_checkpoint(self.model, out, curve)

    return [Curve(), Checkpoint(), Progress()]


def progress_line(done: int, total: int, start: int, elapsed_s: float, recent_returns) -> str:
    """``"  t / T timesteps (p %), E s elapsed, about R s left; mean per-agent episode return of the last k
    episodes: r"``, the remaining time from the rate since ``start`` timesteps."""
    rate = (done - start) / elapsed_s if elapsed_s > 0 and done > start else 0.0
    left = f"about {max(total - done, 0) / rate:.0f} s left" if rate > 0 else "remaining time not known yet"
    ret = (f"; mean per-agent episode return of the last {len(recent_returns)} episodes {np.mean(recent_returns):.3f}"
           if len(recent_returns) else "; no episode finished yet")
    return f"  {done} / {total} timesteps ({100 * min(done / max(total, 1), 1.0):.0f} %), {elapsed_s:.0f} s, {left}{ret}"


def write_curve(curve, out: str, random_return: float, trained_return: float) -> None:
    """learning_curve.csv (timestep, episode_return, episode_length) and learning_curve.png."""
    write_atomic(os.path.join(out, "learning_curve.csv"), "timestep,episode_return,episode_length\n"
                 + "".join(f"{t},{r:.6g},{n}\n" for t, r, n in curve))
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6, 4))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    if curve:
        t = np.array([c[0] for c in curve], float)
        r = np.array([c[1] for c in curve], float)
        ax.plot(t, r, ".", ms=2, alpha=0.3, color="tab:blue", label="episode return (one agent)")
        w = max(1, len(r) // 20)
        if len(r) >= w:
            smooth = np.convolve(r, np.ones(w) / w, mode="valid")
            ax.plot(t[w - 1:], smooth, color="tab:blue", lw=2, label=f"running mean ({w})")
    ax.axhline(random_return, color="tab:red", ls="--", label="random policy (eval)")
    ax.axhline(trained_return, color="tab:green", ls="--", label="trained, deterministic (eval)")
    ax.set_xlabel("timesteps (agent steps)")
    ax.set_ylabel("per-agent episode return")
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure_atomic(fig, os.path.join(out, "learning_curve.png"), dpi=100)
