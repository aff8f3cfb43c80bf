"""The Seyfried et al. (2009) bottleneck experiment of Kabalan et al. (2016), Section 4: one run, a sweep, the summary.

The task format, shared by the reproduction, the calibration and the generalisation: a JSON-able dict
with ``width_m``, ``n_pedestrians``, ``seed``, ``geometry`` (``seyfried_bottleneck`` options), ``params``
(:class:`~crowd_env.walking.model.ModelParams` fields) and ``max_time_s``; optional ``pedestrian``
(overrides of :class:`~crowd_env.core.params.PedestrianDefaults`), ``stall_window_s`` /
``stall_speed_m_s`` (the stall rule) and ``trajectory_fps`` (also record trajectories). :func:`run_one`
runs a task and returns its record: J_s (Eq. 22), densities, speed, lanes, passages, stall state.
:func:`run_sweep` runs the tasks missing from their :class:`~crowd_env.experiments.running.store.RunStore`
through :func:`~crowd_env.experiments.running.backends.execute`; :func:`summarise` gives the mean and spread
per (b, N) beside the experiment, over complete runs only.
"""
from __future__ import annotations

from crowd_env.errors import SetupError, SweepError

import dataclasses
from pathlib import Path

import numpy as np

from ...analysis.experiment import seyfried_2009
from ...analysis.flow import linear_fit
from ...analysis.trajectories import export_run
from ...core.params import PedestrianDefaults
from ...walking.model import ModelParams
from ...walking.presets import DEFAULT_PRESET, get_preset
from ...core.segments import GeometryError
from ...scenarios import ScenarioError, make_scenario
from ..running.backends import ProcessBackend, SerialBackend, execute, failure_report
from ..running.crowd_policy import crowd_policy
from ..running.recording import record_run
from ..running.runner import STALL_SPEED_M_S, STALL_WINDOW_S, run_scenario
from ..running.store import RunStore, check_record, config_hash, normalise_record
from crowd_env.files import write_csv_atomic

__all__ = ["GEOMETRY_OPTIONS", "LANE_BIN_M", "RESULT_COLUMNS", "SetupError", "SweepError", "model_params",
           "params_dict", "bottleneck_config", "check_setups", "check_records", "SUMMARY_FIELDS", "bottleneck_scenario",
           "run_one", "run_sweep", "write_results", "summarise", "write_summary", "flow_fit"]

GEOMETRY_OPTIONS = {  # command-line flag -> seyfried_bottleneck option, with the Seyfried defaults
    "corridor_width": ("corridor_width_m", 4.0),
    "channel_length": ("channel_length_m", 2.8),
    "initial_density": ("initial_density_per_m2", 3.3),
    "section_depth": ("section_depth_m", 1.515),
    "block_start_upstream": ("block_start_upstream_m", 2.24),
    "radius": ("radius_m", 0.23),
}
LANE_BIN_M = 0.01  # Kabalan Section 4.2

# What the results table and the summary read from a run record without a default (older records lack the
# speed and the stationary flow, read with one); a record also needs ``complete`` or, saved before the stall
# rule, ``n_passages`` / ``n_evacuated`` (crowd_env.experiments.running.store.check_record).
SUMMARY_FIELDS = ("width_m", "n_pedestrians", "seed", "specific_flow_per_m_s", "flow_per_s", "n_evacuated", "min_gap_m",
                  "density_front_per_m2", "density_inside_per_m2")

RESULT_COLUMNS = ["width_m", "n_pedestrians", "seed", "specific_flow_per_m_s", "flow_per_s", "complete", "stalled",
                  "stall_time_s", "partial_specific_flow_per_m_s", "partial_flow_per_s", "simulated_time_s",
                  "evacuation_time_s", "n_evacuated", "min_gap_m", "density_front_per_m2", "density_inside_per_m2",
                  "density_front_passages_per_m2", "density_inside_passages_per_m2", "speed_inside_m_s", "stationary_specific_flow_per_m_s",
                  "first_passage_s", "last_passage_s", "n_passages", "wall_time_s", "n_steps", "n_fallback_solves"]


def model_params(preset: str = DEFAULT_PRESET, changes: dict | None = None) -> ModelParams:
    """The preset's model (:mod:`crowd_env.walking.presets`) with ``changes`` (ModelParams fields) on top."""
    return get_preset(preset).params(**(changes or {}))


def params_dict(params: ModelParams) -> dict:
    """The model parameters of a configuration, by their flat names (:meth:`ModelParams.to_dict
    <crowd_env.walking.model.ModelParams.to_dict>`)."""
    return params.to_dict()


def bottleneck_config(params: ModelParams, *, navigation_clearance_m: float, max_time_s: float = 300.0,
                      navigation_wall_slowdown=None, stall_window_s: float | None = None,
                      stall_speed_m_s: float | None = None, **geometry) -> dict:
    """The configuration of a folder of bottleneck runs: geometry (Seyfried's, with ``geometry``'s
    ``seyfried_bottleneck`` options on top), navigation, model parameters and time limit.

    ``navigation_wall_slowdown`` and the stall rule enter only when given, so that folders of runs
    without them keep their configuration; ``stall_window_s`` <= 0 switches the rule off (stored as None).
    """
    defaults = {opt: d for opt, d in GEOMETRY_OPTIONS.values()}
    unknown = sorted(set(geometry) - set(defaults))
    if unknown:
        raise SetupError(f"unknown geometry option(s) {unknown}; known: {sorted(defaults)}")
    geom = {opt: float(geometry.get(opt, d)) for opt, d in defaults.items()}
    geom["navigation_clearance_m"] = float(navigation_clearance_m)
    if navigation_wall_slowdown is not None:
        geom["navigation_wall_slowdown"] = [float(v) for v in navigation_wall_slowdown]
    config = {"geometry": geom, "params": params_dict(params), "max_time_s": float(max_time_s)}
    if stall_window_s is not None:
        config["stall_window_s"] = None if stall_window_s <= 0 else float(stall_window_s)
    if stall_speed_m_s is not None:
        config["stall_speed_m_s"] = float(stall_speed_m_s)
    return config


def check_setups(geometry: dict, widths_m, sizes, seed: int) -> None:
    """Build every (b, N) scenario once (seed ``seed``): an impossible set-up raises :class:`SetupError`
    naming it and the reason, before any folder is touched or worker started."""
    for b in widths_m:
        for n in sizes:
            try:
                make_scenario("seyfried_bottleneck", width_m=b, n_pedestrians=n, seed=seed, **geometry)
            except (GeometryError, ScenarioError) as exc:
                raise SetupError(f"b = {b} m, N = {n}: {exc}") from None


def bottleneck_scenario(task: dict):
    """The ``seyfried_bottleneck`` scenario of a task of the task format (module docstring)."""
    return make_scenario("seyfried_bottleneck", width_m=task["width_m"], n_pedestrians=task["n_pedestrians"],
                         seed=task["seed"], **task["geometry"])


def run_one(task: dict) -> dict:
    """One bottleneck run of the task format (module docstring); returns a JSON-able record.

    A ``policy`` entry drives the crowd, or a fraction of it, by a learned policy instead of the calibrated
    agent (:mod:`crowd_env.experiments.running.crowd_policy`). A ``pedestrian`` override draws the state with those PedestrianDefaults from the same seed (the
    same positions and standard-normal speed draws: common random numbers for the calibration). With
    ``trajectory_fps`` (and ``trajectory_stem``, set by the store) the same run is also recorded and
    exported in PedPy's text format. The record holds every measured figure, ``complete`` /
    ``stalled`` / ``stall_time_s`` and, for an incomplete run, nan flows with the partial ones beside
    them (:mod:`crowd_env.experiments.running.runner`).
    """
    params = ModelParams.from_dict(task["params"])
    scenario = bottleneck_scenario(task)
    agent = crowd_policy(task, scenario, params)  # the calibrated agent, unless the task names a learned policy
    state = None
    if task.get("pedestrian"):
        state = scenario.make_state(defaults=dataclasses.replace(PedestrianDefaults(), **task["pedestrian"]))
    run_kw = {"max_time_s": task["max_time_s"], "state": state,
              "stall_window_s": task.get("stall_window_s", STALL_WINDOW_S),
              "stall_speed_m_s": task.get("stall_speed_m_s", STALL_SPEED_M_S)}
    fps = task.get("trajectory_fps")
    if fps:  # same run, also recording every k-th step
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


def run_sweep(tasks: list, out: Path, jobs: int, desc: str = "bottleneck runs", folder_of=None) -> list:
    """Run the tasks not yet stored under ``out/runs`` on ``jobs`` worker processes (serially for 1);
    returns all records, normalised, in the order of ``tasks``.

    The folders are opened without a configuration check (the caller checks them with
    ``RunStore(out, config)`` first). ``folder_of(task) -> Path``: each task's folder instead of ``out``
    (several configurations in one pool, e.g. one folder per geometry in ``crowd-generalise``). A failed
    run raises :class:`SweepError` once the others are stored.
    """
    stores: dict = {}

    def store_of(task) -> RunStore:
        folder = Path(folder_of(task)) if folder_of is not None else Path(out)
        if folder not in stores:
            stores[folder] = RunStore(folder)
        return stores[folder]

    for t in tasks:
        store_of(t)
    backend = SerialBackend() if jobs <= 1 else ProcessBackend(jobs)
    with backend:
        failed = execute(tasks, store_of, backend, run_one, desc=desc)
    if failed:
        raise SweepError(failure_report(tasks, store_of))
    records = [store_of(t).load(t) for t in tasks]
    check_records(records, [store_of(t).path(t) for t in tasks])  # a stored file lacking a field, named
    return records


def check_records(records: list, sources=None) -> None:
    """Raise :class:`~crowd_env.errors.RunStoreError` naming the first record that lacks one of
    :data:`SUMMARY_FIELDS` (what the results table and the summary read) and what it lacks
    (:func:`~crowd_env.experiments.running.store.check_record`): by ``sources[k]`` (its file) when given, else by
    its place in ``records`` and its b, N, seed."""
    for k, r in enumerate(records):
        label = f"records[{k}]" if sources is None else str(sources[k])
        if sources is None and isinstance(r, dict) and any(key in r for key in ("width_m", "n_pedestrians", "seed")):
            label += f" (b = {r.get('width_m')}, N = {r.get('n_pedestrians')}, seed {r.get('seed')})"
        check_record(r, label, SUMMARY_FIELDS)


def write_results(records: list, out: Path) -> None:
    """``out/results.csv``: one row per run (:data:`RESULT_COLUMNS`), written atomically once every record
    has been checked (:func:`check_records`: a record lacking a field leaves the file as it was)."""
    check_records(records)
    rows = sorted(records, key=lambda r: (r["n_pedestrians"], r["width_m"], r["seed"]))
    write_csv_atomic(Path(out) / "results.csv", RESULT_COLUMNS, rows, extrasaction="ignore")


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
    check_records(records)
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


def write_summary(rows: list, out: Path) -> Path:
    """``out/summary.csv``: the rows of :func:`summarise`, written atomically."""
    if not rows:
        raise SetupError(f"no summary rows to write into {Path(out) / 'summary.csv'} (no runs)")
    path = Path(out) / "summary.csv"
    write_csv_atomic(path, list(rows[0]), rows)
    return path


def flow_fit(rows: list, n: int):
    """Linear fit of J(b) over the widths of group size ``n`` whose mean flow is defined (complete runs);
    None with fewer than 3 such widths."""
    sub = [r for r in rows if r["n_pedestrians"] == n and np.isfinite(r["flow_mean"])]
    if len(sub) < 3:
        return None
    return linear_fit([r["width_m"] for r in sub], [r["flow_mean"] for r in sub])
