"""Reproduce Kabalan et al. (2016) Section 4 on the Seyfried et al. (2009) bottleneck.

Runs widths × group sizes × seeds in parallel (all cores by default) with a progress bar, saves each
finished run at once under ``OUT/runs/`` (a rerun skips finished runs: resumable), then writes
``OUT/results.csv`` (one row per run), ``OUT/summary.csv`` and the figures of Figs. 11-14
(specific flow vs width against the experiment, densities, flow vs width with linear fits and
residual norms, lateral-position histograms), and prints the J_s table beside the experiment. A run
that stalls (:class:`crowd_env.runner.StallDetector`: nobody passes for 20 s and those left stand
still) stops there; a run that is not complete (stalled, or people left at ``--max-time``) reports no
J_s (nan; its partial figure is ``partial_specific_flow_per_m_s``), and every mean of the table is over
the complete runs only, with the stalled and otherwise incomplete runs counted beside it. With
``--trajectories`` every run's trajectories also go to ``OUT/trajectories/`` in PedPy's text format
(see :mod:`crowd_env.analysis.trajectories`).

Example::

    python scripts/reproduce_bottleneck.py --widths 0.8 1.0 --sizes 60 --seeds 10 --out out/bottleneck
"""
from __future__ import annotations

import argparse
import csv
import dataclasses
import hashlib
import json
import os
import sys
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np

from crowd_env.analysis.trajectories import DEFAULT_FRAME_RATE_PER_S
from crowd_env.core.params import ModelParams, ParameterError
from crowd_env.core.presets import DEFAULT_PRESET, PRESETS, get_preset

GEOMETRY_OPTIONS = {  # CLI flag -> seyfried_bottleneck option, with the Seyfried defaults
    "corridor_width": ("corridor_width_m", 4.0),
    "channel_length": ("channel_length_m", 2.8),
    "initial_density": ("initial_density_per_m2", 3.3),
    "section_depth": ("section_depth_m", 1.515),
    "block_start_upstream": ("block_start_upstream_m", 2.24),
    "radius": ("radius_m", 0.23),
}
LANE_BIN_M = 0.01  # Kabalan Section 4.2


# Configurations of the model and the navigation, the base that explicit flags override: see
# crowd_env.core.presets (calibrated, the default; paper, the literal Section 4; recalibrated).


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
                         "and those left moved slower than --stall-speed on average over them (default 20; 0 "
                         "switches the rule off; part of the configuration when given)")
    ap.add_argument("--stall-speed", type=float, default=None, metavar="V",
                    help="stall rule's mean speed threshold in m/s (default 0.05)")
    ap.add_argument("--quick", action="store_true",
                    help="quick check for a fresh machine: N = 60, the 5 widths, 2 seeds (overrides --sizes/--seeds)")
    add_geometry_arguments(ap.add_argument_group("geometry (Seyfried 2009 defaults)"),
                           "erode the walkable area by this distance (m) before solving the eikonal field: the "
                           "radius (0.23) gives the configuration space of the disk centres (presets calibrated and "
                           "recalibrated); 0 is the paper's point field (Eq. 11-13, preset paper); default: the "
                           "preset's")
    m = ap.add_argument_group("model (Kabalan Table 2 with the preset's social force)")
    m.add_argument("--preset", choices=sorted(PRESETS), default=DEFAULT_PRESET,
                   help="base configuration of model and navigation (crowd_env.core.presets): "
                        + "; ".join(f"'{k}'{' (default)' if k == DEFAULT_PRESET else ''}: {v.summary}"
                                    for k, v in sorted(PRESETS.items()))
                        + "; the flags below override it")
    m.add_argument("--A", type=float, default=None, dest="social_strength_n", help="social strength A (N)")
    m.add_argument("--B", type=float, default=None, dest="social_range_m", help="social range B (m)")
    m.add_argument("--anisotropy", type=float, default=None, dest="social_anisotropy", help="λ in [0, 1]")
    m.add_argument("--kn", type=float, default=None, dest="normal_dissipation_kg", help="K_n (kg)")
    m.add_argument("--no-social", action="store_true", help="switch social repulsion off (paper Fig. 9)")
    m.add_argument("--no-rotation", action="store_true", help="freeze headings (paper Section 4.1.1)")
    m.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help="any other ModelParams field, e.g. --param tangential_dissipation_kg=100")
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


def add_geometry_arguments(group, clearance_help: str) -> None:
    """The scenario's geometry and navigation options (shared with ``crowd-calibrate``)."""
    for flag, (_, default) in GEOMETRY_OPTIONS.items():
        group.add_argument(f"--{flag.replace('_', '-')}", type=float, default=default, dest=flag,
                           help=f"default {default}")
    group.add_argument("--navigation-clearance", type=float, default=None, dest="navigation_clearance",
                       help=clearance_help)
    group.add_argument("--navigation-wall-slowdown", type=float, nargs=2, default=None, metavar=("DIST", "FACTOR"),
                       dest="navigation_wall_slowdown",
                       help="slower wavefront speed near walls, an option the paper describes with Eq. 11 but does not "
                            "use: V is multiplied by FACTOR in (0, 1] within DIST m of a wall, so that desired "
                            "directions keep away from walls; default off (V = 1 everywhere, as in the paper)")


def model_params_from_args(args) -> ModelParams:
    changes = dict(get_preset(getattr(args, "preset", DEFAULT_PRESET)).model)
    for name in ("social_strength_n", "social_range_m", "social_anisotropy", "normal_dissipation_kg"):
        if getattr(args, name) is not None:
            changes[name] = getattr(args, name)
    for item in args.param:
        if "=" not in item:
            raise ParameterError(f"--param expects NAME=VALUE, got {item!r}")
        key, value = item.split("=", 1)
        try:
            changes[key] = json.loads(value)
        except json.JSONDecodeError:
            changes[key] = value
    if args.no_social:
        changes["social_forces"] = False
    if args.no_rotation:
        changes["rotation"] = False
    return ModelParams().replace(**changes)


def run_one(task: dict) -> dict:
    """One bottleneck run (executed in a worker process); returns a JSON-able record.

    ``task``: ``width_m``, ``n_pedestrians``, ``seed``, ``geometry`` (``seyfried_bottleneck`` options),
    ``params`` (ModelParams fields), ``max_time_s``; optional ``pedestrian`` (overrides of
    :class:`~crowd_env.core.params.PedestrianDefaults`, e.g. τ or the desired-speed distribution, for the
    calibration: the same seed draws the same positions and standard-normal speed draws),
    ``stall_window_s`` / ``stall_speed_m_s`` (the stall rule, default the runner's) and
    ``trajectory_fps`` / ``trajectory_stem`` (also write trajectories). The record holds every measured
    figure, ``complete`` / ``stalled`` / ``stall_time_s`` and, for an incomplete run, nan flows with the
    partial ones beside them (:mod:`crowd_env.runner`).
    """
    from baselines.social_force import SocialForceAgent
    from crowd_env.core.params import PedestrianDefaults
    from crowd_env.runner import STALL_SPEED_M_S, STALL_WINDOW_S, run_scenario
    from crowd_env.scenarios import make_scenario

    params = ModelParams.from_dict(task["params"])
    scenario = make_scenario("seyfried_bottleneck", width_m=task["width_m"], n_pedestrians=task["n_pedestrians"],
                             seed=task["seed"], **task["geometry"])
    agent = SocialForceAgent(scenario.navigation())
    state = None
    if task.get("pedestrian"):
        state = scenario.make_state(defaults=dataclasses.replace(PedestrianDefaults(), **task["pedestrian"]))
    run_kw = {"max_time_s": task["max_time_s"], "state": state,
              "stall_window_s": task.get("stall_window_s", STALL_WINDOW_S),
              "stall_speed_m_s": task.get("stall_speed_m_s", STALL_SPEED_M_S)}
    fps = task.get("trajectory_fps")
    if fps:  # same run, also recording every k-th step
        from crowd_env.analysis.trajectories import export_run, record_run

        r, traj = record_run(scenario, agent, params, frame_rate_per_s=fps, **run_kw)
        config = {k: task[k] for k in ("geometry", "params", "max_time_s")}
        comments = [f"crowd_env seyfried_bottleneck run: b = {task['width_m']:g} m, N = {task['n_pedestrians']}, "
                    f"seed {task['seed']}, step h = {params.dt_s:g} s, config {config_hash(config)}"]
        export_run(task["trajectory_stem"], traj, scenario.geometry, comments=comments,
                   metadata={"width_m": task["width_m"], "n_pedestrians": task["n_pedestrians"], "seed": task["seed"],
                             "frame_rate_per_s": traj.frame_rate_per_s, "dt_s": params.dt_s,
                             "config_hash": config_hash(config), "measurement_line": "bottleneck"})
    else:
        r = run_scenario(scenario, agent, params, **run_kw)
    half = task["geometry"]["corridor_width_m"] / 2.0
    edges = np.arange(-half, half + LANE_BIN_M / 2, LANE_BIN_M)
    counts, _ = np.histogram(r.lateral_positions_m, bins=edges)
    return {
        "width_m": task["width_m"], "n_pedestrians": task["n_pedestrians"], "seed": task["seed"],
        "specific_flow_per_m_s": r.specific_flow_per_m_s, "flow_per_s": r.flow_per_s,
        "complete": r.complete, "stalled": r.stalled, "stall_time_s": r.stall_time_s,
        "partial_specific_flow_per_m_s": r.partial_specific_flow_per_m_s, "partial_flow_per_s": r.partial_flow_per_s,
        "simulated_time_s": r.simulated_time_s,
        "evacuation_time_s": r.evacuation_time_s, "n_evacuated": r.n_evacuated, "min_gap_m": r.min_gap_m,
        "density_front_per_m2": r.mean_density_per_m2("front"), "density_inside_per_m2": r.mean_density_per_m2("inside"),
        "density_front_passages_per_m2": r.mean_density_per_m2("front", window="passages"),
        "density_inside_passages_per_m2": r.mean_density_per_m2("inside", window="passages"),
        "speed_inside_m_s": r.mean_speed_m_s("inside"),
        "stationary_specific_flow_per_m_s": r.stationary_specific_flow_per_m_s(),
        "first_passage_s": float(r.crossing_times_s.min()) if r.crossing_times_s.size else float("nan"),
        "last_passage_s": float(r.crossing_times_s.max()) if r.crossing_times_s.size else float("nan"),
        "n_passages": int(r.crossing_times_s.size), "wall_time_s": r.wall_time_s, "n_steps": r.n_steps,
        "crossing_times_s": [round(float(t), 4) for t in r.crossing_times_s],
        "n_fallback_solves": r.n_fallback_solves,
        "lane_bin_edges_m": [float(edges[0]), LANE_BIN_M, int(edges.size)], "lane_counts": counts.tolist(),
    }


RESULT_COLUMNS = ["width_m", "n_pedestrians", "seed", "specific_flow_per_m_s", "flow_per_s", "complete", "stalled",
                  "stall_time_s", "partial_specific_flow_per_m_s", "partial_flow_per_s", "simulated_time_s",
                  "evacuation_time_s", "n_evacuated", "min_gap_m", "density_front_per_m2", "density_inside_per_m2",
                  "density_front_passages_per_m2", "density_inside_passages_per_m2", "speed_inside_m_s", "stationary_specific_flow_per_m_s",
                  "first_passage_s", "last_passage_s", "n_passages", "wall_time_s", "n_steps", "n_fallback_solves"]


def normalise_record(record: dict) -> dict:
    """A run record in today's form (``complete``, ``stalled``, partial flows), also from a record saved
    before the stall rule existed (those ran to the time limit and stored the partial J_s of an
    incomplete run as its J_s): there ``complete`` = all N passed, ``stalled`` = False (not known), and
    an incomplete run's J_s / J move to ``partial_*`` (nan in their place). Returns a new dict."""
    r = dict(record)
    if "complete" not in r:
        n_passed = r.get("n_passages", r.get("n_evacuated"))
        r["complete"] = int(n_passed) == int(r["n_pedestrians"])
        for key in ("specific_flow_per_m_s", "flow_per_s"):
            if key in r:
                r[f"partial_{key}"] = r[key]
                if not r["complete"]:
                    r[key] = float("nan")
    r.setdefault("stalled", False)
    r.setdefault("stall_time_s", float("nan"))
    return r


def navigation_clearance_from_args(args) -> float:
    """--navigation-clearance if given, else the preset's."""
    value = getattr(args, "navigation_clearance", None)
    return float(get_preset(getattr(args, "preset", DEFAULT_PRESET)).navigation_clearance_m if value is None else value)


def config_of(args, params: ModelParams) -> dict:
    geometry = {opt: float(getattr(args, flag)) for flag, (opt, _) in GEOMETRY_OPTIONS.items()}
    geometry["navigation_clearance_m"] = navigation_clearance_from_args(args)
    slowdown = getattr(args, "navigation_wall_slowdown", None)
    if slowdown is not None:  # only when set, so that folders of runs without it keep their configuration
        geometry["navigation_wall_slowdown"] = [float(v) for v in slowdown]
    p = {f.name: getattr(params, f.name) for f in dataclasses.fields(params) if f.name != "extra"}
    config = {"geometry": geometry, "params": p, "max_time_s": float(args.max_time)}
    # the stall rule only when set, so that folders of runs with the default keep their configuration
    for flag, key in (("stall_window", "stall_window_s"), ("stall_speed", "stall_speed_m_s")):
        value = getattr(args, flag, None)
        if value is not None:
            config[key] = None if flag == "stall_window" and value <= 0 else float(value)
    return config


def config_hash(config: dict) -> str:
    return hashlib.sha256(json.dumps(config, sort_keys=True).encode()).hexdigest()[:16]


def run_sweep(tasks: list, out: Path, jobs: int, desc: str = "bottleneck runs", folder_of=None) -> list:
    """Run the tasks not yet saved under ``out/runs`` in parallel; returns all records (normalised,
    :func:`normalise_record`).

    A task with ``trajectory_fps`` also needs ``out/trajectories/<run>.txt`` at that frame rate (written
    before its record, so a record implies complete files); without it the run is recomputed.
    ``folder_of(task) -> Path``: the output folder of each task instead of ``out`` (several
    configurations in one pool, e.g. one folder per geometry in ``crowd-generalise``).
    """
    from tqdm import tqdm

    from crowd_env.analysis.trajectories import trajectory_frame_rate

    def folder(t):
        return Path(folder_of(t)) if folder_of is not None else out

    for f in {folder(t) for t in tasks}:
        (f / "runs").mkdir(parents=True, exist_ok=True)
        if any(t.get("trajectory_fps") for t in tasks if folder(t) == f):
            (f / "trajectories").mkdir(parents=True, exist_ok=True)

    def path_of(t):
        return folder(t) / "runs" / f"b{t['width_m']:.3f}_n{t['n_pedestrians']}_s{t['seed']}.json"

    def traj_of(t):
        return folder(t) / "trajectories" / path_of(t).stem

    def done(t):
        if not path_of(t).exists():
            return False
        fps = t.get("trajectory_fps")
        if not fps:
            return True
        found = trajectory_frame_rate(folder(t) / "trajectories" / (path_of(t).stem + ".txt"))
        return found is not None and abs(found - fps) <= 1e-9 * fps

    todo = [dict(t, trajectory_stem=str(traj_of(t))) if t.get("trajectory_fps") else t
            for t in tasks if not done(t)]
    with tqdm(total=len(tasks), initial=len(tasks) - len(todo), desc=desc, unit="run", file=sys.stderr) as bar:
        if jobs <= 1:
            for t in todo:
                _save(path_of(t), run_one(t))
                bar.update()
        elif todo:
            with ProcessPoolExecutor(max_workers=jobs) as pool:
                futures = {pool.submit(run_one, t): t for t in todo}
                for fut in as_completed(futures):
                    _save(path_of(futures[fut]), fut.result())
                    bar.update()
    return [normalise_record(json.loads(path_of(t).read_text())) for t in tasks]


def _save(path: Path, record: dict) -> None:
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(record))
    tmp.replace(path)  # atomic: a killed run never leaves a half-written record


def check_config(out: Path, config: dict) -> None:
    """Refuse to mix runs of different configurations in one output folder."""
    out.mkdir(parents=True, exist_ok=True)
    path = out / "config.json"
    if path.exists():
        old = json.loads(path.read_text())
        if config_hash(old) != config_hash(config):
            diff = sorted(k for k in set(old["params"]) | set(config["params"])
                          if old["params"].get(k) != config["params"].get(k))
            diff += sorted(k for k in config["geometry"] if old["geometry"].get(k) != config["geometry"][k])
            raise SystemExit(f"error: {out} holds runs of a different configuration (differs in {diff}); "
                             f"choose another --out or delete the folder")
    else:
        path.write_text(json.dumps(config, indent=2, sort_keys=True))


def write_results(records: list, out: Path) -> None:
    with open(out / "results.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=RESULT_COLUMNS, extrasaction="ignore")
        w.writeheader()
        for r in sorted(records, key=lambda r: (r["n_pedestrians"], r["width_m"], r["seed"])):
            w.writerow(r)


def _finite_mean(values) -> float:
    """Mean of the finite values; nan, without numpy's empty-slice warning, when there is none."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return float(v.mean()) if v.size else float("nan")


def summarise(records: list) -> list:
    """Mean and standard deviation per (b, N), with the experiment where it is known.

    Every mean (J_s, J, densities, speed, stationary flow) is over the *complete* runs only (``complete``);
    ``runs`` counts all, ``complete`` / ``stalled`` / ``incomplete`` (not complete, not stalled: people
    left at the time limit) count each kind. ``min_gap_m`` is over all runs.
    """
    from crowd_env.analysis.experiment import seyfried_2009

    exp = seyfried_2009()
    groups: dict = {}
    for r in map(normalise_record, records):
        groups.setdefault((r["n_pedestrians"], r["width_m"]), []).append(r)
    rows = []
    for (n, b), rs in sorted(groups.items()):
        done = [r for r in rs if r["complete"]]
        n_stalled = sum(bool(r["stalled"]) for r in rs)
        js = np.array([r["specific_flow_per_m_s"] for r in done], dtype=float)
        js_mean = _finite_mean(js)
        try:
            js_exp = float(exp.specific_flow_per_m_s[exp.lookup(b, n)[0]])
        except ValueError:  # ExperimentError: not measured exactly (N = 20, 40): range check instead
            js_exp = float("nan")
        rows.append({
            "n_pedestrians": n, "width_m": b, "runs": len(rs), "complete": len(done), "stalled": n_stalled,
            "incomplete": len(rs) - len(done) - n_stalled,
            "specific_flow_mean": js_mean, "specific_flow_std": float(np.std(js)) if js.size else float("nan"),
            "specific_flow_exp": js_exp,
            "relative_error": float(js_mean / js_exp - 1.0) if np.isfinite(js_exp) else float("nan"),
            "flow_mean": _finite_mean([r["flow_per_s"] for r in done]),
            "density_front": _finite_mean([r["density_front_per_m2"] for r in done]),
            "density_inside": _finite_mean([r["density_inside_per_m2"] for r in done]),
            # runs saved before the speed was recorded have none
            "speed_inside": _finite_mean([r.get("speed_inside_m_s", np.nan) for r in done]),
            "stationary_specific_flow": _finite_mean([r.get("stationary_specific_flow_per_m_s", np.nan) for r in done]),
            "all_evacuated": all(r["n_evacuated"] == r["n_pedestrians"] for r in rs),
            "min_gap_m": float(min(r["min_gap_m"] for r in rs)),
        })
    return rows


def flow_fit(rows: list, n: int):
    """Linear fit of J(b) over the widths of group size ``n`` whose mean flow is defined (complete runs);
    None with fewer than 3 such widths."""
    from crowd_env.analysis.flow import linear_fit

    sub = [r for r in rows if r["n_pedestrians"] == n and np.isfinite(r["flow_mean"])]
    if len(sub) < 3:
        return None
    return linear_fit([r["width_m"] for r in sub], [r["flow_mean"] for r in sub])


def print_summary(rows: list, records: list, params=None, radius_m: float | None = None) -> None:
    """The J_s table beside the experiment, the linear fits of J(b) and, given the model ``params``
    and the radius, the force-balance estimate of the density in front of the entrance."""
    from crowd_env.analysis.calibration import in_range_check
    from crowd_env.analysis.density import force_balance_jam_density_per_m2, hexagonal_density_per_m2
    from crowd_env.analysis.experiment import (FRONT_DENSITY_RANGE_PER_M2, INSIDE_DENSITY_RANGE_PER_M2,
                                               INSIDE_SPEED_RANGE_M_S, RESIDUAL_NORM_BY_GROUP,
                                               SPECIFIC_FLOW_RANGE_N20_N40_PER_M_S)
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
        from crowd_env.core.params import PedestrianDefaults

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
    except ParameterError as exc:
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
        from crowd_env.analysis.trajectories import TrajectoryFormatError, steps_per_frame

        try:
            fps = 1.0 / (steps_per_frame(args.trajectory_fps, params.dt_s) * params.dt_s)
        except TrajectoryFormatError as exc:
            raise SystemExit(f"error: --trajectory-fps: {exc}")
    config = config_of(args, params)
    # Fail fast on impossible geometry, before the output folder is touched or workers are spawned.
    from crowd_env.core.segments import GeometryError
    from crowd_env.scenarios import ScenarioError, make_scenario
    for b in args.widths:
        for n in args.sizes:
            try:
                make_scenario("seyfried_bottleneck", width_m=b, n_pedestrians=n, seed=args.first_seed,
                              **config["geometry"])
            except (GeometryError, ScenarioError) as exc:
                raise SystemExit(f"error: b = {b} m, N = {n}: {exc}")
    check_config(args.out, config)
    tasks = [dict(width_m=b, n_pedestrians=n, seed=s, trajectory_fps=fps, **config)
             for n in args.sizes for b in args.widths for s in range(args.first_seed, args.first_seed + args.seeds)]
    records = run_sweep(tasks, args.out, args.jobs)
    write_results(records, args.out)
    rows = summarise(records)
    with open(args.out / "summary.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print_summary(rows, records, params, args.radius)
    if not args.no_figures:
        from crowd_env.analysis.figures import bottleneck_figures
        for path in bottleneck_figures(records, rows, args.out):
            print(f"figure: {path}")
    if fps:
        print(f"trajectories ({fps:g} frames/s, PedPy text format): {args.out / 'trajectories'}")
    print(f"results: {args.out / 'results.csv'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
