"""Presets against every target of the experiment (Seyfried et al. 2009; Kabalan et al. 2016, Section 4).

Each preset's runs (:func:`~crowd_env.experiments.calibration.optimize.target_tasks`: N = 20, 40, 60 at the
widths and N = 120 at the capacity widths) go to their own folder ``OUT/<preset>/`` (resumable); the
figures and misses are :func:`crowd_env.analysis.targets.target_table` and
:func:`~crowd_env.analysis.targets.target_error`.
"""
from __future__ import annotations

import json
from pathlib import Path

from ...analysis.calibration import CalibrationError
from ...analysis.targets import target_error, target_table
from ..backends import execute
from ..bottleneck import run_one
from ..store import RunStore
from .optimize import target_tasks

__all__ = ["preset_targets", "write_targets"]


def preset_targets(out, configs: dict, widths_m, seeds, backend) -> tuple:
    """``configs``: preset name -> calibration configuration (:func:`~.tasks.base_config`). Runs what is
    missing under ``out/<name>`` and returns ``(tables, scores)``: per name the target table and the
    :class:`~crowd_env.analysis.targets.TargetScore`. A failed run raises (rerun to retry it)."""
    tables, scores = {}, {}
    for name, config in configs.items():
        store = RunStore(Path(out) / name, config, keyed_by="task")
        tasks = target_tasks(config, {}, {}, widths_m, seeds)
        failed = execute(tasks, store, backend, run_one, desc=f"targets: {name}")
        if failed:
            raise CalibrationError(f"{failed} run(s) of preset {name} failed (see "
                                   f"{Path(out) / name / 'errors.jsonl'}); rerun to retry them")
        records = [store.load(t) for t in tasks]
        tables[name] = target_table(records)
        scores[name] = target_error(records)
    return tables, scores


def write_targets(path, seeds, widths_m, tables: dict, scores: dict) -> Path:
    """``targets.json``: the seeds, widths, every table, and per preset its objective and terms."""
    path = Path(path)
    path.write_text(json.dumps({"seeds": seeds, "widths_m": widths_m, "tables": tables,
                                "objective": {n: e.objective for n, e in scores.items()},
                                "terms": {n: {k: v for k, v in e.terms.items() if k not in e.unscored}
                                          for n, e in scores.items()}}, indent=2))
    return path
