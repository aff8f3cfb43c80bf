"""A run of the runner that also records trajectories, for PedPy and the figures (Kabalan et al. 2016, Section 4).

:func:`record_run` is :func:`~crowd_env.experiments.running.runner.run_scenario` with a
:class:`~crowd_env.analysis.recorder.TrajectoryRecorder` reading the state every k-th step of h; the
measurement side (formats, export, PedPy) is :mod:`crowd_env.analysis.trajectories`.
"""
from __future__ import annotations

import numpy as np

from ...analysis.recorder import ResampledRecorder, TrajectoryRecorder
from ...analysis.trajectories import (DEFAULT_FRAME_RATE_PER_S, Trajectories, TrajectoryFormatError, export_run,
                                      steps_per_frame)
from ...walking.presets import DEFAULT_PRESET, get_preset
from ...scenarios import make_scenario
from ...walking.agent import SocialForceAgent
from .runner import run_scenario

__all__ = ["record_run", "record_bottleneck_run"]


def record_run(scenario, policy, params=None, *, frame_rate_per_s: float = DEFAULT_FRAME_RATE_PER_S, **run_kwargs):
    """:func:`~crowd_env.experiments.running.runner.run_scenario` that also records trajectories at ``frame_rate_per_s``.

    Frame 0 is the start; frame f is at t = f / ``frame_rate_per_s``. When a frame lasts a whole number k of
    steps h (k = 1/(fps h), see :func:`~crowd_env.analysis.trajectories.steps_per_frame`) every k-th step is
    recorded; otherwise (16 frames/s, as the Jülich recordings, from h = 0.01 s) every step is read and the frames
    are interpolated between the two steps around them (:class:`~crowd_env.analysis.recorder.ResampledRecorder`).
    Only pedestrians still inside are recorded. The run itself is unchanged (recording only reads the state).
    ``run_kwargs`` go to ``run_scenario`` (``state``, ``rng`` and ``progress`` are honoured). Returns
    ``(RunResult, Trajectories)``.
    """
    params = get_preset(DEFAULT_PRESET).params() if params is None else params
    try:
        every = steps_per_frame(frame_rate_per_s, params.dt_s)
        recorder = TrajectoryRecorder(only_active=True)
        fps = 1.0 / (every * params.dt_s)
    except TrajectoryFormatError:  # not a whole number of steps a frame: interpolate between steps
        every = 1
        recorder = ResampledRecorder(frame_rate_per_s, only_active=True)
        fps = recorder.frame_rate_per_s
    state = run_kwargs.pop("state", None)
    rng = run_kwargs.pop("rng", None)
    state = scenario.make_state(rng=rng) if state is None else state
    recorder.record(0.0, state.position_m, state.heading_rad, state.active, np.arange(state.n))
    result = run_scenario(scenario, policy, params, state=state, recorder=recorder, record_every=every, **run_kwargs)
    return result, Trajectories.from_recorder(recorder, frame_rate_per_s=fps)


def record_bottleneck_run(width_m: float, n_pedestrians: int, seed: int, stem, *,
                          frame_rate_per_s: float = DEFAULT_FRAME_RATE_PER_S, max_time_s: float = 300.0) -> tuple:
    """One Seyfried bottleneck run (default scenario options and preset) with the calibrated agent, recorded
    and exported in PedPy's text format to ``stem`` (:func:`~crowd_env.analysis.trajectories.export_run`).
    Returns ``(RunResult, Trajectories, Geometry, paths written)``."""
    scenario = make_scenario("seyfried_bottleneck", width_m=width_m, n_pedestrians=n_pedestrians, seed=seed)
    result, traj = record_run(scenario, SocialForceAgent(scenario.navigation()), frame_rate_per_s=frame_rate_per_s,
                              max_time_s=max_time_s)
    paths = export_run(stem, traj, scenario.geometry,
                       comments=[f"crowd_env seyfried_bottleneck run: b = {width_m:g} m, N = {n_pedestrians}, "
                                 f"seed {seed}"],
                       metadata={"width_m": width_m, "n_pedestrians": n_pedestrians, "seed": seed,
                                 "frame_rate_per_s": traj.frame_rate_per_s, "measurement_line": "bottleneck"})
    return result, traj, scenario.geometry, paths
