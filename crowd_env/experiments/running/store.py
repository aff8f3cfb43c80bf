"""The run store: finished bottleneck runs on disk, one atomic JSON file each, under a configuration check.

A folder ``OUT`` holds ``OUT/config.json`` (the configuration its runs share) and ``OUT/runs/<key>.json``,
one file per finished run of the task format of :func:`crowd_env.experiments.validation.bottleneck.run_one`
(b, N, seed, geometry, model parameters, time limit, ...). Every file is written to a temporary name,
fsync'ed and renamed, so a killed sweep never leaves half a record and a rerun skips what is stored
(resumable). A folder holding runs of another configuration, or runs without a configuration, is
refused with :class:`RunStoreError` naming what differs.

Two layouts, both of existing output folders:

- ``keyed_by="run"`` (``crowd-bottleneck``, ``crowd-generalise``): the configuration fixes everything
  but (b, N, seed); the file ``b<b>_n<N>_s<seed>.json`` holds the run's record.
- ``keyed_by="task"`` (``crowd-calibrate``): the model parameters vary from run to run; the file
  ``A<A>_B<B>_b<b>_n<N>_s<seed>_<hash of the task>.json`` holds ``{"task": ..., "record": ...}`` and is
  checked against its task on load.

Model parameters at their :class:`~crowd_env.walking.model.ModelParams` default count as absent when configurations
and tasks are compared and hashed (:func:`canonical`): a folder written before a parameter existed (with the
parameter off, at its default) stays valid and resumable after it is added, while any value that changes the
model still differs.

A task with ``trajectory_fps`` is done only when its trajectory file at that frame rate exists too
(``OUT/trajectories/<key>.txt``, written before the record). Records load normalised
(:func:`normalise_record`: also records saved before the stall rule).
"""
from __future__ import annotations

from crowd_env.errors import RunStoreError

import hashlib
import json
from pathlib import Path

from ...analysis.trajectories import trajectory_frame_rate
from crowd_env.files import append_json_line, read_json_lines, write_json_atomic
from ...core.checks import is_integer, is_number
from ...walking.model import ModelParams

__all__ = ["RunStoreError", "RunStore", "canonical", "config_hash", "normalise_record", "check_record", "run_key", "task_key",
           "CONFIG_NAME", "LAYOUTS"]

CONFIG_NAME = "config.json"
LAYOUTS = ("run", "task")


_MODEL_DEFAULTS = ModelParams().to_dict()


def canonical(config: dict) -> dict:
    """``config`` with the entries of its ``params`` dict (model parameters) that equal the
    :class:`~crowd_env.walking.model.ModelParams` default left out: the form configurations and tasks are compared
    and hashed in, so that adding a parameter (at its default) changes no stored folder."""
    params = config.get("params") if isinstance(config, dict) else None
    if not isinstance(params, dict):
        return config
    kept = {k: v for k, v in params.items() if not (k in _MODEL_DEFAULTS and v == _MODEL_DEFAULTS[k]
                                                    and isinstance(v, bool) == isinstance(_MODEL_DEFAULTS[k], bool))}
    return dict(config, params=kept)


def config_hash(config: dict) -> str:
    """First 16 hex digits of the SHA-256 of :func:`canonical` ``config`` as sorted-key JSON."""
    return hashlib.sha256(json.dumps(canonical(config), sort_keys=True).encode()).hexdigest()[:16]


def run_key(task: dict) -> str:
    """File stem of a run in a folder of one configuration: ``b<b>_n<N>_s<seed>`` for a bottleneck run (b its
    width), ``<setup>_w<W>_rho<density>_n<N>_s<seed>`` for a fundamental-diagram run (a task with a ``setup``:
    ``corridor`` or ``single_file``, W its width)."""
    if "setup" in task:
        return (f"{task['setup']}_w{task['width_m']:.3f}_rho{task['density']:g}_n{task['n_pedestrians']}"
                f"_s{task['seed']}")
    return f"b{task['width_m']:.3f}_n{task['n_pedestrians']}_s{task['seed']}"


def task_key(task: dict) -> str:
    """File stem of a task in a folder whose runs differ in their parameters: readable (A, B, b, N, seed)
    and a hash of the whole task."""
    p = task["params"]
    return (f"A{p['social_strength_n']:g}_B{p['social_range_m']:g}_b{task['width_m']:.3f}_n{task['n_pedestrians']}"
            f"_s{task['seed']}_{config_hash(task)}")


def check_record(record, source: str, fields=("n_pedestrians",)) -> None:
    """Raise :class:`RunStoreError` naming ``source`` (the file, or which record) and what is missing unless
    ``record`` is a dict with every key of ``fields`` and ``complete`` (or, from before the stall rule,
    ``n_passages`` / ``n_evacuated``), its counts integers. The store checks the keys every record needs
    (:func:`normalise_record`'s); a consumer passes the keys it reads (e.g.
    :data:`crowd_env.experiments.validation.bottleneck.SUMMARY_FIELDS`)."""
    if not isinstance(record, dict):
        raise RunStoreError(f"{source}: a run record must be a JSON object (dict), got {type(record).__name__}")
    missing = [k for k in fields if k not in record]
    if "complete" not in record and "n_passages" not in record and "n_evacuated" not in record:
        missing.append("complete (or n_passages / n_evacuated, in a record from before the stall rule)")
    if missing:
        raise RunStoreError(f"{source}: the run record lacks {missing} (a stored run: delete its file to rerun it)")
    for key in ("n_pedestrians", "n_passages", "n_evacuated"):
        value = record.get(key, 0)
        if not (is_integer(value) or (is_number(value) and float(value).is_integer())):
            raise RunStoreError(f"{source}: the run record's {key} must be an integer, got {value!r}")


def normalise_record(record: dict, source: str = "run record") -> dict:
    """A run record in today's form (``complete``, ``stalled``, partial flows), also from a record saved
    before the stall rule existed (those ran to the time limit and stored the partial J_s of an
    incomplete run as its J_s): there ``complete`` = all N passed, ``stalled`` = False (not known), and
    an incomplete run's J_s / J move to ``partial_*`` (nan in their place). Returns a new dict. A record
    without ``n_pedestrians`` or any of ``complete`` / ``n_passages`` / ``n_evacuated`` raises
    :class:`RunStoreError` naming ``source`` (:func:`check_record`)."""
    check_record(record, source)
    r = dict(record)
    if "complete" not in r:
        n_passed = r.get("n_passages", r.get("n_evacuated"))
        r["complete"] = int(n_passed) == int(r["n_pedestrians"])
        for key in ("specific_flow_per_m_s", "flow_per_s"):
            if key in r:
                r[f"partial_{key}"] = r[key]
                if not r["complete"]:
                    r[key] = float("nan")
    r.setdefault("stalled", False)
    r.setdefault("stall_time_s", float("nan"))
    return r


def _config_difference(old: dict, config: dict) -> list:
    old, config = canonical(old), canonical(config)
    diff = sorted(k for k in set(old) | set(config) if k not in ("params", "geometry") and old.get(k) != config.get(k))
    for part in ("params", "geometry"):
        a, b = old.get(part) or {}, config.get(part) or {}
        diff += [f"{part}.{k}" for k in sorted(set(a) | set(b)) if a.get(k) != b.get(k)]
    return diff


def check_config(out, config: dict) -> None:
    """Write ``config`` into a new folder, or check that it equals the folder's: raises :class:`RunStoreError`
    naming what differs, or when the folder holds runs but no configuration."""
    out = Path(out)
    path = out / CONFIG_NAME
    if path.exists():
        try:
            old = json.loads(path.read_text())
        except json.JSONDecodeError as exc:
            raise RunStoreError(f"{path} is not valid JSON ({exc})") from None
        if config_hash(old) != config_hash(config):
            raise RunStoreError(f"{out} holds runs of a different configuration (differs in "
                                f"{_config_difference(old, config)}); choose another --out or delete the folder")
        return
    if (out / "runs").is_dir() and any((out / "runs").iterdir()):
        kind = config.get("kind", "bottleneck")
        raise RunStoreError(f"{out}/runs holds runs but no {CONFIG_NAME}: not a {kind} folder; choose another --out")
    out.mkdir(parents=True, exist_ok=True)
    write_json_atomic(path, config, indent=2, sort_keys=True)


class RunStore:
    """Folder of finished runs ``OUT/runs/<key>.json``, guarded by ``OUT/config.json`` (module docstring).

    ``config``: the folder's configuration, written into a new folder and checked against an existing
    one (None: open the folder without a check, for a caller that checked it already). ``keyed_by``:
    ``"run"`` or ``"task"``, the layout.
    """

    def __init__(self, out, config: dict | None = None, *, keyed_by: str = "run"):
        if keyed_by not in LAYOUTS:
            raise RunStoreError(f"keyed_by must be one of {LAYOUTS}, got {keyed_by!r}")
        self.out = Path(out)
        self.runs_dir = self.out / "runs"
        self.trajectories_dir = self.out / "trajectories"
        self.config = config
        self.keyed_by = keyed_by
        if config is not None:
            check_config(self.out, config)
        self.runs_dir.mkdir(parents=True, exist_ok=True)

    def key(self, task: dict) -> str:
        return run_key(task) if self.keyed_by == "run" else task_key(task)

    def path(self, task: dict) -> Path:
        return self.runs_dir / f"{self.key(task)}.json"

    def trajectory_stem(self, task: dict) -> Path:
        """Where the run's trajectories go (``<stem>.txt`` and its geometry files)."""
        return self.trajectories_dir / self.key(task)

    def done(self, task: dict) -> bool:
        """The run is stored (and, when the task asks for trajectories, so are they, at its frame rate)."""
        if not self.path(task).exists():
            return False
        fps = task.get("trajectory_fps")
        if not fps:
            return True
        found = trajectory_frame_rate(self.trajectories_dir / f"{self.key(task)}.txt")
        return found is not None and abs(found - fps) <= 1e-9 * fps

    def prepare(self, task: dict) -> dict:
        """The task as a worker runs it: with ``trajectory_stem`` when it asks for trajectories."""
        if not task.get("trajectory_fps"):
            return task
        self.trajectories_dir.mkdir(parents=True, exist_ok=True)
        return dict(task, trajectory_stem=str(self.trajectory_stem(task)))

    def save(self, task: dict, record: dict) -> None:
        """Store ``record`` (:func:`check_record` first: nothing is written for an incomplete record)."""
        check_record(record, f"{self.path(task)} (not written)")
        payload = record if self.keyed_by == "run" else {"task": task, "record": record}
        write_json_atomic(self.path(task), payload, indent=None)

    def load(self, task: dict) -> dict | None:
        """The stored record of ``task`` (normalised) or None; an unreadable file, or one holding another
        task, is an error."""
        path = self.path(task)
        if not path.exists():
            return None
        try:
            data = json.loads(path.read_text())
        except (json.JSONDecodeError, OSError) as exc:
            raise RunStoreError(f"{path}: unreadable run record ({exc}); delete it to rerun that run") from None
        if self.keyed_by == "task":
            if not isinstance(data, dict) or "record" not in data:
                raise RunStoreError(f"{path}: not a stored task (a JSON object with 'task' and 'record'); delete it "
                                    f"to rerun that run")
            if canonical(data.get("task")) != canonical(task):
                raise RunStoreError(f"{path} holds a different task than its name says; delete it to rerun that run")
            data = data["record"]
        return normalise_record(data, str(path))

    def log_error(self, task: dict, message: str) -> None:
        """Append a failed run to ``OUT/errors.jsonl`` (fsync'ed); the next sweep retries it."""
        append_json_line(self.errors_path, {"key": self.key(task), "error": message})

    @property
    def errors_path(self) -> Path:
        """``OUT/errors.jsonl``: the failed runs, one JSON line each (:meth:`log_error`)."""
        return self.out / "errors.jsonl"

    def logged_errors(self) -> dict:
        """Run key -> the error logged last for it in :attr:`errors_path` ({} when none was)."""
        return {e["key"]: e["error"] for e in read_json_lines(self.errors_path)
                if isinstance(e, dict) and "key" in e and "error" in e}
