"""The Newton-type projections for large and degenerate contact sets: augmented Lagrangian, interior point, working set.

The gap projection  min ½ ‖v − v'‖²_M  s.t.  r_k(v) = g_k + (B_n v)_k ≥ 0  (g = gap/h, translational
velocities only; the problem of :mod:`~crowd_env.core.solvers.dense_projection`, which keeps pedestrians
from overlapping between the impacts of Kabalan 2016, Eq. 4-8) has a unique v, but in a jam its dual
LCP is degenerate (more contacts than degrees of freedom) and pivoting cycles. These methods do not
care; the :class:`~crowd_env.core.solvers.cascade.SolverCascade` uses them for projections too large
for the dense path, in this order of preference:

* :func:`project_gaps_alm`, the method of multipliers (a proximal point method on the dual). Each
  subproblem

      min_v  φ(v) = ½ ‖v − v'‖²_M + 1/(2ρ) Σ_k max(0, μ_k − ρ r_k(v))²

  is strictly convex and piecewise quadratic; semismooth Newton solves it exactly in a few steps, each
  one a sparse SPD system M + ρ Σ_{k∈I} B_kᵀ B_k (I: the constraints pushing), factorised by an
  envelope Cholesky in reverse Cuthill-McKee order of the contact graph. Then μ ← max(0, μ − ρ r(v)).
  A fixed point is an exact KKT point; the loop stops when μ moves by less than ρ · 1e-12 m/s
  (constraint violation and complementarity below that). Its Newton steps grow with the jam's diameter
  (each adds the constraints a push passes on).
* :func:`project_gaps_interior_point`, whose iterations do not: a Mehrotra predictor-corrector
  interior point method, each iteration one factorisation of M + Bᵀ W B over all candidates on the same
  envelope (pattern and ordering computed once). In a jam, contacts outnumber degrees of freedom and
  the plain weights W = Z S⁻¹ grow without bound on the dependent ones, where the Cholesky
  factorisation breaks down; a dual regularisation δ (the proximal term of an interior point-proximal
  method of multipliers, centred at the current iterate) bounds them by 1/δ: W = Z (S + δ Z)⁻¹. The
  residuals it drives to zero are those of the unregularised problem, so the solution is the same.
* :func:`project_gaps_working_set`: in a door jam only part of the candidates end up active, and the
  active set changes little from one step to the next. It solves the interior point problem on a
  working set (the caller's guess: the last step's active contacts and those nearly closing), adds the
  candidates the answer violates, and solves again until none is: each solve is smaller, and the result
  is the exact projection on all candidates.

Compiled with numba. ``benchmarks/projection.py`` times the three on door jams.
"""
from __future__ import annotations

from crowd_env.errors import InputError

import numba as nb
import numpy as np

from .graph import gap_residuals, normal_velocity, order_dofs, touched_bodies
from .linalg import envelope_cholesky, envelope_solve
from .status import STATUS_MAX_ITER, STATUS_OK

ALM_RHO_RELATIVE = 1e4  # penalty ρ relative to 1 / mean diag(W): large, so the multipliers converge in a few rounds
ALM_RHO_GROWTH_MAX = 1e3  # ρ grows tenfold, up to this factor, when the violation stalls
ALM_MAX_OUTER = 60
ALM_MAX_NEWTON = 200  # Newton steps over all rounds
ALM_TOL_M_S = 1e-10  # stationarity residual tolerated at termination (m/s)
ALM_TOL_KKT_M_S = 1e-10  # constraint violation and multiplier change (÷ρ) tolerated at termination
IP_MAX_ITER = 60  # interior point iterations (a few times what door jams of any size need)
IP_TOL_M_S = 1e-10  # stationarity (÷ mass) and constraint residuals at termination, relative to the largest speed
IP_GAP_TOL = 1e-16  # mean complementarity sᵀz/m at termination, relative to (largest speed × mean mass)
IP_DELTA = 1e-10  # dual regularisation δ/m̄ (s/m per kg): the Newton weights z/(s + δz) stay ≤ m̄/1e-10
IP_COLD_START = 0.1  # cold start: s = max(r(v'), 0) + 0.1 × largest speed, z = 0.1 × largest speed × m̄
IP_WARM_START = 0.01  # from guessed percussions z0: u = v' + M⁻¹ Bᵀ z0, and this shift instead of 0.1
WORKING_SET_MAX_ROUNDS = 4  # solves of project_gaps_working_set before it gives up (one or two suffice in door jams)


@nb.njit(cache=True)
def _slope(a0, a1, mu, rho, r, bd, t):
    """dφ(u + t d)/dt = a0 + t a1 − Σ_k max(0, μ_k − ρ (r_k + t (B d)_k)) (B d)_k, non-decreasing in t
    (φ is convex); a0 = (u − v')ᵀ M d, a1 = dᵀ M d, r = r(u). Computed from gradients, not from φ,
    so that it keeps its sign down to round-off where differences of φ no longer can."""
    s = a0 + t * a1
    for k in range(r.shape[0]):
        w = mu[k] - rho * (r[k] + t * bd[k])
        if w > 0.0:
            s -= w * bd[k]
    return s


@nb.njit(cache=True)
def _normal_velocities(d, c_a, c_b, c_nx, c_ny):
    """B_n d: the normal relative velocity of every contact for velocities ``d`` ((n, ≥2))."""
    out = np.empty(c_a.shape[0])
    for k in range(c_a.shape[0]):
        out[k] = normal_velocity(d, c_a[k], c_b[k], c_nx[k], c_ny[k])
    return out


@nb.njit(cache=True)
def _line_search(u, d, v0, mass, mu, rho, r, c_a, c_b, c_nx, c_ny):
    """Step t ∈ (0, 1] along the Newton direction d from u (r = r(u)): 1 when φ still decreases there
    (the usual case), else a root of the piecewise linear, non-decreasing dφ/dt by Illinois regula
    falsi. The constraint residuals are linear along the line, so B d is formed once and each trial
    costs one pass over the contacts."""
    a0 = 0.0
    a1 = 0.0
    for i in range(u.shape[0]):
        d0 = d[i, 0]
        d1 = d[i, 1]
        a0 += mass[i] * ((u[i, 0] - v0[i, 0]) * d0 + (u[i, 1] - v0[i, 1]) * d1)
        a1 += mass[i] * (d0 * d0 + d1 * d1)
    bd = _normal_velocities(d, c_a, c_b, c_nx, c_ny)  # the residuals' rate along d: r(u + t d) = r + t B d
    s1 = _slope(a0, a1, mu, rho, r, bd, 1.0)
    if s1 <= 0.0:
        return 1.0
    s0 = _slope(a0, a1, mu, rho, r, bd, 0.0)
    if s0 >= 0.0:
        return 1.0  # not a descent direction (round-off level): take the Newton step as it is
    lo, hi = 0.0, 1.0
    flo, fhi = s0, s1
    side = 0
    t = 1.0
    for _ in range(60):
        t = (lo * fhi - hi * flo) / (fhi - flo)
        ft = _slope(a0, a1, mu, rho, r, bd, t)
        if abs(ft) <= 1e-3 * -s0 or hi - lo <= 1e-12:
            break
        if ft < 0.0:
            lo, flo = t, ft
            if side == -1:
                fhi *= 0.5
            side = -1
        else:
            hi, fhi = t, ft
            if side == 1:
                flo *= 0.5
            side = 1
    return t


@nb.njit(cache=True)
def _gradient(u, v0, mass, mu, rho, r, c_a, c_b, c_nx, c_ny, lam):
    """∇φ(u) (n, 2); writes the trial multipliers max(0, μ − ρ r) into ``lam``."""
    grad = np.empty_like(u)
    for i in range(u.shape[0]):
        grad[i, 0] = mass[i] * (u[i, 0] - v0[i, 0])
        grad[i, 1] = mass[i] * (u[i, 1] - v0[i, 1])
    for k in range(r.shape[0]):
        t = mu[k] - rho * r[k]
        lam[k] = t if t > 0.0 else 0.0
        if t > 0.0:
            a = c_a[k]
            b = c_b[k]
            grad[a, 0] -= t * c_nx[k]
            grad[a, 1] -= t * c_ny[k]
            if b >= 0:
                grad[b, 0] += t * c_nx[k]
                grad[b, 1] += t * c_ny[k]
    return grad


@nb.njit(cache=True, fastmath=True)
def _envelope_pattern(n, used, c_a, c_b, pos):
    """Envelope of M + Σ_{k used} w_k B_kᵀ B_k over the degrees of freedom numbered by ``pos`` (body b,
    axis x/y → pos[3b], pos[3b + 1]; −1: no row ever couples it, so the system is diagonal there):
    ``(dof, first, off)``, L[i, j] stored at off[i] + j − first[i]."""
    nd = 0
    for i in range(3 * n):
        if pos[i] >= 0:
            nd += 1
    dof = np.full(nd, -1, np.int64)  # envelope index -> 2 * body + axis
    for b in range(n):
        for d in range(2):
            p = pos[3 * b + d]
            if p >= 0:
                dof[p] = 2 * b + d
    first = np.arange(nd)
    for k in range(c_a.shape[0]):
        if not used[k]:
            continue
        lo = nd
        for body in (c_a[k], c_b[k]):
            if body >= 0:
                for d in range(2):
                    p = pos[3 * body + d]
                    if p >= 0 and p < lo:
                        lo = p
        for body in (c_a[k], c_b[k]):
            if body >= 0:
                for d in range(2):
                    p = pos[3 * body + d]
                    if p >= 0 and lo < first[p]:
                        first[p] = lo
    off = np.empty(nd + 1, np.int64)
    off[0] = 0
    for i in range(nd):
        off[i + 1] = off[i] + i - first[i] + 1
    return dof, first, off


@nb.njit(cache=True, inline="always")
def _row_coefficients(k, c_a, c_b, c_nx, c_ny, pos, idx, coef):
    """Row k of B_n on the envelope rows: its nonzero velocity coefficients ``coef[:cnt]`` (n on body a,
    −n on body b) at envelope rows ``idx[:cnt]`` (up to four); returns cnt."""
    cnt = 0
    for side in range(2):
        body = c_a[k] if side == 0 else c_b[k]
        sg = 1.0 if side == 0 else -1.0
        if body >= 0:
            for d in range(2):
                p = pos[3 * body + d]
                cf = sg * (c_nx[k] if d == 0 else c_ny[k])
                if p >= 0 and cf != 0.0:
                    idx[cnt] = p
                    coef[cnt] = cf
                    cnt += 1
    return cnt


@nb.njit(cache=True, inline="always")
def _row_entries(k, c_a, c_b, c_nx, c_ny, pos, first, off, idx, coef, at, coef_r, coef_c):
    """The lower-triangle terms of B_kᵀ B_k in envelope storage: env[at[e]] gets w_k · coef_r[e] ·
    coef_c[e] for e < the returned count (≤ 10); ``idx``, ``coef``: scratch of 4."""
    cnt = _row_coefficients(k, c_a, c_b, c_nx, c_ny, pos, idx, coef)
    e = 0
    for x in range(cnt):
        for y in range(cnt):
            if idx[y] <= idx[x]:
                i = idx[x]
                at[e] = off[i] + idx[y] - first[i]
                coef_r[e] = coef[x]
                coef_c[e] = coef[y]
                e += 1
    return e


@nb.njit(cache=True, fastmath=True)
def _envelope_diagonal(mass, dof, off, env):
    """``env`` ← M in the envelope storage of :func:`_envelope_pattern` (zeros off the diagonal)."""
    env[:] = 0.0
    for i in range(dof.shape[0]):
        env[off[i + 1] - 1] = mass[dof[i] // 2]


@nb.njit(cache=True)
def _envelope_entries(used, c_a, c_b, c_nx, c_ny, pos, first, off):
    """Where the terms of Σ_{k used} w_k B_kᵀ B_k fall in the envelope of :func:`_envelope_pattern`,
    for a solve that factorises the same pattern many times (:func:`_envelope_factor` then only
    scatters weights): ``(start, at, coef_r, coef_c)``: row k adds w_k · coef_r[e] · coef_c[e] to
    env[at[e]] for e in start[k] … start[k + 1] − 1 (up to ten entries, the lower triangle)."""
    m = c_a.shape[0]
    start = np.zeros(m + 1, np.int64)
    at = np.empty(10 * m, np.int64)
    coef_r = np.empty(10 * m)
    coef_c = np.empty(10 * m)
    idx = np.empty(4, np.int64)
    coef = np.empty(4)
    e = 0
    for k in range(m):
        if used[k]:
            e += _row_entries(k, c_a, c_b, c_nx, c_ny, pos, first, off, idx, coef, at[e:], coef_r[e:], coef_c[e:])
        start[k + 1] = e
    return start, at[:e], coef_r[:e], coef_c[:e]


@nb.njit(cache=True, fastmath=True)
def _envelope_factor(mass, weight, dof, first, off, entries, env):
    """Cholesky factor of M + Σ_k weight_k B_kᵀ B_k in ``env`` (pattern of :func:`_envelope_pattern`,
    ``entries`` of :func:`_envelope_entries`)."""
    start, at, coef_r, coef_c = entries
    _envelope_diagonal(mass, dof, off, env)
    for k in range(start.shape[0] - 1):
        wk = weight[k]
        for e in range(start[k], start[k + 1]):
            env[at[e]] += wk * coef_r[e] * coef_c[e]
    envelope_cholesky(env, off, first)


@nb.njit(cache=True, fastmath=True)
def _newton_factor(n, mass, rho, pushing, c_a, c_b, c_nx, c_ny, pos):
    """Envelope Cholesky factor of M + ρ Σ_{k pushing} B_kᵀ B_k: ``(dof, first, off, env)``. The
    augmented Lagrangian factorises each pattern about once, so the terms are added as they are found
    rather than through :func:`_envelope_entries`."""
    dof, first, off = _envelope_pattern(n, pushing, c_a, c_b, pos)
    env = np.empty(off[dof.shape[0]])
    _envelope_diagonal(mass, dof, off, env)
    idx = np.empty(4, np.int64)
    coef = np.empty(4)
    at = np.empty(10, np.int64)
    coef_r = np.empty(10)
    coef_c = np.empty(10)
    for k in range(c_a.shape[0]):
        if pushing[k]:
            for e in range(_row_entries(k, c_a, c_b, c_nx, c_ny, pos, first, off, idx, coef, at, coef_r, coef_c)):
                env[at[e]] += rho * coef_r[e] * coef_c[e]
    envelope_cholesky(env, off, first)
    return dof, first, off, env


@nb.njit(cache=True, fastmath=True)
def _newton_solve_into(grad, mass, pos, dof, first, off, env, x, out):
    """d solving (M + Σ w_k B_kᵀ B_k) d = −grad into ``out`` ((n, 2)), with the envelope factor and
    ``x`` (one per envelope row) as work space."""
    n = grad.shape[0]
    nd = dof.shape[0]
    for b in range(n):
        for d in range(2):
            if pos[3 * b + d] < 0:
                out[b, d] = -grad[b, d] / mass[b]
    for i in range(nd):
        x[i] = -grad[dof[i] // 2, dof[i] % 2]
    envelope_solve(env, off, first, x)
    for i in range(nd):
        out[dof[i] // 2, dof[i] % 2] = x[i]


@nb.njit(cache=True)
def _newton_solve(grad, mass, pos, dof, first, off, env):
    """d solving (M + ρ Σ B_kᵀ B_k) d = −grad with the factor of :func:`_newton_factor`."""
    out = np.empty_like(grad)
    _newton_solve_into(grad, mass, pos, dof, first, off, env, np.empty(dof.shape[0]), out)
    return out


@nb.njit(cache=True)
def _projection_dofs(n, c_a, c_b, c_nx, c_ny):
    """``pos`` of :func:`~crowd_env.core.solvers.graph.order_dofs` for the projection's rows (translations
    only): old DOF 3b + axis → envelope index, reverse Cuthill-McKee order of the contact graph."""
    m = c_a.shape[0]
    coef_a = np.zeros((m, 3))
    coef_b = np.zeros((m, 3))
    for k in range(m):
        coef_a[k, 0] = c_nx[k]
        coef_a[k, 1] = c_ny[k]
        coef_b[k, 0] = -c_nx[k]
        coef_b[k, 1] = -c_ny[k]
    _, pos = order_dofs(n, c_a, c_b, coef_a, coef_b)
    return pos


@nb.njit(cache=True)
def _speed_scale(v0):
    """max(1 m/s, largest velocity component): the scale of the projections' tolerances."""
    vscale = 1.0
    for i in range(v0.shape[0]):
        vscale = max(vscale, abs(v0[i, 0]), abs(v0[i, 1]))
    return vscale


@nb.njit(cache=True)
def project_gaps_alm(vel, mass, c_a, c_b, c_gap, c_nx, c_ny, dt_s, lam0, max_newton=ALM_MAX_NEWTON):
    """The projection of :func:`~crowd_env.core.solvers.dense_projection.project_gaps` on all candidates at once by
    the augmented Lagrangian method (module docstring), from the multipliers ``lam0`` (≥ 0, e.g. the
    previous step's; zeros without a guess). Exact for degenerate jams. Modifies ``vel[:, :2]`` in
    place on success; returns ``(λ per contact, Newton steps, status)`` (STATUS_MAX_ITER: not
    converged within ``max_newton`` Newton steps, ``vel`` left alone)."""
    n = vel.shape[0]
    m = c_a.shape[0]
    if m == 0:
        return np.zeros(0), 0, STATUS_OK
    g = c_gap / dt_s
    v0 = vel[:, :2].copy()
    wdiag = 0.0
    for k in range(m):
        wdiag += 1.0 / mass[c_a[k]] + (1.0 / mass[c_b[k]] if c_b[k] >= 0 else 0.0)
    rho = ALM_RHO_RELATIVE * m / wdiag
    pos = _projection_dofs(n, c_a, c_b, c_nx, c_ny)
    vscale = _speed_scale(v0)
    tol = ALM_TOL_M_S * vscale
    mu = np.maximum(lam0, 0.0)
    lam = np.zeros(m)
    u = v0.copy()  # the velocities that μ implies, v' + M⁻¹ B_nᵀ μ: exact when μ is
    for k in range(m):
        if mu[k] > 0.0:
            a = c_a[k]
            b = c_b[k]
            u[a, 0] += mu[k] * c_nx[k] / mass[a]
            u[a, 1] += mu[k] * c_ny[k] / mass[a]
            if b >= 0:
                u[b, 0] -= mu[k] * c_nx[k] / mass[b]
                u[b, 1] -= mu[k] * c_ny[k] / mass[b]
    pushing = np.zeros(m, np.bool_)
    factor = None
    n_factor = 0
    rho0 = rho
    last_viol = np.inf
    steps = 0
    for _ in range(ALM_MAX_OUTER):
        r = gap_residuals(u, g, c_a, c_b, c_nx, c_ny)
        grad = _gradient(u, v0, mass, mu, rho, r, c_a, c_b, c_nx, c_ny, lam)
        while True:  # semismooth Newton on φ
            gmax = 0.0
            for i in range(n):
                gmax = max(gmax, abs(grad[i, 0]) / mass[i], abs(grad[i, 1]) / mass[i])
            if gmax <= tol:
                break
            if steps >= max_newton:
                return lam, steps, STATUS_MAX_ITER
            steps += 1
            same = factor is not None
            for k in range(m):
                p = mu[k] - rho * r[k] > 0.0
                same = same and p == pushing[k]
                pushing[k] = p
            if not same:  # the same pushing set (usual in later rounds) reuses the factor
                factor = _newton_factor(n, mass, rho, pushing, c_a, c_b, c_nx, c_ny, pos)
                n_factor += 1
            d = _newton_solve(grad, mass, pos, *factor)
            t = _line_search(u, d, v0, mass, mu, rho, r, c_a, c_b, c_nx, c_ny)
            u = u + t * d
            r = gap_residuals(u, g, c_a, c_b, c_nx, c_ny)
            grad = _gradient(u, v0, mass, mu, rho, r, c_a, c_b, c_nx, c_ny, lam)
        change = 0.0
        for k in range(m):
            change = max(change, abs(lam[k] - mu[k]))
            mu[k] = lam[k]
        viol = change / rho  # largest constraint violation or complementarity gap, m/s
        if viol <= ALM_TOL_KKT_M_S * vscale:
            vel[:, :2] = u
            return lam, steps, STATUS_OK
        if viol > 0.25 * last_viol and rho < ALM_RHO_GROWTH_MAX * rho0:
            # degenerate jams: the multipliers crawl along a flat face of the dual; a stiffer
            # penalty speeds them up (and costs one factorisation and some round-off)
            rho *= 10.0
            tol *= 10.0
            factor = None
        last_viol = viol
    return lam, steps, STATUS_MAX_ITER


@nb.njit(cache=True)
def _percussion_sum_into(z, c_a, c_b, c_nx, c_ny, out):
    """``out`` ((n, 2)) ← B_nᵀ z: the velocity change times mass that percussions z (one per contact)
    produce."""
    out[:] = 0.0
    for k in range(c_a.shape[0]):
        a = c_a[k]
        b = c_b[k]
        out[a, 0] += z[k] * c_nx[k]
        out[a, 1] += z[k] * c_ny[k]
        if b >= 0:
            out[b, 0] -= z[k] * c_nx[k]
            out[b, 1] -= z[k] * c_ny[k]


@nb.njit(cache=True)
def _step_to_boundary(x, dx):
    """Largest t ≤ 1 with x + t dx ≥ 0 (x > 0)."""
    t = 1.0
    for k in range(x.shape[0]):
        if dx[k] < 0.0:
            t = min(t, -x[k] / dx[k])
    return t


@nb.njit(cache=True)
def _ip_direction(rd, s, z, rp, rc, dl, mass, c_a, c_b, c_nx, c_ny, pos, factor, work, du, ds, dz):
    """Newton direction (du, ds, dz), written into those arrays, of the regularised KKT system for
    complementarity target rc: (M + Bᵀ W B) du = −r_d + Bᵀ (S + δZ)⁻¹ (rc − Z r_p),
    dz = (rc − Z r_p − Z B du)/(s + δz), ds = B du + r_p + δ dz. ``work``: (t (m,), rhs (n, 2),
    x (envelope rows,)) scratch."""
    t, rhs, x = work
    m = s.shape[0]
    for k in range(m):
        t[k] = (rc[k] - z[k] * rp[k]) / (s[k] + dl * z[k])
    _percussion_sum_into(t, c_a, c_b, c_nx, c_ny, rhs)
    for i in range(rhs.shape[0]):  # the solve takes −(right-hand side): rd − Bᵀ t
        rhs[i, 0] = rd[i, 0] - rhs[i, 0]
        rhs[i, 1] = rd[i, 1] - rhs[i, 1]
    _newton_solve_into(rhs, mass, pos, *factor, x, du)
    for k in range(m):
        bdu = normal_velocity(du, c_a[k], c_b[k], c_nx[k], c_ny[k])
        dz[k] = (rc[k] - z[k] * rp[k] - z[k] * bdu) / (s[k] + dl * z[k])
        ds[k] = bdu + rp[k] + dl * dz[k]


@nb.njit(cache=True)
def project_gaps_interior_point(vel, mass, c_a, c_b, c_gap, c_nx, c_ny, dt_s, max_iter=IP_MAX_ITER, z0=None):
    """The projection of :func:`~crowd_env.core.solvers.dense_projection.project_gaps` on all candidates by a
    Mehrotra predictor-corrector interior point method with dual regularisation (module docstring).

    Slacks s = r(v) ≥ 0 and percussions z ≥ 0 start at 0.1 × (largest speed) and 0.1 × (largest speed
    × mean mass); with guessed percussions ``z0`` (one per contact, e.g. the last step's; negative
    entries count as 0), at the velocities u = v' + M⁻¹ Bᵀ z0 they imply, with s = max(r(u), 0) and
    z = z0 shifted by 0.01 × the same scales (``IP_WARM_START``). A candidate violated at the start
    (r_k(u) < 0) also starts with the percussion m̄ ‖r_k(u)‖ that would close it on a body of mean
    mass m̄. Every iteration steps 99.9 % of the way to the boundary, with separate step lengths for the
    primal (v, s) and the dual (z) variables (in the predictor's estimate of the complementarity too).
    Stops when stationarity ‖M (v − v') − Bᵀ z‖/m and ‖r(v) − s‖ are ≤ ``IP_TOL_M_S`` and
    sᵀz/m ≤ ``IP_GAP_TOL`` (both relative to the largest speed, the latter times the mean mass)
    (``benchmarks/projection.py`` compares v with the augmented Lagrangian's exact v on door jams).
    The percussion z of a candidate whose slack exceeds z/m̄ at the end (an open gap: the exact z is
    0, the iterate's is about 1e-14 m̄ m/s) is returned as 0, as the other solvers do, so that only
    closed contacts count as pushed. Modifies ``vel[:, :2]`` in place on success; returns ``(z per
    contact, iterations, status)`` (STATUS_MAX_ITER: no convergence within ``max_iter``, ``vel``
    left alone)."""
    n = vel.shape[0]
    m = c_a.shape[0]
    if m == 0:
        return np.zeros(0), 0, STATUS_OK
    # every candidate stays in the Newton matrix: its pattern and ordering are fixed for the whole solve
    used = np.ones(m, np.bool_)
    pos = _projection_dofs(n, c_a, c_b, c_nx, c_ny)
    dof, first, off = _envelope_pattern(n, used, c_a, c_b, pos)
    entries = _envelope_entries(used, c_a, c_b, c_nx, c_ny, pos, first, off)
    env = np.empty(off[dof.shape[0]])
    factor = (dof, first, off, env)
    g = c_gap / dt_s
    v0 = vel[:, :2].copy()
    vscale = _speed_scale(v0)
    mbar = 0.0
    for i in range(n):
        mbar += mass[i] / n
    dl = IP_DELTA / mbar
    u = v0.copy()
    z = np.empty(m)
    bz = np.empty((n, 2))  # B_nᵀ z
    if z0 is None:
        shift = IP_COLD_START
        z[:] = 0.0
    else:  # warm: the velocities the guessed percussions imply
        shift = IP_WARM_START
        for k in range(m):
            z[k] = max(z0[k], 0.0)
        _percussion_sum_into(z, c_a, c_b, c_nx, c_ny, bz)
        for i in range(n):
            u[i, 0] += bz[i, 0] / mass[i]
            u[i, 1] += bz[i, 1] / mass[i]
    r = gap_residuals(u, g, c_a, c_b, c_nx, c_ny)
    s = np.empty(m)
    for k in range(m):  # a candidate violated at u starts with the percussion that closes it on a body of mass m̄
        s[k] = max(r[k], 0.0) + shift * vscale
        z[k] += shift * vscale * mbar + max(-r[k], 0.0) * mbar
    w = np.empty(m)
    rc = np.empty(m)
    rp = np.empty(m)
    rd = np.empty((n, 2))
    du = np.empty((n, 2))
    ds = np.empty(m)
    dz = np.empty(m)
    work = (np.empty(m), np.empty((n, 2)), np.empty(dof.shape[0]))  # scratch of _ip_direction
    for it in range(max_iter + 1):
        _percussion_sum_into(z, c_a, c_b, c_nx, c_ny, bz)
        dmax = 0.0
        for i in range(n):
            for d in range(2):
                rd[i, d] = mass[i] * (u[i, d] - v0[i, d]) - bz[i, d]
                dmax = max(dmax, abs(rd[i, d]) / mass[i])
        pmax = 0.0
        mu = 0.0
        for k in range(m):
            rp[k] = g[k] + normal_velocity(u, c_a[k], c_b[k], c_nx[k], c_ny[k]) - s[k]
            pmax = max(pmax, abs(rp[k]))
            mu += s[k] * z[k]
        mu /= m
        if not (np.isfinite(dmax) and np.isfinite(pmax) and np.isfinite(mu)):
            break
        if dmax <= IP_TOL_M_S * vscale and pmax <= IP_TOL_M_S * vscale and mu <= IP_GAP_TOL * vscale * mbar:
            vel[:, :2] = u
            for k in range(m):  # strictly complementary split: a slack above z/m̄ is an open gap, its z ≈ 0
                if z[k] < mbar * s[k]:
                    z[k] = 0.0
            return z, it, STATUS_OK
        if it == max_iter:
            break
        for k in range(m):
            w[k] = z[k] / (s[k] + dl * z[k])
        _envelope_factor(mass, w, dof, first, off, entries, env)
        for k in range(m):  # predictor (affine scaling): complementarity target 0
            rc[k] = -s[k] * z[k]
        _ip_direction(rd, s, z, rp, rc, dl, mass, c_a, c_b, c_nx, c_ny, pos, factor, work, du, ds, dz)
        tp = _step_to_boundary(s, ds)
        td = _step_to_boundary(z, dz)
        mu_aff = 0.0
        for k in range(m):
            mu_aff += (s[k] + tp * ds[k]) * (z[k] + td * dz[k])
        mu_aff /= m
        sigma = (mu_aff / mu) ** 3
        for k in range(m):  # corrector: centring σμ and the second-order term
            rc[k] = -s[k] * z[k] - ds[k] * dz[k] + sigma * mu
        _ip_direction(rd, s, z, rp, rc, dl, mass, c_a, c_b, c_nx, c_ny, pos, factor, work, du, ds, dz)
        tp = min(1.0, 0.999 * _step_to_boundary(s, ds))  # primal (v, s) and dual (z) step lengths
        td = min(1.0, 0.999 * _step_to_boundary(z, dz))
        for i in range(n):
            u[i, 0] += tp * du[i, 0]
            u[i, 1] += tp * du[i, 1]
        for k in range(m):
            s[k] += tp * ds[k]
            z[k] += td * dz[k]
    return z, max_iter, STATUS_MAX_ITER


def project_gaps_working_set(vel, mass, c_a, c_b, c_gap, c_nx, c_ny, dt_s, working,
                             max_rounds=WORKING_SET_MAX_ROUNDS, z0=None):
    """The projection of :func:`~crowd_env.core.solvers.dense_projection.project_gaps` on all candidates by
    :func:`project_gaps_interior_point` on the candidates ``working`` (bool, one per candidate) only,
    on the pedestrians they touch; the candidates its answer violates (r_k(v) < 0) join the working
    set and it solves again. The answer, with zero percussion on the candidates never in the working
    set, is then a KKT point of the whole problem (feasible, and the others are inactive): the exact
    projection. ``z0`` (one per candidate, ≥ 0, or None: the cold start): guessed percussions (e.g. the
    last step's), from which the first solve starts (:func:`project_gaps_interior_point`); every later
    solve starts from the previous one's percussions. Modifies ``vel[:, :2]`` in
    place on success; returns ``(λ per contact, solves, status)`` (STATUS_MAX_ITER: not settled
    within ``max_rounds`` solves or a solve did not converge; ``vel`` left alone)."""
    m = c_a.shape[0]
    working = np.asarray(working, dtype=bool).copy()
    if working.shape != (m,):
        raise InputError(f"working must be one bool per candidate ({m},), got shape {working.shape}")
    if z0 is not None:
        z0 = np.asarray(z0, dtype=float)
        if z0.shape != (m,) or not np.all(np.isfinite(z0)) or np.any(z0 < 0.0):
            raise InputError(f"z0 must be one finite percussion ≥ 0 per candidate ({m},), got shape {z0.shape}")
    g = c_gap / dt_s
    for solves in range(1, max_rounds + 1):
        rows = np.flatnonzero(working)
        bodies, a_w, b_w = touched_bodies(vel.shape[0], c_a[rows], c_b[rows])
        v_w = vel[bodies]
        start = None if z0 is None else z0[rows]
        z_w, _, status = project_gaps_interior_point(v_w, mass[bodies], a_w, b_w, c_gap[rows], c_nx[rows],
                                                     c_ny[rows], dt_s, IP_MAX_ITER, start)
        if status != STATUS_OK:
            return np.zeros(m), solves, status
        u = vel[:, :2].copy()
        u[bodies] = v_w[:, :2]
        violated = (gap_residuals(u, g, c_a, c_b, c_nx, c_ny) < 0.0) & ~working
        if not violated.any():
            vel[:, :2] = u
            lam = np.zeros(m)
            lam[rows] = z_w
            return lam, solves, STATUS_OK
        working |= violated
        z0 = np.zeros(m)  # the next solve starts from this one's percussions
        z0[rows] = z_w
    return np.zeros(m), max_rounds, STATUS_MAX_ITER
