"""The choice between the solvers: one object, :class:`SolverCascade`, owns it.

A step of the model needs two kinds of solve (the stages of :mod:`crowd_env.core.step`): the Frémond
impact of each cluster of touching, approaching pedestrians (Kabalan 2016, Eq. 4-8; the primal Eq. 7),
and the gap projection that keeps every candidate gap from closing within the step. Each has a fast
exact method for the usual small problem and slower or more robust ones for large and degenerate
problems (jams, where contacts outnumber degrees of freedom). The cascade tries them in order, keeps
the state that makes the next choice better (back-off, warm starts) and counts what it did:

Impacts:

1. dense pivoting, cluster by cluster, inside the compiled impact stage
   (:func:`~crowd_env.core.solvers.impact.resolve_impacts`) for clusters of at most
   ``max_dense_rows`` normal rows and ``max_dense_bodies`` bodies (:meth:`SolverCascade.impact_limits`);
2. the clusters it leaves (too large, or pivoting failed) by :meth:`SolverCascade.solve_impact_cluster`:
   sparse pivoting (:func:`~crowd_env.core.solvers.sparse_qp.solve_rows_sparse`);
3. Clarabel (:func:`~crowd_env.core.solvers.external.solve_rows_qp`) if that fails.

With ``reference=True`` (``ModelParams(solver="cvxpy")``) every cluster goes to the cvxpy reference
(:func:`~crowd_env.core.solvers.reference.solve_rows_cvxpy`) instead.

Projection (:meth:`SolverCascade.project`):

1. dense pivoting per component (:func:`~crowd_env.core.solvers.dense_projection.project_gaps`) while
   every component has at most ``max_dense_projection_rows`` rows; skipped right after a large
   projection (a persistent jam would fail it every step);
2. otherwise the whole projection, on the pedestrians some candidate touches, by the augmented
   Lagrangian (:func:`~crowd_env.core.solvers.large_projection.project_gaps_alm`) within
   ``alm_newton_budget`` Newton steps (``alm_warm_newton_budget`` first from the multipliers of an
   earlier projection in the same step, when a re-detection added candidates). A miss from zero puts it
   off: it is tried again ``alm_skip_after_miss`` large projections later (the ones between go straight
   on), twice as many after each further miss in a row (up to ``alm_skip_max``); a success from zero
   resets that;
3. the interior point method (:func:`~crowd_env.core.solvers.large_projection.project_gaps_interior_point`),
   started, when the previous step also had a large projection, on a working set (that projection's
   active contacts and the candidates whose slack is below ``working_set_slack_m_s``, from its
   percussions: :func:`~crowd_env.core.solvers.large_projection.project_gaps_working_set`);
4. should that fail: PIQP (:func:`~crowd_env.core.solvers.external.project_gaps_ipm`), then
   :func:`project_gaps_large` (sparse pivoting, Clarabel, and a polish). The interior point method
   misses on jams of tens of thousands of candidates pressed together (RiMEA test 4 at 5 P/m²: 30 000
   candidates, no convergence within its 60 iterations, 253 needed, where PIQP takes about 1 s): with
   PIQP installed, a miss puts it off in the same way: it is tried first again ``ipm_skip_after_miss``
   large projections later (the ones between go to PIQP first), twice as many after each further miss
   in a row (up to ``ipm_skip_max``); a success resets that. Should PIQP miss while the interior point method is
   skipped, the latter is tried before the last resorts.

The Simulator's fused step runs the first method of each list only (both compiled into one call); it
asks :meth:`SolverCascade.dense_only` whether a step may go that way, and hands the step to the staged
path, which calls the cascade, when a problem exceeds the dense limits.

Optional solvers. PIQP and Clarabel are an optional extra (``pip install "crowd_env[solvers]"``, which
the README's test command installs), not core dependencies: the package's own methods (dense and
sparse pivoting, the Newton-type projections) carry the steps, and the external ones are last resorts
behind them (cvxpy, a core
dependency for the reference solver, brings Clarabel along in any case). The cascade knows which are
present (``external_solvers``: by default those importable) and never lets a missing one pass
silently: a missing PIQP is skipped, counted in ``n_skipped_solvers``, and the projection goes on to
the next exact method; where Clarabel is the only method left (sparse pivoting failed on an impact
cluster or on a projection), the cascade raises :class:`~crowd_env.errors.SimulationError`
naming it, rather than go on with an unchecked state.
"""
from __future__ import annotations

import numpy as np

from crowd_env.errors import SimulationError

from .dense_projection import MAX_DENSE_PROJECTION_ROWS, PROJECTION_TOL_M_S, project_gaps
from .external import installed_solvers, project_gaps_ipm, project_gaps_qp, solve_rows_qp
from .graph import gap_residuals, touched_bodies
from .impact import MAX_DENSE_BODIES, MAX_DENSE_ROWS
from .large_projection import project_gaps_alm, project_gaps_interior_point, project_gaps_working_set
from .sparse_qp import project_gaps_sparse, solve_rows_sparse
from .status import STATUS_OK, STATUS_TOO_LARGE

ALM_NEWTON_BUDGET = 30  # Newton steps given to project_gaps_alm before the interior point method (their break-even)
ALM_WARM_NEWTON_BUDGET = 10  # the same from the multipliers of an earlier projection in the step
# After the augmented Lagrangian misses from zero it is tried again ALM_SKIP_AFTER_MISS large projections
# later (those between go to the interior point method directly); each further miss in a row doubles
# that, up to ALM_SKIP_MAX (a jam that stays too large for it costs a wasted try only every ALM_SKIP_MAX
# projections).
ALM_SKIP_AFTER_MISS = 10
ALM_SKIP_MAX = 160
# The same back-off for the interior point method (working set and full) when PIQP is installed: after a
# miss it is tried first again IPM_SKIP_AFTER_MISS large projections later (PIQP goes first in those
# between), doubling up to IPM_SKIP_MAX.
IPM_SKIP_AFTER_MISS = 10
IPM_SKIP_MAX = 160
# The interior point method's working set after a large projection in the previous step: that step's
# active contacts and every candidate whose slack at the current velocities is below this (m/s). A
# smaller threshold makes each solve smaller but needs a second solve more often
# (benchmarks/projection.py measures both on door jams).
WORKING_SET_SLACK_M_S = 0.5

_INSTALL_HINT = 'pip install "crowd_env[solvers]"'


class SolverCascade:
    """The choice between the solvers of an impact cluster and of the gap projection (module docstring),
    with its limits, budgets, back-off, warm-start state and counters.

    Constructed by :class:`~crowd_env.core.Simulator` (``Simulator.cascade``) with the defaults below;
    every limit and budget is a constructor argument and a public attribute that may be changed between
    steps (tests use small limits to force the large paths). ``reference``: every impact cluster goes to
    the cvxpy reference solver. ``external_solvers``: the optional solvers (names of
    :data:`~crowd_env.core.solvers.external.OPTIONAL_SOLVERS`) the cascade may call; None: those
    installed.

    Counters (cumulative): ``n_sparse_solves`` impact clusters and projections beyond the dense limits;
    ``n_fallback_solves`` impact clusters handed to Clarabel and projections handed to
    :func:`project_gaps_large`; ``n_alm_newton_steps`` Newton steps of the augmented Lagrangian;
    ``n_ipm_projections`` large projections given to the interior point method (not those it skips);
    ``n_working_set_solves`` its solves on a working set; ``n_piqp_projections`` projections handed
    to PIQP; ``n_skipped_solvers`` times a missing optional solver was skipped.
    """

    def __init__(self, *, max_dense_rows: int = MAX_DENSE_ROWS, max_dense_bodies: int = MAX_DENSE_BODIES,
                 max_dense_projection_rows: int = MAX_DENSE_PROJECTION_ROWS,
                 alm_newton_budget: int = ALM_NEWTON_BUDGET, alm_warm_newton_budget: int = ALM_WARM_NEWTON_BUDGET,
                 alm_skip_after_miss: int = ALM_SKIP_AFTER_MISS, alm_skip_max: int = ALM_SKIP_MAX,
                 ipm_skip_after_miss: int = IPM_SKIP_AFTER_MISS, ipm_skip_max: int = IPM_SKIP_MAX,
                 working_set_slack_m_s: float = WORKING_SET_SLACK_M_S, reference: bool = False,
                 external_solvers=None):
        self.max_dense_rows = max_dense_rows
        self.max_dense_bodies = max_dense_bodies
        self.max_dense_projection_rows = max_dense_projection_rows
        self.alm_newton_budget = alm_newton_budget
        self.alm_warm_newton_budget = alm_warm_newton_budget
        self.alm_skip_after_miss = alm_skip_after_miss
        self.alm_skip_max = alm_skip_max
        self.ipm_skip_after_miss = ipm_skip_after_miss
        self.ipm_skip_max = ipm_skip_max
        self.working_set_slack_m_s = working_set_slack_m_s
        self.reference = bool(reference)
        self.external_solvers = installed_solvers() if external_solvers is None else frozenset(external_solvers)
        self.n_sparse_solves = 0
        self.n_fallback_solves = 0
        self.n_alm_newton_steps = 0
        self.n_ipm_projections = 0
        self.n_working_set_solves = 0
        self.n_piqp_projections = 0
        self.n_skipped_solvers = 0
        self._step = 0  # the step of the projection in progress
        self._large_step = -2  # step of the last large projection
        self._skip_alm = 0  # large projections left before the augmented Lagrangian is tried again
        self._alm_backoff = alm_skip_after_miss  # what the next miss sets _skip_alm to
        self._skip_ipm = 0  # large projections left in which PIQP goes before the interior point method
        self._ipm_backoff = ipm_skip_after_miss  # how many projections later a miss has it tried again
        self._active_keys = np.zeros(0, np.int64)  # contacts active in the last large projection (contact_keys)
        self._active_lam = np.zeros(0)  # their percussions
        self._active_keys_step = -2  # the step they belong to

    def __setstate__(self, state: dict) -> None:
        """Unpickle (a run's checkpoint); a cascade pickled before the interior point method's back-off
        existed gets its defaults, so that an hours-long run goes on with the current code."""
        self.__dict__.update({"ipm_skip_after_miss": IPM_SKIP_AFTER_MISS, "ipm_skip_max": IPM_SKIP_MAX,
                              "_skip_ipm": 0, "_ipm_backoff": IPM_SKIP_AFTER_MISS, **state})

    # ------------------------------------------------------------------ the dense path
    def _large_recently(self, step: int) -> bool:
        """The previous step (or this one) needed a projection too large for the dense path."""
        return self._large_step >= step - 1

    def dense_only(self, step: int) -> bool:
        """Whether step ``step`` may be tried with the dense solvers alone (the Simulator's fused step):
        not with the reference solver (every impact cluster goes to cvxpy), nor right after a large
        projection (:meth:`project` skips the dense projection then; the fused step, which would try
        it, waits too, so that fused and staged runs stay bitwise equal)."""
        return not self.reference and not self._large_recently(step)

    def impact_limits(self) -> tuple:
        """``(max_dense_rows, max_dense_bodies)`` for the compiled impact stage
        (:func:`~crowd_env.core.solvers.impact.resolve_impacts`); rows −1 routes every cluster to
        :meth:`solve_impact_cluster` (the reference solver)."""
        return (-1 if self.reference else self.max_dense_rows), self.max_dense_bodies

    # ------------------------------------------------------------------ impacts
    def solve_impact_cluster(self, mass_diag, row_a, row_b, coef_a, coef_b, row_k, row_kind, v_minus, p_ext):
        """Impact of a cluster the compiled stage left (inputs of
        :func:`~crowd_env.core.solvers.impact.solve_rows`): ``(v_plus, λ)``. Sparse pivoting, Clarabel if
        that fails; the cvxpy reference with ``reference``."""
        rows = (mass_diag, row_a, row_b, coef_a, coef_b, row_k, row_kind, v_minus, p_ext)
        if self.reference:
            from .reference import solve_rows_cvxpy

            return solve_rows_cvxpy(*rows)
        self.n_sparse_solves += 1
        v_plus, lam, status = solve_rows_sparse(*rows)
        if status != STATUS_OK:
            self.n_fallback_solves += 1
            if "clarabel" not in self.external_solvers:
                raise SimulationError(f"sparse pivoting failed on an impact cluster of {mass_diag.shape[0] // 3} "
                                      f"bodies and Clarabel, the solver that takes over, is not available "
                                      f"({_INSTALL_HINT})")
            v_plus, lam = solve_rows_qp(*rows)
        return v_plus, lam

    # ------------------------------------------------------------------ the projection
    def project(self, vel, mass, con, h, step, keys, lam_warm=None):
        """Gap projection of step ``step`` in place on ``vel`` ((n, ≥2) compact velocities; only
        ``vel[:, :2]`` changes); returns the projection percussion per candidate.

        ``con``: the candidates (dict of the :data:`~crowd_env.core.contacts.CONTACT_FIELDS` arrays,
        rows into ``vel``). ``keys``: their :func:`~crowd_env.core.solvers.graph.contact_keys` (one int64
        per candidate, the same for the same contact in every step), or a function returning them
        (called only by a large projection, which matches contacts with the previous step's).
        ``lam_warm`` (one per candidate, or None): multipliers of a projection of the same step from the
        same velocities on a subset of these candidates (before a re-detection added some): the
        augmented Lagrangian starts from them.
        """
        self._step = step
        status = STATUS_TOO_LARGE if self._large_recently(step) else STATUS_OK
        if status == STATUS_OK:
            v_impact = vel[:, :2].copy()
            lam_p, _, status = project_gaps(vel, mass, con["a"], con["b"], con["gap"], con["nx"], con["ny"], h,
                                            PROJECTION_TOL_M_S, self.max_dense_projection_rows)
            if status != STATUS_OK:
                vel[:, :2] = v_impact
        if status != STATUS_OK:
            self.n_sparse_solves += 1
            self._large_step = step
            # The large solvers see only the pedestrians some candidate touches (the others keep their
            # velocity): their cost then follows the jam, not the size of the crowd.
            bodies, c_a, c_b = touched_bodies(vel.shape[0], con["a"], con["b"])
            v_sub = vel[bodies]
            m_sub = mass[bodies]
            keys = np.asarray(keys() if callable(keys) else keys)
            lam_p = self._project_large(v_sub, m_sub, c_a, c_b, con, h, lam_warm, keys)
            vel[bodies, :2] = v_sub[:, :2]
            pushed = lam_p > 0.0  # as compact_contacts counts them
            order = np.argsort(keys[pushed])
            self._active_keys = keys[pushed][order]  # sorted, for _working_set's look-up
            self._active_lam = lam_p[pushed][order]
            self._active_keys_step = step
        return lam_p

    def _project_large(self, vel, mass, c_a, c_b, con, h, lam_warm=None, keys=None):
        """:meth:`project` for a projection too large for the dense path, in place on ``vel`` (the touched
        pedestrians; ``c_a``, ``c_b`` renumbered into them). ``keys`` (:func:`contact_keys` of the
        candidates, or None) let the interior point method start from a working set when the previous
        step had a large projection."""
        args = (vel, mass, c_a, c_b, con["gap"], con["nx"], con["ny"], h)
        starts = [] if lam_warm is None else [(lam_warm, self.alm_warm_newton_budget, False)]
        if self._skip_alm <= 0:
            starts.append((np.zeros(c_a.shape[0]), self.alm_newton_budget, True))
        for lam0, budget, cold in starts:
            lam_p, steps, status = project_gaps_alm(*args, lam0, budget)
            self.n_alm_newton_steps += steps
            if status == STATUS_OK:
                if cold:  # converged from zero: it suits this jam again
                    self._alm_backoff = self.alm_skip_after_miss
                return lam_p
        if self._skip_alm <= 0:  # the augmented Lagrangian missed from zero: skip it for a while
            self._skip_alm = self._alm_backoff
            self._alm_backoff = min(2 * self._alm_backoff, self.alm_skip_max)
        self._skip_alm -= 1
        piqp = "piqp" in self.external_solvers
        skipped = piqp and self._skip_ipm > 0
        if skipped:
            self._skip_ipm -= 1
        else:
            lam_p = self._interior_point(args, vel, c_a, c_b, con, h, keys)
            if lam_p is not None:
                self._ipm_backoff = self.ipm_skip_after_miss
                return lam_p
            if piqp:  # it missed: PIQP goes first until it is tried again _ipm_backoff projections later
                self._skip_ipm = self._ipm_backoff - 1
                self._ipm_backoff = min(2 * self._ipm_backoff, self.ipm_skip_max)
        if piqp:
            self.n_piqp_projections += 1
            lam_p, ok = project_gaps_ipm(*args)
            if ok:
                return lam_p
            if skipped:  # PIQP missed where the interior point method was skipped: it comes before the last resorts
                lam_p = self._interior_point(args, vel, c_a, c_b, con, h, keys)
                if lam_p is not None:
                    return lam_p
        else:
            self.n_skipped_solvers += 1
        # The interior point methods failed: pivoting, Clarabel and its polish.
        self.n_fallback_solves += 1
        lam_p, _ = project_gaps_large(*args, clarabel="clarabel" in self.external_solvers)
        return lam_p

    def _interior_point(self, args, vel, c_a, c_b, con, h, keys):
        """The package's interior point projection (``args`` those of :meth:`_project_large`'s solvers), on
        the working set of :meth:`_working_set` first when there is one; its percussions, or None when it
        does not converge (``vel`` left alone)."""
        self.n_ipm_projections += 1
        start = self._working_set(vel, c_a, c_b, con, h, keys)
        if start is not None:
            working, z0 = start
            lam_p, solves, status = project_gaps_working_set(*args, working, z0=z0)
            self.n_working_set_solves += solves
            if status == STATUS_OK:
                return lam_p
        lam_p, _, status = project_gaps_interior_point(*args)
        return lam_p if status == STATUS_OK else None

    def _working_set(self, vel, c_a, c_b, con, h, keys):
        """The interior point method's first working set and start: ``(working, z0)`` for
        :func:`~crowd_env.core.solvers.large_projection.project_gaps_working_set`, or None without keys
        or a large projection in the previous step. ``working`` (bool per candidate): the contacts active
        in that projection and the candidates whose slack at ``vel`` is below ``working_set_slack_m_s``;
        ``z0``: their percussions there (0 for the others), from which the first solve starts."""
        if keys is None or self._active_keys_step < self._step - 1:
            return None
        slack = gap_residuals(vel, con["gap"] / h, c_a, c_b, con["nx"], con["ny"])
        z0 = np.zeros(keys.shape[0])
        if self._active_keys.shape[0]:
            at = np.minimum(np.searchsorted(self._active_keys, keys), self._active_keys.shape[0] - 1)
            was_active = self._active_keys[at] == keys
            z0[was_active] = self._active_lam[at[was_active]]
        return (z0 > 0.0) | (slack < self.working_set_slack_m_s), z0


def project_gaps_large(vel, mass, c_a, c_b, c_gap, c_nx, c_ny, dt_s, clarabel=True):
    """The projection by the last resorts, for problems the other methods missed, in place on ``vel[:, :2]``.

    1. :func:`~crowd_env.core.solvers.sparse_qp.project_gaps_sparse` (projected Gauss-Seidel guess, then
       exact sparse pivoting with at most ``SPARSE_MAX_ITER`` factorisations);
    2. if pivoting cycles (degenerate jams: linearly dependent contacts make λ non-unique), Clarabel
       on the primal, whose v is unique, then a polish: pivoting started from the constraints
       Clarabel leaves tight, which certifies the exact solution in one or two factorisations;
    3. if even that fails, Clarabel's solution as it is (feasible to ~1e-12, v within ~1e-6).

    Returns ``(λ per contact, path)`` with path 0, 1 or 2 as above. ``clarabel=False`` (Clarabel not
    available): :class:`~crowd_env.errors.SimulationError` where step 2 would be needed
    (``vel`` left alone).
    """
    v_in = vel[:, :2].copy()
    lam, status = project_gaps_sparse(vel, mass, c_a, c_b, c_gap, c_nx, c_ny, dt_s)
    if status == STATUS_OK:
        return lam, 0
    vel[:, :2] = v_in
    if not clarabel:
        raise SimulationError(f"sparse pivoting could not certify a projection of {c_a.shape[0]} contacts and "
                              f"Clarabel, the solver that takes over, is not available ({_INSTALL_HINT})")
    lam = project_gaps_qp(vel, mass, c_a, c_b, c_gap, c_nx, c_ny, dt_s)
    slack = gap_residuals(vel, c_gap / dt_s, c_a, c_b, c_nx, c_ny)
    tight = slack <= 1e-9 * (1.0 + float(np.abs(c_gap).max()) / dt_s)
    v_qp = vel[:, :2].copy()
    vel[:, :2] = v_in
    lam2, status = project_gaps_sparse(vel, mass, c_a, c_b, c_gap, c_nx, c_ny, dt_s, free0=tight, max_iter=3)
    if status == STATUS_OK:
        return lam2, 1
    vel[:, :2] = v_qp
    return lam, 2
