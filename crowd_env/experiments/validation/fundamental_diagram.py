"""The fundamental diagram of the calibrated crowd: a density sweep in the periodic corridor and the single-file
ring, measured like the experiments and set beside them (``crowd-fundamental-diagram --sweep``).

Two set-ups (:data:`SETUPS`), both the scenario ``periodic_corridor`` (a strip periodic along its axis):

- ``corridor``: the Jülich experiment's width, 1.8 m, ``length_m`` long, at a global density ρ (1/m²);
- ``single_file``: a strip 0.7 m wide (< 4 r: nobody can pass anybody, a straight ring), at a 1D density ρ
  (1/m), N = round(ρ L).

Each run walks ``max_time_s`` and is measured over [``transient_s``, ``max_time_s``]: the density is the global
N / (L W) (exact: nobody enters or leaves), the speed the mean speed along the walking direction over the
window (:func:`~crowd_env.analysis.periodic.periodic_corridor_point`); for the single file also the headway
samples (distance to the one ahead, individual speed over one frame interval) and their least-squares line
d = a + b v over v > 0.05 m/s, as the experiment's own fit. Measuring method: global density and mean speed,
not PedPy's Voronoi density in a 2 m area; in a homogeneous periodic strip both estimate the same mean, and the
global one has no area-edge noise. Runs are stored one file each (:class:`~crowd_env.experiments.running.store.RunStore`,
keyed by task) and skipped when found: a stopped sweep resumes; they run on the project's executor
(:mod:`crowd_env.experiments.running.backends`).
"""
from __future__ import annotations

import numpy as np

from crowd_env.errors import InputError

from ...analysis.fd_reference import JUELICH_CORRIDOR_WIDTH_M, juelich_corridor, single_file
from ...analysis.periodic import MIN_FIT_SPEED_M_S, headway_fit, trajectory_frames, unwrap_x
from ...core.checks import check_number
from ...core.params import PedestrianDefaults
from ...walking.model import ModelParams
from ...core.periodic import minimum_image_dx
from ..running.crowd_policy import crowd_policy
from .bottleneck import bottleneck_config, params_dict, run_one
from .periodic import fundamental_diagram_point

__all__ = ["SETUPS", "SINGLE_FILE_WIDTH_M", "fd_tasks", "run_fd_one", "summarise_fd", "headway_fit",
           "MIN_FIT_SPEED_M_S", "CORRIDOR_DENSITIES", "SINGLE_FILE_DENSITIES",
           "door_and_corridor"]

SINGLE_FILE_WIDTH_M = 0.7  # 2 r < W < 4 r for r = 0.23 m: one file, no passing
SETUPS = ("corridor", "single_file")
FRAME_RATE_PER_S = 10.0
# the densities of the shipped bins: the corridor's from 0.4 to 3.4 /m² (the Jülich bins 0.394-3.364), the
# single file's all six (0.658-1.847 /m)
CORRIDOR_DENSITIES = tuple(float(d) for d in juelich_corridor().density if 0.35 <= d <= 3.4)
SINGLE_FILE_DENSITIES = tuple(float(d) for d in single_file().density)


def fd_tasks(setups, densities: dict, seeds, params: ModelParams, *, length_m: float = 20.0,
             max_time_s: float = 40.0, transient_s: float = 15.0,
             corridor_width_m: float = JUELICH_CORRIDOR_WIDTH_M, radius_m: float | None = None) -> list:
    """Tasks of :func:`run_fd_one`, one per set-up, density of ``densities[setup]`` and seed.

    ``corridor_width_m``: the periodic corridor's width (default the Jülich experiment's 1.8 m; the width of a
    door's channel measures the channel's own fundamental diagram). ``radius_m``: the pedestrians' radius (None:
    Kabalan's Table 2, 0.23 m, the tasks as before); the single file's strip then keeps its ratio to the body,
    :data:`SINGLE_FILE_WIDTH_M` × r / 0.23 m (one file, no passing, whatever the body)."""
    unknown = sorted(set(setups) - set(SETUPS))
    if unknown:
        raise InputError(f"unknown set-up(s) {unknown}; choose among {list(SETUPS)}")
    corridor_width_m = check_number("corridor_width_m", corridor_width_m, error=InputError, positive=True)
    base = {"params": params_dict(params), "length_m": float(length_m),
            "max_time_s": float(max_time_s), "transient_s": float(transient_s)}
    width = {"corridor": corridor_width_m, "single_file": SINGLE_FILE_WIDTH_M}
    if radius_m is not None:
        radius_m = check_number("radius_m", radius_m, error=InputError, positive=True)
        base["radius_m"] = radius_m
        width["single_file"] = SINGLE_FILE_WIDTH_M * radius_m / PedestrianDefaults().radius_m
    area = {"corridor": length_m * width["corridor"], "single_file": length_m}  # N = round(ρ · area)
    return [dict(base, setup=s, density=float(d), seed=int(seed), width_m=width[s],
                 n_pedestrians=int(round(d * area[s]))) for s in setups for d in densities[s] for seed in seeds]


def _single_file_samples(time_s, position_m, period_m: float, window_s) -> tuple:
    """(headway (k,), speed (k,)) of a single file: each pedestrian's distance to the next one ahead along x
    (minimum image) and its speed over the next frame interval, for frames in ``window_s``."""
    x = unwrap_x(position_m[..., 0], period_m)  # (F, N)
    dt = np.diff(time_s)
    speed = np.diff(x, axis=0) / dt[:, None]  # (F-1, N)
    keep = (time_s[:-1] >= window_s[0]) & (time_s[1:] <= window_s[1] + 1e-9)
    heads, speeds = [], []
    for f in np.flatnonzero(keep):
        xf = position_m[f, :, 0]
        order = np.argsort(xf)
        ahead = np.roll(order, -1)
        gap = minimum_image_dx(np.ascontiguousarray(xf[ahead] - xf[order]), period_m)
        gap = np.where(gap <= 0.0, gap + period_m, gap)  # one pedestrian alone: its headway is the ring
        heads.append(gap)
        speeds.append(speed[f, order])
    return np.concatenate(heads) if heads else np.zeros(0), np.concatenate(speeds) if speeds else np.zeros(0)


def run_fd_one(task: dict) -> dict:
    """One run of a :func:`fd_tasks` task; returns a JSON-able record (density, speed, flow, headway fit for a
    single file, cost). An optional ``policy`` entry drives the crowd by a learned policy
    (:mod:`crowd_env.experiments.running.crowd_policy`); an optional ``pedestrian`` entry of the task
    (PedestrianDefaults overrides, as in a calibration task) draws the state with those defaults from the same
    seed."""
    params = ModelParams.from_dict(task["params"])
    single = task["setup"] == "single_file"
    width = task["width_m"]
    # a single file's 1D density ρ (1/m) is the strip's ρ / W (1/m²): N = round(ρ L)
    point, result, traj = fundamental_diagram_point(
        task["density"] / width if single else task["density"], length_m=task["length_m"], width_m=width,
        seed=task["seed"], max_time_s=task["max_time_s"], transient_s=task["transient_s"], params=params,
        radius_m=task.get("radius_m", PedestrianDefaults().radius_m),
        frame_rate_per_s=FRAME_RATE_PER_S, pedestrian=task.get("pedestrian"),
        driver=(lambda scenario: crowd_policy(task, scenario, params)) if task.get("policy") else None)
    n = point.n_pedestrians
    record = {"setup": task["setup"], "density": task["density"], "seed": task["seed"], "n_pedestrians": n,
              "density_measured": n / task["length_m"] if single else point.density_per_m2,
              "speed_m_s": point.speed_m_s, "min_gap_m": result.min_gap_m, "wall_time_s": result.wall_time_s,
              "simulated_time_s": result.simulated_time_s, "complete": True, "stalled": False}
    record["flow"] = record["density_measured"] * point.speed_m_s
    if single:
        time_s, position, _ = trajectory_frames(traj)
        heads, speeds = _single_file_samples(time_s, position, task["length_m"], point.window_s)
        record["headway_samples_m"] = np.round(heads[::5], 4).tolist()
        record["speed_samples_m_s"] = np.round(speeds[::5], 4).tolist()
    return record


def summarise_fd(records: list) -> dict:
    """Per set-up rows (mean over seeds per density) beside the experiment, and for the single file the headway
    fit over all samples: ``{"corridor": [...], "single_file": [...], "single_file_fit": (a, b, k)}``."""
    out = {}
    for setup, table in (("corridor", juelich_corridor()), ("single_file", single_file())):
        rows = []
        for d in sorted({r["density"] for r in records if r["setup"] == setup}):
            rs = [r for r in records if r["setup"] == setup and r["density"] == d]
            rho = float(np.mean([r["density_measured"] for r in rs]))
            v = np.array([r["speed_m_s"] for r in rs])
            ref = float(table.speed_at(d))  # the bin's own speed when d is a bin (the defaults are)
            rows.append({"density": rho, "nominal_density": d, "speed_m_s": float(v.mean()), "speed_sd_m_s": float(v.std(ddof=1)) if
                         v.size > 1 else float("nan"), "flow": rho * float(v.mean()), "seeds": len(rs),
                         "experiment_speed_m_s": ref, "difference_m_s": float(v.mean()) - ref,
                         "min_gap_m": float(min(r["min_gap_m"] for r in rs))})
        out[setup] = rows
    sf = [r for r in records if r["setup"] == "single_file"]
    if sf:
        out["single_file_fit"] = headway_fit(np.concatenate([r["headway_samples_m"] for r in sf]),
                                             np.concatenate([r["speed_samples_m_s"] for r in sf]))
    return out


# The candidates table (docs/validation/fundamental_diagram.md): the door and the corridor of a parameter point.
CANDIDATE_WIDTHS_M = (0.8, 1.0, 1.2)
CANDIDATE_DOOR_SEEDS = (0, 1)
CANDIDATE_DENSITIES = (0.628, 1.147, 1.629, 2.105, 2.616, 3.101)  # Jülich bins across the diagram


def door_and_corridor(params: ModelParams, *, navigation_clearance_m: float, widths_m=CANDIDATE_WIDTHS_M,
                      door_seeds=CANDIDATE_DOOR_SEEDS, densities=CANDIDATE_DENSITIES, corridor_seeds=(0,),
                      n_pedestrians: int = 60, door_max_time_s: float = 120.0, corridor_max_time_s: float = 25.0,
                      corridor_transient_s: float = 10.0) -> dict:
    """One row of the candidates table: Seyfried's bottleneck (N = ``n_pedestrians`` at ``widths_m``, mean over
    ``door_seeds`` of J_s, density in front and inside, speed inside, complete runs) and the periodic corridor's
    mean speed at ``densities`` beside the Jülich bins, with the largest miss. A point with an incomplete door run
    has nan J_s at that width (never a partial flow)."""
    config = bottleneck_config(params, navigation_clearance_m=navigation_clearance_m, max_time_s=door_max_time_s)
    door = {}
    for b in widths_m:
        recs = [run_one(dict(config, width_m=float(b), n_pedestrians=int(n_pedestrians), seed=int(s)))
                for s in door_seeds]
        complete = [r for r in recs if r["complete"]]

        def mean(key, rs=complete):
            v = [r[key] for r in rs if np.isfinite(r[key])]
            return float(np.mean(v)) if v else float("nan")

        door[float(b)] = {"specific_flow_per_m_s": mean("specific_flow_per_m_s") if len(complete) == len(recs)
                          else float("nan"), "density_front_per_m2": mean("density_front_per_m2", recs),
                          "density_inside_per_m2": mean("density_inside_per_m2", recs),
                          "speed_inside_m_s": mean("speed_inside_m_s", recs), "complete": len(complete),
                          "runs": len(recs)}
    tasks = fd_tasks(["corridor"], {"corridor": densities}, corridor_seeds, params, max_time_s=corridor_max_time_s,
                     transient_s=corridor_transient_s)
    records = [run_fd_one(t) for t in tasks]
    ref = juelich_corridor()
    corridor = {}
    for d in densities:
        v = float(np.mean([r["speed_m_s"] for r in records if r["density"] == float(d)]))
        corridor[float(d)] = {"speed_m_s": v, "experiment_speed_m_s": float(ref.speed_at(d))}
    miss = max(abs(c["speed_m_s"] - c["experiment_speed_m_s"]) for c in corridor.values())
    return {"door": door, "corridor": corridor, "corridor_max_miss_m_s": float(miss)}
