"""Calibration runs (A, B, ..., b, N, seed) in the bottleneck task format (Kabalan et al. 2016, Section 4.1.2).

A calibration task is a task of :func:`crowd_env.experiments.bottleneck.run_one` (``width_m``,
``n_pedestrians``, ``seed``, ``geometry``, ``params``, ``max_time_s``) plus ``pedestrian``: overrides of
:class:`~crowd_env.core.params.PedestrianDefaults` (τ, desired-speed mean/std), empty by default. Every
task runs through ``run_one`` itself, so calibration numbers are those of the reproduction. The runs of
one calibration folder share :func:`base_config` and differ in their parameters: they are stored with
``RunStore(out, config, keyed_by="task")`` (:mod:`crowd_env.experiments.store`).
"""
from __future__ import annotations

from ...analysis.calibration import CalibrationError
from ...core.params import ModelParams, ParameterError
from ..bottleneck import params_dict

__all__ = ["PEDESTRIAN_FIELDS", "SIGNIFICANT_DIGITS", "canonical", "check_pedestrian", "base_config", "make_task"]

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


def base_config(geometry: dict, params: ModelParams, max_time_s: float) -> dict:
    """The fixed part of a calibration (geometry, base model parameters, time limit): one per folder."""
    return {"kind": "calibration", "geometry": dict(geometry), "params": params_dict(params),
            "max_time_s": float(max_time_s)}


def make_task(config: dict, model: dict, pedestrian: dict, width_m: float, n_pedestrians: int, seed: int) -> dict:
    """One run: ``config`` with the ModelParams overrides ``model`` and PedestrianDefaults overrides ``pedestrian``."""
    changes = {k: canonical(v) for k, v in model.items()}
    try:
        params = ModelParams.from_dict(config["params"]).replace(**changes)
    except ParameterError as exc:
        raise CalibrationError(str(exc)) from None
    return {"width_m": float(width_m), "n_pedestrians": int(n_pedestrians), "seed": int(seed),
            "geometry": config["geometry"], "params": params_dict(params), "max_time_s": config["max_time_s"],
            "pedestrian": check_pedestrian(pedestrian)}
