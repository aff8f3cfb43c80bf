"""What every RiMEA set-up shares: :func:`rimea_scenario` and the body radius.

Each test's set-up is an ordinary :class:`~crowd_env.scenarios.Scenario` built with the public API
(:func:`~crowd_env.scenarios.scenario_from_polygon`, per-pedestrian parameters such as
``desired_speed_m_s`` and ``premovement_s``, destinations), registered under ``rimea_<test>_<name>`` so
that users can run, train on or modify it like any other scenario. Dimensions follow RiMEA 4.1.1 where its
text gives them and JuPedSim's transcription of its figures otherwise (docs/validation/rimea.md lists the
sources test by test). ``quick`` options give the reduced versions of the default test suite.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..scenario import Scenario
from ..polygon import scenario_from_polygon

__all__ = ["rimea_scenario", "RIMEA_RADIUS_M"]

RIMEA_RADIUS_M = 0.23  # the preset's body radius (PedestrianDefaults), used in every test


def rimea_scenario(name: str, walkable_area, exits, spawn_area, n_pedestrians: int, *, seed: int = 0,
                   position_m=None, desired_speed_m_s=None, premovement_s=None, destination=None, exit_names=None,
                   measurement_lines=None, radius_m: float = RIMEA_RADIUS_M, heading_rad=None,
                   route_choice: str | None = None, metadata: dict | None = None) -> Scenario:
    """A RiMEA set-up: :func:`~crowd_env.scenarios.scenario_from_polygon` (walkable area, exits, pedestrians
    placed in ``spawn_area``, or at ``position_m`` when given) plus the per-pedestrian values a test
    prescribes: ``desired_speed_m_s`` and ``premovement_s`` (scalars or (N,) arrays; None: the preset's
    desired-speed distribution, resp. no premovement), ``destination`` and ``route_choice``."""
    base = scenario_from_polygon(walkable_area, exits, spawn_area, n_pedestrians, seed=seed, radius_m=radius_m,
                                 exit_names=exit_names, measurement_lines=measurement_lines, name=name)
    params = dict(base.pedestrian_params)
    if desired_speed_m_s is not None:
        params["desired_speed_m_s"] = desired_speed_m_s
    if premovement_s is not None:
        params["premovement_s"] = premovement_s
    position = base.position_m if position_m is None else np.asarray(position_m, dtype=np.float64)
    meta = {**base.metadata, **(metadata or {})}
    return replace(base, position_m=position, pedestrian_params=params, destination=destination,
                   heading_rad=heading_rad, route_choice=route_choice, metadata=meta)
