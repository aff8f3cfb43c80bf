"""The dense gap projection: v = argmin ‖v − v'‖_M s.t. gap_k + h (B_n v)_k ≥ 0 for every candidate.

The impact law of Kabalan 2016 (Eq. 4-8) acts on contacts that touch; this projection, the same LCP
with K = 0 (W = B_n M⁻¹ B_nᵀ, q = B_n v' + gap/h), is the time step's guarantee that no candidate gap
closes within the step, so that pedestrians never overlap. Solved on a growing set of violated
constraints, component by component, by :func:`~crowd_env.core.solvers.pivoting.lcp_bpp`. Used in
every step first (the fused step has no other); a component with more than
``MAX_DENSE_PROJECTION_ROWS`` active constraints, or a failure of pivoting, hands the whole projection
to the large projections (:class:`~crowd_env.core.solvers.cascade.SolverCascade`).
"""
from __future__ import annotations

import numba as nb
import numpy as np

from .graph import find_root, normal_velocity, union
from .pivoting import lcp_bpp
from .status import STATUS_MAX_ITER, STATUS_OK, STATUS_TOO_LARGE

MAX_DENSE_PROJECTION_ROWS = 200  # rows of one component above which the large projections take over
PROJECTION_TOL_M_S = 1e-10  # violation (gap/h + normal speed, m/s) the projection tolerates before acting


@nb.njit(cache=True)
def project_gaps(vel, mass, c_a, c_b, c_gap, c_nx, c_ny, dt_s, tol, max_rows=MAX_DENSE_PROJECTION_ROWS):
    """Velocity projection: v = argmin ‖v − v'‖_M s.t. gap_k + h (B_n v)_k ≥ 0 for every candidate.

    Solved as the LCP with W = B_n M⁻¹ B_nᵀ, q = B_n v' + gap/h on a growing set of violated
    constraints (exact for the full set at termination). Only translational velocities change.
    A component with more than ``max_rows`` active constraints stops it with STATUS_TOO_LARGE
    (velocities restored): the caller then uses a large projection (:mod:`~crowd_env.core.solvers.cascade`).
    A projection onto a convex set containing 0 cannot add kinetic energy. Returns
    ``(λ per contact, rounds, status)``; λ is the projection percussion (kg m/s).
    """
    n = vel.shape[0]
    nc = c_a.shape[0]
    lam_out = np.zeros(nc)
    active = np.zeros(nc, np.bool_)
    n_act = 0
    for c in range(nc):
        if c_gap[c] / dt_s + normal_velocity(vel, c_a[c], c_b[c], c_nx[c], c_ny[c]) < -tol:
            active[c] = True
            n_act += 1
    if n_act == 0:
        return lam_out, 0, STATUS_OK
    v0 = vel[:, :2].copy()
    status = STATUS_OK
    local = np.full(n, -1, np.int64)
    rounds = 0
    for rounds in range(1, 101):
        parent = np.arange(n)
        for c in range(nc):
            if active[c] and c_b[c] >= 0:
                union(parent, c_a[c], c_b[c])
        root = np.empty(n, np.int64)
        for i in range(n):
            root[i] = find_root(parent, i)
        vel[:, :2] = v0
        act_ids = np.flatnonzero(active)
        act_root = np.empty(act_ids.shape[0], np.int64)
        for k in range(act_ids.shape[0]):
            act_root[k] = root[c_a[act_ids[k]]]
        order = np.argsort(act_root, kind="mergesort")
        start = 0
        while start < order.shape[0]:
            rt = act_root[order[start]]
            stop = start
            while stop < order.shape[0] and act_root[order[stop]] == rt:
                stop += 1
            cids = act_ids[order[start:stop]]
            m = cids.shape[0]
            if m > max_rows:
                vel[:, :2] = v0
                return lam_out, rounds, STATUS_TOO_LARGE
            # Bodies of this cluster.
            nb_ = 0
            for c in cids:
                for body in (c_a[c], c_b[c]):
                    if body >= 0 and local[body] < 0:
                        local[body] = nb_
                        nb_ += 1
            bodies = np.empty(nb_, np.int64)
            for c in cids:
                for body in (c_a[c], c_b[c]):
                    if body >= 0:
                        bodies[local[body]] = body
            # W = B_n M⁻¹ B_nᵀ assembled body by body; q = B_n v' + gap / h.
            W = np.zeros((m, m))
            q = np.empty(m)
            for r in range(m):
                c = cids[r]
                q[r] = c_gap[c] / dt_s + normal_velocity(vel, c_a[c], c_b[c], c_nx[c], c_ny[c])
                for s in range(m):
                    c2 = cids[s]
                    dot = c_nx[c] * c_nx[c2] + c_ny[c] * c_ny[c2]
                    acc = 0.0
                    if c_a[c] == c_a[c2]:
                        acc += dot / mass[c_a[c]]
                    if c_b[c] >= 0 and c_b[c] == c_b[c2]:
                        acc += dot / mass[c_b[c]]
                    if c_b[c2] >= 0 and c_a[c] == c_b[c2]:
                        acc -= dot / mass[c_a[c]]
                    if c_b[c] >= 0 and c_b[c] == c_a[c2]:
                        acc -= dot / mass[c_b[c]]
                    W[r, s] = acc
            lam, st = lcp_bpp(W, q)
            if st != STATUS_OK:
                vel[:, :2] = v0
                return lam_out, rounds, st
            for r in range(m):
                c = cids[r]
                lam_out[c] = lam[r]
                if lam[r] != 0.0:
                    a = c_a[c]
                    vel[a, 0] += lam[r] * c_nx[c] / mass[a]
                    vel[a, 1] += lam[r] * c_ny[c] / mass[a]
                    b = c_b[c]
                    if b >= 0:
                        vel[b, 0] -= lam[r] * c_nx[c] / mass[b]
                        vel[b, 1] -= lam[r] * c_ny[c] / mass[b]
            for k in range(nb_):
                local[bodies[k]] = -1
            start = stop
        added = 0
        for c in range(nc):
            if not active[c]:
                if c_gap[c] / dt_s + normal_velocity(vel, c_a[c], c_b[c], c_nx[c], c_ny[c]) < -tol:
                    active[c] = True
                    added += 1
        if added == 0:
            return lam_out, rounds, status
    # The active set still grew in the last round: the last solve missed some constraints.
    vel[:, :2] = v0
    return lam_out, rounds, STATUS_MAX_ITER
