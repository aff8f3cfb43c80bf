"""Compiled rollouts: many steps of the calibrated crowd in one compiled call, measured as the runner measures.

When every pedestrian follows the calibrated agent (:class:`~crowd_env.walking.agent.SocialForceAgent`:
the reproduction, the calibration, the benchmarks), a step needs no Python: :func:`rollout_steps` loops,
in compiled code, over

1. the agent's decision (:func:`~crowd_env.walking.agent.agent_step`: e_d from the eikonal field,
   Eq. 11-13, and the social forces, Eq. 16);
2. the model's step (:func:`~crowd_env.core.step.fused_step`, Eq. 1-10, 14-15, 17-21) and the exit
   test (:func:`~crowd_env.core.step.leave_at_exits`), as :meth:`~crowd_env.core.Simulator.step` runs
   them;
3. the runner's measurement of the step (:func:`measure_step`: first passages of the measurement line
   with interpolated times, densities and mean speeds in the measurement areas, lateral positions in
   the channel, the smallest gap, trajectory frames at the requested rate, and the stall rule of
   :class:`~crowd_env.experiments.runner.StallDetector`).

It returns to Python when the steps asked for are done, when nobody is left, when the crowd stalled, or
when the next step needs the Python path (``ROLLOUT_PYTHON_STEP``: an impact cluster or projection
beyond the dense solvers, or an input the Python path must reject with its error: not finite, or an
intent beyond :data:`~crowd_env.core.step.MAX_INPUT_SPEED_M_S`); the
runner then runs that one step through ``policy(sim)`` and ``Simulator.step`` (the staged path and the
solver cascade) and :func:`measure_step`, and goes on compiled. Both paths call the same kernels in the
same order, so a run is the same to the last bit either way (``tests/experiments/test_rollout.py``,
with jams that hand steps to the staged path mid-run).
"""
from __future__ import annotations

import numba as nb
import numpy as np

from ..analysis.flow import crossing_alpha
from ..core.periodic import minimum_image_dx
from ..core.polygons import point_in_interior
from ..core.step import FUSED_OK, MAX_INPUT_SPEED_M_S, first_non_finite, first_out_of_bound, fused_step, leave_at_exits
from ..core.contacts import active_links
from ..walking.agent import AGENT_OK, agent_step

# Steps per compiled call at most (the runner calls ``progress`` between calls).
ROLLOUT_CHUNK_STEPS = 2000

ROLLOUT_LIMIT = 0  # the steps asked for are done
ROLLOUT_EMPTY = 1  # nobody is left
ROLLOUT_STALLED = 2  # the stall rule fired
ROLLOUT_PYTHON_STEP = 3  # the next step needs the Python path (nothing of it was done)

# Slots of the stall rule's state array (StallDetector.state).
STALL_N, STALL_SUM, STALL_LAST_PROGRESS_S, STALL_STALLED, STALL_TIME_S = range(5)
# Slots of the run's counters (RunMeasures.counts) and scalars (RunMeasures.scalars).
COUNT_PASSED, COUNT_STEPS, COUNT_LATERAL, COUNT_FRAMES = range(4)
SCALAR_MIN_GAP_M, SCALAR_LAST_EXIT_S = range(2)


@nb.njit(cache=True, inline="always")
def _in_box(x, y, k, boxes):
    """The point lies in the open bounding box of polygon k (the cheap test before the exact one)."""
    return boxes[k, 0] < x < boxes[k, 2] and boxes[k, 1] < y < boxes[k, 3]


@nb.njit(cache=True)
def mean_speed_of(velocity, mask):
    """Mean ‖u‖ over the pedestrians flagged in ``mask`` (N,); nan when none is."""
    total = 0.0
    count = 0
    for i in range(mask.shape[0]):
        if mask[i]:
            total += np.sqrt(velocity[i, 0] ** 2 + velocity[i, 1] ** 2)
            count += 1
    return total / count if count else np.nan


@nb.njit(cache=True)
def stall_update(ring, state, window_steps, window_s, speed_m_s, dt_s, time_s, velocity, remaining, progressed):
    """One step of the stall rule (:class:`~crowd_env.experiments.runner.StallDetector`), in place on its
    ``ring`` of per-step mean speeds and its ``state`` (``STALL_*`` slots). ``window_steps`` 0: rule off.
    Returns whether the run is stalled (from then on)."""
    if state[STALL_STALLED] != 0.0 or window_steps == 0:
        return state[STALL_STALLED] != 0.0
    anyone = False
    for i in range(remaining.shape[0]):
        if remaining[i]:
            anyone = True
            break
    if progressed or not anyone:
        state[STALL_LAST_PROGRESS_S] = time_s
        state[STALL_N] = 0.0
        state[STALL_SUM] = 0.0
        return False
    v = mean_speed_of(velocity, remaining)
    n = int(state[STALL_N])
    slot = n % window_steps
    if n >= window_steps:
        state[STALL_SUM] -= ring[slot]
    ring[slot] = v
    state[STALL_SUM] += v
    n += 1
    state[STALL_N] = n
    if n >= window_steps and time_s - state[STALL_LAST_PROGRESS_S] >= window_s - 0.5 * dt_s \
            and state[STALL_SUM] / window_steps < speed_m_s:
        state[STALL_STALLED] = 1.0
        state[STALL_TIME_S] = time_s
    return state[STALL_STALLED] != 0.0


@nb.njit(cache=True)
def measure_step(position, velocity, heading, active, premovement, index, previous, n_exited, t_prev_s, time_s, step_count,
                 step_min_gap_m, line, has_line, passed, cross_ids, cross_times, areas, area_size_m2, lane_area,
                 density, speed, lateral, record_every, frame_time_s, frame_position, frame_heading, frame_active,
                 stall_ring, stall_state, stall_window_steps, stall_window_s, stall_speed_m_s, dt_s, counts, scalars,
                 period_m=0.0):
    """The runner's measurement of one step that moved the pedestrians ``index`` (active before it) from
    ``previous`` (compact) to ``position``, from ``t_prev_s`` to ``time_s`` (with ``period_m`` L > 0 the move
    is the nearest image of the displacement, so a step across the seam crosses no line between). In place:

    - first passages of the measurement line (``line`` = (a, t, normal) of
      :class:`~crowd_env.analysis.flow.MeasurementLine`; time interpolated within the step, Eq. 22) into
      ``passed``, ``cross_ids``, ``cross_times``;
    - per area of the packed polygons ``areas`` (all but a separate lane area): density (count / area)
      and mean speed of the active pedestrians in its open interior, row ``counts[COUNT_STEPS]`` of
      ``density``/``speed``; the lateral positions y inside area ``lane_area`` (−1: none) into ``lateral``;
    - the smallest gap, the time of the last exit; every ``record_every``-th step (0: never) a frame;
    - the stall rule (:func:`stall_update`). Returns whether the run is stalled.
    """
    progressed = n_exited > 0
    if progressed:
        scalars[SCALAR_LAST_EXIT_S] = time_s
    if has_line:
        a, t, normal = line
        for k in range(index.shape[0]):
            i = index[k]
            x1 = position[i, 0]
            if period_m > 0.0:
                x1 = previous[k, 0] + minimum_image_dx(x1 - previous[k, 0], period_m)
            alpha = crossing_alpha(previous[k, 0], previous[k, 1], x1, position[i, 1], a, t, normal)
            if not np.isnan(alpha) and not passed[i]:
                passed[i] = True
                cross_ids[counts[COUNT_PASSED]] = i
                cross_times[counts[COUNT_PASSED]] = t_prev_s + alpha * (time_s - t_prev_s)
                counts[COUNT_PASSED] += 1
                progressed = True
    vertices, ring_start, ring_owner, boxes = areas
    row = counts[COUNT_STEPS]
    for area in range(density.shape[1]):
        count = 0
        total = 0.0
        for i in range(active.shape[0]):
            if active[i] and _in_box(position[i, 0], position[i, 1], area, boxes) and \
                    point_in_interior(position[i, 0], position[i, 1], area, vertices, ring_start, ring_owner, boxes):
                count += 1
                total += np.sqrt(velocity[i, 0] ** 2 + velocity[i, 1] ** 2)
        density[row, area] = count / area_size_m2[area]
        speed[row, area] = total / count if count else np.nan
    if lane_area >= 0:
        for i in range(active.shape[0]):
            if active[i] and _in_box(position[i, 0], position[i, 1], lane_area, boxes) and \
                    point_in_interior(position[i, 0], position[i, 1], lane_area, vertices, ring_start, ring_owner, boxes):
                lateral[counts[COUNT_LATERAL]] = position[i, 1]
                counts[COUNT_LATERAL] += 1
    counts[COUNT_STEPS] += 1
    scalars[SCALAR_MIN_GAP_M] = min(scalars[SCALAR_MIN_GAP_M], step_min_gap_m)
    if record_every > 0 and step_count % record_every == 0:
        f = counts[COUNT_FRAMES]
        frame_time_s[f] = step_count * dt_s
        for i in range(active.shape[0]):
            frame_position[f, i, 0] = position[i, 0]
            frame_position[f, i, 1] = position[i, 1]
            frame_heading[f, i] = heading[i]
            frame_active[f, i] = active[i]
        counts[COUNT_FRAMES] += 1
    remaining = np.empty_like(active)  # those left who have started to walk (a waiting crowd is no stall)
    for i in range(active.shape[0]):
        remaining[i] = active[i] and not passed[i] and time_s >= premovement[i]
    return stall_update(stall_ring, stall_state, stall_window_steps, stall_window_s, stall_speed_m_s, dt_s, time_s,
                        velocity, remaining, progressed)


@nb.njit(cache=True)
def rollout_steps(max_steps, time_s, step_count, bodies, world, model, agent, line, has_line, passed, cross_ids,
                  cross_times, areas, area_size_m2, lane_area, density, speed, lateral, record_every, frame_time_s,
                  frame_position, frame_heading, frame_active, stall_ring, stall_state, stall_window_steps,
                  stall_window_s, stall_speed_m_s, counts, scalars):
    """Up to ``max_steps`` steps of the calibrated crowd, each the agent's decision, the fused step, the exit
    test and :func:`measure_step` (module docstring). ``bodies``, ``world``, ``model`` and ``agent`` are
    the tuples :func:`~crowd_env.experiments.runner.run_scenario` builds from the simulator and the agent.
    Returns ``(status, steps done, clock, re-detection rounds)``; the state arrays in ``bodies`` and the measurements are
    updated in place."""
    (position, radius, velocity, angular_velocity, heading, mass, inertia, tau, stiffness, damping, desired_speed,
     active, links, link_offsets, premovement) = bodies
    walls, wall_owner, exits, exit_destination, period_m = world
    (dt_s, eps_m, k_n, k_tg, k_v, rotation, max_dense_rows, max_dense_bodies, max_projection_rows) = model
    (origin_m, resolution_m, travel_time, direction, field_of, social, strength_n, range_m, anisotropy, cutoff_m,
     wall_strength_n, wall_range_m, vision, ttc) = agent
    exit_vertices, exit_ring_start, exit_ring_owner, exit_boxes = exits
    no_force = np.zeros((0, 2))
    no_scale = np.zeros(0)
    done = 0
    n_redetect = 0
    while done < max_steps:
        n = 0
        for i in range(active.shape[0]):
            if active[i]:
                n += 1
        if n == 0:
            return ROLLOUT_EMPTY, done, time_s, n_redetect
        index = np.empty(n, np.int64)
        n = 0
        for i in range(active.shape[0]):
            if active[i]:
                index[n] = i
                n += 1
        status, intents, theta_d, pairs, pair_radius = agent_step(
            position, radius, index, origin_m, resolution_m, travel_time, direction, field_of, desired_speed, tau,
            mass, heading, velocity, walls, wall_owner, social, strength_n, range_m, anisotropy, cutoff_m, wall_strength_n,
            wall_range_m, premovement, time_s, vision, ttc, period_m)
        if status != AGENT_OK or first_out_of_bound(intents, no_scale, MAX_INPUT_SPEED_M_S) >= 0 or \
                first_non_finite(theta_d) >= 0:
            return ROLLOUT_PYTHON_STEP, done, time_s, n_redetect
        l_a, l_b, dvec, gi, gj = active_links(position, heading, active, index, links, link_offsets, period_m)
        previous = np.empty((n, 2))
        for k in range(n):
            previous[k, 0] = position[index[k], 0]
            previous[k, 1] = position[index[k], 1]
        fused, _, _, _, _, _, _, min_gap, rounds = fused_step(
            position, radius, velocity, angular_velocity, heading, mass, inertia, tau, stiffness, damping, intents,
            theta_d, True, no_force, False, index, walls, wall_owner, pairs, pair_radius, l_a, l_b, dvec, gi, gj,
            dt_s, eps_m, k_n, k_tg, k_v, rotation, max_dense_rows, max_dense_bodies, max_projection_rows, period_m)
        if fused != FUSED_OK:
            return ROLLOUT_PYTHON_STEP, done, time_s, n_redetect
        n_redetect += rounds
        exited = leave_at_exits(position, active, index, previous, exit_destination, exit_vertices, exit_ring_start,
                                exit_ring_owner, exit_boxes)
        t_prev = time_s
        time_s += dt_s
        step_count += 1
        done += 1
        if measure_step(position, velocity, heading, active, premovement, index, previous, exited.shape[0], t_prev,
                        time_s,
                        step_count, min_gap, line, has_line, passed, cross_ids, cross_times, areas, area_size_m2,
                        lane_area, density, speed, lateral, record_every, frame_time_s, frame_position, frame_heading,
                        frame_active, stall_ring, stall_state, stall_window_steps, stall_window_s, stall_speed_m_s,
                        dt_s, counts, scalars, period_m):
            return ROLLOUT_STALLED, done, time_s, n_redetect
    return ROLLOUT_LIMIT, done, time_s, n_redetect
