"""The door against the corridor, measured on the experiments as they were run.

The fundamental-diagram work found every candidate on one band in the periodic corridor: the more a crowd slows
with density, the less its door passes (docs/validation/fundamental_diagram.md). This module redraws that band
with the virtual experiments' measure (:mod:`crowd_env.experiments.validation.virtual_experiments`): for every model point
scored on them (a calibration's ``evaluations.jsonl`` under ``--objective virtual``, a ``targets.json`` of
``crowd-calibrate targets --virtual``, a ``virtual_experiments.csv`` of ``crowd-virtual-experiments``), the door, Seyfried's J_s at b = 1.0 m and N = 60, against

- the queue: the Voronoi density behind the 0.95 m exit (run ``uo-180-180-095``, 2.45 /m²), where people keep
  their distance in a queue that carries the exit's flow;
- the narrow entrance: the flow through the 0.70 m entrance (run ``uo-070-180-180``, 1.64 /s), a short opening fed
  by a dense crowd.

A point lacks a figure when its runs at that case all stalled; it is counted and named, never drawn.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

from crowd_env.errors import InputError
from crowd_env.files import write_csv_atomic

from ...analysis.corridor_runs import uo_run
from ...analysis.experiment import seyfried_2009
from ...analysis.figures import pyplot, save_figure

__all__ = ["BAND_FIGURES", "band_points", "band_figure", "calibration_name", "write_band"]

DOOR = "specific_flow_per_m_s b1 n60"
QUEUE = "density_per_m2 uo-180-180-095"
ENTRANCE = "flow_exit_per_s uo-070-180-180"
BAND_FIGURES = (DOOR, QUEUE, ENTRANCE)  # the keys of a point's figures (the calibration objective's names)
BAND_COLUMNS = ("source", "label", "door_js_per_m_s", "queue_density_per_m2", "entrance_flow_per_s")


def _experiment() -> dict:
    ref = seyfried_2009()
    return {DOOR: float(ref.specific_flow_per_m_s[ref.lookup(1.0, 60)[0]]),
            QUEUE: uo_run("uo-180-180-095").density_per_m2, ENTRANCE: uo_run("uo-070-180-180").flow_exit_per_s}


def _label(values: dict) -> str:
    return ", ".join(f"{k}={v:.4g}" for k, v in values.items())


def band_points(paths) -> tuple:
    """``(points, missing)`` from calibration ``evaluations.jsonl`` files, ``targets.json`` files and
    ``virtual_experiments.csv`` tables: each point a dict with ``source`` (the file), ``label`` (the preset, the free
    parameters' values, or the virtual experiments' folder name) and :data:`BAND_FIGURES` (a virtual experiments'
    table gives the means over its complete runs; a targets.json keeps no figures for a preset whose runs stalled
    anywhere: draw its virtual experiments' table instead);
    ``missing``: ``(source, label, reason)`` of the points that lack one (a failed point: a run stalled or stayed
    incomplete, and the calibration kept no figures; or a point scored without the corridor runs). A file of neither kind raises :class:`~crowd_env.errors.InputError`."""
    points, missing = [], []

    def add(source, label, figures, failed=False):
        absent = [k for k in BAND_FIGURES if not _finite(figures.get(k))]
        if failed:
            missing.append((source, label, "a failed point: a run stalled or stayed incomplete"))
        elif absent:
            missing.append((source, label, f"no {', '.join(absent)}"))
        else:
            points.append({"source": source, "label": label, **{k: float(figures[k]) for k in BAND_FIGURES}})

    for path in map(Path, paths):
        if not path.is_file():
            raise InputError(f"{path}: no such file (give a calibration's evaluations.jsonl or a targets.json)")
        if path.suffix == ".csv":
            add(str(path), path.parent.name, _virtual_figures(path))
        elif path.suffix == ".jsonl":
            for i, line in enumerate(path.read_text().splitlines()):
                if line.strip():
                    entry = json.loads(line)
                    if "values" not in entry:
                        raise InputError(f"{path}, line {i + 1}: not a calibration evaluation (no 'values')")
                    add(str(path), _label(entry["values"]), entry.get("figures") or {}, bool(entry.get("failed_point")))
        else:
            content = json.loads(path.read_text())
            if "figures" not in content:
                raise InputError(f"{path}: a targets.json without figures (written before they were stored: rerun "
                                 "crowd-calibrate targets --virtual, it resumes from its runs)")
            for name, figures in content["figures"].items():
                add(str(path), name, figures)
    return points, missing


def _virtual_figures(path) -> dict:
    """The band's figures from a ``virtual_experiments.csv`` (the model's mean over the complete runs of each row)."""
    import csv

    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows or not {"experiment", "case", "quantity", "model"} <= set(rows[0]):
        raise InputError(f"{path}: not a table of crowd-virtual-experiments (columns experiment, case, quantity, model)")
    wanted = {DOOR: ("bottleneck", "b = 1.0 m, N = 60", "J_s"), QUEUE: ("corridor", "uo-180-180-095", "density"),
              ENTRANCE: ("corridor", "uo-070-180-180", "exit flow")}
    figures = {}
    for key, (experiment, case, quantity) in wanted.items():
        for r in rows:
            if r["experiment"] == experiment and r["case"].startswith(case) and r["quantity"].startswith(quantity):
                figures[key] = float(r["model"])
    return figures


def _finite(value) -> bool:
    return isinstance(value, (int, float)) and math.isfinite(value)


def calibration_name(source) -> str:
    """The name a calibration's points go by in the figure: the folder of its ``evaluations.jsonl`` (the ``--out``
    of ``crowd-calibrate optimize``, above its ``optimise/`` folder)."""
    path = Path(source)
    folder = path.parent.parent if path.parent.name == "optimise" else path.parent
    return folder.name or str(path)


def band_figure(points: list, path, *, highlight=()) -> Path:
    """Two panels, the door's J_s (b = 1.0 m, N = 60) against the queue's density (left) and against the narrow
    entrance's flow (right): each calibration's points (from one ``evaluations.jsonl``) in a colour of their own,
    named by :func:`calibration_name` (grey when there is only one), the other points (presets, tables) grey, the
    names in ``highlight`` (presets) labelled, the experiment a star."""
    if not points:
        raise InputError("no point has every figure of the band (see band_points' missing)")
    plt = pyplot()
    exp = _experiment()
    calibrations = list(dict.fromkeys(p["source"] for p in points if p["source"].endswith(".jsonl")))
    palette = [f"C{i}" for i in range(10) if i != 3]  # C3 marks the highlighted points
    groups = [([p for p in points if p["source"] == s], palette[i % len(palette)] if len(calibrations) > 1 else "0.6",
               f"calibration {calibration_name(s)}" if len(calibrations) > 1 else "calibration points")
              for i, s in enumerate(calibrations)]
    others = [p for p in points if p["source"] not in calibrations]
    if others:
        groups.append((others, "0.6" if len(calibrations) > 1 else "0.4", "presets and tables"))
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    for ax, key, xlabel in ((axes[0], QUEUE, "density behind the 0.95 m exit (1/m²)"),
                            (axes[1], ENTRANCE, "flow through the 0.70 m entrance (1/s)")):
        for group, colour, name in groups:
            ax.scatter([p[key] for p in group], [p[DOOR] for p in group], s=14, color=colour, label=name)
        for p in points:
            if p["label"] in highlight:
                ax.scatter(p[key], p[DOOR], s=40, color="C3", zorder=3)
                ax.annotate(p["label"], (p[key], p[DOOR]), textcoords="offset points", xytext=(5, 4), fontsize=8)
        ax.scatter(exp[key], exp[DOOR], marker="*", s=180, color="k", zorder=4, label="experiments")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("Seyfried J_s, b = 1.0 m, N = 60 (1/(m s))")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    return save_figure(fig, path)


def write_band(out, paths, *, highlight=()) -> tuple:
    """``OUT/band.csv`` (every point's figures) and ``OUT/band.png``; returns ``(paths written, missing)``."""
    points, missing = band_points(paths)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rows = [[p["source"], p["label"], p[DOOR], p[QUEUE], p[ENTRANCE]] for p in points]
    write_csv_atomic(out / "band.csv", BAND_COLUMNS, rows)
    return [out / "band.csv", band_figure(points, out / "band.png", highlight=highlight)], missing
