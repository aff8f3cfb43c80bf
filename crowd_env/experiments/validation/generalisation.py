"""Generalisation: the model on bottleneck set-ups other than Seyfried et al.'s (2009), measured only.

A preset runs, untuned, on a grid of corridor widths, channel lengths, bottleneck widths b and group
sizes N through the reproduction's own task, run function and store
(:mod:`crowd_env.experiments.validation.bottleneck`): J_s (Kabalan et al. 2016, Eq. 22), the stall rule, the gaps.
The geometry is Seyfried's otherwise (holding sections of 1.515 m at 3.3 /m², the nearest 2.24 m
upstream; the corridor as long as the N pedestrians need; measurement line in the middle of the
channel). Each geometry is one configuration with its own folder ``OUT/corridor<W>m_channel<L>m/``,
exactly the output folder of ``crowd-bottleneck --preset P --corridor-width W --channel-length L
--max-time T``: a killed sweep resumes, and a folder of another configuration is refused.
"""
from __future__ import annotations

from crowd_env.errors import GeneralisationError
from crowd_env.files import write_csv_atomic

from pathlib import Path

import numpy as np

from ...walking.presets import get_preset
from ...core.segments import GeometryError
from ...scenarios import ScenarioError, make_scenario
from .bottleneck import RESULT_COLUMNS, bottleneck_config, model_params, run_sweep, summarise
from ..running.store import RunStore

__all__ = ["DEFAULT_CORRIDOR_WIDTHS_M", "DEFAULT_CHANNEL_LENGTHS_M", "DEFAULT_WIDTHS_M", "DEFAULT_SIZES",
           "DEFAULT_SEEDS", "QUICK", "OVERLAP_TOLERANCE_M", "CSV_COLUMNS", "GeneralisationError", "geometry_folder",
           "geometry_config", "check_setups", "run_generalisation", "run_counts", "write_csv", "figure"]

DEFAULT_CORRIDOR_WIDTHS_M = (4.0, 6.0, 8.0)
DEFAULT_CHANNEL_LENGTHS_M = (0.4, 2.0, 5.0)
DEFAULT_WIDTHS_M = (0.8, 1.2, 1.6, 2.0, 2.5)
DEFAULT_SIZES = (20, 60, 120, 250)
DEFAULT_SEEDS = 2
QUICK = {"corridor_widths": [4.0, 8.0], "channel_lengths": [0.4, 5.0], "widths": [0.8, 1.6, 2.5],
         "sizes": [20, 250], "seeds": 1}  # the extremes of every axis, 24 runs
OVERLAP_TOLERANCE_M = 1e-3  # contact tolerance: a gap below -1 mm is an overlap beyond it
CSV_COLUMNS = ["corridor_width_m", "channel_length_m"] + RESULT_COLUMNS


def geometry_folder(out: Path, corridor_width_m: float, channel_length_m: float) -> Path:
    return Path(out) / f"corridor{corridor_width_m:g}m_channel{channel_length_m:g}m"


def geometry_config(preset: str, corridor_width_m: float, channel_length_m: float, max_time_s: float) -> dict:
    """The configuration ``crowd-bottleneck`` writes for this preset and geometry (Seyfried's otherwise)."""
    return bottleneck_config(model_params(preset), navigation_clearance_m=get_preset(preset).navigation_clearance_m,
                             max_time_s=float(max_time_s), corridor_width_m=float(corridor_width_m),
                             channel_length_m=float(channel_length_m), radius_m=get_preset(preset).radius_m)


def check_setups(configs: dict, widths, sizes, seed: int) -> None:
    """Build every scenario once (seed ``seed``): an impossible set-up raises :class:`GeneralisationError`
    naming it and the reason (a channel wider than the corridor, not wider than a pedestrian, a corridor
    too narrow to hold anybody at the start density, ...), before any folder is touched or worker started."""
    for (cw, cl), config in configs.items():
        for b in widths:
            for n in sizes:
                try:
                    make_scenario("seyfried_bottleneck", width_m=b, n_pedestrians=n, seed=seed, **config["geometry"])
                except (GeometryError, ScenarioError) as exc:
                    raise GeneralisationError(f"impossible set-up: corridor {cw:g} m, channel {cl:g} m, b = {b:g} m, "
                                              f"N = {n}: {exc}") from None


def run_generalisation(out, preset: str, geometries, widths, sizes, seeds, max_time_s: float, jobs: int) -> list:
    """Every run of the grid (missing ones computed, in one pool): the records, each with its
    ``corridor_width_m`` and ``channel_length_m``, in the order geometry, N, b, seed.

    Every set-up is built first and every folder's configuration checked before anything runs
    (:class:`GeneralisationError`, :class:`~crowd_env.experiments.running.store.RunStoreError`)."""
    geometries = [(float(cw), float(cl)) for cw, cl in geometries]
    configs = {g: geometry_config(preset, *g, max_time_s) for g in geometries}
    seeds = list(seeds)
    check_setups(configs, widths, sizes, seeds[0])
    for g, config in configs.items():
        RunStore(geometry_folder(out, *g), config)
    tasks = [dict(width_m=float(b), n_pedestrians=int(n), seed=s, **configs[g])
             for g in geometries for n in sizes for b in widths for s in seeds]

    def folder_of(task):
        return geometry_folder(out, task["geometry"]["corridor_width_m"], task["geometry"]["channel_length_m"])

    records = run_sweep(tasks, out, jobs, desc="generalisation runs", folder_of=folder_of)
    for t, r in zip(tasks, records):
        r["corridor_width_m"] = t["geometry"]["corridor_width_m"]
        r["channel_length_m"] = t["geometry"]["channel_length_m"]
    return records


def run_counts(records: list) -> dict:
    """Counts of complete, stalled and otherwise incomplete runs, of runs whose smallest gap is below
    -:data:`OVERLAP_TOLERANCE_M`, and the smallest gap."""
    n_complete = sum(bool(r["complete"]) for r in records)
    n_stalled = sum(bool(r["stalled"]) for r in records)
    gaps = np.array([r["min_gap_m"] for r in records], dtype=float)
    return {"runs": len(records), "complete": n_complete, "stalled": n_stalled,
            "incomplete": len(records) - n_complete - n_stalled,
            "overlapping": int(np.count_nonzero(gaps < -OVERLAP_TOLERANCE_M)), "min_gap_m": float(np.min(gaps))}


def write_csv(records: list, path: Path) -> None:
    """One row per run (:data:`CSV_COLUMNS`)."""
    write_csv_atomic(path, CSV_COLUMNS, sorted(records, key=lambda r: (
        r["corridor_width_m"], r["channel_length_m"], r["n_pedestrians"], r["width_m"], r["seed"])),
        extrasaction="ignore")


def figure(records: list, geometries: list, path: Path, preset: str) -> Path:
    """J_s vs b per N (mean over complete runs, single runs as dots), one panel per geometry; stalled
    runs as red crosses on the b axis, otherwise incomplete runs as orange ones."""
    from ...analysis.figures import pyplot, save_figure

    plt = pyplot()
    cws = sorted({cw for cw, _ in geometries})
    cls = sorted({cl for _, cl in geometries})
    sizes = sorted({r["n_pedestrians"] for r in records})
    fig, axes = plt.subplots(len(cws), len(cls), figsize=(3.8 * len(cls), 3.2 * len(cws)), squeeze=False,
                             sharex=True, sharey=True)
    top = max([r["specific_flow_per_m_s"] for r in records if r["complete"]] + [2.5])
    for i, cw in enumerate(cws):
        for j, cl in enumerate(cls):
            ax = axes[i][j]
            recs = [r for r in records if r["corridor_width_m"] == cw and r["channel_length_m"] == cl]
            rows = summarise(recs) if recs else []
            for k, n in enumerate(sizes):
                sub = [r for r in rows if r["n_pedestrians"] == n]
                ax.plot([r["width_m"] for r in sub], [r["specific_flow_mean"] for r in sub], "o-", color=f"C{k}",
                        ms=4, label=f"N = {n}")
                done = [r for r in recs if r["n_pedestrians"] == n and r["complete"]]
                ax.plot([r["width_m"] for r in done], [r["specific_flow_per_m_s"] for r in done], ".", color=f"C{k}",
                        alpha=0.4, ms=3)
            for kind, color in (("stalled", "red"), ("incomplete", "orange")):
                bad = [r for r in recs if not r["complete"] and bool(r["stalled"]) == (kind == "stalled")]
                if bad:
                    ax.plot([r["width_m"] for r in bad], [0.05 * top] * len(bad), "x", color=color, ms=8, mew=2,
                            label=f"{kind} ({len(bad)})")
            ax.set_title(f"corridor {cw:g} m, channel {cl:g} m", fontsize=9)
            ax.set_ylim(0, 1.1 * top)
            if i == len(cws) - 1:
                ax.set_xlabel("b (m)")
            if j == 0:
                ax.set_ylabel("J_s (1/(m s))")
            ax.legend(fontsize=6)
    fig.suptitle(f"generalisation, preset {preset}: specific flow vs width (means over complete runs)", fontsize=10)
    return Path(save_figure(fig, path))
