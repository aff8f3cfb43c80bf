"""Contact detection and the contact operator rows (Kabalan Eq. 1, 2 and 8).

Narrow phase: disk-disk and disk-wall candidates whose gap is within a speculative margin
δ = ε + 2 h (‖u_i‖ + ‖u_j‖) (stage 3 of :mod:`crowd_env.core.step`); for bodies of three circles
(:mod:`crowd_env.core.body`) circle-circle and circle-wall candidates, each carrying which circles touch and their
arms from the bodies' centres, the speeds then including the turning (abs(ω) times the arm). The contact operator B (Δ = B v)
is stored row by row in a two-body sparse form that the Frémond solvers of :mod:`crowd_env.core.solvers`
(compiled, sparse and cvxpy) take as input:

* ``row_a``/``row_b``: local body indices (``row_b = -1`` for a wall, which has infinite mass);
* ``coef_a``/``coef_b``: the three coefficients (x, y, θ) of each body in the row;
* ``row_k``: the dissipation coefficient of the row (K_n, K_tg or K_v);
* ``row_kind``: 0 normal (carries the non-interpenetration constraint), 1 tangent, 2 hand link.

Conventions: the normal n points from j to i (from the wall into i); t = e_z × n; the contact
point lies on the line of the two circles' centres at ρ_i = d r_i/(r_i + r_j) from i's (ρ_i = r_i against a wall),
so that angular momentum is conserved exactly; a shoulder circle's arm a adds a × n to the normal row's θ
coefficient (:func:`build_rows`). Velocities are (u_x, u_y, ω) per body.

Periodic along x (``period_m`` L > 0): every displacement between two bodies (a pair's line of centres, a
hand link's d = A_i − A_j) is taken to its nearest image (:func:`~crowd_env.core.periodic.minimum_image_dx`),
so a contact across the seam has the rows of the same contact away from it. Walls are not periodic.
"""
from __future__ import annotations

import numba as nb
import numpy as np

from .body import arm_cross, body_circles, circle_count
from .bundles import Candidates, Links
from .periodic import minimum_image_dx
from .segments import wall_rows

NORMAL, TANGENT, LINK = 0, 1, 2


@nb.njit(cache=True)
def pair_candidates(position, radius, speed, pairs, index, eps_m, dt_s, margin_out, period_m=0.0):
    """Disk-disk candidates among ``pairs`` (rows into ``index``) with gap ≤ ε + 2h(‖u_i‖+‖u_j‖).

    ``speed`` (n,): ‖u‖ of each pedestrian of ``index`` (compact rows). Returns
    ``(a, b, gap, nx, ny, d)`` with a, b rows into ``index``; also writes each pedestrian's own
    margin ε + 2h‖u_i‖ into ``margin_out`` (used for walls). ``period_m``: nearest images along x.
    """
    circles = (position[:0], radius[:0], np.zeros((0, 2)))  # the disks themselves (unread)
    a_out, b_out, _, geo, m = _pair_rows(position, radius, speed, pairs, index, eps_m, dt_s, margin_out, period_m,
                                         circles, 1)
    return a_out[:m], b_out[:m], geo[:m, 0].copy(), geo[:m, 1].copy(), geo[:m, 2].copy(), geo[:m, 3].copy()


@nb.njit(cache=True)
def _pair_rows(position, radius, speed, pairs, index, eps_m, dt_s, margin_out, period_m, circles, k):
    """:func:`pair_candidates` in buffers, between the ``k`` circles of each body (``circles``: centres, radii and
    arms of :func:`~crowd_env.core.body.body_circles`; unread when k = 1, the disks themselves): ``(a, b, sub, geo,
    m)``, the first m rows holding the candidates (``sub`` = s_a k + s_b, the two circles; geo: gap, nx, ny, d between
    the circles' centres, the two arms)."""
    centre, crad, carm = circles
    n = index.shape[0]
    for q in range(n):
        margin_out[q] = eps_m + 2.0 * dt_s * speed[q]
    p = pairs.shape[0]
    a_out = np.empty(p * k * k, np.int64)
    b_out = np.empty(p * k * k, np.int64)
    sub = np.empty(p * k * k, np.int64)
    geo = np.empty((p * k * k, 8 if k > 1 else 4))  # the arms only for circles
    m = 0
    for q in range(p):
        a = pairs[q, 0]
        b = pairs[q, 1]
        i = index[a]
        j = index[b]
        dx = minimum_image_dx(position[i, 0] - position[j, 0], period_m)
        dy = position[i, 1] - position[j, 1]
        d2 = dx * dx + dy * dy
        limit = margin_out[a] + margin_out[b] - eps_m
        # a pair beyond the limit by more than 1e-9 m (far above the rounding of the test below) is left before the
        # root: the superset of pairs a caller passes (e.g. all within the social forces' reach) is mostly such.
        # Every circle of a body lies within its disk of radius r (crowd_env.core.body), so the test holds for them.
        reach = abs(limit + radius[i] + radius[j]) + 1e-9
        if d2 > reach * reach:
            continue
        for sa in range(k):
            ca = a * k + sa
            for sb in range(k):
                cb = b * k + sb
                if k > 1:
                    dx = minimum_image_dx(centre[ca, 0] - centre[cb, 0], period_m)
                    dy = centre[ca, 1] - centre[cb, 1]
                    d2 = dx * dx + dy * dy
                    ra, rb = crad[ca], crad[cb]
                else:
                    ra, rb = radius[i], radius[j]
                d = np.sqrt(d2)
                gap = d - ra - rb
                if gap > limit:
                    continue
                a_out[m] = a
                b_out[m] = b
                sub[m] = sa * k + sb
                geo[m, 0] = gap
                if d > 1e-12:
                    geo[m, 1] = dx / d
                    geo[m, 2] = dy / d
                else:  # coincident centres (only reachable from corrupted input): any unit normal
                    geo[m, 1] = 1.0
                    geo[m, 2] = 0.0
                geo[m, 3] = d
                if k > 1:
                    geo[m, 4] = carm[ca, 0]
                    geo[m, 5] = carm[ca, 1]
                    geo[m, 6] = carm[cb, 0]
                    geo[m, 7] = carm[cb, 1]
                m += 1
    return a_out, b_out, sub, geo, m


CONTACT_FIELDS = Candidates._fields  # ("a", "b", "gap", "nx", "ny", "rho_a", "rho_b", "wall", "sub", "arm_a", "arm_b")


@nb.njit(cache=True)
def contact_candidates(position, heading, radius, depth_m, speed, index, pairs, walls, wall_owner, eps_m, dt_s,
                       period_m=0.0):
    """Candidate contacts (pedestrian pairs, then walls) among the pedestrians ``index``, between their bodies'
    circles (:mod:`crowd_env.core.body`: the disk itself when the body depth ``depth_m`` is 0).

    ``speed`` (n,) compact speeds of the margins (:func:`~crowd_env.core.step.speeds`); ``pairs`` rows into
    ``index`` (any superset of the pairs within 2 r_max + margins); ``period_m``: nearest images along x (module
    docstring). Returns the arrays of :data:`CONTACT_FIELDS`, one entry per contact: ``a``/``b`` rows into
    ``index`` (b = -1 for a wall), ``gap`` (m), ``nx``/``ny`` (unit normal from b to a), ``rho_a``/``rho_b``
    (distances of the contact point from the two circles' centres, ρ_i = d r_i/(r_i + r_j), ρ = r against a wall),
    ``wall`` (segment id or -1), ``sub`` (the circles: s_a K + s_b, s_a against a wall), ``arm_a``/``arm_b`` (C, 2)
    (the circles' centres from the bodies' centres; zero for disks): a
    :class:`~crowd_env.core.bundles.Candidates`.
    """
    n = index.shape[0]
    k = circle_count(depth_m)
    if k > 1:
        circles = body_circles(position, heading, radius, index, depth_m)
    else:  # the disks themselves: nothing to copy (the kernels read position and radius)
        circles = (position[:0], radius[:0], np.zeros((0, 2)))
    margin = np.empty(n)
    a, b, sub, geo, npair = _pair_rows(position, radius, speed, pairs, index, eps_m, dt_s, margin, period_m, circles,
                                       k)
    if walls.shape[0] and k > 1:  # each circle against the walls, with its body's margin
        circle_margin = np.empty(n * k)
        for c in range(n * k):
            circle_margin[c] = margin[c // k]
        wa, wseg, wout, nwall = wall_rows(circles[0], circles[1], np.arange(n * k), walls, wall_owner, circle_margin)
    elif walls.shape[0]:  # read from the two buffers directly (pair_candidates and wall_proximity copy them out)
        wa, wseg, wout, nwall = wall_rows(position, radius, index, walls, wall_owner, margin)
    else:
        wa = wseg = np.zeros(0, np.int64)
        wout = np.zeros((0, 5))
        nwall = 0
    m = npair + nwall
    c_a = np.empty(m, np.int64)
    c_b = np.empty(m, np.int64)
    c_gap = np.empty(m)
    c_nx = np.empty(m)
    c_ny = np.empty(m)
    c_rho_a = np.empty(m)
    c_rho_b = np.empty(m)
    c_wall = np.empty(m, np.int64)
    c_sub = np.empty(m, np.int64)
    c_arm_a = np.zeros((m, 2))
    c_arm_b = np.zeros((m, 2))
    crad, carm = circles[1], circles[2]
    for q in range(npair):
        if k > 1:
            ra = crad[a[q] * k + sub[q] // k]
            rb = crad[b[q] * k + sub[q] % k]
        else:
            ra = radius[index[a[q]]]
            rb = radius[index[b[q]]]
        c_a[q] = a[q]
        c_b[q] = b[q]
        c_gap[q] = geo[q, 0]
        c_nx[q] = geo[q, 1]
        c_ny[q] = geo[q, 2]
        c_rho_a[q] = geo[q, 3] * ra / (ra + rb)
        c_rho_b[q] = geo[q, 3] - c_rho_a[q]
        c_wall[q] = -1
        c_sub[q] = sub[q]
        if k > 1:
            c_arm_a[q, 0] = geo[q, 4]
            c_arm_a[q, 1] = geo[q, 5]
            c_arm_b[q, 0] = geo[q, 6]
            c_arm_b[q, 1] = geo[q, 7]
    for q in range(nwall):
        c = npair + q
        c_a[c] = wa[q] // k
        c_b[c] = -1
        c_gap[c] = wout[q, 0]
        c_nx[c] = wout[q, 1]
        c_ny[c] = wout[q, 2]
        c_rho_b[c] = 0.0
        c_wall[c] = wseg[q]
        c_sub[c] = wa[q] % k
        if k > 1:
            c_rho_a[c] = crad[wa[q]]
            c_arm_a[c, 0] = carm[wa[q], 0]
            c_arm_a[c, 1] = carm[wa[q], 1]
        else:
            c_rho_a[c] = radius[index[wa[q]]]
    return Candidates(c_a, c_b, c_gap, c_nx, c_ny, c_rho_a, c_rho_b, c_wall, c_sub, c_arm_a, c_arm_b)


@nb.njit(cache=True, inline="always")
def turning_rate(vel, contacts, c):
    """The part of contact ``c``'s normal velocity that the bodies' turning makes, ω_a (a_a × n) − ω_b (a_b × n)
    with a the circles' arms (m/s; 0 for disks): the θ columns of its normal row of B (:func:`build_rows`) times the
    angular velocities of the compact (n, 3) ``vel``."""
    nx = contacts.nx[c]
    ny = contacts.ny[c]
    rate = vel[contacts.a[c], 2] * arm_cross(contacts.arm_a, c, nx, ny)
    b = contacts.b[c]
    if b >= 0:
        rate -= vel[b, 2] * arm_cross(contacts.arm_b, c, nx, ny)
    return rate


@nb.njit(cache=True)
def turning_gaps(contacts, vel, dt_s, depth_m):
    """The gaps the gap projection must keep from closing when the projection moves the bodies but not their
    headings: gap + h × :func:`turning_rate` at the compact velocities ``vel`` (whose ω the projection leaves
    alone), so that g + h (n·(u_a − u_b) + turning) ≥ 0. For disks (``depth_m`` = 0) the candidates' own gaps.

    A body whose turning alone would close a contact within the step (g + h × turning < min(g, 0), its own part of
    the turning closing) stops turning first: its ω is set to 0 in ``vel`` (in place; this only takes kinetic energy
    away), until no contact is closed by a turning, so that the projection, which moves bodies only, has a solution
    whenever it has one for bodies that do not turn (a body turned between two walls cannot be freed by moving it).
    Returns ``(gaps, stopped)``, ``stopped`` whether some body stopped."""
    if depth_m <= 0.0:
        return contacts.gap, False
    out = np.empty(contacts.gap.shape[0])
    stopped = False
    for _ in range(vel.shape[0] + 1):  # each round stops at least one body, or ends
        changed = False
        for c in range(out.shape[0]):
            g = contacts.gap[c]
            rate = turning_rate(vel, contacts, c)
            if g + dt_s * rate < min(g, 0.0):
                nx = contacts.nx[c]
                ny = contacts.ny[c]
                a = contacts.a[c]
                if vel[a, 2] * arm_cross(contacts.arm_a, c, nx, ny) < 0.0:
                    vel[a, 2] = 0.0
                    changed = True
                b = contacts.b[c]
                if b >= 0 and vel[b, 2] * arm_cross(contacts.arm_b, c, nx, ny) > 0.0:
                    vel[b, 2] = 0.0
                    changed = True
        stopped = stopped or changed
        if not changed:
            break
    for c in range(out.shape[0]):
        out[c] = contacts.gap[c] + dt_s * turning_rate(vel, contacts, c)
    return out, stopped


def detect_contacts(position, radius, velocity, index, pairs, walls, wall_owner, eps_m, dt_s, period_m=0.0, *,
                    heading=None, depth_m=0.0):
    """:func:`contact_candidates` as a dict keyed by :data:`CONTACT_FIELDS`, from full (N, 2) velocities (margins
    from ‖u‖ alone: the bodies do not turn).

    ``pairs`` are rows into ``index`` (e.g. from :func:`~crowd_env.core.neighbors.grid_pairs`); ``heading`` (N,)
    (default 0) and ``depth_m`` the bodies' shape (:mod:`crowd_env.core.body`).
    """
    index = np.ascontiguousarray(index, dtype=np.int64)
    v = np.asarray(velocity, dtype=np.float64)[index]
    speed = np.sqrt(v[:, 0] ** 2 + v[:, 1] ** 2)
    pairs = np.ascontiguousarray(pairs, dtype=np.int64).reshape(-1, 2)
    heading = np.zeros(len(position)) if heading is None else np.ascontiguousarray(heading, dtype=np.float64)
    arrays = contact_candidates(position, heading, radius, float(depth_m), speed, index, pairs, walls, wall_owner,
                                float(eps_m), float(dt_s), float(period_m))
    return dict(zip(CONTACT_FIELDS, arrays))


@nb.njit(cache=True)
def link_geometry(position, heading, links, offsets, period_m=0.0):
    """Shoulder points of hand links (Eq. 2): returns d = A_i − A_j (nearest image along x with ``period_m``),
    g_i = A_i − x_i, g_j = A_j − x_j."""
    nl = links.shape[0]
    dvec = np.empty((nl, 2))
    gi = np.empty((nl, 2))
    gj = np.empty((nl, 2))
    for l in range(nl):
        i = links[l, 0]
        j = links[l, 1]
        ci = np.cos(heading[i])
        si = np.sin(heading[i])
        cj = np.cos(heading[j])
        sj = np.sin(heading[j])
        gi[l, 0] = ci * offsets[l, 0] - si * offsets[l, 1]
        gi[l, 1] = si * offsets[l, 0] + ci * offsets[l, 1]
        gj[l, 0] = cj * offsets[l, 2] - sj * offsets[l, 3]
        gj[l, 1] = sj * offsets[l, 2] + cj * offsets[l, 3]
        dvec[l, 0] = minimum_image_dx(position[i, 0] + gi[l, 0] - position[j, 0] - gj[l, 0], period_m)
        dvec[l, 1] = position[i, 1] + gi[l, 1] - position[j, 1] - gj[l, 1]
    return dvec, gi, gj


@nb.njit(cache=True)
def active_links(position, heading, active, index, links, offsets, period_m=0.0):
    """The hand links whose two pedestrians are active, with pedestrians as rows into ``index`` (the
    active ones, ascending), and their :func:`link_geometry`: a :class:`~crowd_env.core.bundles.Links`."""
    rank = np.full(active.shape[0], -1, np.int64)
    for k in range(index.shape[0]):
        rank[index[k]] = k
    keep = np.empty(links.shape[0], np.int64)
    m = 0
    for l in range(links.shape[0]):
        if active[links[l, 0]] and active[links[l, 1]]:
            keep[m] = l
            m += 1
    kept = np.empty((m, 2), np.int64)
    kept_offsets = np.empty((m, 4))
    l_a = np.empty(m, np.int64)
    l_b = np.empty(m, np.int64)
    for q in range(m):
        kept[q, 0] = links[keep[q], 0]
        kept[q, 1] = links[keep[q], 1]
        for c in range(4):
            kept_offsets[q, c] = offsets[keep[q], c]
        l_a[q] = rank[kept[q, 0]]
        l_b[q] = rank[kept[q, 1]]
    dvec, gi, gj = link_geometry(position, heading, kept, kept_offsets, period_m)
    return Links(l_a, l_b, dvec, gi, gj)


@nb.njit(cache=True)
def build_rows(contact_ids, contacts, link_ids, links, local, k_n, k_tg, k_v, rotation):
    """Rows of B for the contacts ``contact_ids`` of the :class:`~crowd_env.core.bundles.Candidates` ``contacts``
    and the links ``link_ids`` of the :class:`~crowd_env.core.bundles.Links` ``links``, with bodies renumbered by
    ``local``.

    Normal rows come first (one per contact, in the order of ``contact_ids``), then tangent rows
    (only when K_tg > 0), then link rows (only when K_v > 0). Without rotation the θ coefficients
    are zero, so the impact cannot spin anyone. The contact point lies at l = a − ρ n from a body's centre (a: its
    circle's arm, zero for the paper's disk; ρ n from b's circle for b): the θ coefficients are l × n in the normal
    row (zero for a disk, whose contact normal passes through its centre) and l × t in the tangent row.
    """
    c_a, c_b, c_nx, c_ny, c_rho_a, c_rho_b = contacts.a, contacts.b, contacts.nx, contacts.ny, contacts.rho_a, \
        contacts.rho_b
    arm_a, arm_b = contacts.arm_a, contacts.arm_b
    l_a, l_b, dvec, gi, gj = links
    nc = contact_ids.shape[0]
    nl = link_ids.shape[0] if k_v > 0.0 else 0
    nt = nc if k_tg > 0.0 else 0
    m = nc + nt + nl
    row_a = np.empty(m, np.int64)
    row_b = np.empty(m, np.int64)
    coef_a = np.zeros((m, 3))
    coef_b = np.zeros((m, 3))
    row_k = np.empty(m)
    row_kind = np.empty(m, np.int64)
    rot = 1.0 if rotation else 0.0
    for r in range(nc):
        c = contact_ids[r]
        a = local[c_a[c]]
        b = -1 if c_b[c] < 0 else local[c_b[c]]
        nx = c_nx[c]
        ny = c_ny[c]
        row_a[r] = a
        row_b[r] = b
        coef_a[r, 0] = nx
        coef_a[r, 1] = ny
        coef_b[r, 0] = -nx
        coef_b[r, 1] = -ny
        row_k[r] = k_n
        row_kind[r] = NORMAL
        turn_a = arm_a[c, 0] != 0.0 or arm_a[c, 1] != 0.0  # a shoulder circle: its contact has a lever arm
        turn_b = b >= 0 and (arm_b[c, 0] != 0.0 or arm_b[c, 1] != 0.0)
        if turn_a:
            coef_a[r, 2] = arm_cross(arm_a, c, nx, ny) * rot
        if turn_b:
            coef_b[r, 2] = -arm_cross(arm_b, c, nx, ny) * rot
        if nt:
            t = nc + r
            tx = -ny
            ty = nx
            row_a[t] = a
            row_b[t] = b
            coef_a[t, 0] = tx
            coef_a[t, 1] = ty
            coef_a[t, 2] = -c_rho_a[c] * rot
            coef_b[t, 0] = -tx
            coef_b[t, 1] = -ty
            coef_b[t, 2] = -c_rho_b[c] * rot
            if turn_a:
                coef_a[t, 2] = (arm_cross(arm_a, c, tx, ty) - c_rho_a[c]) * rot
            if turn_b:
                coef_b[t, 2] = -(arm_cross(arm_b, c, tx, ty) + c_rho_b[c]) * rot
            row_k[t] = k_tg
            row_kind[t] = TANGENT
    for q in range(nl):
        l = link_ids[q]
        r = nc + nt + q
        dx = dvec[l, 0]
        dy = dvec[l, 1]
        row_a[r] = local[l_a[l]]
        row_b[r] = local[l_b[l]]
        coef_a[r, 0] = 2.0 * dx
        coef_a[r, 1] = 2.0 * dy
        coef_a[r, 2] = 2.0 * (gi[l, 0] * dy - gi[l, 1] * dx) * rot
        coef_b[r, 0] = -2.0 * dx
        coef_b[r, 1] = -2.0 * dy
        coef_b[r, 2] = -2.0 * (gj[l, 0] * dy - gj[l, 1] * dx) * rot
        row_k[r] = k_v
        row_kind[r] = LINK
    return row_a, row_b, coef_a, coef_b, row_k, row_kind


def rows_to_dense(n_bodies, row_a, row_b, coef_a, coef_b):
    """Dense B (m, 3n) from the two-body row form (for the reference solver and tests)."""
    m = row_a.shape[0]
    B = np.zeros((m, 3 * n_bodies))
    for r in range(m):
        B[r, 3 * row_a[r]:3 * row_a[r] + 3] += coef_a[r]
        if row_b[r] >= 0:
            B[r, 3 * row_b[r]:3 * row_b[r] + 3] += coef_b[r]
    return B
