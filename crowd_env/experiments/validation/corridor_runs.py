"""The nine Jülich corridor runs simulated as they were run and measured as they were measured.

Each task is one UO run (:mod:`crowd_env.scenarios.juelich_corridor`: the waiting area, the entrance, the 8 m
corridor and its exit, N as in the experiment) with a seed and a model: :func:`run_corridor_one` records it at the
recordings' 16 frames/s and measures it with :func:`~crowd_env.analysis.corridor_runs.measure_uo_run`, the
measurement that gives the shipped rows from the recordings (Voronoi density and speed in y in [−2, 0], flows
across y = 0 and the exit over the steady state). A run that is not complete (stalled: nobody passed the exit
for 20 s and those left got nowhere, the runner's stall rule; or people left at the time limit) reports no
figure, only why. :func:`summarise_corridor` sets the seed means of the complete runs beside each experiment.

Task format (JSON): ``run`` (the experiment's name), ``entrance_width_m``, ``corridor_width_m``, ``exit_width_m``,
``width_m`` (the exit's, for the run store's file names), ``n_pedestrians``, ``seed``, ``params``
(:class:`~crowd_env.walking.model.ModelParams` fields), ``geometry`` (``juelich_corridor`` options beyond the widths
and N), ``max_time_s``; optional ``pedestrian`` (overrides of :class:`~crowd_env.core.params.PedestrianDefaults`)
and ``policy`` (:mod:`crowd_env.experiments.running.crowd_policy`).
"""
from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np

from crowd_env.errors import InputError

from ...analysis.corridor_runs import (UO_FRAME_RATE_PER_S, approach_profile, door_passage, juelich_uo_runs,
                                      measure_uo_run, neighbour_spacing, opening_entries, passage_lapses,
                                      recorded_uo_trajectories, uo_measurement_area, uo_run)
from ...scenarios.juelich_corridor import (UO_BARRIER_THICKNESS_M, UO_BARRIER_Y_M, UO_CORRIDOR_END_Y_M,
                                           UO_END_WALL_THICKNESS_M, UO_ENTRANCE_LINE_Y_M)
from ...core.params import PedestrianDefaults
from ...walking.model import ModelParams
from ...scenarios import make_scenario
from ..running.crowd_policy import crowd_policy
from ..running.recording import record_run
from .bottleneck import params_dict

__all__ = ["CORRIDOR_RUN_NAMES", "CORRIDOR_TOLERANCES", "corridor_tasks", "run_corridor_one", "summarise_corridor",
           "corridor_scenario", "passage_figures", "recorded_passage_figures", "PASSAGE_FIELDS", "ENTRY_FIELDS"]

CORRIDOR_RUN_NAMES = tuple(r.name for r in juelich_uo_runs())
# The targets for each run: speed within ±0.10 m/s, density within ±15 %, exit flow within ±10 %.
CORRIDOR_TOLERANCES = {"speed_m_s": 0.10, "density_relative": 0.15, "flow_exit_relative": 0.10}
_FLOOR_HALF_WIDTH_M = 5.0  # the entrance line spans any floor before the corridor (the scenario's is 5 m wide)
_KABALAN_RADIUS_M = PedestrianDefaults().radius_m  # Table 2's body: passages off the axis its centre can take
_MEASURED = ("density_per_m2", "density_sd_per_m2", "speed_m_s", "speed_sd_m_s", "flow_y0_per_s", "flow_exit_per_s",
             "steady_from_frame", "steady_to_frame")


def corridor_tasks(params: ModelParams, *, runs=CORRIDOR_RUN_NAMES, seeds=(0,), geometry: dict | None = None,
                   pedestrian: dict | None = None, max_time_s: float = 300.0) -> list:
    """One task per run name of ``runs`` and seed (module docstring), with the experiment's widths and N."""
    if isinstance(runs, str):
        runs = (runs,)
    if not runs:
        raise InputError("corridor_tasks needs at least one run")
    tasks = []
    for name in runs:
        run = uo_run(name)
        for seed in seeds:
            task = {"experiment": "corridor", "run": run.name, "entrance_width_m": run.entrance_width_m,
                    "corridor_width_m": run.corridor_width_m, "exit_width_m": run.exit_width_m,
                    "width_m": run.exit_width_m, "n_pedestrians": run.n_pedestrians, "seed": int(seed),
                    "params": params_dict(params), "geometry": dict(geometry or {}), "max_time_s": float(max_time_s)}
            if pedestrian:
                task["pedestrian"] = dict(pedestrian)
            tasks.append(task)
    return tasks


def corridor_scenario(task: dict):
    """The ``juelich_corridor`` scenario of a corridor task (:func:`corridor_tasks`)."""
    return make_scenario("juelich_corridor", entrance_width_m=task["entrance_width_m"],
                         exit_width_m=task["exit_width_m"], corridor_width_m=task["corridor_width_m"],
                         n_pedestrians=task["n_pedestrians"], seed=task["seed"], **task["geometry"])


def run_corridor_one(task: dict) -> dict:
    """One corridor run of the task format; a JSON-able record: the measured figures (nan unless the run is
    complete), ``complete`` / ``stalled`` / ``stall_time_s``, the exit's passages, the smallest gap and the cost."""
    params = ModelParams.from_dict(task["params"])
    scenario = corridor_scenario(task)
    state = None
    if task.get("pedestrian"):
        state = scenario.make_state(defaults=dataclasses.replace(PedestrianDefaults(), **task["pedestrian"]))
    policy = crowd_policy(task, scenario, params)
    result, traj = record_run(scenario, policy, params, frame_rate_per_s=UO_FRAME_RATE_PER_S, state=state,
                              max_time_s=task["max_time_s"], line="exit", density_areas=(), lane_area=None)
    record = {"experiment": "corridor", "run": task["run"], "seed": task["seed"], "n_pedestrians": task["n_pedestrians"],
              "width_m": task["width_m"], "complete": bool(result.complete), "stalled": bool(result.stalled),
              "stall_time_s": result.stall_time_s, "n_passages": int(result.n_passed),
              "n_evacuated": int(result.n_evacuated), "min_gap_m": result.min_gap_m,
              "simulated_time_s": result.simulated_time_s, "wall_time_s": result.wall_time_s, "n_steps": result.n_steps}
    measured = dict.fromkeys(_MEASURED, math.nan)
    if result.complete:
        m = measure_uo_run(traj, corridor_width_m=task["corridor_width_m"], exit_width_m=task["exit_width_m"])
        measured = {k: getattr(m, k) for k in _MEASURED}
        record.update(passage_figures(traj, corridor_width_m=task["corridor_width_m"], exit_width_m=task["exit_width_m"],
                                      entrance_width_m=task["entrance_width_m"],
                                      window_frames=(m.steady_from_frame, m.steady_to_frame),
                                      barrier_thickness_m=scenario.metadata["barrier_thickness_m"],
                                      end_wall_thickness_m=scenario.metadata["end_wall_thickness_m"]))
    record.update(measured)
    return record


PASSAGE_FIELDS = ("headway_median_s", "speed_median_m_s", "lateral_sd_m", "share_off_axis", "following_median_m",
                  "lateral_step_median_m", "side_alternation")  # the DoorPassage fields a run's record keeps, as exit_* and entrance_*


ENTRY_FIELDS = ("wait_median_s", "before_median_m", "offset_median_m", "share_beside", "speed_median_m_s")
# the OpeningEntry fields a run's record keeps, as exit_entry_* and entrance_entry_*


def passage_figures(trajectories, *, corridor_width_m: float, exit_width_m: float, window_frames: tuple,
                    entrance_width_m: float, barrier_thickness_m: float = UO_BARRIER_THICKNESS_M,
                    end_wall_thickness_m: float = UO_END_WALL_THICKNESS_M) -> dict:
    """How a run passes its exit and approaches it over its steady state, as JSON-able record fields: ``exit_*``
    (:func:`~crowd_env.analysis.corridor_runs.door_passage` at y = −4 m across the exit) and ``entrance_*`` (the same
    at y = 7.6 m, 0.4 m past the entrance, where the camera sees everybody who came through), each with the share of
    the passages farther off the opening's axis than the centre of a disk of Kabalan's 0.23 m can pass it
    (``*_share_off_axis``) and how far behind and beside the one before each passer crossed
    (``*_following_median_m``, ``*_lateral_step_median_m``) and on which side (``*_side_alternation``);
    ``approach_*`` (:func:`~crowd_env.analysis.corridor_runs.approach_profile`: density and
    speed in 0.5 m bands before the exit); ``spacing_*`` (:func:`~crowd_env.analysis.corridor_runs.neighbour_spacing`
    in the measurement area: how close walkers come to each other ahead and beside, its bearing edges, the 1 %, 5 %
    and 50 % quantiles of the distance per bin and the share closer than 0.46 m, two radii of Kabalan's body);
    ``entrance_lapses_s`` and ``exit_lapses_s`` (:func:`~crowd_env.analysis.corridor_runs.passage_lapses`: the time
    lapses between successive passages of the entrance line and of the exit line, each over its own steady state);
    ``entrance_entry_*`` and ``exit_entry_*`` (:func:`~crowd_env.analysis.corridor_runs.opening_entries`, the
    fields :data:`ENTRY_FIELDS` and ``*_entry_positions_m``, each pair's: where the next walker stood when the one
    before left the opening through the barrier, ``barrier_thickness_m`` thick, or the end wall,
    ``end_wall_thickness_m``; NaN and none for the recordings' entrances, which the camera sees only past the
    barrier).
    The same function measures the recordings (:func:`recorded_passage_figures`)."""
    half = 0.5 * exit_width_m
    centre = 0.5 * corridor_width_m
    door = (centre - half, centre + half)
    floor = (centre - _FLOOR_HALF_WIDTH_M, centre + _FLOOR_HALF_WIDTH_M)
    exit_ = door_passage(trajectories, y_m=UO_CORRIDOR_END_Y_M, x_range_m=door, window_frames=window_frames,
                         off_axis_m=max(half - _KABALAN_RADIUS_M, 0.0))
    entrance = door_passage(trajectories, y_m=UO_ENTRANCE_LINE_Y_M, x_range_m=floor, window_frames=window_frames,
                            off_axis_m=max(0.5 * entrance_width_m - _KABALAN_RADIUS_M, 0.0))
    y, density, speed = approach_profile(trajectories, corridor_width_m=corridor_width_m, window_frames=window_frames)
    spacing = neighbour_spacing(trajectories, area=uo_measurement_area(corridor_width_m), window_frames=window_frames)
    figures = {f"{where}_{field}": getattr(passage, field)
               for where, passage in (("exit", exit_), ("entrance", entrance))
               for field in PASSAGE_FIELDS}
    half_e = 0.5 * entrance_width_m
    for where, upstream, downstream, span in (
            ("entrance", UO_BARRIER_Y_M + barrier_thickness_m, UO_BARRIER_Y_M, (centre - half_e, centre + half_e)),
            ("exit", UO_CORRIDOR_END_Y_M, UO_CORRIDOR_END_Y_M - end_wall_thickness_m, door)):
        entry = opening_entries(trajectories, upstream_y_m=upstream, downstream_y_m=downstream, x_range_m=span,
                                window_frames=window_frames)
        figures.update({f"{where}_entry_{field}": getattr(entry, field) for field in ENTRY_FIELDS})
        figures[f"{where}_entry_positions_m"] = [list(p) for p in entry.positions_m]
    return {**figures, "approach_y_m": y.tolist(), "approach_density_per_m2": density.tolist(),
            "approach_speed_m_s": speed.tolist(), "spacing_bearing_edges_deg": spacing.bearing_edges_deg.tolist(),
            "spacing_q01_m": spacing.distance_m[:, 0].tolist(), "spacing_q05_m": spacing.distance_m[:, 1].tolist(),
            "spacing_median_m": spacing.distance_m[:, 2].tolist(), "spacing_share_closer": spacing.share_closer.tolist(),
            "entrance_lapses_s": passage_lapses(trajectories, y_m=UO_ENTRANCE_LINE_Y_M, x_range_m=floor).tolist(),
            "exit_lapses_s": passage_lapses(trajectories, y_m=UO_CORRIDOR_END_Y_M, x_range_m=door).tolist()}


def recorded_passage_figures(name: str) -> dict:
    """:func:`passage_figures` of the recording of run ``name`` over its hand-chosen steady state (measured once per
    process: every table and figure of ``crowd-virtual-experiments`` sets its runs beside it; a fresh dict each call)."""
    return dict(_recorded_passage_figures(name))


@functools.lru_cache(maxsize=None)
def _recorded_passage_figures(name: str) -> dict:
    run = uo_run(name)
    return passage_figures(recorded_uo_trajectories(name), corridor_width_m=run.corridor_width_m,
                           entrance_width_m=run.entrance_width_m,
                           exit_width_m=run.exit_width_m, window_frames=(run.steady_from_frame, run.steady_to_frame))


def _mean(values) -> float:
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    return float(v.mean()) if v.size else math.nan


def summarise_corridor(records: list) -> list:
    """One row per run: the seed means of the complete runs (density, speed, exit and y = 0 flows) beside the
    experiment, the misses against :data:`CORRIDOR_TOLERANCES` (``*_miss`` in units of the tolerance: within
    it when at most 1), and how many runs were complete, stalled or otherwise incomplete."""
    rows = []
    for run in juelich_uo_runs():
        rs = [r for r in records if r.get("experiment") == "corridor" and r["run"] == run.name]
        if not rs:
            continue
        done = [r for r in rs if r["complete"]]
        rho, v = _mean([r["density_per_m2"] for r in done]), _mean([r["speed_m_s"] for r in done])
        j_exit, j_y0 = _mean([r["flow_exit_per_s"] for r in done]), _mean([r["flow_y0_per_s"] for r in done])
        rows.append({
            "run": run.name, "entrance_width_m": run.entrance_width_m, "exit_width_m": run.exit_width_m,
            "n_pedestrians": run.n_pedestrians, "runs": len(rs), "complete": len(done),
            "stalled": sum(bool(r["stalled"]) for r in rs),
            "incomplete": sum(not r["complete"] and not r["stalled"] for r in rs),
            "density_per_m2": rho, "density_exp": run.density_per_m2, "speed_m_s": v, "speed_exp": run.speed_m_s,
            "flow_exit_per_s": j_exit, "flow_exit_exp": run.flow_exit_per_s, "flow_y0_per_s": j_y0,
            "flow_y0_exp": run.flow_y0_per_s,
            "density_miss": abs(rho / run.density_per_m2 - 1.0) / CORRIDOR_TOLERANCES["density_relative"],
            "speed_miss": abs(v - run.speed_m_s) / CORRIDOR_TOLERANCES["speed_m_s"],
            "flow_exit_miss": abs(j_exit / run.flow_exit_per_s - 1.0) / CORRIDOR_TOLERANCES["flow_exit_relative"],
            "min_gap_m": float(min(r["min_gap_m"] for r in rs)),
        })
    return rows
