"""One point of the fundamental diagram in the periodic corridor: a run of the calibrated crowd at a fixed global
density, measured after its transient (:mod:`crowd_env.scenarios.periodic_corridor`,
:mod:`crowd_env.analysis.periodic`).

The run is :func:`~crowd_env.experiments.running.recording.record_run` (the compiled rollout of
:func:`~crowd_env.experiments.running.runner.run_scenario`, no exits, no stall rule, to ``max_time_s``) recording
frames at ``frame_rate_per_s``; the point is :func:`~crowd_env.analysis.periodic.periodic_corridor_point`
over [``transient_s``, ``max_time_s``].
"""
from __future__ import annotations

import dataclasses

from crowd_env.errors import InputError

from ...analysis.periodic import PeriodicCorridorPoint, periodic_corridor_point, trajectory_frames
from ...core.checks import check_number
from ...core.params import PedestrianDefaults
from ...scenarios import make_scenario
from ...walking.agent import SocialForceAgent
from ..running.recording import record_run

__all__ = ["fundamental_diagram_point"]


def fundamental_diagram_point(density_per_m2: float, *, length_m: float = 20.0, width_m: float = 1.8,
                              westbound_fraction: float = 0.0, seed: int = 0, radius_m: float = 0.23,
                              max_time_s: float = 30.0, transient_s: float = 10.0, params=None,
                              frame_rate_per_s: float = 10.0, pedestrian: dict | None = None, driver=None) -> tuple:
    """ρ, v and J_s of the periodic corridor ``length_m`` x ``width_m`` at ``density_per_m2`` (options of the
    scenario ``periodic_corridor``), walked for ``max_time_s`` with ``params`` (default: the default preset)
    and measured after ``transient_s``; ``pedestrian``: overrides of :class:`~crowd_env.core.params.PedestrianDefaults`
    (τ, desired-speed mean/std) to draw the state with, from the same seed (as a calibration task's);
    ``driver(scenario) -> policy(sim)``: who walks (default: the calibrated agent). Returns
    ``(PeriodicCorridorPoint, RunResult, Trajectories)``, the trajectories as recorded (x wrapped;
    :func:`~crowd_env.analysis.periodic.unwrap_trajectories` for PedPy)."""
    max_time_s = check_number("max_time_s", max_time_s, error=InputError, positive=True)
    transient_s = check_number("transient_s", transient_s, error=InputError, minimum=0.0)
    if transient_s >= max_time_s:
        raise InputError(f"transient_s = {transient_s:g} s must end before max_time_s = {max_time_s:g} s")
    scenario = make_scenario("periodic_corridor", length_m=length_m, width_m=width_m, density_per_m2=density_per_m2,
                             westbound_fraction=westbound_fraction, seed=seed, radius_m=radius_m)
    state = None if not pedestrian else scenario.make_state(
        defaults=dataclasses.replace(PedestrianDefaults(), **pedestrian))
    policy = SocialForceAgent(scenario.navigation()) if driver is None else driver(scenario)
    result, traj = record_run(scenario, policy, params, state=state,
                              frame_rate_per_s=frame_rate_per_s, max_time_s=max_time_s, line=None, density_areas=(),
                              lane_area=None)
    time_s, position, _ = trajectory_frames(traj)
    point: PeriodicCorridorPoint = periodic_corridor_point(
        time_s, position, period_m=scenario.geometry.period_x_m, width_m=width_m,
        direction_x=scenario.metadata["direction_x"], window_s=(transient_s, max_time_s))
    return point, result, traj
