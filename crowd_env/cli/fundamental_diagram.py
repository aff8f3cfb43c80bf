"""Fundamental diagram (speed and specific flow vs density) of a bottleneck run, computed with PedPy.

Either runs one Seyfried bottleneck run (``--width``, ``--n``, ``--seed``; its trajectories are exported
beside the outputs in PedPy's text format) or reads an exported trajectory file (``--trajectory``,
e.g. from ``crowd-bottleneck --trajectories``) with its geometry JSON. In each measurement area
PedPy computes the classic density and the mean individual speed per frame; J_s = ρ v. Writes
``OUT/fundamental_diagram.csv`` (one row per area and occupied frame) and ``OUT/fundamental_diagram.png``.

Examples::

    crowd-fundamental-diagram --width 1.0 --n 60 --seed 0 --out out/fd
    crowd-fundamental-diagram --trajectory out/bottleneck/trajectories/b1.000_n60_s0.txt --out out/fd
"""
from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np

from ..analysis.figures import fundamental_diagram_figure
from ..analysis.trajectories import (DEFAULT_FRAME_RATE_PER_S, Trajectories, TrajectoryFormatError,
                                     fundamental_diagram_data, pedpy_measurement_area, read_geometry)
from ..experiments.recording import record_bottleneck_run

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
    return ap


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
    with open(csv_path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(CSV_COLUMNS)
        for a, d in data.items():
            for row in zip(d["frame"], d["time_s"], d["density_per_m2"], d["speed_m_s"], d["specific_flow_per_m_s"]):
                w.writerow([a, int(row[0])] + [f"{v:.6g}" for v in row[1:]])
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
