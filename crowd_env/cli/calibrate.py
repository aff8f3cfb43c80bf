"""Calibrate the social force of Kabalan et al. (2016) against Seyfried et al. (2009) (Section 4.1.2).

``grid``: ε_T (Eq. 24; Eq. 23 per group size) on an (A, B) grid like the paper's Fig. 10 (20 × 20
linearly spaced values in A ∈ [10, 1000] N, B ∈ [0.01, 0.2] m by default), each point = the
reproduction's (b, N) runs × seeds; writes ``surface.csv``, ``valley.csv`` (for each B the A minimising
ε_T), ``calibration.json`` (best point, fit A = a exp(c B) of the valley beside the paper's
A = 1501 exp(-7.98 B)) and ``fig10_epsilon_surface.png``.
``optimize``: Nelder–Mead (or Powell) on log-parameters over A, B and optionally lambda, tau,
speed_mean, speed_std and the vision rule's vision_time_gap_s, vision_jam_gap_m, vision_half_angle_rad,
vision_body_scale, with the same seeds for every candidate; writes ``optimise/optimum.json``. ``--objective
targets+fd`` scores every point on the bottleneck's targets and the fundamental diagram at once (the periodic
corridor's speeds at the Jülich bins, monotone in density, the single file's speeds and headway fit;
crowd_env.experiments.validation.calibration.objective), running the density sweep's runs beside the bottleneck's on the same executor.
``targets``: every preset against every target of the experiment (``targets.json``); ``--fd`` adds each
preset's fundamental-diagram sweep and its rows (the corridor's speeds at the Jülich bins, flow peak and
monotone speed, the single file's speeds and headway fit) and terms, the ``--fd-*`` options setting its runs.
``landscape``: the objective along one parameter, the others fixed by the preset (e.g. ε_T in λ);
writes ``landscape_<param>.csv`` and ``.png``.

Runs execute as single Ray tasks (A, B, b, N, seed): locally on all cores by default, on a running
cluster with ``--address HOST:PORT``; ``--backend process|serial`` without Ray. Every finished run is
saved at once under ``OUT/runs/``; rerunning the same command skips finished runs. A folder holding
another configuration (geometry, model parameters, time limit) is refused.

Examples::

    crowd-calibrate grid --grid-size 4 4 --seeds 1 --out out/calibration
    crowd-calibrate grid --address 10.0.0.1:6379 --seeds 5 --out out/calibration_fine
    crowd-calibrate optimize --free A B --x0 A=790 B=0.08 --seeds 3 --out out/calibration
    crowd-calibrate targets --fd --seeds 10 --backend process --jobs 2 --out out/targets
    crowd-calibrate optimize --preset vision --objective targets+fd --free A vision_time_gap_s vision_body_scale \
        --bounds vision_body_scale=0.3:1.0 --seeds 2 --out out/calibration_fd
"""
from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

from ..experiments.validation.calibration.errors import PAPER_VALLEY_FIT, CalibrationError, check_grid_values, grid_axis
from ..analysis.experiment import ExperimentError, ExperimentTable
from ..experiments.validation.calibration.objective import TargetWeights, required_cases
from ..core.params import ParameterError
from ..errors import InputError
from ..walking.presets import DEFAULT_PRESET, PRESETS
from ..experiments.running.backends import DeferredBackend, make_backend
from ..experiments.validation.bottleneck import check_setups
from ..experiments.validation.corridor_runs import CORRIDOR_RUN_NAMES
from ..experiments.validation.calibration import (FREE_PARAMETERS, analyse_surface, base_config, evaluate_grid, optimise,
                                       write_grid_outputs)
from ..experiments.validation.calibration.grid import check_run_plan
from ..experiments.validation.calibration.landscape import entry_failed, landscape, write_landscape
from ..experiments.validation.calibration.optimize import PointEvaluator
from ..experiments.validation.calibration.preset_targets import preset_targets, write_targets
from ..experiments.validation.calibration.tasks import FDPlan
from ..experiments.validation.fundamental_diagram import CORRIDOR_DENSITIES, SINGLE_FILE_DENSITIES
from ..experiments.running.store import RunStore
from .options import add_key_values, add_geometry_arguments, config_of, key_values, model_params_from_args


OBJECTIVE_HELP = ("'epsilon': ε_T of Eq. 24 (+ --range-weight), the paper's; 'targets': every figure the experiment "
                  "measured (crowd_env.experiments.validation.calibration.objective: N = 60 flows, N = 20/40 range and order, speed and "
                  "densities, capacity N = 120 vs 60), on N = 20, 40, 60 at --widths and N = 120 at 1.0 and 1.2 m "
                  "(--sizes is then unused); 'targets+fd': those and the fundamental diagram (periodic corridor "
                  "speeds at the Jülich bins and monotone, single-file speeds and headway fit), its runs set by the "
                  "--fd-* options; 'virtual': every shipped experiment as it was run (the bottleneck's targets, the "
                  "nine Jülich corridor runs with their entrance and exit: density, speed, exit flow; the single "
                  "file), the only one with --free radius, wall_slowdown_m and wall_speed_factor; a point with a "
                  "stalled run counts as failed")


def _add_target_arguments(parser) -> None:
    """The target objective's weights and the fundamental diagram's runs (optimize, landscape)."""
    g = parser.add_argument_group("target objective and fundamental diagram (--objective targets / targets+fd)")
    add_key_values(g, "--weight",
                   f"weights of the target terms (default 1 each): {', '.join(TargetWeights().as_dict())}, "
                   "corridor_runs (--objective virtual)")
    _add_fd_arguments(g)


# the --fd-* options and their defaults (given without the fundamental diagram's runs they are refused)
FD_OPTION_DEFAULTS = {"fd_seeds": None, "fd_densities": list(CORRIDOR_DENSITIES),
                      "fd_single_file_densities": list(SINGLE_FILE_DENSITIES), "fd_length": 20.0, "fd_time": 40.0,
                      "fd_transient": 15.0}


def _add_fd_arguments(g) -> None:
    """The fundamental diagram's runs (--fd-*: optimize and landscape with --objective targets+fd, targets --fd)."""
    g.add_argument("--fd-seeds", type=int, default=FD_OPTION_DEFAULTS["fd_seeds"],
                   help="seeds per fundamental-diagram density: --first-seed.. (default: --seeds; same at every point)")
    g.add_argument("--fd-densities", type=float, nargs="+", default=list(FD_OPTION_DEFAULTS["fd_densities"]),
                   help="corridor densities (1/m², shipped Jülich bins; default all from 0.4 to 3.4)")
    g.add_argument("--fd-single-file-densities", type=float, nargs="+",
                   default=list(FD_OPTION_DEFAULTS["fd_single_file_densities"]),
                   help="single-file densities (1/m, shipped bins; default all six)")
    g.add_argument("--fd-length", type=float, default=FD_OPTION_DEFAULTS["fd_length"],
                   help="length of the periodic strips (m)")
    g.add_argument("--fd-time", type=float, default=FD_OPTION_DEFAULTS["fd_time"],
                   help="simulated time per fundamental-diagram run (s)")
    g.add_argument("--fd-transient", type=float, default=FD_OPTION_DEFAULTS["fd_transient"],
                   help="time left out before measuring (s)")


def _weights(args) -> TargetWeights | None:
    """--weight NAME=VALUE ... as TargetWeights (None when none is given)."""
    if not args.weight:
        return None
    if args.objective not in ("targets", "targets+fd", "virtual"):
        raise CalibrationError("--weight weighs the terms of --objective targets, targets+fd or virtual")
    known = TargetWeights().virtual_dict() if args.objective == "virtual" else TargetWeights().as_dict()
    values = {}
    for k, v in key_values(args.weight, "--weight expects NAME=VALUE", parse=str.strip).items():
        if k not in known:
            raise CalibrationError(f"unknown weight {k!r}; choose from {list(known)}")
        values[k] = float(v)
    return TargetWeights(**values)


def _fd_plan(args, wanted: bool) -> FDPlan | None:
    """The fundamental diagram's runs of each point or preset from the --fd-* options (None unless ``wanted``:
    --objective targets+fd, targets --fd)."""
    if not wanted:
        given = [f"--{name.replace('_', '-')}" for name, default in FD_OPTION_DEFAULTS.items()
                 if getattr(args, name) != default]
        if given:
            raise CalibrationError(f"{', '.join(given)} set(s) the fundamental diagram's runs, which this command "
                                   f"runs only with --objective targets+fd (optimize, landscape) or --fd (targets)")
        return None
    k = args.seeds if args.fd_seeds is None else args.fd_seeds
    return FDPlan(seeds=tuple(range(args.first_seed, args.first_seed + k)) if k >= 1 else (),
                  corridor_densities=tuple(args.fd_densities),
                  single_file_densities=tuple(args.fd_single_file_densities),
                  length_m=args.fd_length, max_time_s=args.fd_time, transient_s=args.fd_transient)


def build_parser() -> argparse.ArgumentParser:
    common = _common_parser()
    ap = argparse.ArgumentParser(prog="crowd-calibrate", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="mode", required=True)
    _add_grid_parser(sub, common)
    _add_optimize_parser(sub, common)
    _add_targets_parser(sub, common)
    _add_landscape_parser(sub, common)
    bp = sub.add_parser("band", help="the door against the corridor for every point scored on the virtual experiments "
                                     "(crowd_env.experiments.validation.door_band): OUT/band.csv and OUT/band.png")
    bp.add_argument("files", nargs="+", type=Path,
                    help="calibration evaluations.jsonl (--objective virtual), targets.json (targets --virtual) and "
                         "virtual_experiments.csv (crowd-virtual-experiments; labelled by its folder)")
    bp.add_argument("--out", type=Path, default=Path("out/band"), help="output folder")
    bp.add_argument("--highlight", nargs="+", default=["calibrated", "joint", "paper", "recalibrated", "vision"],
                    help="points to label (preset names in a targets.json)")
    return ap


def _common_parser() -> argparse.ArgumentParser:
    """The options every mode shares: runs, distribution, geometry, fixed model parameters."""
    common = argparse.ArgumentParser(add_help=False)
    run = common.add_argument_group("runs (each point = widths × sizes × seeds)")
    run.add_argument("--out", type=Path, default=Path("out/calibration"), help="output folder (resumable)")
    run.add_argument("--widths", type=float, nargs="+", default=[0.8, 0.9, 1.0, 1.1, 1.2], help="widths b (m)")
    run.add_argument("--sizes", type=int, nargs="+", default=[20, 40, 60],
                     help="group sizes N; ε_T uses those with experimental values (N = 60 shipped), N = 20/40 "
                          "are checked against the range [1.77, 2.31] 1/(m s)")
    run.add_argument("--seeds", type=int, default=1, help="seeds per (b, N): first..first+S-1 (same at every point)")
    run.add_argument("--first-seed", type=int, default=0)
    run.add_argument("--max-time", type=float, default=300.0, help="simulated time limit per run (s)")
    run.add_argument("--reference", type=Path, default=None,
                     help="CSV with columns b_m,n_pedestrians,specific_flow_per_m_s (default: shipped Seyfried N = 60)")
    run.add_argument("--range-weight", type=float, default=0.0,
                     help="add this × mean (J_s/bound - 1)² of the N without reference outside [1.77, 2.31] (default 0)")
    run.add_argument("--incomplete", choices=["bound", "partial"], default="bound",
                     help="runs where not all N passed within --max-time: 'bound' counts J_s = N/((T - t_first) b) "
                          "(default), 'partial' the reproduction's J_s of the passages so far")
    dist = common.add_argument_group("distribution")
    dist.add_argument("--backend", choices=["ray", "process", "serial"], default="ray")
    dist.add_argument("--address", default=None,
                      help="Ray cluster to join (HOST:PORT, ray://HOST:PORT or auto); default: local Ray on all cores")
    dist.add_argument("--jobs", type=int, default=None, help="CPUs of the local Ray instance / process pool")
    dist.add_argument("--connect-timeout", type=float, default=5.0, help="seconds to reach --address before giving up")
    add_geometry_arguments(common.add_argument_group("geometry (Seyfried 2009 defaults, as crowd-bottleneck)"),
                           "default: the preset's (0 for 'paper', 0.23 for 'calibrated' and 'recalibrated'); given, "
                           "it reaches the corridor runs of --objective virtual and targets --virtual too",
                           wall_slowdown_where="the bottleneck's field and, with --objective virtual or targets "
                                               "--virtual, every corridor run's")
    m = common.add_argument_group("fixed model parameters")
    m.add_argument("--preset", choices=sorted(PRESETS), default=DEFAULT_PRESET,
                   help="base configuration as in crowd-bottleneck (crowd_env.walking.presets; A, B and the other free "
                        "parameters are then set by the grid/optimiser)")
    m.add_argument("--anisotropy", type=float, default=None, dest="social_anisotropy", help="λ in [0, 1]")
    m.add_argument("--kn", type=float, default=None, dest="normal_dissipation_kg", help="K_n (kg)")
    m.add_argument("--no-rotation", action="store_true", help="freeze headings (Section 4.1.1)")
    add_key_values(m, "--param", "any other ModelParams field")
    common.set_defaults(social_strength_n=None, social_range_m=None, no_social=False)

    return common


def _add_grid_parser(sub, common) -> None:
    gp = sub.add_parser("grid", parents=[common], help="ε_T on an (A, B) grid (Fig. 10)")
    gp.add_argument("--A-range", type=float, nargs=2, default=None, metavar=("LOW", "HIGH"), dest="a_range",
                    help="default 10 1000 (N)")
    gp.add_argument("--B-range", type=float, nargs=2, default=None, metavar=("LOW", "HIGH"), dest="b_range",
                    help="default 0.01 0.2 (m)")
    gp.add_argument("--grid-size", type=int, nargs=2, default=None, metavar=("N_A", "N_B"),
                    help="values of A and B (default, as the paper: 20 20)")
    gp.add_argument("--spacing", choices=["linear", "log"], default="linear", help="grid spacing (paper: linear)")
    gp.add_argument("--A-values", type=float, nargs="+", default=None, dest="a_values", help="explicit A values (N)")
    gp.add_argument("--B-values", type=float, nargs="+", default=None, dest="b_values", help="explicit B values (m)")
    gp.add_argument("--keep-edge-minima", action="store_true",
                    help="fit A(B) also through minima at the A grid ends (default: interior ones when >= 2)")
    gp.add_argument("--no-figures", action="store_true")


def _add_optimize_parser(sub, common) -> None:
    op = sub.add_parser("optimize", aliases=["optimise"], parents=[common], help="minimise ε_T (Eq. 25)")
    op.add_argument("--free", nargs="+", default=["A", "B"],
                    help=f"free parameters: {' '.join(FREE_PARAMETERS)} (vision_rays is fixed: --param vision_rays=N)")
    add_key_values(op, "--x0", "start values, e.g. A=790 B=0.08")
    add_key_values(op, "--bounds", "bounds, e.g. A=10:3000", metavar="NAME=LOW:HIGH")
    op.add_argument("--method", choices=["Nelder-Mead", "Powell"], default="Nelder-Mead")
    op.add_argument("--max-evaluations", type=int, default=60, help="parameter points evaluated at most")
    op.add_argument("--xatol", type=float, default=0.02, help="tolerance on ln A, ln B, ... (0.02 = 2 %%)")
    op.add_argument("--fatol", type=float, default=1e-4, help="tolerance on ε_T")
    op.add_argument("--objective", choices=["epsilon", "targets", "targets+fd", "virtual"], default="epsilon",
                    help=OBJECTIVE_HELP)
    _add_target_arguments(op)


def _add_targets_parser(sub, common) -> None:
    tp = sub.add_parser("targets", parents=[common],
                        help="every preset against every target of the experiment (one table; N = 20, 40, 60 at "
                             "--widths and N = 120 at 1.0 and 1.2 m, --seeds seeds each); with --fd also the "
                             "fundamental diagram's rows (periodic 1.8 m corridor: speeds at the Jülich bins, flow "
                             "peak, monotone; single file: speeds, headway fit)")
    tp.add_argument("--presets", nargs="+", choices=sorted(PRESETS), default=sorted(PRESETS),
                    help="presets to compare (default all); runs go to OUT/<preset>/ (resumable)")
    tp.add_argument("--virtual", action="store_true",
                    help="every shipped experiment as it was run instead of the periodic corridor's sweep: the "
                         "bottleneck's targets, a row per Jülich corridor run (density, speed, exit flow, each within "
                         "its tolerance), the single file; scored as --objective virtual")
    g = tp.add_argument_group("fundamental diagram (--fd)")
    g.add_argument("--fd", action="store_true",
                   help="also run each preset's fundamental-diagram sweep (the --fd-* options) and add its rows and "
                        "terms, as --objective targets+fd scores a point")
    _add_fd_arguments(g)


def _add_landscape_parser(sub, common) -> None:
    lp = sub.add_parser("landscape", parents=[common],
                        help="the objective along one parameter, the others fixed by the preset (e.g. ε_T in λ)")
    lp.add_argument("--vary", required=True, choices=list(FREE_PARAMETERS), help="the parameter to vary")
    lp.add_argument("--values", type=float, nargs="+", required=True, help="its values (natural units)")
    lp.add_argument("--objective", choices=["epsilon", "targets", "targets+fd", "virtual"], default="targets",
                    help="as optimize (default 'targets': the figures of every target are kept per value)")
    _add_target_arguments(lp)
    lp.add_argument("--no-figures", action="store_true")


def _calibration_config(args, params) -> dict:
    """The folder's configuration: the bottleneck's runs as the flags describe them (``config_of``); an explicit
    ``--navigation-clearance`` reaches the corridor runs too (``--objective virtual``, ``targets --virtual``), as in
    crowd-virtual-experiments, where without it the corridor keeps the disk centres' field of its body."""
    cfg = config_of(args, params)
    clearance = getattr(args, "navigation_clearance", None)
    corridor = getattr(args, "objective", None) == "virtual" or getattr(args, "virtual", False)
    return base_config(cfg["geometry"], params, cfg["max_time_s"],
                       corridor_geometry={"navigation_clearance_m": float(clearance)}
                       if corridor and clearance is not None else None)


def _backend(args) -> DeferredBackend:
    """The backend of the flags, started at the first run: every mode checks its plan inside ``with _backend(args)``
    before it runs anything, so an impossible plan is refused before Ray starts or a pool forks."""
    return DeferredBackend(lambda: make_backend(args.backend, address=args.address, jobs=args.jobs,
                                                connect_timeout_s=args.connect_timeout))


def _seeds(args) -> list:
    """Seeds first..first+S-1 of ``--first-seed``/``--seeds`` (empty for S < 1: check_run_plan names it)."""
    return list(range(args.first_seed, args.first_seed + args.seeds)) if args.seeds >= 1 else []


def run_landscape(args) -> int:
    """``crowd-calibrate landscape``: :func:`crowd_env.experiments.validation.calibration.landscape.landscape` and its outputs."""
    params = model_params_from_args(args)
    config = _calibration_config(args, params)
    seeds = _seeds(args)
    with _backend(args) as be:
        evaluator = PointEvaluator(args.out, config, args.widths, args.sizes, seeds, be,
                                   reference=_reference(args.reference), range_weight=args.range_weight,
                                   incomplete=args.incomplete, objective=args.objective, weights=_weights(args),
                                   fd_plan=_fd_plan(args, args.objective == "targets+fd"))
        entries = landscape(evaluator, args.vary, args.values)
    print(f"{args.vary:>10}  {'objective':>10}  {'ε_T':>10}  failed")
    for e in entries:
        print(f"{e['values'][args.vary]:>10.4g}  {e['objective']:>10.4g}  {e['epsilon_total']:>10.4g}  "
              f"{'yes' if entry_failed(e) else 'no'}")
    for p in write_landscape(args.vary, entries, args.out, figure=not args.no_figures):
        print(f"wrote {p}")
    return 0


def run_targets(args) -> int:
    """``crowd-calibrate targets``: the target table of each preset, side by side (crowd_env.experiments.validation.calibration.objective);
    ``--fd``: with the fundamental diagram's rows and terms (:func:`crowd_env.experiments.validation.calibration.objective.fd_table`)."""
    seeds = _seeds(args)
    widths, _, seeds = check_run_plan(args.widths, [60], seeds)
    required_cases(widths)  # capacity widths among --widths, or a clear error
    configs = {}
    for name in args.presets:
        args.preset = name
        configs[name] = _calibration_config(args, model_params_from_args(args))
    fd_plan = _fd_plan(args, args.fd)
    with _backend(args) as be:
        tables, scores = preset_targets(args.out, configs, widths, seeds, be, fd_plan=fd_plan, virtual=args.virtual)
    print(f"every target, {len(seeds)} seed(s) per (b, N); figures are seed means over complete runs")
    if fd_plan is not None:
        print(f"fundamental diagram: {len(fd_plan.seeds)} seed(s) per density, {fd_plan.max_time_s:g} s of which the "
              f"first {fd_plan.transient_s:g} s are left out; figures are seed means per density")
    width = max(len(r["target"]) for t in tables.values() for r in t)
    print(f"{'target':<{width}}  {'criterion':<22}" + "".join(f"  {n:<34}" for n in tables))
    for k, row in enumerate(next(iter(tables.values()))):
        cells = "".join(f"  {('ok  ' if t[k]['passed'] else 'MISS') + ' ' + t[k]['figure']:<34}" for t in tables.values())
        print(f"{row['target']:<{width}}  {row['criterion']:<22}{cells}")
    print("objective (crowd_env.experiments.validation.calibration.objective, lower is better): "
          + ", ".join(f"{n} {e.objective:.4f}" + (" (failed: incomplete runs)" if e.failed else "")
                      for n, e in scores.items()))
    out = write_targets(args.out / "targets.json", seeds, widths, tables, scores, fd_plan=fd_plan, virtual=args.virtual)
    print(f"wrote {out}")
    return 0


def _reference(path: Path | None):
    """A reference table from CSV (``#`` comment lines allowed), e.g. with N = 20 / 40 values."""
    if path is None:
        return None
    try:
        lines = [ln for ln in Path(path).read_text().splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
        rows = list(csv.DictReader(lines))
        if not rows:
            raise CalibrationError("no data rows")
        return ExperimentTable.from_arrays([float(r["b_m"]) for r in rows], [int(r["n_pedestrians"]) for r in rows],
                                           [float(r["specific_flow_per_m_s"]) for r in rows], source=str(path))
    except (OSError, ValueError, KeyError, TypeError, ExperimentError) as exc:
        raise CalibrationError(f"--reference {path}: {exc!r} (expected columns b_m,n_pedestrians,specific_flow_per_m_s)")


def _grid_axes(args):
    """(A values, B values) from explicit values or range × size; both for one axis is an error."""
    size = args.grid_size or [20, 20]
    axes = []
    for k, (name, values, rng, default) in enumerate((("A", args.a_values, args.a_range, (10.0, 1000.0)),
                                                      ("B", args.b_values, args.b_range, (0.01, 0.2)))):
        if values is not None:
            if rng is not None or args.grid_size is not None:
                raise CalibrationError(f"--{name}-values sets the {name} grid; do not combine it with --{name}-range "
                                       f"or --grid-size")
            axes.append(check_grid_values(values, name))
        else:
            lo, hi = rng or default
            axes.append(grid_axis(lo, hi, size[k], name, args.spacing))
    return tuple(axes)


def run_band(args) -> int:
    """``crowd-calibrate band``: :func:`crowd_env.experiments.validation.door_band.write_band`."""
    from ..experiments.validation.door_band import write_band

    paths, missing = write_band(args.out, args.files, highlight=args.highlight)
    for source, label, reason in missing:
        print(f"not drawn: {label} ({source}): {reason}", file=sys.stderr)
    for p in paths:
        print(f"wrote {p}")
    return 0


def run(args) -> int:
    if args.mode == "band":
        return run_band(args)
    if args.mode == "targets":
        return run_targets(args)
    if args.mode == "landscape":
        return run_landscape(args)
    params = model_params_from_args(args)
    config = _calibration_config(args, params)
    seeds = _seeds(args)
    widths, sizes, seeds = check_run_plan(args.widths, args.sizes, seeds)
    reference = _reference(args.reference)
    if args.mode == "grid":
        a, b = _grid_axes(args)
    else:
        x0 = {k: float(v) for k, v in key_values(args.x0, "--x0 expects NAME=VALUE", parse=str.strip).items()}
        bounds = {}
        for k, v in key_values(args.bounds, "--bounds expects NAME=LOW:HIGH", parse=str.strip).items():
            lo, sep, hi = v.partition(":")
            if not sep:
                raise CalibrationError(f"--bounds expects NAME=LOW:HIGH, got {k}={v!r}")
            bounds[k] = (float(lo), float(hi))
    if args.mode != "grid" and args.objective in ("targets", "targets+fd", "virtual"):
        sizes = sorted({n for _, n in required_cases(widths)})
    if args.mode != "grid" and args.objective == "virtual":
        print(f"each point: {len(required_cases(widths)) * len(seeds)} bottleneck runs, "
              f"{len(CORRIDOR_RUN_NAMES) * len(seeds)} corridor runs, {len(SINGLE_FILE_DENSITIES) * len(seeds)} "
              f"single-file runs", file=sys.stderr)
    weights = None if args.mode == "grid" else _weights(args)
    fd_plan = None if args.mode == "grid" else _fd_plan(args, args.objective == "targets+fd")
    if fd_plan is not None:
        print(f"each point: {len(required_cases(widths)) * len(seeds)} bottleneck runs + {fd_plan.n_runs} "
              f"fundamental-diagram runs", file=sys.stderr)
    check_setups(config["geometry"], widths, sizes, seeds[0])  # impossible geometry fails before any worker starts
    RunStore(args.out, config, keyed_by="task")  # a folder of another configuration is refused before anything runs
    meta = {"widths_m": widths, "sizes": sizes, "seeds": seeds, "range_weight": args.range_weight,
            "reference": "shipped Seyfried 2009 N = 60" if reference is None else str(args.reference),
            "backend": args.backend, "address": args.address, "incomplete": args.incomplete}
    with _backend(args) as be:
        if args.mode == "grid":
            result = evaluate_grid(args.out, config, a, b, widths, sizes, seeds, be, reference=reference,
                                   range_weight=args.range_weight, incomplete=args.incomplete)
        else:
            res = optimise(args.out, config, args.free, widths, sizes, seeds, be, x0=x0, bounds=bounds,
                           method=args.method, max_evaluations=args.max_evaluations, xatol=args.xatol,
                           fatol=args.fatol, reference=reference, range_weight=args.range_weight,
                           incomplete=args.incomplete, objective=args.objective, weights=weights, fd_plan=fd_plan)
    if args.mode != "grid":
        shown = ", ".join(f"{k} = {v:.5g}" for k, v in res.best.items())
        print(f"best after {res.n_evaluations} evaluations ({res.n_computed} computed now): {shown}; "
              f"objective {res.objective:.5g}, ε_T {res.epsilon_total:.5g} ({res.message})")
        print(f"results: {args.out / 'optimise' / 'optimum.json'}")
        return 0
    if result.n_failed_runs:
        print(f"warning: {result.failure_report}", file=sys.stderr)
    analysis = analyse_surface(result, use_objective=args.range_weight > 0, exclude_edges=not args.keep_edge_minima)
    paths = write_grid_outputs(result, args.out, analysis, meta, figure=not args.no_figures)
    best, fit = analysis["best"], analysis["fit"]
    print(f"best grid point: A = {best['social_strength_n']:.4g} N, B = {best['social_range_m']:.4g} m, "
          f"ε_T = {best['epsilon']:.4g}")
    print("valley of minima (B m: A* N, ε_T):",
          "; ".join(f"{bb:.3g}: {aa:.4g}, {ee:.3g}" for bb, aa, ee in
                    zip(analysis["valley"].social_range_m, analysis["valley"].social_strength_n, analysis["valley"].epsilon)))
    if fit is not None:
        print(f"fit A = {fit.coefficient_n:.4g} exp({fit.rate_per_m:.4g} B) through {fit.n_points} minima; "
              f"paper: A = {PAPER_VALLEY_FIT.coefficient_n:g} exp({PAPER_VALLEY_FIT.rate_per_m:g} B)")
    else:
        print("fit A(B): needs minima at >= 2 values of B")
    for p in paths:
        print(f"wrote {p}")
    return 0


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return run(args)
    except (CalibrationError, ParameterError, InputError, ValueError) as exc:
        raise SystemExit(f"error: {exc}") from None
    except KeyboardInterrupt:
        raise SystemExit("interrupted: finished runs are saved; rerun the same command to continue") from None


if __name__ == "__main__":
    sys.exit(main())
