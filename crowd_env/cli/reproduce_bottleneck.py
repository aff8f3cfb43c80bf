"""Reproduce Kabalan et al. (2016) Section 4 on the Seyfried et al. (2009) bottleneck.

Runs widths × group sizes × seeds in parallel (all cores by default) with a progress bar, saves each
finished run at once under ``OUT/runs/`` (a rerun skips finished runs: resumable), then writes
``OUT/results.csv`` (one row per run), ``OUT/summary.csv`` and the figures of Figs. 11-14
(specific flow vs width against the experiment, densities, flow vs width with linear fits and
residual norms, lateral-position histograms), and prints the J_s table beside the experiment. A run
that stalls (:class:`crowd_env.experiments.running.runner.StallDetector`: nobody passes for 20 s and those left get
nowhere) stops there; a run that is not complete (stalled, or people left at ``--max-time``) reports no
J_s (nan; its partial figure is ``partial_specific_flow_per_m_s``), and every mean of the table is over
the complete runs only, with the stalled and otherwise incomplete runs counted beside it. With
``--trajectories`` every run's trajectories also go to ``OUT/trajectories/`` in PedPy's text format
(see :mod:`crowd_env.analysis.trajectories`).

Example::

    crowd-bottleneck --widths 0.8 1.0 --sizes 60 --seeds 10 --out out/bottleneck

The pipeline is :mod:`crowd_env.experiments.validation.bottleneck`; this module parses the flags and prints.
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

from ..experiments.validation.calibration.errors import in_range_check
from ..analysis.density import force_balance_jam_density_per_m2, hexagonal_density_per_m2
from ..analysis.experiment import (FRONT_DENSITY_RANGE_PER_M2, INSIDE_DENSITY_RANGE_PER_M2, INSIDE_SPEED_RANGE_M_S,
                                   RESIDUAL_NORM_BY_GROUP, SPECIFIC_FLOW_RANGE_N20_N40_PER_M_S)
from ..analysis.figures import bottleneck_figures
from ..analysis.trajectories import DEFAULT_FRAME_RATE_PER_S, TrajectoryFormatError, steps_per_frame
from ..core.params import ParameterError, PedestrianDefaults
from ..errors import InputError, OptionError
from ..walking.presets import DEFAULT_PRESET, PRESETS
from ..experiments.validation.bottleneck import (SetupError, SweepError, check_setups, flow_fit, run_sweep, summarise,
                                                 write_results, write_summary)
from ..core.timestep import check_time_step_floor
from ..experiments.running.runner import check_step_limit
from ..experiments.running.store import RunStore, RunStoreError
from .options import add_key_values, add_geometry_arguments, config_of, model_params_from_args, radius_from_args

# Configurations of the model and the navigation, the base that explicit flags override: see
# crowd_env.walking.presets (calibrated, the default; paper, the literal Section 4; recalibrated).


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="crowd-bottleneck", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--widths", type=float, nargs="+", default=[0.8, 0.9, 1.0, 1.1, 1.2], help="bottleneck widths b (m)")
    ap.add_argument("--sizes", type=int, nargs="+", default=[20, 40, 60], help="group sizes N")
    ap.add_argument("--seeds", type=int, default=10, help="number of seeds per (b, N): seeds 0..S-1")
    ap.add_argument("--first-seed", type=int, default=0, help="first seed (seeds first..first+S-1)")
    ap.add_argument("--out", type=Path, default=Path("out/bottleneck"), help="output folder")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="parallel worker processes")
    ap.add_argument("--max-time", type=float, default=300.0, help="simulated time limit per run (s)")
    ap.add_argument("--stall-window", type=float, default=None, metavar="S",
                    help="stall rule: a run stops as stalled when nobody has crossed the line or left for S seconds "
                         "and those left got no farther than --stall-speed times S, net (default 20; 0 "
                         "switches the rule off; part of the configuration when given)")
    ap.add_argument("--stall-speed", type=float, default=None, metavar="V",
                    help="stall rule's mean net speed threshold in m/s: net displacement over the window / S (default 0.05)")
    ap.add_argument("--quick", action="store_true",
                    help="quick check for a fresh machine: N = 60, the 5 widths, 2 seeds (overrides --sizes/--seeds)")
    add_geometry_arguments(ap.add_argument_group("geometry (Seyfried 2009 defaults)"),
                           "erode the walkable area by this distance (m) before solving the eikonal field: the "
                           "radius (0.23) gives the configuration space of the disk centres (presets calibrated and "
                           "recalibrated); 0 is the paper's point field (Eq. 11-13, preset paper); default: the "
                           "preset's")
    m = ap.add_argument_group("model (Kabalan Table 2 with the preset's social force)")
    m.add_argument("--preset", choices=sorted(PRESETS), default=DEFAULT_PRESET,
                   help="base configuration of model and navigation (crowd_env.walking.presets): "
                        + "; ".join(f"'{k}'{' (default)' if k == DEFAULT_PRESET else ''}: {v.summary}"
                                    for k, v in sorted(PRESETS.items()))
                        + "; the flags below override it")
    m.add_argument("--A", type=float, default=None, dest="social_strength_n", help="social strength A (N)")
    m.add_argument("--B", type=float, default=None, dest="social_range_m", help="social range B (m)")
    m.add_argument("--anisotropy", type=float, default=None, dest="social_anisotropy", help="λ in [0, 1]")
    m.add_argument("--kn", type=float, default=None, dest="normal_dissipation_kg", help="K_n (kg)")
    m.add_argument("--no-social", action="store_true", help="switch social repulsion off (paper Fig. 9)")
    m.add_argument("--no-rotation", action="store_true", help="freeze headings (paper Section 4.1.1)")
    add_key_values(m, "--param",
                   "any other ModelParams field, e.g. --param tangential_dissipation_kg=100")
    ap.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    t = ap.add_argument_group("trajectories (PedPy text format; an output option, not part of the configuration)")
    t.add_argument("--trajectories", action="store_true",
                   help="also write each run's trajectories to OUT/trajectories/<run>.txt (pedpy.load_trajectory_from_txt "
                        "reads it: id frame x y z in m, heading) with <run>.geometry.json (walkable area and measurement "
                        "areas as WKT, measurement line end points) and <run>.geometry.wkt; finished runs without "
                        "trajectory files (or at another frame rate) are recomputed once")
    t.add_argument("--trajectory-fps", type=float, default=DEFAULT_FRAME_RATE_PER_S, dest="trajectory_fps",
                   help="frame rate of the trajectory files, 1/(k h) for an integer k (default 25: every 4th step "
                        "of h = 0.01 s)")
    return ap


def print_summary(rows: list, records: list, params=None, radius_m: float | None = None) -> None:
    """The J_s table beside the experiment, the linear fits of J(b) and, given the model ``params``
    and the radius, the force-balance estimate of the density in front of the entrance."""
    print("\nSpecific flow J_s = N/(Δt b) (1/(m s)), model mean ± std over seeds vs Seyfried et al. (2009)")
    print(f"{'N':>4} {'b (m)':>6} {'runs':>5} {'stall/inc':>9} {'model':>15} {'experiment':>11} {'error':>8} "
          f"{'front /m²':>10} {'inside /m²':>10} {'v in (m/s)':>10} {'J_s stat':>8} {'evacuated':>9} "
          f"{'min gap (m)':>12}")
    any_incomplete = False
    for r in rows:
        stalled, incomplete = r.get("stalled", 0), r.get("incomplete", 0)
        partial = r.get("complete", r["runs"]) < r["runs"]
        any_incomplete |= partial
        exp = f"{r['specific_flow_exp']:.3f}" if np.isfinite(r["specific_flow_exp"]) else \
            "[{:g},{:g}]".format(*SPECIFIC_FLOW_RANGE_N20_N40_PER_M_S)
        err = f"{100 * r['relative_error']:+.1f}%" if np.isfinite(r["relative_error"]) else "-" if not np.isfinite(
            r["specific_flow_mean"]) else ("in" if in_range_check(np.array([r["specific_flow_mean"]]),
                                                                   SPECIFIC_FLOW_RANGE_N20_N40_PER_M_S).all_inside
                                           else "OUT")
        mark = "*" if partial else " "
        print(f"{r['n_pedestrians']:>4} {r['width_m']:>6.2f} {r['runs']:>5} {f'{stalled}/{incomplete}':>9} "
              f"{r['specific_flow_mean']:>7.3f} ± {r['specific_flow_std']:.3f}{mark} {exp:>11} {err:>8} "
              f"{r['density_front']:>10.2f} {r['density_inside']:>10.2f} "
              f"{r['speed_inside']:>10.2f} {r['stationary_specific_flow']:>8.3f} {str(r['all_evacuated']):>9} "
              f"{r['min_gap_m']:>12.2e}")
    print("front / inside: mean densities, v in: mean speed inside, J_s stat: passages per m and s, all over the "
          "stationary window (20 % to 80 % of the passages); J_s stat = inside · v in in a stationary channel "
          "(experiment, N = 60: inside {:g}-{:g} /m², v in {:g}-{:g} m/s)".format(
              *INSIDE_DENSITY_RANGE_PER_M2, *INSIDE_SPEED_RANGE_M_S))
    print("stall/inc: runs that stalled (nobody passed for the stall window while those left stood still; stopped "
          "there) / runs otherwise incomplete (people left at the time limit); neither reports a J_s")
    if any_incomplete:
        n_bad = sum(r["runs"] - r["complete"] for r in rows)
        print(f"* mean over the complete runs only ({n_bad} of {sum(r['runs'] for r in rows)} runs incomplete): "
              "not comparable with the experiment's J_s over everybody")
    for n in sorted({r["n_pedestrians"] for r in rows}):
        fit = flow_fit(rows, n)
        if fit is not None:
            ref = RESIDUAL_NORM_BY_GROUP.get(n)
            print(f"N = {n}: flow J(b) = {fit.slope:.3f} b + {fit.intercept:+.3f}, residual norm {fit.residual_norm:.3f}"
                  + (f" (experiment {ref})" if ref is not None else ""))
    if params is not None and radius_m is not None and params.social_forces and params.social_strength_n > 0:
        ped = PedestrianDefaults()
        front_lo, front_hi = FRONT_DENSITY_RANGE_PER_M2
        rho = float(force_balance_jam_density_per_m2(params.social_strength_n, params.social_range_m, radius_m,
                                                     ped.mass_kg, ped.desired_speed_mean_m_s, ped.tau_s))
        print(f"density in front: force balance m‖u_d‖/τ = A exp((2r − d)/B) in a hexagonal packing gives "
              f"{rho:.2f} /m² for A = {params.social_strength_n:g} N, B = {params.social_range_m:g} m "
              f"(experiment {front_lo:g}-{front_hi:g} /m²; densest packing of r = {radius_m:g} m disks "
              f"{float(hexagonal_density_per_m2(2.0 * radius_m)):.2f} /m²)")


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    if args.quick:
        args.sizes, args.seeds = [60], 2
    try:
        params = model_params_from_args(args)
    except (ParameterError, OptionError) as exc:
        raise SystemExit(f"error: {exc}")
    for b in args.widths:
        if not 0 < b < args.corridor_width:
            raise SystemExit(f"error: width {b} m must lie in (0, corridor width {args.corridor_width} m)")
    for n in args.sizes:
        if n < 2:
            raise SystemExit(f"error: group size {n} must be at least 2 (J = N/Δt needs two passages)")
    if args.seeds < 1 or args.jobs < 1:
        raise SystemExit("error: --seeds and --jobs must be >= 1")
    fps = None
    if args.trajectories:
        try:
            fps = 1.0 / (steps_per_frame(args.trajectory_fps, params.dt_s) * params.dt_s)
        except TrajectoryFormatError as exc:
            raise SystemExit(f"error: --trajectory-fps: {exc}")
    config = config_of(args, params)
    # Fail fast on impossible geometry, before the output folder is touched or workers are spawned.
    try:
        check_step_limit(args.max_time, params.dt_s)
        check_time_step_floor(params.dt_s, error=InputError, name="--param dt_s")
        check_setups(config["geometry"], args.widths, args.sizes, args.first_seed)
        RunStore(args.out, config)  # a folder of another configuration is refused
    except (InputError, SetupError, RunStoreError) as exc:
        raise SystemExit(f"error: {exc}") from None
    tasks = [dict(width_m=b, n_pedestrians=n, seed=s, trajectory_fps=fps, **config)
             for n in args.sizes for b in args.widths for s in range(args.first_seed, args.first_seed + args.seeds)]
    try:
        records = run_sweep(tasks, args.out, args.jobs)
    except (SweepError, RunStoreError) as exc:  # failed runs (their reasons), a damaged run record (named)
        raise SystemExit(f"error: {exc}") from None
    write_results(records, args.out)
    rows = summarise(records)
    write_summary(rows, args.out)
    print_summary(rows, records, params, radius_from_args(args))
    if not args.no_figures:
        for path in bottleneck_figures(records, rows, args.out):
            print(f"figure: {path}")
    if fps:
        print(f"trajectories ({fps:g} frames/s, PedPy text format): {args.out / 'trajectories'}")
    print(f"results: {args.out / 'results.csv'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
