"""Fundamental diagram (speed and specific flow vs density) of a bottleneck run, computed with PedPy.

Either runs one Seyfried bottleneck run (``--width``, ``--n``, ``--seed``; its trajectories are exported
beside the outputs in PedPy's text format) or reads an exported trajectory file (``--trajectory``,
e.g. from ``crowd-bottleneck --trajectories``) with its geometry JSON. In each measurement area
PedPy computes the classic density and the mean individual speed per frame; J_s = ρ v. Writes
``OUT/fundamental_diagram.csv`` (one row per area and occupied frame) and ``OUT/fundamental_diagram.png``.

With ``--sweep`` it instead sweeps density in the periodic corridor (1.8 m, the Jülich experiment's width) and
the single-file ring (:mod:`crowd_env.experiments.validation.fundamental_diagram`), prints each density's mean speed beside
the experiment's, the single file's headway fit d = a + b v, and writes ``OUT/fd_sweep.csv``, ``OUT/fd_sweep.json``
and ``OUT/fd_sweep.png`` (beside the Jülich corridor bins, Seyfried's single file and Weidmann's curve). Runs are
kept under ``OUT/runs``: a stopped sweep resumes.

Examples::

    crowd-fundamental-diagram --width 1.0 --n 60 --seed 0 --out out/fd
    crowd-fundamental-diagram --trajectory out/bottleneck/trajectories/b1.000_n60_s0.txt --out out/fd
    crowd-fundamental-diagram --sweep --preset calibrated --seeds 3 --out out/fd-sweep
    crowd-fundamental-diagram --candidates --preset vision --grid vision_body_scale=0.3,0.5 --out out/fd-candidates

With ``--candidates`` it measures parameter points on the door and the corridor at once (the candidates table of
docs/validation/fundamental_diagram.md): for each point of ``--grid`` (the product of the values given, on top of
``--preset`` and ``--set``), Seyfried's bottleneck (N = 60 at 0.8, 1.0, 1.2 m, seeds 0-1: J_s, density in front
and inside, speed inside) and the periodic corridor's speed at six Jülich bins (seed 0), one line each, appended
to ``OUT/candidates.jsonl`` as it is done (a point found there is not run again).
"""
from __future__ import annotations

import argparse
import itertools
import json
import sys
from pathlib import Path

import numpy as np

from ..analysis.fd_reference import JUELICH_CORRIDOR_WIDTH_M
from ..analysis.figures import candidates_figure, fd_sweep_figure, fundamental_diagram_figure
from ..analysis.trajectories import (DEFAULT_FRAME_RATE_PER_S, Trajectories, TrajectoryFormatError,
                                     fundamental_diagram_data, pedpy_measurement_area, read_geometry)
from ..core.params import ParameterError
from ..errors import OptionError
from ..walking.presets import DEFAULT_PRESET, PRESETS, get_preset
from ..experiments.running.backends import execute, failure_report, make_backend
from ..experiments.validation.bottleneck import params_dict
from ..experiments.validation.fundamental_diagram import (CORRIDOR_DENSITIES, SETUPS, SINGLE_FILE_DENSITIES, door_and_corridor,
                                               fd_tasks, run_fd_one, summarise_fd)
from ..experiments.running.recording import record_bottleneck_run
from ..experiments.running.store import RunStore
from crowd_env.files import write_atomic, write_csv_atomic, write_json_atomic
from .options import add_key_values, json_or_text, key_values

CSV_COLUMNS = ["area", "frame", "time_s", "density_per_m2", "speed_m_s", "specific_flow_per_m_s"]


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="crowd-fundamental-diagram", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--trajectory", type=Path, help="PedPy text trajectory to analyse instead of running a simulation")
    ap.add_argument("--geometry", type=Path,
                    help="geometry JSON of the trajectory (default: <trajectory stem>.geometry.json beside it)")
    ap.add_argument("--width", type=float, default=1.0, help="bottleneck width b (m) of the simulated run")
    ap.add_argument("--n", type=int, default=60, help="number of pedestrians of the simulated run")
    ap.add_argument("--seed", type=int, default=0, help="seed of the simulated run")
    ap.add_argument("--max-time", type=float, default=300.0, help="simulated time limit (s)")
    ap.add_argument("--fps", type=float, default=DEFAULT_FRAME_RATE_PER_S,
                    help="frame rate of the recorded trajectory, 1/(k h) (default 25)")
    ap.add_argument("--areas", nargs="+", help="measurement areas (default: all of the geometry: front, inside)")
    ap.add_argument("--speed-window", type=float, default=0.4, help="time window of the individual speeds (s)")
    ap.add_argument("--out", type=Path, default=Path("out/fundamental_diagram"), help="output folder")
    sw = ap.add_argument_group("density sweep (--sweep)")
    sw.add_argument("--sweep", action="store_true", help="sweep density in the periodic corridor and single file")
    sw.add_argument("--setups", nargs="+", default=list(SETUPS), choices=SETUPS, help="set-ups to sweep")
    sw.add_argument("--densities", type=float, nargs="+", default=list(CORRIDOR_DENSITIES),
                    help="corridor densities (1/m²)")
    sw.add_argument("--single-file-densities", type=float, nargs="+", default=list(SINGLE_FILE_DENSITIES),
                    help="single-file densities (1/m)")
    sw.add_argument("--seeds", type=int, default=3, help="seeds per density (0..k-1)")
    sw.add_argument("--preset", default=DEFAULT_PRESET, choices=sorted(PRESETS), help="model preset")
    sw.add_argument("--length", type=float, default=20.0, help="length of the periodic strip (m)")
    sw.add_argument("--corridor-width", type=float, default=JUELICH_CORRIDOR_WIDTH_M,
                    help="width of the periodic corridor (m; default the Jülich experiment's; a door's width measures "
                         "its channel; the experiment columns stay the 1.8 m corridor's)")
    sw.add_argument("--sweep-time", type=float, default=40.0, help="simulated time per run (s)")
    sw.add_argument("--transient", type=float, default=15.0, help="time left out before measuring (s)")
    sw.add_argument("--backend", default="process", choices=["ray", "process", "serial"], help="executor")
    sw.add_argument("--jobs", type=int, default=None, help="worker processes (default: the cores)")
    cd = ap.add_argument_group("door and corridor of parameter points (--candidates)")
    cd.add_argument("--candidates", action="store_true", help="measure parameter points on the door and corridor")
    add_key_values(cd, "--set",
                   "ModelParams fields on top of --preset (for --candidates and --sweep)")
    add_key_values(cd, "--grid", "ModelParams fields to vary (every combination); values as JSON (null for None)",
                   metavar="NAME=V1,V2,...")
    return ap


def _assignments(items, what: str) -> dict:
    """``--set`` NAME=VALUE or ``--grid`` NAME=V1,V2,... items (:func:`~crowd_env.cli.options.key_values`), each value
    read as JSON (numbers, true, false, null); ``--grid`` gives a list per name."""
    try:
        texts = key_values(items, f"{what} expected NAME=VALUE", parse=str)
    except OptionError as exc:
        raise SystemExit(f"error: {exc}") from None
    out = {}
    for name, value in texts.items():
        values = [json_or_text(v) for v in value.split(",")]
        if any(isinstance(v, str) for v in values):
            raise SystemExit(f"error: {what} {name}={value}: {value!r} is not a number, null, true or false")
        out[name] = values if what == "--grid" else values[0]
    return out


def _candidates(args) -> int:
    preset = get_preset(args.preset)
    fixed = _assignments(args.set, "--set")
    grid = _assignments(args.grid, "--grid")
    done = {}
    path = args.out / "candidates.jsonl"
    if path.exists():
        for line in path.read_text().splitlines():
            row = json.loads(line)
            done[json.dumps([row["preset"], row["changes"]], sort_keys=True)] = row
    print(f"preset {args.preset} with {fixed or 'no changes'}: J_s at b = 0.8 / 1.0 / 1.2 m (experiment 1.61 / 1.90 / "
          f"1.97), front / inside density (4-6 / 1.42-1.73 /m²), corridor speed at 0.63 / 1.15 / 1.63 / 2.11 / 2.62 / "
          f"3.10 /m² (experiment 1.37 / 1.18 / 0.99 / 0.63 / 0.42 / 0.34 m/s), largest miss")
    for combo in itertools.product(*grid.values()):
        changes = {**fixed, **dict(zip(grid, combo))}
        key = json.dumps([args.preset, changes], sort_keys=True)
        if key not in done:
            try:
                params = preset.params(**changes)
            except ParameterError as exc:
                raise SystemExit(f"error: {exc}") from None
            row = {"preset": args.preset, "changes": changes,
                   **door_and_corridor(params, navigation_clearance_m=preset.navigation_clearance_m)}
            done[key] = row
            write_atomic(path, "".join(json.dumps(r) + "\n" for r in done.values()))  # never half a line
        row = done[key]
        door, corr = list(row["door"].values()), list(row["corridor"].values())
        flows = " / ".join(f"{d['specific_flow_per_m_s']:.2f}" for d in door)
        speeds = " / ".join(f"{c['speed_m_s']:.2f}" for c in corr)
        front = np.mean([d["density_front_per_m2"] for d in door])
        inside = np.mean([d["density_inside_per_m2"] for d in door])
        print(f"{changes}: J_s {flows}, front {front:.1f}, inside {inside:.2f}, corridor {speeds}, "
              f"miss {row['corridor_max_miss_m_s']:.2f}", flush=True)
    png = candidates_figure(list(done.values()), args.out / "candidates.png")
    print(f"figure (every point of {path}): {png}")
    return 0


def _sweep(args) -> int:
    params = get_preset(args.preset).params(**_assignments(args.set, "--set"))
    tasks = fd_tasks(args.setups, {"corridor": args.densities, "single_file": args.single_file_densities},
                     range(args.seeds), params, length_m=args.length, max_time_s=args.sweep_time,
                     transient_s=args.transient, corridor_width_m=args.corridor_width)
    store = RunStore(args.out, {"kind": "fundamental_diagram_sweep", "preset": args.preset,
                                "params": params_dict(params)})
    with make_backend(args.backend, jobs=args.jobs) as backend:
        failed = execute(tasks, store, backend, run_fd_one, desc="fundamental diagram runs")
    if failed:
        raise SystemExit(f"error: {failure_report(tasks, store)}")
    records = [store.load(t) for t in tasks]
    summary = summarise_fd(records)
    lines = []
    for setup, unit in (("corridor", "1/m²"), ("single_file", "1/m")):
        if not summary[setup]:
            continue
        spread = " ± sd over seeds" if args.seeds > 1 else " (one seed: no spread)"
        print(f"{setup} ({args.preset}, {args.seeds} seed{'s' if args.seeds > 1 else ''}): density ({unit}), speed "
              f"(m/s){spread}, experiment, difference, specific flow")
        for r in summary[setup]:
            sd = f" ± {r['speed_sd_m_s']:.3f}" if np.isfinite(r["speed_sd_m_s"]) else ""
            print(f"  {r['density']:5.2f}  {r['speed_m_s']:.3f}{sd}  "
                  f"{r['experiment_speed_m_s']:.3f}  {r['difference_m_s']:+.3f}  {r['flow']:.3f}")
            lines.append({"setup": setup, **r})
    if "single_file_fit" in summary:
        a, b, k = summary["single_file_fit"]
        print(f"single file headway fit d = a + b v over {k} samples (v > 0.05 m/s): a = {a:.3f} m, b = {b:.3f} s "
              f"(experiment: 0.34 m, 1.08 s)")
    write_csv_atomic(args.out / "fd_sweep.csv", list(lines[0]), lines)
    write_json_atomic(args.out / "fd_sweep.json", summary)
    png = fd_sweep_figure(summary, args.out / "fd_sweep.png", title=f"fundamental diagram, preset {args.preset}")
    print(f"figure: {png}\ntable: {args.out / 'fd_sweep.csv'}")
    return 0


def _simulate(args):
    stem = args.out / f"b{args.width:.3f}_n{args.n}_s{args.seed}"
    try:
        result, traj, geometry, paths = record_bottleneck_run(args.width, args.n, args.seed, stem,
                                                              frame_rate_per_s=args.fps, max_time_s=args.max_time)
    except TrajectoryFormatError as exc:
        raise SystemExit(f"error: --fps: {exc}")
    print(f"simulated b = {args.width:g} m, N = {args.n}, seed {args.seed}: J_s = {result.specific_flow_per_m_s:.3f} "
          f"1/(m s); trajectory {paths[0]}")
    return traj, geometry, f"b = {args.width:g} m, N = {args.n}, seed {args.seed}"


def _load(args):
    geometry_path = args.geometry
    if geometry_path is None:
        geometry_path = args.trajectory.with_name(args.trajectory.stem + ".geometry.json")
        if not geometry_path.is_file():
            raise SystemExit(f"error: no geometry file {geometry_path} beside the trajectory; pass --geometry")
    try:
        traj = Trajectories.read_txt(args.trajectory)
        geometry = read_geometry(geometry_path)
    except (TrajectoryFormatError, FileNotFoundError) as exc:
        raise SystemExit(f"error: {exc}")
    return traj, geometry, args.trajectory.name


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    if args.sweep and args.candidates:
        raise SystemExit("error: choose --sweep or --candidates, not both")
    if args.sweep:
        return _sweep(args)
    if args.candidates:
        return _candidates(args)
    traj, geometry, label = _load(args) if args.trajectory is not None else _simulate(args)
    names = args.areas or sorted(geometry.measurement_areas)
    unknown = [a for a in names if a not in geometry.measurement_areas]
    if unknown:
        raise SystemExit(f"error: unknown measurement area(s) {unknown}; the geometry has {sorted(geometry.measurement_areas)}")
    if not names:
        raise SystemExit("error: the geometry has no measurement area")
    traj_data = traj.to_pedpy()
    data = {a: fundamental_diagram_data(traj_data, pedpy_measurement_area(geometry, a), args.speed_window) for a in names}
    csv_path = args.out / "fundamental_diagram.csv"
    write_csv_atomic(csv_path, CSV_COLUMNS, (
        [a, int(row[0])] + [f"{v:.6g}" for v in row[1:]] for a, d in data.items()
        for row in zip(d["frame"], d["time_s"], d["density_per_m2"], d["speed_m_s"], d["specific_flow_per_m_s"])))
    png = fundamental_diagram_figure(data, args.out / "fundamental_diagram.png", title=f"fundamental diagram (PedPy), {label}")
    for a, d in data.items():
        if d["frame"].size:
            print(f"{a:>8}: {d['frame'].size} occupied frames, mean ρ = {np.mean(d['density_per_m2']):.2f} /m², "
                  f"mean v = {np.mean(d['speed_m_s']):.2f} m/s, mean J_s = {np.mean(d['specific_flow_per_m_s']):.2f} 1/(m s)")
        else:
            print(f"{a:>8}: nobody ever inside")
    print(f"figure: {png}\ntable: {csv_path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
