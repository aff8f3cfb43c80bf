"""Calibration runs (A, B, ..., b, N, seed) in the bottleneck task format (Kabalan et al. 2016, Section 4.1.2).

A calibration task is a task of :func:`crowd_env.experiments.validation.bottleneck.run_one` (``width_m``,
``n_pedestrians``, ``seed``, ``geometry``, ``params``, ``max_time_s``) plus ``pedestrian``: overrides of
:class:`~crowd_env.core.params.PedestrianDefaults` (τ, desired-speed mean/std), empty by default. Every
task runs through ``run_one`` itself, so calibration numbers are those of the reproduction. The runs of
one calibration folder share :func:`base_config` and differ in their parameters: they are stored with
``RunStore(out, config, keyed_by="task")`` (:mod:`crowd_env.experiments.running.store`).

With the fundamental diagram in the objective (``--objective targets+fd``) a point also has the runs of the
density sweep (:func:`make_fd_tasks`: :func:`crowd_env.experiments.validation.fundamental_diagram.fd_tasks` of both set-ups
at the densities and seeds of an :class:`FDPlan`, the same for every point, with the point's model and
pedestrian parameters), in the same folder and on the same executor; :func:`run_calibration_task` runs either
kind (a task with a ``setup`` key is a sweep run).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from .errors import CalibrationError
from .objective import DENSITY_MATCH, corridor_fd_bins, single_file_bins
from ....core.params import ParameterError, PedestrianDefaults
from ....walking.model import ModelParams
from ..bottleneck import params_dict, run_one
from ..corridor_runs import corridor_tasks, run_corridor_one
from ..fundamental_diagram import CORRIDOR_DENSITIES, SETUPS, SINGLE_FILE_DENSITIES, fd_tasks, run_fd_one

__all__ = ["PEDESTRIAN_FIELDS", "body_clearance_m", "SIGNIFICANT_DIGITS", "canonical", "check_pedestrian", "base_config", "make_task",
           "FDPlan", "make_fd_tasks", "run_calibration_task", "with_body", "make_virtual_tasks"]

# PedestrianDefaults fields a calibration may vary (per-pedestrian, drawn/set in Scenario.make_state).
PEDESTRIAN_FIELDS = ("tau_s", "desired_speed_mean_m_s", "desired_speed_std_m_s")
SIGNIFICANT_DIGITS = 6  # parameter values are rounded to this before running (stable cache keys)


def canonical(value: float) -> float:
    """``value`` rounded to :data:`SIGNIFICANT_DIGITS` significant digits (the value actually simulated)."""
    return float(f"{float(value):.{SIGNIFICANT_DIGITS}g}")


def check_pedestrian(pedestrian: dict) -> dict:
    """Validated per-pedestrian overrides (names in :data:`PEDESTRIAN_FIELDS`, values finite and > 0)."""
    unknown = sorted(set(pedestrian) - set(PEDESTRIAN_FIELDS))
    if unknown:
        raise CalibrationError(f"unknown pedestrian parameter(s) {unknown}; calibratable: {list(PEDESTRIAN_FIELDS)}")
    out = {}
    for name, value in sorted(pedestrian.items()):
        v = float(value)
        if not (v > 0 and v < float("inf")):
            raise CalibrationError(f"{name} must be finite and > 0, got {value!r}")
        out[name] = canonical(v)
    return out


def base_config(geometry: dict, params: ModelParams, max_time_s: float, *,
                corridor_geometry: dict | None = None) -> dict:
    """The fixed part of a calibration (geometry, base model parameters, time limit): one per folder.
    ``corridor_geometry``: options of every Jülich corridor run (``--objective virtual``) beyond the body and the
    wall slowdown, which follow the bottleneck's (:func:`corridor_run_options`); an explicit navigation clearance is
    one. Left out when empty, so that earlier folders keep their configuration."""
    config = {"kind": "calibration", "geometry": dict(geometry), "params": params_dict(params),
              "max_time_s": float(max_time_s)}
    if corridor_geometry:
        config["corridor_geometry"] = dict(corridor_geometry)
    return config


def _point_params(config: dict, model: dict) -> ModelParams:
    """``config``'s model parameters with the overrides ``model`` (values rounded by :func:`canonical`)."""
    changes = {k: canonical(v) for k, v in model.items()}
    try:
        return ModelParams.from_dict(config["params"]).replace(**changes)
    except ParameterError as exc:
        raise CalibrationError(str(exc)) from None


def make_task(config: dict, model: dict, pedestrian: dict, width_m: float, n_pedestrians: int, seed: int) -> dict:
    """One run: ``config`` with the ModelParams overrides ``model`` and PedestrianDefaults overrides ``pedestrian``."""
    params = _point_params(config, model)
    return {"width_m": float(width_m), "n_pedestrians": int(n_pedestrians), "seed": int(seed),
            "geometry": config["geometry"], "params": params_dict(params), "max_time_s": config["max_time_s"],
            "pedestrian": check_pedestrian(pedestrian)}


@dataclass(frozen=True)
class FDPlan:
    """The fundamental-diagram runs of every calibration point: the corridor (1/m²) and single-file (1/m)
    densities, each a shipped bin the objective scores (default: all of them,
    :data:`~crowd_env.experiments.validation.fundamental_diagram.CORRIDOR_DENSITIES` and ``SINGLE_FILE_DENSITIES``), the
    seeds (the same at every point: common random numbers), and the periodic strip's length, simulated time and
    transient left out (the sweep's defaults, :func:`~crowd_env.experiments.validation.fundamental_diagram.fd_tasks`)."""

    seeds: tuple = (0,)
    corridor_densities: tuple = CORRIDOR_DENSITIES
    single_file_densities: tuple = SINGLE_FILE_DENSITIES
    length_m: float = 20.0
    max_time_s: float = 40.0
    transient_s: float = 15.0

    def __post_init__(self) -> None:
        seeds = tuple(int(x) for x in self.seeds)
        if not seeds or any(x < 0 for x in seeds) or len(set(seeds)) != len(seeds):
            raise CalibrationError(f"fundamental-diagram seeds must be distinct integers >= 0, at least one, got "
                                   f"{list(self.seeds)}")
        object.__setattr__(self, "seeds", seeds)
        for name, bins, unit in (("corridor_densities", corridor_fd_bins(), "1/m²"),
                                 ("single_file_densities", single_file_bins(), "1/m")):
            values = tuple(float(x) for x in getattr(self, name))
            if not values or len(set(values)) != len(values):
                raise CalibrationError(f"{name} must be distinct and at least one, got {list(values)}")
            off = [x for x in values if not np.any(np.abs(bins[:, 0] - x) <= DENSITY_MATCH)]
            if off:
                raise CalibrationError(f"{name} {off} are no shipped bins the objective scores; choose among "
                                       f"{', '.join(f'{x:g}' for x in bins[:, 0])} ({unit})")
            object.__setattr__(self, name, values)
        for name in ("length_m", "max_time_s", "transient_s"):
            v = float(getattr(self, name))
            if not math.isfinite(v) or v < 0 or (v == 0 and name != "transient_s"):
                raise CalibrationError(f"{name} must be finite and {'>= 0' if name == 'transient_s' else '> 0'}, "
                                       f"got {getattr(self, name)!r}")
            object.__setattr__(self, name, v)
        if self.transient_s >= self.max_time_s:
            raise CalibrationError(f"the transient ({self.transient_s:g} s) must end before the fundamental-diagram "
                                   f"runs do ({self.max_time_s:g} s)")

    def as_dict(self) -> dict:
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}

    @property
    def n_runs(self) -> int:
        """Runs per parameter point."""
        return len(self.seeds) * (len(self.corridor_densities) + len(self.single_file_densities))


def make_fd_tasks(config: dict, model: dict, pedestrian: dict, plan: FDPlan) -> list:
    """The fundamental-diagram runs of one parameter point (tasks of
    :func:`~crowd_env.experiments.validation.fundamental_diagram.run_fd_one` with ``pedestrian``): ``config``'s model
    parameters with the overrides ``model``, every set-up, density and seed of ``plan``. The sweep's strips hold
    pedestrians of the default radius; a calibration on another radius is refused."""
    radius = float(config["geometry"].get("radius_m", PedestrianDefaults().radius_m))
    if abs(radius - PedestrianDefaults().radius_m) > 1e-12:
        raise CalibrationError(f"the fundamental-diagram runs are built for r = {PedestrianDefaults().radius_m:g} m "
                               f"(the single file's 0.7 m strip), not the configuration's {radius:g} m")
    tasks = fd_tasks(SETUPS, {"corridor": plan.corridor_densities, "single_file": plan.single_file_densities},
                     plan.seeds, _point_params(config, model), length_m=plan.length_m, max_time_s=plan.max_time_s,
                     transient_s=plan.transient_s)
    ped = check_pedestrian(pedestrian)
    return [dict(t, pedestrian=ped) for t in tasks]


def body_clearance_m(clearance_m: float, radius_m: float, new_radius_m: float) -> float:
    """The navigation clearance for a body of ``new_radius_m`` where the field had ``clearance_m`` for a body of
    ``radius_m``: the new radius where the field was that body's configuration space (clearance = radius), else the
    clearance as it was (a point field, clearance 0, stays one; a chosen clearance stays chosen)."""
    return float(new_radius_m) if abs(float(clearance_m) - float(radius_m)) < 1e-12 else float(clearance_m)


def with_body(task: dict, radius_m: float | None) -> dict:
    """A bottleneck task (:func:`make_task`) with the pedestrians' radius ``radius_m`` (None: unchanged): the
    geometry's ``radius_m``, and its navigation clearance with it where the field is the disk centres' (clearance
    = radius), as the presets' is; a point field (clearance 0) stays one."""
    if radius_m is None:
        return task
    geometry = dict(task["geometry"])
    old = float(geometry.get("radius_m", PedestrianDefaults().radius_m))
    geometry["navigation_clearance_m"] = body_clearance_m(geometry.get("navigation_clearance_m", old), old, radius_m)
    geometry["radius_m"] = float(radius_m)
    return dict(task, geometry=geometry)


def with_navigation(task: dict, wall_slowdown) -> dict:
    """A bottleneck task with the navigation field's wall slowdown ``(distance_m, speed_factor)`` (Eq. 11's V < 1
    within distance_m of a wall; None: the task's own)."""
    if wall_slowdown is None:
        return task
    return dict(task, geometry={**task["geometry"], "navigation_wall_slowdown": [float(v) for v in wall_slowdown]})


def corridor_run_options(config: dict, radius_m: float | None, wall_slowdown) -> dict:
    """The options of every corridor run of a point (:func:`make_virtual_tasks`): the configuration's
    ``corridor_geometry`` (:func:`base_config`), the body ``radius_m`` (None: the scenario's) and the wall slowdown
    ``wall_slowdown`` (None: the configuration's, if any). The corridor's field is the disk centres' of its body
    unless ``corridor_geometry`` sets a clearance, as in ``crowd-virtual-experiments``. Options left at the
    scenario's defaults stay out, so that stored runs keep their keys."""
    out = dict(config.get("corridor_geometry") or {})
    if radius_m is not None:
        out["radius_m"] = float(radius_m)
    if wall_slowdown is None:
        wall_slowdown = config["geometry"].get("navigation_wall_slowdown")
    if wall_slowdown is not None:
        out["navigation_wall_slowdown"] = [float(v) for v in wall_slowdown]
    return out


def make_virtual_tasks(config: dict, model: dict, pedestrian: dict, widths_m, seeds, *, radius_m: float | None = None,
                       navigation_wall_slowdown=None, single_file_densities=SINGLE_FILE_DENSITIES,
                       max_time_s: float | None = None) -> list:
    """The runs of one parameter point on every shipped experiment as it was run (the objective
    :func:`~crowd_env.experiments.validation.calibration.objective.virtual_error`): the bottleneck's
    :func:`~crowd_env.experiments.validation.calibration.objective.required_cases` at ``widths_m``, the nine Jülich
    corridor runs (:func:`~crowd_env.experiments.validation.corridor_runs.corridor_tasks`) and the single file at
    ``single_file_densities``, every one at ``seeds`` (common random numbers), with ``config``'s model and the
    overrides ``model`` (ModelParams fields), ``pedestrian`` (PedestrianDefaults fields), ``radius_m`` (the
    body; None: the configuration's) and ``navigation_wall_slowdown`` (``(distance_m, speed_factor)`` in the
    bottleneck's and every corridor run's field; None: the configuration's). The single-file ring has no walls."""
    from .objective import required_cases

    params = _point_params(config, model)
    ped = check_pedestrian(pedestrian)
    limit = float(config["max_time_s"] if max_time_s is None else max_time_s)
    if radius_m is None:  # the configuration's body (a preset's, e.g. joint's) in every experiment, not only its own
        own = config["geometry"].get("radius_m")
        radius_m = None if own is None or float(own) == PedestrianDefaults().radius_m else float(own)
    neck = [with_navigation(with_body(make_task(config, model, pedestrian, b, n, s), radius_m),
                            navigation_wall_slowdown) for b, n in required_cases(widths_m) for s in seeds]
    corridor = corridor_tasks(params, seeds=seeds, pedestrian=ped or None, max_time_s=limit,
                              geometry=corridor_run_options(config, radius_m, navigation_wall_slowdown))
    single = [dict(t, pedestrian=ped) for t in fd_tasks(["single_file"], {"single_file": single_file_densities}, seeds,
                                                       params, radius_m=radius_m)]
    return neck + corridor + single


def run_calibration_task(task: dict, run_fn=run_one, fd_run_fn=run_fd_one, corridor_run_fn=run_corridor_one) -> dict:
    """Run a calibration task of any kind: ``fd_run_fn`` for a fundamental-diagram run (a ``setup`` key),
    ``corridor_run_fn`` for a Jülich corridor run (``experiment`` = ``"corridor"``), ``run_fn`` for a bottleneck run
    (bind them with :func:`functools.partial` for an executor)."""
    if task.get("experiment") == "corridor":
        return corridor_run_fn(task)
    return fd_run_fn(task) if "setup" in task else run_fn(task)
