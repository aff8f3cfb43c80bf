"""The calibration objective along one parameter, the others fixed: e.g. the ε_T landscape in λ.

Each value is one point of :class:`~crowd_env.experiments.validation.calibration.optimize.PointEvaluator` (the
optimiser's own evaluation: same runs, same cache, same common random numbers), so a landscape and an
optimisation in one folder share their runs. ``landscape.csv`` holds the objective, ε_T (Eq. 24), every target
term and, with the target objective, the figures that explain the shape: J_s of N = 20, 40, 60 and
the capacity ratio (stationary rate of N = 120 over N = 60) per width.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from crowd_env.files import write_csv_atomic
from .errors import CalibrationError
from .optimize import FREE_PARAMETERS, PointEvaluator


def landscape(evaluator: PointEvaluator, name: str, values, verbose: bool = True) -> list:
    """Evaluate ``evaluator`` at ``{name: v}`` for each v of ``values`` (in order); returns the entries."""
    if name not in FREE_PARAMETERS:
        raise CalibrationError(f"unknown parameter {name!r}; choose from {list(FREE_PARAMETERS)}")
    p = FREE_PARAMETERS[name]
    values = [float(v) for v in values]
    if not values:
        raise CalibrationError("a landscape needs at least one value")
    bad = [v for v in values if not (math.isfinite(v) and p.bounds[0] <= v <= p.bounds[1])]
    if bad:
        raise CalibrationError(f"values of {name} outside its admissible range {p.bounds}: {bad}")
    if len(set(values)) != len(values):
        raise CalibrationError(f"repeated values of {name}: {values}")
    entries = []
    for k, v in enumerate(values):
        entry = evaluator({name: v}, desc=f"{name} = {v:g} ({k + 1}/{len(values)})")
        entries.append(entry)
        if verbose:
            print(f"{name} = {v:g}: objective {entry['objective']:.5g}, ε_T {entry['epsilon_total']:.5g}",
                  file=sys.stderr)
    return entries


def entry_failed(entry: dict) -> bool:
    """Whether an evaluation entry is a failed point: a run raised, stalled or did not complete."""
    return bool(entry.get("failed_point") or entry.get("n_stalled") or entry.get("failed_runs"))


def _row(name: str, entry: dict) -> dict:
    row = {name: entry["values"][name], "objective": entry["objective"], "epsilon_total": entry["epsilon_total"],
           "n_stalled": entry.get("n_stalled", 0), "n_incomplete": entry.get("n_incomplete", 0),
           "failed": entry_failed(entry)}
    row.update({f"term_{k}": v for k, v in (entry.get("terms") or {}).items()})
    row.update({f"capacity_ratio_b{k}": v for k, v in (entry.get("capacity_ratio") or {}).items()})
    row.update({k.replace("specific_flow_per_m_s ", "js_").replace(" ", "_"): v
                for k, v in (entry.get("figures") or {}).items() if k.startswith("specific_flow_per_m_s ")})
    return row


def write_landscape(name: str, entries: list, out, figure: bool = True) -> list:
    """``landscape_<name>.csv`` (a row per value) and, with ``figure``, ``landscape_<name>.png``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rows = [_row(name, e) for e in entries]
    fields = list(dict.fromkeys(k for r in rows for k in r))
    path = out / f"landscape_{name}.csv"
    write_csv_atomic(path, fields, rows)
    paths = [path]
    if figure:
        paths.append(landscape_figure(name, rows, out / f"landscape_{name}.png"))
    return paths


def landscape_figure(name: str, rows: list, path) -> Path:
    """(a) objective and ε_T against the parameter (log scale; failed points marked); (b) J_s at b = 1 m
    for each N; (c) the capacity ratio N = 120 / N = 60 with its band (when the target objective ran)."""
    from ....analysis.figures import pyplot, save_figure
    from .objective import CAPACITY_RANGE

    plt = pyplot()
    x = np.array([r[name] for r in rows], dtype=float)
    order = np.argsort(x)
    x = x[order]
    rows = [rows[k] for k in order]
    fig, axes = plt.subplots(1, 3, figsize=(13.5, 4.0))
    ax = axes[0]
    obj = np.array([r["objective"] for r in rows], dtype=float)
    eps = np.array([r["epsilon_total"] for r in rows], dtype=float)
    failed = np.array([r["failed"] for r in rows])
    ok = ~failed
    ax.semilogy(x[ok], obj[ok], "o-", label="objective (all targets)")
    ax.semilogy(x, eps, "s--", label="ε_T, N = 60 (Eq. 24)")
    if failed.any():
        for xv in x[failed]:
            ax.axvline(xv, color="red", alpha=0.3)
        ax.plot([], [], color="red", alpha=0.3, label="incomplete/stalled run: failed point")
    ax.set_xlabel(name)
    ax.set_ylabel("objective")
    ax.legend(fontsize=7)
    ax.set_title(f"calibration objective along {name}")
    ax = axes[1]
    for n in (20, 40, 60, 120):
        key = f"js_b1_n{n}"
        if any(key in r for r in rows):
            ax.plot(x, [r.get(key, np.nan) for r in rows], "o-", label=f"N = {n}")
    ax.axhspan(1.77, 2.31, color="grey", alpha=0.15, label="N = 20/40 range")
    ax.set_xlabel(name)
    ax.set_ylabel("J_s at b = 1 m (1/(m s))")
    ax.legend(fontsize=7)
    ax.set_title("flow against crowd size")
    ax = axes[2]
    cap_keys = sorted({k for r in rows for k in r if k.startswith("capacity_ratio_b")})
    for key in cap_keys:
        ax.plot(x, [r.get(key, np.nan) for r in rows], "o-", label=f"b = {key.removeprefix('capacity_ratio_b')} m")
    ax.axhspan(*CAPACITY_RANGE, color="grey", alpha=0.15, label="capacity band")
    ax.set_xlabel(name)
    ax.set_ylabel("stationary rate N = 120 / N = 60")
    ax.legend(fontsize=7)
    ax.set_title("capacity criterion")
    fig.tight_layout()
    save_figure(fig, path)
    return Path(path)
