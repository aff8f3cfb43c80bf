"""Generalisation: the model on bottleneck set-ups other than Seyfried et al.'s (2009), measured only.

Runs a preset (``--preset``, default: the reproduction's default preset) on a grid of corridor widths,
channel lengths, bottleneck widths b and group sizes N, through the reproduction's own run function
and run store (:mod:`crowd_env.experiments.validation.generalisation`): nothing is tuned, the model parameters
are the preset's. The geometry is Seyfried's otherwise (holding sections of
1.515 m at 3.3 /m², the nearest 2.24 m upstream; the corridor is made as long as the N pedestrians need;
measurement line in the middle of the channel; a 2 m outflow). Each geometry is one configuration and
gets its own sub-folder ``OUT/corridor<W>m_channel<L>m/``, which is exactly the output folder of
``crowd-bottleneck --preset P --corridor-width W --channel-length L --max-time T`` (same
``config.json``, same run files): a killed sweep resumes where it stopped, and one ``OUT`` holds the
whole grid; a folder holding another configuration (e.g. another preset) is refused.

Prints per geometry the specific flow J_s = N/(Δt b) of every run per (N, b), each run marked complete
or stalled (the runner's stall rule) or incomplete (people left at the time limit), the mean over the
complete runs, and per N the linear fit of the flow J(b) with its residual norm; then one line with the
counts of complete, stalled and incomplete runs and of runs whose smallest gap is below -1 mm
(overlap beyond the contact tolerance). Writes ``OUT/generalisation.csv`` (one row per run) and
``OUT/generalisation_specific_flow.png`` (J_s vs b per N, one panel per geometry).

Default grid: corridor widths 4, 6, 8 m × channel lengths 0.4, 2.0, 5.0 m × b = 0.8, 1.2, 1.6, 2.0,
2.5 m × N = 20, 60, 120, 250 × 2 seeds = 360 runs; ``--quick``: corridors 4 and 8 m, channels 0.4 and
5.0 m, b = 0.8, 1.6 and 2.5 m, N = 20 and 250, 1 seed (24 runs: the extremes of every axis).

Example::

    crowd-generalise --quick --out out/generalisation
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

from ..core.params import ParameterError
from ..walking.presets import DEFAULT_PRESET, PRESETS
from ..experiments.validation.bottleneck import flow_fit, summarise
from ..experiments.validation.generalisation import (DEFAULT_CHANNEL_LENGTHS_M, DEFAULT_CORRIDOR_WIDTHS_M, DEFAULT_SEEDS,
                                          DEFAULT_SIZES, DEFAULT_WIDTHS_M, QUICK, GeneralisationError, figure,
                                          geometry_folder, run_counts, run_generalisation, write_csv)
from ..experiments.running.store import RunStoreError


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="crowd-generalise", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--preset", choices=sorted(PRESETS), default=DEFAULT_PRESET,
                    help=f"model configuration (crowd-bottleneck's presets; default: its default, {DEFAULT_PRESET!r})")
    ap.add_argument("--corridor-widths", type=float, nargs="+", default=list(DEFAULT_CORRIDOR_WIDTHS_M),
                    metavar="W", help="corridor widths (m)")
    ap.add_argument("--channel-lengths", type=float, nargs="+", default=list(DEFAULT_CHANNEL_LENGTHS_M),
                    metavar="L", help="channel (bottleneck) lengths (m)")
    ap.add_argument("--widths", type=float, nargs="+", default=list(DEFAULT_WIDTHS_M), metavar="B",
                    help="bottleneck widths b (m)")
    ap.add_argument("--sizes", type=int, nargs="+", default=list(DEFAULT_SIZES), metavar="N", help="group sizes N")
    ap.add_argument("--seeds", type=int, default=DEFAULT_SEEDS, help="seeds per set-up: first..first+S-1")
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--max-time", type=float, default=300.0, help="simulated time limit per run (s)")
    ap.add_argument("--quick", action="store_true",
                    help="a small subset: corridors 4 and 8 m, channels 0.4 and 5 m, b = 0.8, 1.6 and 2.5 m, N = 20 "
                         "and 250, 1 seed (24 runs; overrides the axis flags)")
    ap.add_argument("--out", type=Path, default=Path("out/generalisation"), help="output folder (resumable)")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="parallel worker processes")
    ap.add_argument("--no-figures", action="store_true", help="skip the figure")
    return ap


def _check_axes(args) -> None:
    for name in ("corridor_widths", "channel_lengths", "widths"):
        values = getattr(args, name)
        if any(not np.isfinite(v) or v <= 0 for v in values) or len(set(values)) != len(values):
            raise SystemExit(f"error: --{name.replace('_', '-')} must be distinct positive numbers, got {values}")
    if any(n < 2 for n in args.sizes) or len(set(args.sizes)) != len(args.sizes):
        raise SystemExit(f"error: --sizes must be distinct and >= 2 (J = N/Δt needs two passages), got {args.sizes}")
    if args.seeds < 1 or args.jobs < 1 or args.first_seed < 0:
        raise SystemExit("error: --seeds and --jobs must be >= 1, --first-seed >= 0")
    if not (np.isfinite(args.max_time) and args.max_time > 0):
        raise SystemExit(f"error: --max-time must be > 0, got {args.max_time}")


def run_mark(r: dict) -> str:
    """One run in the table: its J_s if complete, else why not."""
    if r["complete"]:
        return f"{r['specific_flow_per_m_s']:.2f}"
    if r["stalled"]:
        return f"STALL@{r['stall_time_s']:.0f}s({r['n_passages']}/{r['n_pedestrians']})"
    return f"INC({r['n_passages']}/{r['n_pedestrians']})"


def print_geometry(cw: float, cl: float, folder: Path, records: list) -> None:
    rows = summarise(records)
    print(f"\n== corridor {cw:g} m, channel {cl:g} m ({folder})")
    print(f"{'N':>5} {'b (m)':>6}  {'J_s mean':>8}  {'J (1/s)':>7}  J_s per run (1/(m s); STALL@t: stalled at t, "
          f"INC: people left at the time limit; (passed/N))")
    by_cell: dict = {}
    for r in records:
        by_cell.setdefault((r["n_pedestrians"], r["width_m"]), []).append(r)
    for row in rows:
        cell = sorted(by_cell[(row["n_pedestrians"], row["width_m"])], key=lambda r: r["seed"])
        mark = "*" if row["complete"] < row["runs"] else " "
        print(f"{row['n_pedestrians']:>5} {row['width_m']:>6.2f}  {row['specific_flow_mean']:>7.3f}{mark}  "
              f"{row['flow_mean']:>7.3f}  " + " ".join(run_mark(r) for r in cell))
    for n in sorted({r["n_pedestrians"] for r in rows}):
        fit = flow_fit(rows, n)
        if fit is None:
            print(f"  N = {n}: J(b) fit needs complete runs at >= 3 widths")
        else:
            n_w = sum(1 for r in rows if r["n_pedestrians"] == n and np.isfinite(r["flow_mean"]))
            print(f"  N = {n}: J(b) = {fit.slope:.3f} b {fit.intercept:+.3f} (1/s), residual norm "
                  f"{fit.residual_norm:.3f} over {n_w} widths")
    if any(r["complete"] < r["runs"] for r in rows):
        print("  * mean over the complete runs only")



def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    if args.quick:
        for key, value in QUICK.items():
            setattr(args, key, list(value) if isinstance(value, list) else value)
    _check_axes(args)
    geometries = [(float(cw), float(cl)) for cw in args.corridor_widths for cl in args.channel_lengths]
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    try:
        records = run_generalisation(args.out, args.preset, geometries, args.widths, args.sizes, seeds, args.max_time,
                                     args.jobs)
    except (ParameterError, GeneralisationError, RunStoreError) as exc:
        raise SystemExit(f"error: {exc}") from None
    print(f"generalisation of preset {args.preset!r}: {len(geometries)} geometries × {len(args.widths)} widths × "
          f"{len(args.sizes)} sizes × {args.seeds} seed(s) = {len(records)} runs (no parameter tuned)")
    for g in geometries:
        print_geometry(*g, geometry_folder(args.out, *g),
                       [r for r in records if (r["corridor_width_m"], r["channel_length_m"]) == g])
    args.out.mkdir(parents=True, exist_ok=True)
    write_csv(records, args.out / "generalisation.csv")
    counts = run_counts(records)
    if not args.no_figures:
        print(f"figure: {figure(records, geometries, args.out / 'generalisation_specific_flow.png', args.preset)}")
    print(f"results: {args.out / 'generalisation.csv'}")
    print(f"runs: {counts['runs']}; complete {counts['complete']}, stalled {counts['stalled']}, incomplete at the time "
          f"limit {counts['incomplete']}; smallest gap below -1 mm (overlap beyond the contact tolerance) "
          f"in {counts['overlapping']} (worst {1e3 * counts['min_gap_m']:+.2f} mm)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
