"""Compiled rollouts: many steps of the calibrated crowd in one compiled call, measured as the runner measures.

When every pedestrian follows the calibrated agent (:class:`~crowd_env.walking.agent.SocialForceAgent`:
the reproduction, the calibration, the benchmarks), a step needs no Python: :func:`rollout_steps` loops,
in compiled code, over

1. the agent's decision (:func:`~crowd_env.walking.agent.decide`: e_d from the eikonal field,
   Eq. 11-13, and the social forces, Eq. 16);
2. the model's step, :func:`~crowd_env.core.step.advance_named` (the inputs' bounds, the hand links, the fused
   step of Eq. 1-10, 14-15, 17-21, the exit test and the clock): the body of the very kernel
   :meth:`~crowd_env.core.Simulator.step` runs (:func:`~crowd_env.core.step.advance`), inlined;
3. the runner's measurement of the step (:func:`measure_step`: first passages of the measurement line
   with interpolated times, densities and mean speeds in the measurement areas, lateral positions in
   the channel, the smallest gap, trajectory frames at the requested rate, and the stall rule of
   :class:`~crowd_env.experiments.running.runner.StallDetector`).

It returns to Python when the steps asked for are done, when nobody is left, when the crowd stalled, or
when the next step needs the Python path (``ROLLOUT_PYTHON_STEP``: an impact cluster or projection
beyond the dense solvers, or an input the Python path must reject with its error: not finite, or an
intent beyond :data:`~crowd_env.core.step.MAX_INPUT_SPEED_M_S`); the
runner then runs that one step through ``policy(sim)`` and ``Simulator.step`` (the staged path and the
solver cascade) and :func:`measure_step`, and goes on compiled. Both paths call the same kernels in the
same order, so a run is the same to the last bit either way (``tests/experiments/running/test_rollout.py``,
with jams that hand steps to the staged path mid-run).
"""
from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np

from ...analysis.flow import crossing_alpha
from ...core.periodic import minimum_image_dx
from ...core.polygons import point_in_interior
from ...core.bundles import Bodies, StepInputs, StepParams, World
from ...core.step import FUSED_OK, active_rows, advance_named
from ...walking.agent import AGENT_OK, decide

# Steps per compiled call at most (the runner calls ``progress`` between calls).
ROLLOUT_CHUNK_STEPS = 2000

ROLLOUT_LIMIT = 0  # the steps asked for are done
ROLLOUT_EMPTY = 1  # nobody is left
ROLLOUT_STALLED = 2  # the stall rule fired
ROLLOUT_PYTHON_STEP = 3  # the next step needs the Python path (nothing of it was done)

class Measures(NamedTuple):
    """The arrays :func:`measure_step` fills (in place) and what it measures with; built by the runner
    (``_RunMeasures.bundle``). ``line``: (a, t, normal) of :class:`~crowd_env.analysis.flow.MeasurementLine`;
    ``areas``: the packed polygons' arrays (:class:`~crowd_env.core.polygons.PackedPolygons`)."""

    line: tuple
    has_line: bool
    passed: np.ndarray  # (N,) bool: crossed the line
    cross_ids: np.ndarray  # (N,) int64 in order of passage
    cross_times: np.ndarray  # (N,) s
    areas: tuple
    area_size_m2: np.ndarray  # (A,)
    lane_area: int  # the area whose lateral positions are kept, -1: none
    density: np.ndarray  # (steps, A) 1/m²
    speed: np.ndarray  # (steps, A) m/s
    lateral: np.ndarray  # lateral positions y (m)
    record_every: int  # a frame every so many steps (0: none)
    frame_time_s: np.ndarray
    frame_position: np.ndarray  # (F, N, 2)
    frame_heading: np.ndarray  # (F, N)
    frame_active: np.ndarray  # (F, N)
    counts: np.ndarray  # COUNT_* slots
    scalars: np.ndarray  # SCALAR_* slots


class StallRule(NamedTuple):
    """The stall rule's ring of position snapshots and its ``STALL_*`` state, with its settings
    (:class:`~crowd_env.experiments.running.runner.StallDetector`; ``window_steps`` 0: off). ``snapshots`` (K, N, 2)
    holds the positions every ``snapshot_every`` steps, ``snapshot_time_s`` (K,) their times (nan: empty slot)."""

    snapshots: np.ndarray
    snapshot_time_s: np.ndarray
    state: np.ndarray
    window_steps: int
    snapshot_every: int
    window_s: float
    speed_m_s: float


# Slots of the stall rule's state array (StallDetector.state): steps seen, snapshots taken, the last passage or
# exit, stalled (0/1) and when.
STALL_STEPS, STALL_SNAPSHOTS, STALL_LAST_PROGRESS_S, STALL_STALLED, STALL_TIME_S = range(5)
# Slots of the run's counters (RunMeasures.counts) and scalars (RunMeasures.scalars).
COUNT_PASSED, COUNT_STEPS, COUNT_LATERAL, COUNT_FRAMES = range(4)
SCALAR_MIN_GAP_M, SCALAR_LAST_EXIT_S = range(2)


@nb.njit(cache=True, inline="always")
def _in_box(x, y, k, boxes):
    """The point lies in the open bounding box of polygon k (the cheap test before the exact one)."""
    return boxes[k, 0] < x < boxes[k, 2] and boxes[k, 1] < y < boxes[k, 3]


@nb.njit(cache=True)
def mean_displacement_of(position, snapshot, mask):
    """Mean distance between ``position`` and ``snapshot`` (N, 2) over the pedestrians flagged in ``mask`` (N,);
    nan when none is."""
    total = 0.0
    count = 0
    for i in range(mask.shape[0]):
        if mask[i]:
            total += np.sqrt((position[i, 0] - snapshot[i, 0]) ** 2 + (position[i, 1] - snapshot[i, 1]) ** 2)
            count += 1
    return total / count if count else np.nan


@nb.njit(cache=True)
def stall_update(stall, dt_s, time_s, position, remaining, progressed):
    """One step of the stall rule (:class:`~crowd_env.experiments.running.runner.StallDetector`), in place on the
    :class:`StallRule` ``stall``'s snapshots and its ``STALL_*`` state: every ``snapshot_every`` steps the positions
    go into the ring; once nobody has passed or left for ``window_s``, the run is stalled when the remaining
    pedestrians' mean net displacement since the newest snapshot at least ``window_s`` old is below ``speed_m_s``
    times its age (their mean net speed, whatever they jitter). Returns whether the run is stalled (from then on)."""
    state = stall.state
    if state[STALL_STALLED] != 0.0 or stall.window_steps == 0:
        return state[STALL_STALLED] != 0.0
    steps = int(state[STALL_STEPS])
    if steps % stall.snapshot_every == 0:
        slot = int(state[STALL_SNAPSHOTS]) % stall.snapshots.shape[0]
        stall.snapshots[slot, :, :] = position
        stall.snapshot_time_s[slot] = time_s
        state[STALL_SNAPSHOTS] += 1.0
    state[STALL_STEPS] = steps + 1
    anyone = False
    for i in range(remaining.shape[0]):
        if remaining[i]:
            anyone = True
            break
    if progressed or not anyone:
        state[STALL_LAST_PROGRESS_S] = time_s
        return False
    if time_s - state[STALL_LAST_PROGRESS_S] < stall.window_s - 0.5 * dt_s:
        return False
    best = -1
    for k in range(stall.snapshot_time_s.shape[0]):  # the newest snapshot at least a window old
        t = stall.snapshot_time_s[k]
        if t <= time_s - stall.window_s + 0.5 * dt_s and (best < 0 or t > stall.snapshot_time_s[best]):
            best = k
    if best < 0:
        return False
    age = time_s - stall.snapshot_time_s[best]
    if mean_displacement_of(position, stall.snapshots[best], remaining) < stall.speed_m_s * age:
        state[STALL_STALLED] = 1.0
        state[STALL_TIME_S] = time_s
    return state[STALL_STALLED] != 0.0


@nb.njit(cache=True)
def measure_step(bodies, index, previous, n_exited, t_prev_s, time_s, step_count, step_min_gap_m, dt_s, period_m,
                 measures, stall):
    """The runner's measurement of one step of ``dt_s`` that moved the pedestrians ``index`` (active before it) of
    ``bodies`` (:class:`~crowd_env.core.bundles.Bodies`) from ``previous`` (compact) to their positions, from
    ``t_prev_s`` to ``time_s`` (with ``period_m`` L > 0 the move is the nearest image of the displacement, so a step
    across the seam crosses no line between). In place on the :class:`Measures` ``measures``:

    - first passages of the measurement line (time interpolated within the step, Eq. 22) into
      ``passed``, ``cross_ids``, ``cross_times``;
    - per area of the packed polygons ``areas`` (all but a separate lane area): density (count / area)
      and mean speed of the active pedestrians in its open interior, row ``counts[COUNT_STEPS]`` of
      ``density``/``speed``; the lateral positions y inside area ``lane_area`` (−1: none) into ``lateral``;
    - the smallest gap, the time of the last exit; every ``record_every``-th step (0: never) a frame;
    - the stall rule (:func:`stall_update` on ``stall``). Returns whether the run is stalled.
    """
    position, velocity, active = bodies.position_m, bodies.velocity_m_s, bodies.active
    m = measures
    counts, scalars, passed = m.counts, m.scalars, m.passed
    progressed = n_exited > 0
    if progressed:
        scalars[SCALAR_LAST_EXIT_S] = time_s
    if m.has_line:
        a, t, normal = m.line
        for k in range(index.shape[0]):
            i = index[k]
            x1 = position[i, 0]
            if period_m > 0.0:
                x1 = previous[k, 0] + minimum_image_dx(x1 - previous[k, 0], period_m)
            alpha = crossing_alpha(previous[k, 0], previous[k, 1], x1, position[i, 1], a, t, normal)
            if not np.isnan(alpha) and not passed[i]:
                passed[i] = True
                m.cross_ids[counts[COUNT_PASSED]] = i
                m.cross_times[counts[COUNT_PASSED]] = t_prev_s + alpha * (time_s - t_prev_s)
                counts[COUNT_PASSED] += 1
                progressed = True
    vertices, ring_start, ring_owner, boxes = m.areas
    row = counts[COUNT_STEPS]
    for area in range(m.density.shape[1]):
        count = 0
        total = 0.0
        for i in range(active.shape[0]):
            if active[i] and _in_box(position[i, 0], position[i, 1], area, boxes) and \
                    point_in_interior(position[i, 0], position[i, 1], area, vertices, ring_start, ring_owner, boxes):
                count += 1
                total += np.sqrt(velocity[i, 0] ** 2 + velocity[i, 1] ** 2)
        m.density[row, area] = count / m.area_size_m2[area]
        m.speed[row, area] = total / count if count else np.nan
    lane_area = m.lane_area
    if lane_area >= 0:
        for i in range(active.shape[0]):
            if active[i] and _in_box(position[i, 0], position[i, 1], lane_area, boxes) and \
                    point_in_interior(position[i, 0], position[i, 1], lane_area, vertices, ring_start, ring_owner, boxes):
                m.lateral[counts[COUNT_LATERAL]] = position[i, 1]
                counts[COUNT_LATERAL] += 1
    counts[COUNT_STEPS] += 1
    scalars[SCALAR_MIN_GAP_M] = min(scalars[SCALAR_MIN_GAP_M], step_min_gap_m)
    if m.record_every > 0 and step_count % m.record_every == 0:
        f = counts[COUNT_FRAMES]
        m.frame_time_s[f] = step_count * dt_s
        frame_position, frame_heading, frame_active, heading = m.frame_position, m.frame_heading, m.frame_active, \
            bodies.heading_rad
        for i in range(active.shape[0]):
            frame_position[f, i, 0] = position[i, 0]
            frame_position[f, i, 1] = position[i, 1]
            frame_heading[f, i] = heading[i]
            frame_active[f, i] = active[i]
        counts[COUNT_FRAMES] += 1
    remaining = np.empty_like(active)  # those left who have started to walk (a waiting crowd is no stall)
    premovement_s = bodies.premovement_s
    for i in range(active.shape[0]):
        remaining[i] = active[i] and not passed[i] and time_s >= premovement_s[i]
    return stall_update(stall, dt_s, time_s, position, remaining, progressed)


@nb.njit(cache=True)
def rollout_steps(max_steps, time_s, step_count, bodies, world, params, agent, measures, stall):
    """Up to ``max_steps`` steps of the calibrated crowd from ``time_s`` (step ``step_count``), each the agent's
    decision (:func:`~crowd_env.walking.agent.decide` of the :class:`~crowd_env.walking.agent.CompiledAgent`
    ``agent``), the core's step (:func:`~crowd_env.core.step.advance_named` on the bundles ``bodies``, ``world``,
    ``params`` of :mod:`crowd_env.core.bundles`) and :func:`measure_step` (module docstring). Returns
    ``(status, steps done, clock, re-detection rounds)``; the state arrays in ``bodies`` and the measurements
    are updated in place. ``bodies``, ``world``, ``params`` come as :func:`~crowd_env.core.step.advance` takes them,
    plain tuples of the bundles' fields."""
    no_force = np.zeros((0, 2))
    named_bodies, named_world, named_params = Bodies(*bodies), World(*world), StepParams(*params)
    done = 0
    n_redetect = 0
    while done < max_steps:
        index = active_rows(named_bodies.active)
        if index.shape[0] == 0:
            return ROLLOUT_EMPTY, done, time_s, n_redetect
        decision = decide(agent, named_bodies, named_world, index, time_s)
        if decision.status != AGENT_OK:
            return ROLLOUT_PYTHON_STEP, done, time_s, n_redetect
        inputs = StepInputs(decision.intents_m_s, decision.desired_heading_rad, True, no_force, False)
        outcome = advance_named(named_bodies, named_world, named_params, inputs, index, decision.pairs,
                                decision.pair_radius_m, time_s)
        step = outcome.figures
        if step.status != FUSED_OK:
            return ROLLOUT_PYTHON_STEP, done, time_s, n_redetect
        n_redetect += step.n_redetections
        t_prev = time_s
        time_s = outcome.time_s
        step_count += 1
        done += 1
        if measure_step(named_bodies, index, outcome.previous_m, outcome.exited.shape[0], t_prev, time_s, step_count,
                        step.min_gap_m, named_params.dt_s, named_world.period_m, measures, stall):
            return ROLLOUT_STALLED, done, time_s, n_redetect
    return ROLLOUT_LIMIT, done, time_s, n_redetect
