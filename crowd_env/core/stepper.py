"""Compiled stages of one time step, and the whole step fused into one compiled call.

:class:`~crowd_env.core.Simulator` runs a step either as separate stages from Python (timed, with
every fallback: sparse and interior-point solvers for huge or degenerate clusters, re-detection
after impacts that speed someone up) or, by default, as :func:`fused_step`: the same compiled
stages in one call, with no Python between them. The fused call handles the common case (every
cluster small enough for the dense solvers, no re-detection needed); otherwise it reports which
stage needs the general path and leaves the state untouched, and the simulator runs the staged
step from the start. Both paths call the same functions, so they agree to the last bit.
"""
from __future__ import annotations

import numba as nb
import numpy as np

from .collision import STATUS_OK, project_gaps, resolve_impacts
from .contacts import contact_candidates
from .neighbors import grid_pairs
from .segments import closest_point_on_segment

FUSED_OK = 0
FUSED_LARGE_CLUSTER = 1  # an impact cluster needs the sparse solver
FUSED_REDETECT = 2  # impacts or the projection made someone faster than the detection margins
FUSED_PROJECTION = 3  # the projection needs the sparse / interior-point path
VTOL_M_S = 1e-9  # normal speed below which a touching contact counts as approaching or resting
PROJECTION_TOL_M_S = 1e-10  # violation (gap/h + normal speed, m/s) the projection tolerates before acting


@nb.njit(cache=True)
def wrap_angle_scalar(angle):
    """Wrap an angle (rad) to (−π, π]."""
    return np.pi - np.mod(np.pi - angle, 2.0 * np.pi)


@nb.njit(cache=True)
def direction_angles_rad(vectors):
    """atan2(y, x) of each row of ``vectors`` ((n, 2)), in rad, by the same compiled atan2 as the kernels
    (numpy's vectorised ``np.arctan2`` can differ from it in the last bit, as numpy 2.4's does): headings
    computed here and inside a kernel (the baseline agent's θ_d, Eq. 15) agree bitwise, as
    ``test_equivalence_all_controlled_with_baseline_intents`` requires."""
    out = np.empty(vectors.shape[0])
    for i in range(vectors.shape[0]):
        out[i] = np.arctan2(vectors[i, 1], vectors[i, 0])
    return out


@nb.njit(cache=True)
def smooth_update(velocity, angular_velocity, heading, mass, inertia, tau, stiffness, damping, intents,
                  theta_d, has_theta_d, force, has_force, index, dt_s, rotation):
    """Step 1, the smooth dynamics (Eq. 3, 14, 15) of the pedestrians ``index``: compact (n, 3) u*, ω*.

    u* = u + h/τ (u_intent − u) + h f/m (explicit Euler);
    ω* = ω + h (−k wrap(θ − θ_d) − c ω)/I, with θ_d the intent's direction when not given.
    """
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
def commit_step(position, velocity, angular_velocity, heading, index, vel, dt_s, rotation):
    """Step 5: store the final velocities and advance positions (and headings) by h."""
    for k in range(index.shape[0]):
        i = index[k]
        velocity[i, 0] = vel[k, 0]
        velocity[i, 1] = vel[k, 1]
        angular_velocity[i] = vel[k, 2]
        position[i, 0] += dt_s * vel[k, 0]
        position[i, 1] += dt_s * vel[k, 1]
        if rotation:
            heading[i] = wrap_angle_scalar(heading[i] + dt_s * vel[k, 2])


@nb.njit(cache=True)
def kinetic_energy(vel, mass, inertia):
    """½ Σ (m |u|² + I ω²) in joules for compact (n, 3) velocities."""
    e = 0.0
    for k in range(vel.shape[0]):
        e += mass[k] * (vel[k, 0] ** 2 + vel[k, 1] ** 2) + inertia[k] * vel[k, 2] ** 2
    return 0.5 * e


@nb.njit(cache=True)
def speeds(vel):
    """|u| of compact (n, 3) velocities."""
    out = np.empty(vel.shape[0])
    for k in range(vel.shape[0]):
        out[k] = np.sqrt(vel[k, 0] ** 2 + vel[k, 1] ** 2)
    return out


@nb.njit(cache=True)
def grown_margins(vel, detection_speed, eps_m, dt_s):
    """Rows whose speed exceeds 2 s + ε/(2h), s being the speed the margins were built from: a pair
    left out of the candidates could then close within the step (Simulator step 4)."""
    out = np.empty(vel.shape[0], np.int64)
    m = 0
    for k in range(vel.shape[0]):
        if np.sqrt(vel[k, 0] ** 2 + vel[k, 1] ** 2) > 2.0 * detection_speed[k] + 0.5 * eps_m / dt_s:
            out[m] = k
            m += 1
    return out[:m]


@nb.njit(cache=True)
def candidate_gaps_min(position, radius, index, walls, c_a, c_b, c_wall):
    """Smallest current gap (m) over candidate contacts (inf when there is none)."""
    best = np.inf
    for c in range(c_a.shape[0]):
        i = index[c_a[c]]
        if c_b[c] >= 0:
            j = index[c_b[c]]
            g = np.sqrt((position[i, 0] - position[j, 0]) ** 2 + (position[i, 1] - position[j, 1]) ** 2) \
                - radius[i] - radius[j]
        else:
            s = c_wall[c]
            qx, qy, _ = closest_point_on_segment(position[i, 0], position[i, 1], walls[s, 0], walls[s, 1],
                                                 walls[s, 2], walls[s, 3])
            g = np.sqrt((position[i, 0] - qx) ** 2 + (position[i, 1] - qy) ** 2) - radius[i]
        best = min(best, g)
    return best


@nb.njit(cache=True)
def rows_sweeping_boxes(previous, position, index, boxes):
    """Rows k of ``index`` whose straight move from ``previous[k]`` to ``position[index[k]]`` has a
    bounding box meeting one of the closed boxes (K, 4) (xmin, ymin, xmax, ymax): the cheap prefilter
    of the exit test."""
    out = np.empty(index.shape[0], np.int64)
    m = 0
    for k in range(index.shape[0]):
        x0 = previous[k, 0]
        y0 = previous[k, 1]
        x1 = position[index[k], 0]
        y1 = position[index[k], 1]
        for b in range(boxes.shape[0]):
            if min(x0, x1) <= boxes[b, 2] and max(x0, x1) >= boxes[b, 0] and \
                    min(y0, y1) <= boxes[b, 3] and max(y0, y1) >= boxes[b, 1]:
                out[m] = k
                m += 1
                break
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
def fused_step(position, radius, velocity, angular_velocity, heading, mass_all, inertia_all, tau, stiffness,
               damping, intents, theta_d, has_theta_d, force, has_force, index, walls, wall_owner,
               cached_pairs, cached_radius_m, l_a, l_b, dvec, gi, gj, dt_s, eps_m, k_n, k_tg, k_v, rotation, max_dense_rows, max_dense_bodies,
               max_projection_rows):
    """Steps 1-5 of :class:`~crowd_env.core.Simulator` in one compiled call (see the module docstring).

    Returns ``(status, contacts, ke0, ke1, ke2, n_clusters, max_cluster, min_gap)``, ``contacts`` being
    :func:`compact_contacts`. With ``status != FUSED_OK`` nothing was written and the caller must run
    the staged step. ``min_gap``: smallest gap after the step among the candidate
    contacts (pairs not among them cannot have closed). ``cached_pairs`` (rows into ``index``, all
    pairs within ``cached_radius_m``, e.g. from the policy's social forces this step) are reused when
    they reach far enough, exactly like :meth:`Simulator.neighbor_pairs`.
    """
    n = index.shape[0]
    vel = smooth_update(velocity, angular_velocity, heading, mass_all, inertia_all, tau, stiffness, damping,
                        intents, theta_d, has_theta_d, force, has_force, index, dt_s, rotation)
    speed_star = speeds(vel)
    vmax = 0.0
    r_max = 0.0
    for k in range(n):
        vmax = max(vmax, speed_star[k])
        r_max = max(r_max, radius[index[k]])
    reach = 2.0 * r_max + eps_m + 4.0 * dt_s * vmax
    pairs = cached_pairs if reach <= cached_radius_m else grid_pairs(position, index, reach)
    c_a, c_b, c_gap, c_nx, c_ny, c_rho_a, c_rho_b, c_wall = contact_candidates(
        position, radius, speed_star, index, pairs, walls, wall_owner, eps_m, dt_s)
    mass = np.empty(n)
    inertia = np.empty(n)
    for k in range(n):
        mass[k] = mass_all[index[k]]
        inertia[k] = inertia_all[index[k]]
    ke0 = kinetic_energy(vel, mass, inertia)
    p_n, p_t, in_impact, root, unsolved, n_clusters, max_cluster = resolve_impacts(
        vel, mass, inertia, c_a, c_b, c_gap, c_nx, c_ny, c_rho_a, c_rho_b, l_a, l_b, dvec, gi, gj,
        k_n, k_tg, k_v, eps_m, VTOL_M_S, rotation, max_dense_rows, max_dense_bodies)
    none = compact_contacts(index, c_a[:0], c_b[:0], c_wall[:0], p_n[:0], p_t[:0], p_n[:0], in_impact[:0])
    if unsolved.shape[0]:
        return FUSED_LARGE_CLUSTER, none, ke0, 0.0, 0.0, 0, 0, np.inf
    ke1 = kinetic_energy(vel, mass, inertia)
    if grown_margins(vel, speed_star, eps_m, dt_s).shape[0]:
        return FUSED_REDETECT, none, ke0, ke1, 0.0, 0, 0, np.inf
    lam_p, _, st = project_gaps(vel, mass, c_a, c_b, c_gap, c_nx, c_ny, dt_s, PROJECTION_TOL_M_S,
                                max_projection_rows)
    if st != STATUS_OK:
        return FUSED_PROJECTION, none, ke0, ke1, 0.0, 0, 0, np.inf
    if grown_margins(vel, speed_star, eps_m, dt_s).shape[0]:
        return FUSED_REDETECT, none, ke0, ke1, 0.0, 0, 0, np.inf
    ke2 = kinetic_energy(vel, mass, inertia)
    commit_step(position, velocity, angular_velocity, heading, index, vel, dt_s, rotation)
    min_gap = candidate_gaps_min(position, radius, index, walls, c_a, c_b, c_wall)
    contacts = compact_contacts(index, c_a, c_b, c_wall, p_n, p_t, lam_p, in_impact)
    return FUSED_OK, contacts, ke0, ke1, ke2, n_clusters, max_cluster, min_gap
