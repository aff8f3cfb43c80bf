"""The evaluation harness's results as a reader sees them: the summary table, its 95 % intervals, a CSV of every
episode and a bar chart per metric (:mod:`crowd_env.experiments.running.evaluation` runs and measures)."""
from __future__ import annotations

import math
from dataclasses import asdict, fields

import numpy as np

from crowd_env.files import save_figure_atomic, write_csv_atomic

from ..running.evaluation import METRICS, EpisodeMetrics, summarize
from . import tables

__all__ = ["format_table", "format_intervals", "write_csv", "plot_results"]


def format_table(rows) -> str:
    """One plain-text table of the summary (means over seeds; NaN-valued episodes left out, counted in [k/n];
    J_s is NaN for incomplete episodes, so its mean is over the complete ones)."""
    head = ["scenario", "policy", "evac.", "stalled"] + [label for _, label in METRICS]
    lines = []
    for row in rows:
        cells = [row["scenario"], row["policy"], f"{100 * row['evacuated_fraction']:.0f}%",
                 f"{row.get('n_stalled', 0)}/{row['n_episodes']}"]
        for key, _ in METRICS:
            v, k, n = row[key], row[key + "_n"], row["n_episodes"]
            s = "nan" if not np.isfinite(v) else (f"{v:.0f}" if key == "n_percussions" else
                                                   f"{v:.4f}" if key == "min_gap_m" else f"{v:.3f}")
            if k < n:
                s += f" [{k}/{n}]"
            cells.append(s)
        lines.append(cells)
    return tables.format_table(head, lines, align="<<" + ">" * (len(head) - 2))


def format_intervals(rows) -> str:
    """The 95 % intervals of :func:`summarize`'s means (:func:`confidence_interval`, a percentile bootstrap over
    the episodes), one table laid out as :func:`format_table`'s."""
    head = ["scenario", "policy", "episodes"] + [label for _, label in METRICS]
    lines = []
    for row in rows:
        cells = [row["scenario"], row["policy"], str(row["n_episodes"])]
        for key, _ in METRICS:
            lo, hi = row[key + "_ci_low"], row[key + "_ci_high"]
            digits = 0 if key == "n_percussions" else 4 if key == "min_gap_m" else 3
            cells.append("nan" if not (np.isfinite(lo) and np.isfinite(hi)) else f"{lo:.{digits}f}..{hi:.{digits}f}")
        lines.append(cells)
    return tables.format_table(head, lines, align="<<" + ">" * (len(head) - 2))


def write_csv(results, path) -> None:
    """Every episode's metrics, one row each, as CSV at ``path`` (written atomically)."""
    write_csv_atomic(path, [f.name for f in fields(EpisodeMetrics)], [asdict(r) for r in results])


def plot_results(results, path) -> None:
    """Bar chart per metric (mean ± std over seeds), one bar per policy, grouped by scenario."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    rows = summarize(results)
    scenarios = list(dict.fromkeys(r["scenario"] for r in rows))
    policies = list(dict.fromkeys(r["policy"] for r in rows))
    ncols = 4
    nrows = math.ceil(len(METRICS) / ncols)
    fig = Figure(figsize=(3.4 * ncols, 3.0 * nrows + 0.4))
    FigureCanvasAgg(fig)
    width = 0.8 / max(len(policies), 1)
    for m, (key, label) in enumerate(METRICS):
        ax = fig.add_subplot(nrows, ncols, m + 1)
        for p, pol in enumerate(policies):
            xs, ys, es = [], [], []
            for s, scen in enumerate(scenarios):
                row = next((r for r in rows if r["scenario"] == scen and r["policy"] == pol), None)
                if row is None:
                    continue
                xs.append(s + (p - (len(policies) - 1) / 2) * width)
                ys.append(row[key] if np.isfinite(row[key]) else 0.0)
                es.append(row[key + "_std"] if np.isfinite(row[key + "_std"]) else 0.0)
            ax.bar(xs, ys, width, yerr=es, label=pol, capsize=2)
        ax.set_title(label, fontsize=9)
        ax.set_xticks(range(len(scenarios)))
        ax.set_xticklabels([f"S{s}" for s in range(len(scenarios))], fontsize=8)
        ax.tick_params(labelsize=8)
    fig.axes[0].legend(fontsize=7)
    fig.suptitle("; ".join(f"S{s}: {scen}" for s, scen in enumerate(scenarios)) + "  (NaN shown as 0)", fontsize=8)
    fig.tight_layout()
    save_figure_atomic(fig, path, dpi=100)
