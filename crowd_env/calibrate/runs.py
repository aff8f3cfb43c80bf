"""Single calibration runs (A, B, ..., b, N, seed): task records, the run function, the resumable store.

A task is the reproduction's task dict (``crowd_env.cli.reproduce_bottleneck.run_one``: ``width_m``,
``n_pedestrians``, ``seed``, ``geometry``, ``params``, ``max_time_s``) plus ``pedestrian``: overrides of
:class:`~crowd_env.core.params.PedestrianDefaults` (τ, desired-speed mean/std), empty by default. Every
task runs through ``run_one`` itself (which applies the pedestrian overrides), so calibration numbers
are those of the bottleneck reproduction and its records hold the same figures (J_s, speed inside,
densities, stationary flow, ``complete``/``stalled``). Records saved before the stall rule load through
:func:`~crowd_env.cli.reproduce_bottleneck.normalise_record`. Each finished run is written at once as
one JSON file (atomic rename after fsync) named by a hash of the whole task, so a rerun after a crash or
kill skips it and loses nothing.
"""
from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path

from ..analysis.calibration import CalibrationError
from ..cli.reproduce_bottleneck import config_hash, normalise_record, run_one
from ..core.params import ModelParams, ParameterError

# PedestrianDefaults fields a calibration may vary (per-pedestrian, drawn/set in Scenario.make_state).
PEDESTRIAN_FIELDS = ("tau_s", "desired_speed_mean_m_s", "desired_speed_std_m_s")
SIGNIFICANT_DIGITS = 6  # parameter values are rounded to this before running (stable cache keys)
CONFIG_NAME = "config.json"


def canonical(value: float) -> float:
    """``value`` rounded to :data:`SIGNIFICANT_DIGITS` significant digits (the value actually simulated)."""
    return float(f"{float(value):.{SIGNIFICANT_DIGITS}g}")


def check_pedestrian(pedestrian: dict) -> dict:
    """Validated per-pedestrian overrides (names in :data:`PEDESTRIAN_FIELDS`, values finite and > 0)."""
    unknown = sorted(set(pedestrian) - set(PEDESTRIAN_FIELDS))
    if unknown:
        raise CalibrationError(f"unknown pedestrian parameter(s) {unknown}; calibratable: {list(PEDESTRIAN_FIELDS)}")
    out = {}
    for name, value in sorted(pedestrian.items()):
        v = float(value)
        if not (v > 0 and v < float("inf")):
            raise CalibrationError(f"{name} must be finite and > 0, got {value!r}")
        out[name] = canonical(v)
    return out


def _params_dict(params: ModelParams) -> dict:
    return {f.name: getattr(params, f.name) for f in dataclasses.fields(params) if f.name != "extra"}


def base_config(geometry: dict, params: ModelParams, max_time_s: float) -> dict:
    """The fixed part of a calibration (geometry, base model parameters, time limit): one per folder."""
    return {"kind": "calibration", "geometry": dict(geometry), "params": _params_dict(params),
            "max_time_s": float(max_time_s)}


def make_task(config: dict, model: dict, pedestrian: dict, width_m: float, n_pedestrians: int, seed: int) -> dict:
    """One run: ``config`` with the ModelParams overrides ``model`` and PedestrianDefaults overrides ``pedestrian``."""
    changes = {k: canonical(v) for k, v in model.items()}
    try:
        params = ModelParams.from_dict(config["params"]).replace(**changes)
    except ParameterError as exc:
        raise CalibrationError(str(exc)) from None
    return {"width_m": float(width_m), "n_pedestrians": int(n_pedestrians), "seed": int(seed),
            "geometry": config["geometry"], "params": _params_dict(params), "max_time_s": config["max_time_s"],
            "pedestrian": check_pedestrian(pedestrian)}


def task_key(task: dict) -> str:
    """File stem of a task: readable (A, B, b, N, seed) and a hash of the whole task."""
    p = task["params"]
    return (f"A{p['social_strength_n']:g}_B{p['social_range_m']:g}_b{task['width_m']:.3f}_n{task['n_pedestrians']}"
            f"_s{task['seed']}_{config_hash(task)}")


def run_task(task: dict) -> dict:
    """Run one task: the reproduction's ``run_one`` (pedestrian overrides, if any, draw the state with those
    :class:`PedestrianDefaults` from the same seed, so common random numbers)."""
    return run_one(task)


def _write_atomic(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    with open(tmp, "w") as fh:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())
    tmp.replace(path)  # a killed process never leaves a half-written file under the final name


class RunStore:
    """Folder of finished runs ``OUT/runs/<key>.json`` (record + its task), guarded by ``OUT/config.json``."""

    def __init__(self, out, config: dict):
        self.out = Path(out)
        self.runs_dir = self.out / "runs"
        self.config = config
        check_config(self.out, config)
        self.runs_dir.mkdir(parents=True, exist_ok=True)

    def path(self, task: dict) -> Path:
        return self.runs_dir / f"{task_key(task)}.json"

    def done(self, task: dict) -> bool:
        return self.path(task).exists()

    def save(self, task: dict, record: dict) -> None:
        _write_atomic(self.path(task), json.dumps({"task": task, "record": record}))

    def load(self, task: dict) -> dict | None:
        """The stored record of ``task`` or None; a file holding another task is an error."""
        path = self.path(task)
        if not path.exists():
            return None
        try:
            data = json.loads(path.read_text())
        except (json.JSONDecodeError, OSError) as exc:
            raise CalibrationError(f"{path}: unreadable run record ({exc}); delete it to rerun that run") from None
        if data.get("task") != task:
            raise CalibrationError(f"{path} holds a different task than its name says; delete it to rerun that run")
        return normalise_record(data["record"])

    def log_error(self, task: dict, message: str) -> None:
        with open(self.out / "errors.jsonl", "a") as fh:
            fh.write(json.dumps({"key": task_key(task), "error": message}) + "\n")
            fh.flush()
            os.fsync(fh.fileno())


def check_config(out: Path, config: dict) -> None:
    """Write ``config`` into a new folder, or check it equals the folder's: raises naming what differs."""
    out = Path(out)
    path = out / CONFIG_NAME
    if path.exists():
        try:
            old = json.loads(path.read_text())
        except json.JSONDecodeError as exc:
            raise CalibrationError(f"{path} is not valid JSON ({exc})") from None
        if config_hash(old) != config_hash(config):
            diff = sorted(k for k in set(old) | set(config) if k not in ("params", "geometry") and old.get(k) != config.get(k))
            for part in ("params", "geometry"):
                a, b = old.get(part) or {}, config.get(part) or {}
                diff += [f"{part}.{k}" for k in sorted(set(a) | set(b)) if a.get(k) != b.get(k)]
            raise CalibrationError(f"{out} holds results of a different configuration (differs in {diff}); "
                                   f"choose another --out or delete the folder")
        return
    if out.exists() and (out / "runs").exists() and any((out / "runs").iterdir()):
        raise CalibrationError(f"{out}/runs holds runs but no {CONFIG_NAME}: not a calibration folder; choose another --out")
    out.mkdir(parents=True, exist_ok=True)
    _write_atomic(path, json.dumps(config, indent=2, sort_keys=True))
