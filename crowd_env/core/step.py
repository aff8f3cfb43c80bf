"""One time step of the Kabalan et al. (2016) model: its stages, written once, and their compiled kernels.

The stages, in order (the names are the keys of ``StepResult.timings_s`` in a staged step)::

    STAGES = ("smooth", "neighbors", "contacts", "impacts", "projection", "integrate")

1. ``smooth`` (Eq. 3, 14, 15): :func:`smooth_update`, u* = u + h/τ (u_intent − u) + h f_ext/m,
   ω* = ω + h (−k wrap(θ − θ_d) − c ω)/I;
2. ``neighbors``: :func:`detection_reach` (the speeds u* and the reach 2 r_max + ε + 4 h max ‖u*‖ of the
   detection margins), then the cell grid's pairs within that reach;
3. ``contacts``: :func:`~crowd_env.core.contacts.contact_candidates` with the speculative margin
   ε + 2h(‖u_i‖ + ‖u_j‖) (exact narrow phase), and :func:`compact_bodies`;
4. ``impacts``: :func:`impact_stage`, the Frémond impact (Eq. 4-8) of every cluster of touching,
   approaching contacts and hand links (:func:`~crowd_env.core.solvers.impact.resolve_impacts`; the
   clusters it leaves go to the solver cascade), then :func:`kinetic_energy`;
5. ``projection``: the gap projection, so that no candidate gap closes within the step; before and
   after it, :func:`grown_margins` tells whether the impacts or the projection made someone faster
   than the margins allow (a push passed along a chain): candidates must then be detected again around
   them, with :func:`redetection_reach`, and the projection repeated if a new one binds;
   then :func:`kinetic_energy`;
6. ``integrate``: :func:`finish_step` (positions advance with the final velocities, the smallest
   candidate gap, the contacts that carried a percussion), then pedestrians whose centre's path of the
   step met an exit leave (:func:`leave_at_exits`).

Two paths run these stages with the same functions in this order. By default
:class:`~crowd_env.core.Simulator` runs :func:`advance` (the hand links, :func:`fused_step`, the exit test and
the clock: the one compiled step, which the compiled rollouts of the experiments run too), the stages compiled
into one call with the dense solvers only; the kernels take the bundles of :mod:`crowd_env.core.bundles`. It
handles the common case (every cluster within the dense limits, every projection within the dense one,
re-detections included); otherwise it reports which stage needs the general path (``FUSED_*``) and leaves the
state untouched, and the simulator runs the staged step (``Simulator._staged_step``) from the start: the same
stage functions called one by one from Python, timed, with the
:class:`~crowd_env.core.solvers.cascade.SolverCascade` for large or degenerate problems and the
re-detection loop. Both paths call the same kernels, so they agree to the last bit
(``test_fused_and_staged_steps_agree_bitwise``).

Periodic along x (``period_m`` L > 0, the periodic corridor): the neighbour grid, the contact candidates, the
gap checks and the re-detection take every pedestrian-pedestrian displacement to its nearest image
(:mod:`crowd_env.core.periodic`), and :func:`commit_step` brings x back into [0, L) after the move. With
``period_m`` = 0 every stage computes what it computed before, to the bit.
"""
from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np

from .angles import wrap_angle_scalar
from .body import arm_m, circle, circle_count
from .bundles import Bodies, Candidates, Links, StepInputs, StepParams, World
from .contacts import active_links, contact_candidates, turning_gaps
from .neighbors import grid_pairs, grid_pairs_around
from .periodic import minimum_image_dx, wrap_x
from .polygons import path_meets_polygon
from .segments import closest_point_on_segment
from .solvers.dense_projection import PROJECTION_TOL_M_S, project_gaps
from .solvers.graph import contact_keys, gap_residuals
from .solvers.impact import VTOL_M_S, resolve_impacts
from .solvers.status import STATUS_OK

STAGES = ("smooth", "neighbors", "contacts", "impacts", "projection", "integrate")
FUSED_OK = 0
FUSED_LARGE_CLUSTER = 1  # an impact cluster needs the sparse solver
FUSED_INPUT = 2  # an input beyond the step's bounds (advance): the Python path raises naming it
FUSED_PROJECTION = 3  # the projection needs the sparse / interior-point path
MAX_REDETECT = 10  # re-detection rounds per step (speeds are bounded: one or two rounds suffice in practice)


class StepFigures(NamedTuple):
    """What :func:`fused_step` reports: its ``status`` (``FUSED_*``), the ``contacts`` that carried a percussion
    (:func:`compact_contacts`), the kinetic energies before the impacts, after them and after the projection (J),
    the impact clusters' count and largest size, the smallest candidate gap after the step (m) and the re-detection
    rounds."""

    status: int
    contacts: tuple
    ke_before_impact_j: float
    ke_after_impact_j: float
    ke_after_projection_j: float
    n_clusters: int
    max_cluster: int
    min_gap_m: float
    n_redetections: int


class StepOutcome(NamedTuple):
    """What :func:`advance_named` reports: :func:`fused_step`'s :class:`StepFigures`, the pedestrians who left
    (``exited``, indices), the compact positions before the move (``previous_m``, (n, 2)) and the clock after the step
    (``time_s``; unchanged when ``figures.status`` is not ``FUSED_OK``)."""

    figures: StepFigures
    exited: np.ndarray
    previous_m: np.ndarray
    time_s: float


@nb.njit(cache=True, inline="always")
def smooth_update(bodies, inputs, index, params):
    """Stage 1, the smooth dynamics (Eq. 3, 14, 15) of the pedestrians ``index`` of ``bodies`` given ``inputs``
    (:class:`~crowd_env.core.bundles.StepInputs`), with h and the heading dynamics on or off of ``params``: compact
    (n, 3) u*, ω*.

    u* = u + h/τ (u_intent − u) + h f/m (explicit Euler);
    ω* = ω + h (−k wrap(θ − θ_d) − c ω)/I, with θ_d the intent's direction when not given.
    """
    velocity, angular_velocity, heading = bodies.velocity_m_s, bodies.angular_velocity_rad_s, bodies.heading_rad
    mass, inertia, tau = bodies.mass_kg, bodies.inertia_kg_m2, bodies.tau_s
    stiffness, damping = bodies.heading_stiffness, bodies.heading_damping
    intents, theta_d, has_theta_d = inputs.intents_m_s, inputs.desired_heading_rad, inputs.has_desired_heading
    force, has_force = inputs.external_force_n, inputs.has_external_force
    dt_s, rotation = params.dt_s, params.rotation
    n = index.shape[0]
    vel = np.empty((n, 3))
    for k in range(n):
        i = index[k]
        ux = velocity[i, 0]
        uy = velocity[i, 1]
        ax = (intents[i, 0] - ux) / tau[i]
        ay = (intents[i, 1] - uy) / tau[i]
        if has_force:
            ax += force[i, 0] / mass[i]
            ay += force[i, 1] / mass[i]
        vel[k, 0] = ux + dt_s * ax
        vel[k, 1] = uy + dt_s * ay
        if rotation:
            theta = heading[i]
            if has_theta_d:
                target = theta_d[i]
            else:
                sx = intents[i, 0]
                sy = intents[i, 1]
                target = np.arctan2(sy, sx) if np.sqrt(sx * sx + sy * sy) > 1e-12 else theta
            omega = angular_velocity[i]
            torque = -stiffness[i] * wrap_angle_scalar(theta - target) - damping[i] * omega
            vel[k, 2] = omega + dt_s * torque / inertia[i]
        else:
            vel[k, 2] = 0.0
    return vel


@nb.njit(cache=True)
def commit_step(position, velocity, angular_velocity, heading, index, vel, dt_s, rotation, period_m=0.0):
    """Stage 6: store the final velocities and advance positions (and headings) by h; with ``period_m`` L > 0,
    x is brought back into [0, L)."""
    for k in range(index.shape[0]):
        i = index[k]
        velocity[i, 0] = vel[k, 0]
        velocity[i, 1] = vel[k, 1]
        angular_velocity[i] = vel[k, 2]
        position[i, 0] = wrap_x(position[i, 0] + dt_s * vel[k, 0], period_m)
        position[i, 1] += dt_s * vel[k, 1]
        if rotation:
            heading[i] = wrap_angle_scalar(heading[i] + dt_s * vel[k, 2])


@nb.njit(cache=True)
def kinetic_energy(vel, mass, inertia):
    """½ Σ (m ‖u‖² + I ω²) in joules for compact (n, 3) velocities."""
    e = 0.0
    for k in range(vel.shape[0]):
        e += mass[k] * (vel[k, 0] ** 2 + vel[k, 1] ** 2) + inertia[k] * vel[k, 2] ** 2
    return 0.5 * e


@nb.njit(cache=True, inline="always")
def circle_speed(vel, k, radius, index, depth_m):
    """How fast a point of row ``k``'s circles can move, from compact (n, 3) velocities: ‖u‖, plus abs(ω) times the
    shoulder circles' arm (:func:`~crowd_env.core.body.arm_m`) for bodies of depth ``depth_m`` > 0. The contact
    margins are built from these."""
    speed = np.sqrt(vel[k, 0] ** 2 + vel[k, 1] ** 2)
    if depth_m > 0.0:
        speed += abs(vel[k, 2]) * arm_m(radius[index[k]], depth_m)
    return speed


@nb.njit(cache=True)
def speeds(vel, radius, index, depth_m):
    """:func:`circle_speed` of every row of the compact (n, 3) velocities ``vel``."""
    out = np.empty(vel.shape[0])
    for k in range(vel.shape[0]):
        out[k] = circle_speed(vel, k, radius, index, depth_m)
    return out


@nb.njit(cache=True)
def grown_margins(vel, detection_speed, eps_m, dt_s, radius, index, depth_m):
    """Rows whose :func:`circle_speed` exceeds 2 s + ε/(2h), s being the speed the margins were built from: a pair
    left out of the candidates could then close within the step (stage 5)."""
    out = np.empty(vel.shape[0], np.int64)
    m = 0
    for k in range(vel.shape[0]):
        if circle_speed(vel, k, radius, index, depth_m) > 2.0 * detection_speed[k] + 0.5 * eps_m / dt_s:
            out[m] = k
            m += 1
    return out[:m]


@nb.njit(cache=True)
def candidate_gaps_min(position, heading, radius, depth_m, index, walls, contacts, period_m=0.0):
    """Smallest current gap (m) over the candidate contacts ``contacts`` (between the circles each names, at the
    bodies' current positions and headings; inf when there is none; pairs at their nearest image along x with
    ``period_m``)."""
    c_a, c_b, c_wall, c_sub = contacts.a, contacts.b, contacts.wall, contacts.sub
    k = circle_count(depth_m)
    best = np.inf
    for c in range(c_a.shape[0]):
        i = index[c_a[c]]
        if c_b[c] >= 0:
            j = index[c_b[c]]
            oax, oay, ra = circle(heading[i], radius[i], depth_m, c_sub[c] // k)
            obx, oby, rb = circle(heading[j], radius[j], depth_m, c_sub[c] % k)
            g = np.sqrt(minimum_image_dx(position[i, 0] + oax - position[j, 0] - obx, period_m) ** 2
                        + (position[i, 1] + oay - position[j, 1] - oby) ** 2) - ra - rb
        else:
            s = c_wall[c]
            ox, oy, ra = circle(heading[i], radius[i], depth_m, c_sub[c])
            qx, qy, _ = closest_point_on_segment(position[i, 0] + ox, position[i, 1] + oy, walls[s, 0], walls[s, 1],
                                                 walls[s, 2], walls[s, 3])
            g = np.sqrt((position[i, 0] + ox - qx) ** 2 + (position[i, 1] + oy - qy) ** 2) - ra
        best = min(best, g)
    return best


@nb.njit(cache=True)
def leave_at_exits(position, active, index, previous, destination, vertices, ring_start, ring_owner, boxes):
    """Stage 6's exit test: the pedestrians ``index`` whose centre's straight move of the step, from
    ``previous[k]`` to ``position[index[k]]``, meets an exit (closed polygons, packed by
    :func:`~crowd_env.core.polygons.pack_polygons`): their own exit ``destination[i]``, or any exit where
    it is −1 (an exit thinner than a step cannot be stepped over). They become inactive; returns their
    indices."""
    out = np.empty(index.shape[0], np.int64)
    m = 0
    for k in range(index.shape[0]):
        i = index[k]
        x0 = previous[k, 0]
        y0 = previous[k, 1]
        x1 = position[i, 0]
        y1 = position[i, 1]
        d = destination[i]
        hit = False
        for e in range(boxes.shape[0]):
            if (d >= 0 and e != d) or max(x0, x1) < boxes[e, 0] or min(x0, x1) > boxes[e, 2] or \
                    max(y0, y1) < boxes[e, 1] or min(y0, y1) > boxes[e, 3]:
                continue  # not its exit, or the path's box misses the exit's (the cheap test first)
            if path_meets_polygon(x0, y0, x1, y1, e, vertices, ring_start, ring_owner, boxes):
                hit = True
                break
        if hit:
            active[i] = False
            out[m] = i
            m += 1
    return out[:m]


@nb.njit(cache=True)
def first_non_finite(arr):
    """Row of the first non-finite entry of a 1-D or 2-D float array, −1 when all are finite."""
    flat = arr.reshape(-1)
    per_row = flat.shape[0] // max(arr.shape[0], 1)
    for k in range(flat.shape[0]):
        if not np.isfinite(flat[k]):
            return k // per_row
    return -1


# The largest speed an input of a step may stand for (m/s): the intent ‖u_int‖, and the speed τ‖f‖/m an
# external force f is equivalent to in Eq. 14 (u* − u = h/τ (u_int + τ f/m − u)). The contact detection's
# margins ε + 2h(‖u_i‖ + ‖u_j‖) and the gap projection hold for any finite speed, but their rounding grows
# with the distance h‖u‖ a body travels in a step (about 1e-16 h‖u‖): on the Seyfried bottleneck intents of
# 1e8 m/s (2e6 m/s after one step, 2e4 m per step) still left overlaps below 5e-10 m, intents of 1e12 m/s put
# every centre outside the walls, and above about 1e153 m/s the kinetic energy overflows. 1e3 m/s (10 m per step
# at h = 0.01 s, 750 times a walker's 1.34 m/s) keeps five orders of magnitude from the first; Simulator.step
# refuses larger inputs with an InputError naming the argument, the pedestrian and this bound.
MAX_INPUT_SPEED_M_S = 1.0e3


@nb.njit(cache=True)
def first_out_of_bound(arr, scale, bound):
    """Row of the first row of a 1-D or 2-D float array with a non-finite entry, or whose Euclidean norm times
    ``scale[row]`` (``scale`` empty: 1) exceeds ``bound`` (inf: finiteness only); −1 when there is none."""
    flat = arr.reshape(-1)
    n = arr.shape[0]
    per_row = flat.shape[0] // max(n, 1)
    scaled = scale.shape[0] > 0
    for r in range(n):
        ss = 0.0
        for c in range(per_row):
            x = flat[r * per_row + c]
            if not np.isfinite(x):
                return r
            ss += x * x
        if np.sqrt(ss) * (scale[r] if scaled else 1.0) > bound:
            return r
    return -1


@nb.njit(cache=True)
def compact_contacts(index, c_a, c_b, c_wall, p_normal, p_tangent, p_projection, in_impact):
    """The contacts that carried a percussion (in the impact set, or pushed by the projection), with
    pedestrian indices (j = −1 for a wall): ``(i, j, wall, normal percussion, tangential percussion)``."""
    m = 0
    for c in range(c_a.shape[0]):
        if in_impact[c] or p_projection[c] > 0.0:
            m += 1
    ci = np.empty(m, np.int64)
    cj = np.empty(m, np.int64)
    cw = np.empty(m, np.int64)
    pn = np.empty(m)
    pt = np.empty(m)
    m = 0
    for c in range(c_a.shape[0]):
        if in_impact[c] or p_projection[c] > 0.0:
            ci[m] = index[c_a[c]]
            cj[m] = index[c_b[c]] if c_b[c] >= 0 else -1
            cw[m] = c_wall[c]
            pn[m] = p_normal[c] + p_projection[c]
            pt[m] = p_tangent[c]
            m += 1
    return ci, cj, cw, pn, pt


@nb.njit(cache=True)
def detection_reach(vel, radius, index, eps_m, dt_s, depth_m):
    """Stage 2: the :func:`speeds` of the compact velocities ``vel`` (the detection margins are built from
    them; ‖u*‖ for disks), the largest radius r_max of the pedestrians ``index``, and the reach
    2 r_max + ε + 4 h max|u*| within which a pair can be a candidate: ``(speed, r_max, reach)``."""
    speed = speeds(vel, radius, index, depth_m)
    vmax = 0.0
    r_max = 0.0
    for k in range(index.shape[0]):
        vmax = max(vmax, speed[k])
        r_max = max(r_max, radius[index[k]])
    return speed, r_max, 2.0 * r_max + eps_m + 4.0 * dt_s * vmax


@nb.njit(cache=True)
def redetection_reach(r_max, eps_m, dt_s, grown_speed_max, speed_max):
    """Stage 5's re-detection: the reach 2 r_max + ε + 2h (s_g + s_max) around the pedestrians whose
    speed grew (the fastest of them s_g, the fastest of all s_max) within which new candidates lie."""
    return 2.0 * r_max + eps_m + 2.0 * dt_s * (grown_speed_max + speed_max)


@nb.njit(cache=True)
def compact_bodies(mass_all, inertia_all, index):
    """Stage 3: mass and moment of inertia of the pedestrians ``index``, compact: ``(mass, inertia)``."""
    n = index.shape[0]
    mass = np.empty(n)
    inertia = np.empty(n)
    for k in range(n):
        mass[k] = mass_all[index[k]]
        inertia[k] = inertia_all[index[k]]
    return mass, inertia


@nb.njit(cache=True)
def impact_stage(vel, mass, inertia, contacts, links, params):
    """Stage 4: the kinetic energy before the impacts, then the dense Frémond impacts of every cluster of the
    candidates ``contacts`` and the hand links ``links`` within the limits of ``params``
    (:func:`~crowd_env.core.solvers.impact.resolve_impacts`, in place on ``vel``):
    ``(ke_before, p_normal, p_tangent, in_impact, root, unsolved, n_clusters, max_cluster)``; the
    clusters in ``unsolved`` are left for the solver cascade."""
    ke0 = kinetic_energy(vel, mass, inertia)
    p_n, p_t, in_impact, root, unsolved, n_clusters, max_cluster = resolve_impacts(vel, mass, inertia, contacts,
                                                                                   links, params, VTOL_M_S)
    return ke0, p_n, p_t, in_impact, root, unsolved, n_clusters, max_cluster


@nb.njit(cache=True, inline="always")
def finish_step(bodies, world, params, index, vel, contacts, percussions, p_projection):
    """Stage 6 (before the exit test): :func:`commit_step` of the final compact velocities ``vel``, then the
    smallest gap after the step among the candidates ``contacts`` (pairs not among them cannot have closed) and the
    contacts that carried a percussion (``percussions`` = ``(normal, tangential, in the impact set)``, and the gap
    projection's ``p_projection``): ``(min_gap, contacts)``, ``contacts`` being :func:`compact_contacts`."""
    position, period_m = bodies.position_m, world.period_m
    commit_step(position, bodies.velocity_m_s, bodies.angular_velocity_rad_s, bodies.heading_rad, index, vel,
                params.dt_s, params.rotation, period_m)
    min_gap = candidate_gaps_min(position, bodies.heading_rad, bodies.radius_m, params.body_depth_m, index, world.walls,
                                 contacts, period_m)
    p_normal, p_tangent, in_impact = percussions
    return min_gap, compact_contacts(index, contacts.a, contacts.b, contacts.wall, p_normal, p_tangent, p_projection,
                                     in_impact)


@nb.njit(cache=True)
def redetect_candidates(bodies, index, world, params, speed, grown, contacts):
    """Stage 5's re-detection: the candidates with margins from the speeds ``speed`` (compact (n,)) that
    ``contacts`` lacks, as a :class:`~crowd_env.core.bundles.Candidates` (rows into ``index``). Only pairs involving
    a pedestrian whose margin grew (rows ``grown``) can be new (positions have not moved yet in this
    step): candidates are built among them and their neighbours within :func:`redetection_reach`."""
    position, radius = bodies.position_m, bodies.radius_m
    walls, wall_owner, period_m = world.walls, world.wall_owner, world.period_m
    eps_m, dt_s, depth_m = params.contact_tolerance_m, params.dt_s, params.body_depth_m
    c_a, c_b, c_wall, c_sub = contacts.a, contacts.b, contacts.wall, contacts.sub
    n = index.shape[0]
    r_max = 0.0
    for k in range(n):
        r_max = max(r_max, radius[index[k]])
    g_max = 0.0
    for k in range(grown.shape[0]):
        g_max = max(g_max, speed[grown[k]])
    s_max = 0.0
    for k in range(n):
        s_max = max(s_max, speed[k])
    pairs = grid_pairs_around(position, index, grown, redetection_reach(r_max, eps_m, dt_s, g_max, s_max), period_m)
    mark = np.zeros(n, np.bool_)
    for k in range(grown.shape[0]):
        mark[grown[k]] = True
    for p in range(pairs.shape[0]):
        mark[pairs[p, 0]] = True
        mark[pairs[p, 1]] = True
    sub = np.flatnonzero(mark)  # the grown pedestrians and their neighbours, ascending
    row_in_sub = np.full(n, -1, np.int64)
    for q in range(sub.shape[0]):
        row_in_sub[sub[q]] = q
    sub_pairs = np.empty_like(pairs)
    for p in range(pairs.shape[0]):
        sub_pairs[p, 0] = row_in_sub[pairs[p, 0]]
        sub_pairs[p, 1] = row_in_sub[pairs[p, 1]]
    found = contact_candidates(position, bodies.heading_rad, radius, depth_m, speed[sub], index[sub], sub_pairs,
                               walls, wall_owner, eps_m, dt_s, period_m)
    a, b, wall, circles = found.a, found.b, found.wall, found.sub
    for c in range(a.shape[0]):
        a[c] = sub[a[c]]
        if b[c] >= 0:
            b[c] = sub[b[c]]
    near = np.flatnonzero(row_in_sub[c_a] >= 0)  # a known candidate matching a new one has its row a in sub
    kk = circle_count(depth_m) ** 2
    known = np.sort(contact_keys(c_a[near], c_b[near], c_wall[near], c_sub[near], n, walls.shape[0], kk))
    keys = contact_keys(a, b, wall, circles, n, walls.shape[0], kk)
    at = np.searchsorted(known, keys)
    new = np.empty(a.shape[0], np.bool_)
    for c in range(a.shape[0]):
        new[c] = not (at[c] < known.shape[0] and known[at[c]] == keys[c])
    return Candidates(a[new], b[new], found.gap[new], found.nx[new], found.ny[new], found.rho_a[new], found.rho_b[new],
                      wall[new], circles[new], found.arm_a[new], found.arm_b[new])


@nb.njit(cache=True)
def redetection_round(bodies, index, world, params, vel, v_impact, det_speed, grown, candidates, percussions, lam_p,
                      projected):
    """One round of stage 5's re-detection, as both steps run it (the fused one with the dense projection, the
    staged one with the solver cascade; the module docstring, stage 5), for the rows ``grown`` of
    :func:`grown_margins` (non-empty; the callers test it first, the cheap common case). The candidates
    (``candidates``, a :class:`~crowd_env.core.bundles.Candidates`) were chosen with margins from
    the speeds ``det_speed``: where the compact velocities ``vel`` grew beyond them, the speeds are
    raised to ‖u‖ and the candidates they now call for (:func:`redetect_candidates`) appended, with zero
    percussions (``percussions``: normal, tangential, in the impact set) and, when ``projected`` (the gap
    projection's percussions ``lam_p`` are those of ``vel``), zero projection percussions. If a new candidate
    then binds (its gap would close at ``vel``), ``vel[:, :2]`` goes back to the post-impact ``v_impact`` and
    the projection must run again; else the projected velocities satisfy the new candidates too (with zero
    percussion on them they are the exact projection over all, its KKT point).

    Returns ``(det_speed, candidates, percussions, lam_p, added, projected)``: ``added`` whether candidates were
    added (one re-detection), ``projected`` whether ``lam_p`` still holds for ``vel``."""
    dt_s = params.dt_s
    det_speed = np.maximum(det_speed, speeds(vel, bodies.radius_m, index, params.body_depth_m))
    new = redetect_candidates(bodies, index, world, params, det_speed, grown, candidates)
    extra = new.a.shape[0]
    if not extra:
        return det_speed, candidates, percussions, lam_p, False, projected
    candidates = Candidates(np.concatenate((candidates.a, new.a)), np.concatenate((candidates.b, new.b)),
                            np.concatenate((candidates.gap, new.gap)), np.concatenate((candidates.nx, new.nx)),
                            np.concatenate((candidates.ny, new.ny)), np.concatenate((candidates.rho_a, new.rho_a)),
                            np.concatenate((candidates.rho_b, new.rho_b)), np.concatenate((candidates.wall, new.wall)),
                            np.concatenate((candidates.sub, new.sub)), np.concatenate((candidates.arm_a, new.arm_a)),
                            np.concatenate((candidates.arm_b, new.arm_b)))
    p_n, p_t, in_impact = percussions
    percussions = (np.concatenate((p_n, np.zeros(extra))), np.concatenate((p_t, np.zeros(extra))),
                   np.concatenate((in_impact, np.zeros(extra, np.bool_))))
    if projected:
        lam_p = np.concatenate((lam_p, np.zeros(extra)))
        gap, stopped = turning_gaps(new, vel, dt_s, params.body_depth_m)
        # a new one binds, or a body stopped turning against one (the known candidates' gaps changed)
        if stopped or gap_residuals(vel, gap / dt_s, new.a, new.b, new.nx, new.ny).min() < 0.0:
            vel[:, :2] = v_impact
            projected = False
    return det_speed, candidates, percussions, lam_p, True, projected


@nb.njit(cache=True, inline="always")
def fused_step(bodies, world, params, inputs, index, links, cached_pairs, cached_radius_m):
    """The stages 1-6 (but the exit test) in one compiled call, with the dense solvers only (module docstring).
    ``bodies``, ``world``, ``params``, ``inputs``: the bundles of :mod:`crowd_env.core.bundles`; ``index`` the
    active pedestrians, ``links`` their :func:`~crowd_env.core.contacts.active_links` (a
    :class:`~crowd_env.core.bundles.Links`).

    Returns :class:`StepFigures`. With ``status != FUSED_OK`` nothing was written and the caller must run
    the staged step. ``cached_pairs`` (rows into ``index``, all pairs within ``cached_radius_m``, e.g.
    from the policy's social forces this step) are reused when they reach far enough, exactly like
    :meth:`Simulator.neighbor_pairs`.
    """
    position, radius = bodies.position_m, bodies.radius_m
    walls, wall_owner, period_m = world.walls, world.wall_owner, world.period_m
    dt_s, eps_m = params.dt_s, params.contact_tolerance_m
    vel = smooth_update(bodies, inputs, index, params)
    depth_m = params.body_depth_m
    speed_star, r_max, reach = detection_reach(vel, radius, index, eps_m, dt_s, depth_m)
    pairs = cached_pairs if reach <= cached_radius_m else grid_pairs(position, index, reach, period_m)
    candidates = contact_candidates(position, bodies.heading_rad, radius, depth_m, speed_star, index, pairs, walls,
                                    wall_owner, eps_m, dt_s, period_m)
    mass, inertia = compact_bodies(bodies.mass_kg, bodies.inertia_kg_m2, index)
    ke0, p_n, p_t, in_impact, root, unsolved, n_clusters, max_cluster = impact_stage(vel, mass, inertia, candidates,
                                                                                     links, params)
    none = compact_contacts(index, candidates.a[:0], candidates.b[:0], candidates.wall[:0], p_n[:0], p_t[:0], p_n[:0],
                            in_impact[:0])
    if unsolved.shape[0]:
        return StepFigures(FUSED_LARGE_CLUSTER, none, ke0, 0.0, 0.0, 0, 0, np.inf, 0)
    ke1 = kinetic_energy(vel, mass, inertia)
    # Stage 5 as Simulator._staged_projection runs it, with the dense projection
    v_impact = vel[:, :2].copy()
    det_speed = speed_star
    percussions = (p_n, p_t, in_impact)
    lam_p = np.zeros(0)
    projected = False
    n_redetect = 0
    for _ in range(MAX_REDETECT + 1):
        grown = grown_margins(vel, det_speed, eps_m, dt_s, radius, index, depth_m)
        if grown.shape[0]:
            det_speed, candidates, percussions, lam_p, added, projected = redetection_round(
                bodies, index, world, params, vel, v_impact, det_speed, grown, candidates, percussions, lam_p,
                projected)
            n_redetect += added
        if projected:
            break
        gap, _ = turning_gaps(candidates, vel, dt_s, depth_m)
        lam_p, _, st = project_gaps(vel, mass, candidates.a, candidates.b, gap, candidates.nx, candidates.ny, dt_s,
                                    PROJECTION_TOL_M_S, params.max_dense_projection_rows)
        if st != STATUS_OK:
            return StepFigures(FUSED_PROJECTION, none, ke0, ke1, 0.0, 0, 0, np.inf, 0)
        projected = True
    ke2 = kinetic_energy(vel, mass, inertia)
    min_gap, contacts = finish_step(bodies, world, params, index, vel, candidates, percussions, lam_p)
    return StepFigures(FUSED_OK, contacts, ke0, ke1, ke2, n_clusters, max_cluster, min_gap, n_redetect)


@nb.njit(cache=True)
def active_rows(active):
    """The indices of the active pedestrians, ascending (``np.flatnonzero(active)``)."""
    n = 0
    for i in range(active.shape[0]):
        if active[i]:
            n += 1
    index = np.empty(n, np.int64)
    n = 0
    for i in range(active.shape[0]):
        if active[i]:
            index[n] = i
            n += 1
    return index


@nb.njit(cache=True)
def first_bad_input(inputs, tau, mass):
    """Whether a step input (:class:`~crowd_env.core.bundles.StepInputs`) is beyond what
    :meth:`~crowd_env.core.Simulator.step` accepts (the checks of its ``_check_input``: every entry finite, ‖u_int‖
    and τ‖f‖/m at most :data:`MAX_INPUT_SPEED_M_S`, with τ ``tau`` and m ``mass`` (N,)); the Python path then
    raises naming it."""
    if first_out_of_bound(inputs.intents_m_s, tau[:0], MAX_INPUT_SPEED_M_S) >= 0:  # no scale: empty
        return True
    if inputs.has_desired_heading and first_non_finite(inputs.desired_heading_rad) >= 0:
        return True
    return inputs.has_external_force and first_out_of_bound(inputs.external_force_n, tau / mass,
                                                            MAX_INPUT_SPEED_M_S) >= 0


@nb.njit(cache=True)
def advance(bodies, world, params, inputs, index, cached_pairs, cached_radius_m, time_s):
    """One whole step of the pedestrians ``index`` (active, ascending) from ``time_s``, as
    :meth:`~crowd_env.core.Simulator.step` runs it when the dense solvers serve: the inputs' bounds
    (:func:`first_bad_input`), the hand links between active pedestrians
    (:func:`~crowd_env.core.contacts.active_links`), :func:`fused_step`, the exit test
    (:func:`leave_at_exits` through the exits of ``world``) and the clock t + h. The one compiled step that the
    simulator and the compiled rollouts share.

    ``bodies``, ``world``, ``params``, ``inputs``: the bundles :class:`~crowd_env.core.bundles.Bodies`,
    :class:`~crowd_env.core.bundles.World`, :class:`~crowd_env.core.bundles.StepParams`,
    :class:`~crowd_env.core.bundles.StepInputs` as plain tuples of their fields (``tuple(bundle)``, e.g.
    :meth:`CrowdState.array_fields <crowd_env.core.state.CrowdState.array_fields>`), named here (a plain tuple
    is typed by numba's dispatcher in C, a named one in Python, several µs per call). The compiled rollouts
    inline its body, :func:`advance_named`, rather than call it: a compiled function that calls another
    generates its callees' machine code again, and without this level the rollout's first compilation is
    about 10 s shorter (``docs/performance.md``).

    Returns the fields of :class:`StepFigures` then ``exited`` and ``time_s`` of :class:`StepOutcome`, as one plain
    tuple (a named one costs Python about 0.5 µs more per step to build): :func:`fused_step`'s figures, the
    pedestrians who left and the new clock; ``contacts`` is None when no contact carried a percussion and ``exited``
    None when nobody left (each array handed back to Python costs about 0.3 µs, and most steps have neither). With
    ``status != FUSED_OK`` (``FUSED_INPUT``: an input out of bounds) nothing was written and the clock is
    ``time_s``. (:func:`advance_named` also gives the positions before the move, which the rollouts use; they are
    not handed back here.)
    """
    outcome = advance_named(Bodies(*bodies), World(*world), StepParams(*params), StepInputs(*inputs), index,
                            cached_pairs, cached_radius_m, time_s)
    f = outcome.figures
    return (f.status, f.contacts if f.contacts[0].shape[0] else None, f.ke_before_impact_j, f.ke_after_impact_j,
            f.ke_after_projection_j, f.n_clusters, f.max_cluster, f.min_gap_m, f.n_redetections,
            outcome.exited if outcome.exited.shape[0] else None, outcome.time_s)


@nb.njit(cache=True, inline="always")
def advance_named(bodies, world, params, inputs, index, cached_pairs, cached_radius_m, time_s):
    """:func:`advance` on the named bundles: inlined into :func:`advance` and into the compiled rollouts
    (:func:`crowd_env.experiments.running.rollout.rollout_steps`), so both run the same operations. Returns a
    :class:`StepOutcome`."""
    n = index.shape[0]
    previous = np.empty((n, 2))
    position = bodies.position_m
    for k in range(n):
        previous[k, 0] = position[index[k], 0]
        previous[k, 1] = position[index[k], 1]
    if first_bad_input(inputs, bodies.tau_s, bodies.mass_kg):
        no_one = np.zeros(0, np.int64)
        none = compact_contacts(index, no_one, no_one, no_one, np.zeros(0), np.zeros(0), np.zeros(0),
                                np.zeros(0, np.bool_))
        return StepOutcome(StepFigures(FUSED_INPUT, none, 0.0, 0.0, 0.0, 0, 0, np.inf, 0), no_one, previous, time_s)
    if bodies.links.shape[0]:
        links = active_links(bodies.position_m, bodies.heading_rad, bodies.active, index, bodies.links,
                             bodies.link_offsets_m, world.period_m)
    else:  # what active_links gives without links: empty views, no allocation
        none_2d = bodies.position_m[:0]
        links = Links(index[:0], index[:0], none_2d, none_2d, none_2d)
    figures = fused_step(bodies, world, params, inputs, index, links, cached_pairs, cached_radius_m)
    if figures.status != FUSED_OK:
        return StepOutcome(figures, np.zeros(0, np.int64), previous, time_s)
    exited = leave_at_exits(bodies.position_m, bodies.active, index, previous, world.exit_destination,
                            world.exit_vertices, world.exit_ring_start, world.exit_ring_owner, world.exit_boxes)
    return StepOutcome(figures, exited, previous, time_s + params.dt_s)
