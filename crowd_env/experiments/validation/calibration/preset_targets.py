"""Presets against every target of the experiment (Seyfried et al. 2009; Kabalan et al. 2016, Section 4).

Each preset's runs (:func:`~crowd_env.experiments.validation.calibration.optimize.target_tasks`: N = 20, 40, 60 at the
widths and N = 120 at the capacity widths) go to their own folder ``OUT/<preset>/`` (resumable); the
figures and misses are :func:`crowd_env.experiments.validation.calibration.objective.target_table` and
:func:`~crowd_env.experiments.validation.calibration.objective.target_error`.

With an :class:`~crowd_env.experiments.validation.calibration.tasks.FDPlan` (``crowd-calibrate targets --fd``) each preset
also runs the fundamental-diagram sweep of the plan (:func:`~.tasks.make_fd_tasks`: the periodic 1.8 m corridor
and the single file, issue 36), in the same folder, store and executor as its bottleneck runs
(:func:`~.tasks.run_calibration_task` runs either kind); its table gains the rows of
:func:`crowd_env.experiments.validation.calibration.objective.fd_table` and its score the fundamental diagram's four terms, as the
calibration's ``--objective targets+fd`` scores a point.
"""
from __future__ import annotations

from functools import partial
from pathlib import Path

from crowd_env.files import write_json_atomic
from .errors import CalibrationError
from .objective import corridor_table, fd_table, single_file_table, target_error, target_table, virtual_error
from ...running.backends import execute, failure_report
from ..bottleneck import run_one
from ..fundamental_diagram import run_fd_one
from ...running.store import RunStore
from .optimize import target_tasks
from .tasks import FDPlan, make_fd_tasks, make_virtual_tasks, run_calibration_task

__all__ = ["preset_targets", "write_targets"]


def preset_targets(out, configs: dict, widths_m, seeds, backend, fd_plan: FDPlan | None = None,
                   virtual: bool = False) -> tuple:
    """``configs``: preset name -> calibration configuration (:func:`~.tasks.base_config`). Runs what is
    missing under ``out/<name>`` and returns ``(tables, scores)``: per name the target table and the
    :class:`~crowd_env.experiments.validation.calibration.objective.TargetScore`. A failed run raises, saying why (:func:`~crowd_env.experiments.running.backends.failure_report`).

    ``fd_plan``: also the fundamental diagram's runs of the plan for every preset (every preset's tasks are
    built before any runs, so a configuration the sweep cannot run fails first); the table then ends with
    :func:`~crowd_env.experiments.validation.calibration.objective.fd_table`'s rows and the score includes its terms (``fd=True``).

    ``virtual``: every shipped experiment as it was run instead (:func:`~.tasks.make_virtual_tasks`: the bottleneck's
    cases, the nine Jülich corridor runs, the single file, at ``seeds``); the table ends with one row per corridor
    run (:func:`~crowd_env.experiments.validation.calibration.objective.corridor_table`) and the single file's rows,
    and the score is :func:`~crowd_env.experiments.validation.calibration.objective.virtual_error`. Not with
    ``fd_plan``."""
    if virtual and fd_plan is not None:
        raise CalibrationError("the virtual experiments replace the periodic corridor's sweep: give one or the other")
    if virtual:
        tasks_of = {name: make_virtual_tasks(config, {}, {}, widths_m, seeds) for name, config in configs.items()}
    else:
        tasks_of = {name: target_tasks(config, {}, {}, widths_m, seeds)
                    + ([] if fd_plan is None else make_fd_tasks(config, {}, {}, fd_plan))
                    for name, config in configs.items()}
    run_fn = run_one if fd_plan is None and not virtual else partial(run_calibration_task, run_fn=run_one,
                                                                     fd_run_fn=run_fd_one)
    tables, scores = {}, {}
    for name, config in configs.items():
        store = RunStore(Path(out) / name, config, keyed_by="task")
        tasks = tasks_of[name]
        failed = execute(tasks, store, backend, run_fn, desc=f"targets: {name}")
        if failed:
            raise CalibrationError(f"preset {name}: {failure_report(tasks, store)}")
        records = [store.load(t) for t in tasks]
        if virtual:
            neck = [r for r in records if "setup" not in r and r.get("experiment") != "corridor"]
            tables[name] = target_table(neck) + corridor_table(records) + single_file_table(records)
            scores[name] = virtual_error(records)
        else:
            tables[name] = target_table(records) + ([] if fd_plan is None else fd_table(records))
            scores[name] = target_error(records, fd=fd_plan is not None)
    return tables, scores


def write_targets(path, seeds, widths_m, tables: dict, scores: dict, fd_plan: FDPlan | None = None,
                  virtual: bool = False) -> Path:
    """``targets.json``: the seeds, widths, every table, and per preset its objective, terms and figures (the seed
    means the terms came from); with
    ``fd_plan`` (the fundamental diagram's runs were part of it) also the plan, under ``fd``; ``virtual``: marks
    the virtual experiments' tables."""
    path = Path(path)
    content = {"seeds": seeds, "widths_m": widths_m, "tables": tables, "virtual_experiments": bool(virtual),
               "objective": {n: e.objective for n, e in scores.items()},
               "terms": {n: {k: v for k, v in e.terms.items() if k not in e.unscored} for n, e in scores.items()},
               "figures": {n: e.figures for n, e in scores.items()}}
    if fd_plan is not None:
        content["fd"] = fd_plan.as_dict()
    write_json_atomic(path, content, indent=2)
    return path
