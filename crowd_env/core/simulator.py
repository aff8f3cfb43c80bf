"""One time step of the Kabalan et al. (2016) model (collision-problem.md, "Recommended time step").

1. smooth update (Eq. 3, 14, 15): u* = u + h/τ (u_intent − u) + h f_ext/m,
   ω* = ω + h (−k wrap(θ − θ_d) − c ω)/I;
2. candidate contacts with a speculative margin ε + 2h(|u_i| + |u_j|) (cell-grid broad phase, exact
   narrow phase);
3. Frémond impact (Eq. 7) on every cluster of touching, approaching contacts and hand links (dense
   compiled solver for small clusters, sparse pivoting for large ones);
4. velocity projection so that no candidate gap closes within the step; where the impact or the
   projection made someone faster than the margins allow (a push passed along a chain), candidates
   are detected again around them and the projection repeated, so that no pair left out can
   close either (overlap stays at round-off, far below the 1e-3 m contact tolerance);
5. positions advance with the final velocities; pedestrians whose centre enters an exit leave (with
   per-pedestrian ``destination``: only through their own destination exit).

The velocity intent ``(N, 2)`` in m/s is the only behavioural input; external forces (for example
Helbing's social repulsion, Eq. 16) can be added per step. The core knows nothing of RL.

By default a step runs as one compiled call (:func:`crowd_env.core.stepper.fused_step`); steps that
need a fallback solver or a re-detection, and every step of a ``Simulator(profile=True)`` (which
times each stage into ``StepResult.timings_s``), run the same compiled stages one by one from Python.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import shapely

from .projection import project_gaps_alm, project_gaps_interior_point, project_gaps_working_set
from .collision import (MAX_DENSE_BODIES, MAX_DENSE_PROJECTION_ROWS, MAX_DENSE_ROWS, STATUS_OK, STATUS_TOO_LARGE,
                        gap_residuals, project_gaps, project_gaps_ipm, project_gaps_large, renumber_rows,
                        resolve_impacts, solve_clusters, solve_rows_qp, solve_rows_sparse, touched_bodies)
from .contacts import CONTACT_FIELDS, contact_candidates, link_geometry
from .neighbors import grid_pairs, grid_pairs_around
from .params import ModelParams, ParameterError
from .segments import as_segments, endpoint_owners, wall_proximity
from .state import CrowdState, StateError
from .stepper import (FUSED_OK, PROJECTION_TOL_M_S, VTOL_M_S, candidate_gaps_min, commit_step, compact_contacts,
                      first_non_finite, fused_step, grown_margins, kinetic_energy, rows_sweeping_boxes, smooth_update,
                      speeds)


ALM_NEWTON_BUDGET = 30  # Newton steps given to project_gaps_alm before the interior point method (break-even: 27-30)
ALM_WARM_NEWTON_BUDGET = 10  # the same from the multipliers of an earlier projection in the step
# After the augmented Lagrangian misses from zero, the next ALM_SKIP_AFTER_MISS large projections go to
# the interior point method directly; each further miss in a row doubles that, up to ALM_SKIP_MAX (a
# jam that stays too large for it costs a wasted try only every ALM_SKIP_MAX projections).
ALM_SKIP_AFTER_MISS = 10
ALM_SKIP_MAX = 160
# The interior point method's working set after a large projection in the previous step: that step's
# active contacts and every candidate whose slack at the current velocities is below this (m/s).
# Measured on door jams of 1250 pedestrians: 0.3 m/s needs a second solve in 7 of 24 steps, 0.5 m/s in
# 1 of 24, while each solve shrinks to about 70 % of the candidates (benchmarks/projection.py).
WORKING_SET_SLACK_M_S = 0.5
MAX_REDETECT = 10  # re-detection rounds per step (speeds are bounded: one or two rounds suffice in practice)


class SimulationError(RuntimeError):
    """The numerical solution failed (should not happen; report it with the seed)."""


@dataclass
class StepResult:
    """What one step did. Contact arrays hold pedestrian indices (``j = -1`` for a wall)."""

    time_s: float
    contact_i: np.ndarray
    contact_j: np.ndarray
    contact_wall: np.ndarray
    percussion_normal: np.ndarray  # kg m/s, impact (reactive + dissipative) + projection
    percussion_tangent: np.ndarray
    n_impact_clusters: int
    max_cluster_size: int
    kinetic_energy_before_impact_j: float
    kinetic_energy_after_impact_j: float
    kinetic_energy_after_projection_j: float
    exited: np.ndarray
    timings_s: dict = field(default_factory=dict)
    min_gap_m: float = np.inf  # smallest gap after the step among contact candidates (inf: none within ε)


class Simulator:
    """Owns a :class:`CrowdState`, the walls and the :class:`ModelParams`; advances with :meth:`step`.

    ``geometry`` may be any object with ``walls`` ((S, 4) segments) and ``in_exit(points)``
    (bool mask); or pass ``walls`` directly and optionally ``exit_test``. ``destination``: None (a
    pedestrian leaves through any exit) or (N,) int indices into ``geometry.exits``, -1 for any exit:
    pedestrian i then leaves only when its centre enters exit ``destination[i]`` (another exit is floor
    for it; see :class:`~crowd_env.scenarios.Scenario`).
    """

    def __init__(self, state: CrowdState, *, geometry=None, walls=None, exit_test=None,
                 params: ModelParams | None = None, profile: bool = False, destination=None):
        if not isinstance(state, CrowdState):
            raise StateError(f"state must be a CrowdState, got {type(state).__name__}")
        self.params = ModelParams() if params is None else params
        if not isinstance(self.params, ModelParams):
            raise ParameterError(f"params must be a ModelParams, got {type(self.params).__name__}")
        if geometry is not None and walls is not None:
            raise ParameterError("give either geometry or walls, not both")
        self.geometry = geometry
        self.walls = as_segments(geometry.walls if geometry is not None else ([] if walls is None else walls))
        self._wall_owner = endpoint_owners(self.walls)
        self._exit_test = geometry.in_exit if geometry is not None else exit_test
        # Bounding boxes of the exits: only pedestrians inside one need the exact (shapely) test.
        self._exit_boxes = None
        if geometry is not None and getattr(geometry, "exits", None):
            self._exit_boxes = np.ascontiguousarray([shapely.bounds(e) for e in geometry.exits], dtype=np.float64)
        self.destination = self._check_destination(destination, state.n)
        state.validate()
        self._check_walls(state)
        self.state = state
        self.time_s = 0.0
        self.step_count = 0
        self.n_fallback_solves = 0
        self.n_redetections = 0  # steps where faster post-impact speeds called for more candidates
        self.n_sparse_solves = 0  # impact clusters / projections too large for the dense path
        self.n_staged_steps = 0  # steps run stage by stage (profiling, fallbacks, re-detection)
        self.n_alm_newton_steps = 0  # Newton steps of the augmented Lagrangian projection (project_gaps_alm)
        self.n_ipm_projections = 0  # large projections given to the interior point method (project_gaps_interior_point)
        self.n_working_set_solves = 0  # ... solves on a working set of candidates (project_gaps_working_set)
        self.n_piqp_projections = 0  # ... of which it missed, handed to PIQP (project_gaps_ipm)
        # Size limits of the dense (compiled) solvers; larger problems take the sparse path. Exposed so
        # that tests can force either path; both are exact, so results agree to round-off.
        self.max_dense_rows = MAX_DENSE_ROWS
        self.max_dense_bodies = MAX_DENSE_BODIES
        self.max_dense_projection_rows = MAX_DENSE_PROJECTION_ROWS
        self._large_step = -2  # step of the last large projection
        self._skip_alm = 0  # large projections left before the augmented Lagrangian is tried again
        self._alm_backoff = ALM_SKIP_AFTER_MISS  # what the next miss sets _skip_alm to
        self._active_keys = np.zeros(0, np.int64)  # contacts active in the last large projection (_contact_keys)
        self._active_lam = np.zeros(0)  # their percussions
        self._active_keys_step = -2  # the step they belong to
        self.profile = profile
        self._pairs_key = -1
        self._pairs = None
        self._pairs_radius = -1.0
        self._index = None
        self._index_key = -1

    def _check_walls(self, state, tolerance_m: float = 1e-9) -> None:
        """Raise :class:`StateError` naming the pedestrian and the wall when one overlaps a wall."""
        idx = np.flatnonzero(state.active)
        if not self.walls.shape[0] or not idx.size:
            return
        ped, seg, gap, *_ = wall_proximity(state.position_m, state.radius_m, idx, self.walls, self._wall_owner,
                                           np.zeros(idx.shape[0]))
        if gap.shape[0] and gap.min() < -tolerance_m:
            k = int(np.argmin(gap))
            i = int(idx[ped[k]])
            raise StateError(f"pedestrian {i} at {state.position_m[i].tolist()} overlaps wall segment {int(seg[k])} "
                             f"{self.walls[seg[k]].tolist()} by {-gap[k]:.4g} m at start")

    def _check_destination(self, destination, n: int):
        """None or a read-only (N,) int64 copy of ``destination`` (exit indices of the geometry, -1 = any)."""
        if destination is None:
            return None
        if self.geometry is None or not hasattr(self.geometry, "exits"):
            raise ParameterError("per-pedestrian destinations need a geometry with exits")
        dest = np.asarray(destination)
        n_exits = len(self.geometry.exits)
        if dest.shape != (n,) or not np.issubdtype(dest.dtype, np.integer):
            raise ParameterError(f"destination must be an ({n},) integer array of exit indices, got shape "
                                 f"{dest.shape}, dtype {dest.dtype}")
        bad = np.flatnonzero((dest < -1) | (dest >= n_exits))
        if bad.size:
            raise ParameterError(f"pedestrian {int(bad[0])} has destination {int(dest[bad[0]])}; the geometry has "
                                 f"exits 0..{n_exits - 1} (-1: any exit)")
        dest = dest.astype(np.int64, copy=True)
        dest.setflags(write=False)
        return dest

    def _at_destination(self, paths, destination) -> np.ndarray:
        """(n,) bool: each step's path (shapely linestrings) touches exit ``destination`` (any exit for -1;
        the caller checked that)."""
        ok = destination < 0
        for d in np.unique(destination[~ok]):
            sel = destination == d
            ok[sel] = shapely.intersects(self.geometry.exits[int(d)], paths[sel])
        return ok

    @property
    def _large_projection_last_step(self) -> bool:
        """The previous step (or this one) needed a projection too large for the dense path."""
        return self._large_step >= self.step_count - 1

    @property
    def wall_owner(self) -> np.ndarray:
        """Shared wall vertices, :func:`~crowd_env.core.segments.endpoint_owners` of :attr:`walls`: what
        wall contacts and wall repulsion need so that a vertex shared by segments counts once."""
        return self._wall_owner

    # ------------------------------------------------------------------ neighbours
    @property
    def active_index(self) -> np.ndarray:
        """Indices of the pedestrians still in the simulation."""
        if self._index_key != self.step_count:  # pedestrians leave only at the end of a step
            self._index_key = self.step_count
            self._index = np.flatnonzero(self.state.active)
        return self._index

    def neighbor_pairs(self, radius_m: float) -> np.ndarray:
        """Pairs (P, 2) of rows into :attr:`active_index` with centre distance ≤ ``radius_m``.

        Built on a cell grid (:func:`~crowd_env.core.neighbors.grid_pairs`) at most once per step and
        radius: a later call with a smaller radius reuses the list (a superset: callers filter by
        distance).
        """
        if self._pairs_key != self.step_count:
            self._pairs_key = self.step_count
            self._pairs = None
            self._pairs_radius = -1.0
        if radius_m > self._pairs_radius:
            self._pairs = grid_pairs(self.state.position_m, self.active_index, float(radius_m))
            self._pairs_radius = radius_m
        return self._pairs

    def _cached_pairs(self):
        """(pairs, radius) already built this step, or an empty list with radius −1."""
        if self._pairs_key == self.step_count and self._pairs is not None:
            return self._pairs, float(self._pairs_radius)
        return _NO_PAIRS, -1.0

    def wall_proximity(self, margin_m: float):
        """Wall neighbours of the active pedestrians within ``margin_m`` of their surface
        (see :func:`crowd_env.core.segments.wall_proximity`)."""
        idx = self.active_index
        return wall_proximity(self.state.position_m, self.state.radius_m, idx, self.walls, self._wall_owner,
                              np.full(idx.shape[0], margin_m))

    # ------------------------------------------------------------------ stepping
    def _check_input(self, name, value, shape):
        arr = np.ascontiguousarray(value, dtype=np.float64)
        if arr.shape != shape:
            raise ValueError(f"{name} must have shape {shape} (one row per pedestrian), got {arr.shape}")
        if first_non_finite(arr) >= 0:
            bad = np.flatnonzero(~np.isfinite(arr).reshape(shape[0], -1).all(axis=1))
            raise ValueError(f"{name} is not finite for pedestrian(s) {bad[:10].tolist()}")
        return arr

    def step(self, intents_m_s, *, desired_heading_rad=None, external_force_n=None) -> StepResult:
        """Advance one step of ``params.dt_s``.

        ``intents_m_s`` (N, 2): velocity intent of every pedestrian (rows of inactive ones are ignored).
        ``desired_heading_rad`` (N,): θ_d of Eq. 15; by default the direction of the intent (the
        current heading where the intent is zero). ``external_force_n`` (N, 2): added forces.
        """
        n_all = self.state.n
        intents = self._check_input("intents_m_s", intents_m_s, (n_all, 2))
        theta_d = _EMPTY_1D if desired_heading_rad is None else \
            self._check_input("desired_heading_rad", desired_heading_rad, (n_all,))
        force = _EMPTY_2D if external_force_n is None else \
            self._check_input("external_force_n", external_force_n, (n_all, 2))
        inputs = (intents, theta_d, desired_heading_rad is not None, force, external_force_n is not None)
        # Right after a large projection the staged step skips the dense projection (see _project); the
        # fused step would try it, so it waits a step too: fused and staged runs stay bitwise equal.
        if not self.profile and self.params.solver != "cvxpy" and self.active_index.shape[0] \
                and not self._large_projection_last_step:
            result = self._fused_step(inputs)
            if result is not None:
                return result
        return self._staged_step(inputs)

    def _fused_step(self, inputs):
        """The whole step as one compiled call; None when a stage needs the general path (nothing changed)."""
        st = self.state
        p = self.params
        idx = self.active_index
        links = self._active_links(idx)
        t0 = time.perf_counter()
        previous = st.position_m[idx]
        status, contacts, ke0, ke1, ke2, n_clusters, max_cluster, min_gap = fused_step(
            st.position_m, st.radius_m, st.velocity_m_s, st.angular_velocity_rad_s, st.heading_rad, st.mass_kg,
            st.inertia_kg_m2, st.tau_s, st.heading_stiffness, st.heading_damping, *inputs, idx, self.walls,
            self._wall_owner, *self._cached_pairs(), *links, p.dt_s, p.contact_tolerance_m, p.normal_dissipation_kg,
            p.tangential_dissipation_kg, p.link_dissipation_kg_per_m2, p.rotation, self.max_dense_rows,
            self.max_dense_bodies, self.max_dense_projection_rows)
        if status != FUSED_OK:
            return None
        exited = self._leave_at_exits(idx, previous)
        return self._result(contacts, ke0, ke1, ke2, n_clusters, max_cluster, exited,
                            {"fused": time.perf_counter() - t0}, min_gap)

    def _staged_step(self, inputs) -> StepResult:
        """Steps 1-5 stage by stage, timed, with every fallback (module docstring)."""
        self.n_staged_steps += 1
        st = self.state
        p = self.params
        h = p.dt_s
        timings = {}
        t0 = time.perf_counter()
        idx = self.active_index
        n = idx.shape[0]
        # 1. smooth update (explicit Euler on the velocity, semi-implicit on positions)
        vel = smooth_update(st.velocity_m_s, st.angular_velocity_rad_s, st.heading_rad, st.mass_kg,
                            st.inertia_kg_m2, st.tau_s, st.heading_stiffness, st.heading_damping, *inputs, idx, h,
                            p.rotation)
        t1 = time.perf_counter()
        timings["smooth"] = t1 - t0
        # 2. contact candidates
        speed_star = speeds(vel)
        vmax = float(speed_star.max()) if n else 0.0
        r_max = float(st.radius_m[idx].max()) if n else 0.0
        pairs = self.neighbor_pairs(2.0 * r_max + p.contact_tolerance_m + 4.0 * h * vmax)
        t2 = time.perf_counter()
        timings["neighbors"] = t2 - t1
        con = dict(zip(CONTACT_FIELDS, contact_candidates(st.position_m, st.radius_m, speed_star, idx, pairs,
                                                          self.walls, self._wall_owner, p.contact_tolerance_m, h)))
        links_a, links_b, dvec, gi, gj = self._active_links(idx)
        t3 = time.perf_counter()
        timings["contacts"] = t3 - t2
        mass = st.mass_kg[idx]
        inertia = st.inertia_kg_m2[idx]
        ke0 = kinetic_energy(vel, mass, inertia)
        # 3. impacts
        cluster_args = (con["a"], con["b"], con["nx"], con["ny"], con["rho_a"], con["rho_b"], links_a, links_b,
                        dvec, gi, gj, p.normal_dissipation_kg, p.tangential_dissipation_kg,
                        p.link_dissipation_kg_per_m2, p.rotation)
        p_n, p_t, in_impact, root, unsolved, n_clusters, max_cluster = resolve_impacts(
            vel, mass, inertia, con["a"], con["b"], con["gap"], con["nx"], con["ny"], con["rho_a"], con["rho_b"],
            links_a, links_b, dvec, gi, gj, p.normal_dissipation_kg, p.tangential_dissipation_kg,
            p.link_dissipation_kg_per_m2, p.contact_tolerance_m, VTOL_M_S, p.rotation,
            -1 if p.solver == "cvxpy" else self.max_dense_rows, self.max_dense_bodies)
        if unsolved.shape[0]:
            if p.solver == "cvxpy":
                from .reference import solve_rows_cvxpy as solve
            else:
                solve = self._solve_large_cluster
            solve_clusters(unsolved, root, vel, mass, inertia, in_impact, *cluster_args, solve, p_n, p_t)
        ke1 = kinetic_energy(vel, mass, inertia)
        t4 = time.perf_counter()
        timings["impacts"] = t4 - t3
        # 4. projection. The candidates were chosen with margins from the pre-impact speeds s_i: a pair
        # left out has gap > ε + 2h (s_i + s_j), so it cannot close within the step while every speed
        # satisfies |u_i| ≤ 2 s_i + ε/(2h). Impacts and the projection can speed a pedestrian up beyond
        # that (a push passed along a jammed chain): then detect again with the larger speeds (before
        # projecting, and after it if needed) and, if a new candidate binds, project from the
        # post-impact velocities again.
        v_impact = vel[:, :2].copy()
        det_speed = speed_star
        lam_p = None
        lam_warm = None  # the last projection's multipliers, extended to the new candidates (zeros)
        for _ in range(MAX_REDETECT + 1):
            grown = grown_margins(vel, det_speed, p.contact_tolerance_m, h)
            if grown.size:
                det_speed = np.maximum(det_speed, speeds(vel))
                merged = self._redetect(con, det_speed, grown, idx, r_max, h)
                if merged is not None:
                    extra = merged["a"].shape[0] - con["a"].shape[0]
                    con = merged
                    p_n = np.concatenate([p_n, np.zeros(extra)])
                    p_t = np.concatenate([p_t, np.zeros(extra)])
                    in_impact = np.concatenate([in_impact, np.zeros(extra, dtype=bool)])
                    self.n_redetections += 1
                    if lam_p is not None:
                        lam_p = np.concatenate([lam_p, np.zeros(extra)])
                        new = slice(con["a"].shape[0] - extra, None)
                        if gap_residuals(vel, con["gap"][new] / h, con["a"][new], con["b"][new], con["nx"][new],
                                         con["ny"][new]).min() < 0.0:  # a new candidate binds: project again
                            vel[:, :2] = v_impact
                            lam_warm = lam_p
                            lam_p = None
                        # else the projected velocities satisfy the new candidates too: with zero percussion
                        # on them they are the exact projection over all (its KKT point), nothing to redo
            if lam_p is not None:
                break
            lam_p = self._project(vel, mass, con, h, idx, lam_warm)
        ke2 = kinetic_energy(vel, mass, inertia)
        t5 = time.perf_counter()
        timings["projection"] = t5 - t4
        # 5. integrate and leave at exits
        previous = st.position_m[idx]
        commit_step(st.position_m, st.velocity_m_s, st.angular_velocity_rad_s, st.heading_rad, idx, vel, h,
                    p.rotation)
        min_gap = candidate_gaps_min(st.position_m, st.radius_m, idx, self.walls, con["a"], con["b"], con["wall"])
        exited = self._leave_at_exits(idx, previous)
        timings["integrate"] = time.perf_counter() - t5
        contacts = compact_contacts(idx, con["a"], con["b"], con["wall"], p_n, p_t, lam_p, in_impact)
        return self._result(contacts, ke0, ke1, ke2, n_clusters, max_cluster, exited, timings, min_gap)

    def _leave_at_exits(self, idx, previous_m) -> np.ndarray:
        """Deactivate pedestrians whose centre entered an exit during the step (their straight path from
        ``previous_m``, (n, 2) compact, touches one: an exit thinner than a step cannot be stepped over);
        advance the clock. Returns their indices. With a bare ``exit_test`` callable (no geometry) only
        the end points are tested."""
        st = self.state
        exited = np.zeros(0, np.int64)
        if self._exit_test is not None and idx.shape[0]:
            if self._exit_boxes is None:
                near = idx
                out = np.asarray(self._exit_test(st.position_m[near]), dtype=bool)
            else:
                rows = rows_sweeping_boxes(previous_m, st.position_m, idx, self._exit_boxes)
                near = idx[rows]
                out = np.zeros(0, bool)
                if near.shape[0]:
                    paths = shapely.linestrings(np.stack([previous_m[rows], st.position_m[near]], axis=1))
                    out = shapely.intersects(self.geometry.exit_area, paths)
                    if self.destination is not None and out.any():  # in an exit: is it the pedestrian's own?
                        out[out] = self._at_destination(paths[out], self.destination[near[out]])
            if out.any():
                exited = near[out]
                st.active[exited] = False
        self.time_s += self.params.dt_s
        self.step_count += 1
        return exited

    def _result(self, contacts, ke0, ke1, ke2, n_clusters, max_cluster, exited, timings, min_gap) -> StepResult:
        contact_i, contact_j, contact_wall, p_normal, p_tangent = contacts
        return StepResult(time_s=self.time_s, contact_i=contact_i, contact_j=contact_j, contact_wall=contact_wall,
                          percussion_normal=p_normal, percussion_tangent=p_tangent,
                          n_impact_clusters=int(n_clusters), max_cluster_size=int(max_cluster),
                          kinetic_energy_before_impact_j=float(ke0), kinetic_energy_after_impact_j=float(ke1),
                          kinetic_energy_after_projection_j=float(ke2), exited=exited, timings_s=timings,
                          min_gap_m=float(min_gap))

    def _solve_large_cluster(self, *rows):
        """Impact of a cluster too large for the dense path: sparse pivoting, Clarabel if that fails."""
        self.n_sparse_solves += 1
        v_plus, lam, status = solve_rows_sparse(*rows)
        if status != STATUS_OK:
            self.n_fallback_solves += 1
            v_plus, lam = solve_rows_qp(*rows)
        return v_plus, lam

    def _project(self, vel, mass, con, h, idx, lam_warm=None):
        """Gap projection (step 4) in place on ``vel``; returns the projection percussion per contact.

        Components of active constraints small enough are solved densely (:func:`project_gaps`);
        otherwise the whole projection goes to :func:`project_gaps_alm` (augmented Lagrangian, exact
        in degenerate jams) within ``ALM_NEWTON_BUDGET`` Newton steps, and to
        :func:`project_gaps_interior_point` (Mehrotra, dual-regularised, on the same envelope Cholesky)
        should that not converge; PIQP (:func:`project_gaps_ipm`) and then :func:`project_gaps_large`
        (pivoting, Clarabel, polish) serve if even that fails. The augmented Lagrangian's Newton
        steps grow with the diameter of the jam (10-21 at 400 pedestrians in one jam, 30-75 at 1400),
        the interior point iterations do not (11-17): after a miss the interior point method is used
        directly for a while: the augmented Lagrangian is tried again after ``ALM_SKIP_AFTER_MISS`` large
        projections, after twice as many at each further miss in a row (up to ``ALM_SKIP_MAX``). Right
        after a large projection, the interior point method starts from a working set
        (:meth:`_working_set`, :func:`project_gaps_working_set`): the same exact answer from smaller
        solves (1.2-1.4× faster in the door jams of ``benchmarks/projection.py`` at N = 1000-10 000).

        ``lam_warm`` (one per candidate, or None): multipliers of a projection of the same step from the
        same velocities on a subset of these candidates (before a re-detection added some). The
        augmented Lagrangian then starts from them and converges in a few Newton steps (measured in a
        door jam of 1400 pedestrians: 1-8 steps instead of 40-70 from zero).
        """
        # In a persistent jam the dense path fails every step: skip it right after a large projection
        # (step() then skips the fused step too, so fused and staged runs stay bitwise equal).
        status = STATUS_TOO_LARGE if self._large_projection_last_step else STATUS_OK
        if status == STATUS_OK:
            v_impact = vel[:, :2].copy()
            lam_p, _, status = project_gaps(vel, mass, con["a"], con["b"], con["gap"], con["nx"], con["ny"], h,
                                            PROJECTION_TOL_M_S, self.max_dense_projection_rows)
            if status != STATUS_OK:
                vel[:, :2] = v_impact
        if status != STATUS_OK:
            self.n_sparse_solves += 1
            self._large_step = self.step_count
            # The large solvers see only the pedestrians some candidate touches (the others keep their
            # velocity): their cost then follows the jam, not the size of the crowd.
            bodies, c_a, c_b = touched_bodies(vel.shape[0], con["a"], con["b"])
            v_sub = vel[bodies]
            m_sub = mass[bodies]
            keys = _contact_keys(idx[con["a"]], np.where(con["b"] >= 0, idx[np.maximum(con["b"], 0)], -1),
                                 con["wall"], self.state.n, self.walls.shape[0])
            lam_p = self._project_large(v_sub, m_sub, c_a, c_b, con, h, lam_warm, keys)
            vel[bodies, :2] = v_sub[:, :2]
            pushed = lam_p > 0.0  # as compact_contacts counts them
            order = np.argsort(keys[pushed])
            self._active_keys = keys[pushed][order]  # sorted, for _working_set's look-up
            self._active_lam = lam_p[pushed][order]
            self._active_keys_step = self.step_count
        return lam_p

    def _project_large(self, vel, mass, c_a, c_b, con, h, lam_warm=None, keys=None):
        """:meth:`_project` for a projection too large for the dense path, in place on ``vel``. ``keys``
        (:func:`_contact_keys` of the candidates, or None) let the interior point method start from a
        working set (:data:`WORKING_SET_SLACK_M_S`) when the previous step had a large projection."""
        args = (vel, mass, c_a, c_b, con["gap"], con["nx"], con["ny"], h)
        starts = [] if lam_warm is None else [(lam_warm, ALM_WARM_NEWTON_BUDGET, False)]
        if self._skip_alm <= 0:
            starts.append((np.zeros(c_a.shape[0]), ALM_NEWTON_BUDGET, True))
        for lam0, budget, cold in starts:
            lam_p, steps, status = project_gaps_alm(*args, lam0, budget)
            self.n_alm_newton_steps += steps
            if status == STATUS_OK:
                if cold:  # converged from zero: it suits this jam again
                    self._alm_backoff = ALM_SKIP_AFTER_MISS
                return lam_p
        if self._skip_alm <= 0:  # the augmented Lagrangian missed from zero: skip it for a while
            self._skip_alm = self._alm_backoff
            self._alm_backoff = min(2 * self._alm_backoff, ALM_SKIP_MAX)
        self._skip_alm -= 1
        self.n_ipm_projections += 1
        start = self._working_set(vel, c_a, c_b, con, h, keys)
        if start is not None:
            working, z0 = start
            lam_p, solves, status = project_gaps_working_set(*args, working, z0=z0)
            self.n_working_set_solves += solves
            if status == STATUS_OK:
                return lam_p
        lam_p, _, status = project_gaps_interior_point(*args)
        if status == STATUS_OK:
            return lam_p
        self.n_piqp_projections += 1  # not seen in practice: PIQP, a proximal interior point method
        lam_p, ok = project_gaps_ipm(*args)
        if ok:
            return lam_p
        # The interior point method failed (not seen in practice): pivoting, Clarabel and its polish.
        self.n_fallback_solves += 1
        lam_p, _ = project_gaps_large(*args)
        return lam_p

    def _working_set(self, vel, c_a, c_b, con, h, keys):
        """The interior point method's first working set and start: ``(working, z0)`` for
        :func:`project_gaps_working_set`, or None without keys or a large projection in the previous
        step. ``working`` (bool per candidate): the contacts active in that projection and the
        candidates whose slack at ``vel`` is below :data:`WORKING_SET_SLACK_M_S`; ``z0``: their
        percussions there (0 for the others), from which the first solve starts (1.02-1.09× faster than
        from the cold start on the door jams of ``benchmarks/projection.py`` at N = 1000-10 000)."""
        if keys is None or self._active_keys_step < self.step_count - 1:
            return None
        slack = gap_residuals(vel, con["gap"] / h, c_a, c_b, con["nx"], con["ny"])
        z0 = np.zeros(keys.shape[0])
        if self._active_keys.shape[0]:
            at = np.minimum(np.searchsorted(self._active_keys, keys), self._active_keys.shape[0] - 1)
            was_active = self._active_keys[at] == keys
            z0[was_active] = self._active_lam[at[was_active]]
        return (z0 > 0.0) | (slack < WORKING_SET_SLACK_M_S), z0

    def _redetect(self, con, speed, grown, idx, r_max, h):
        """Candidates with margins from the speeds ``speed`` (compact, (n,)) appended to ``con``;
        None when there is no new one. Only pairs involving a pedestrian whose margin grew
        (compact rows ``grown``) can be new (positions have not moved yet in this step)."""
        p = self.params
        reach = 2.0 * r_max + p.contact_tolerance_m + 2.0 * h * (float(speed[grown].max()) + float(speed.max()))
        pairs = grid_pairs_around(self.state.position_m, idx, grown, reach)
        # Candidates among the grown pedestrians and their neighbours only (rows ``sub`` of idx).
        sub = np.unique(np.concatenate([grown, pairs.ravel()]))
        row_in_sub = np.full(idx.shape[0], -1, np.int64)
        row_in_sub[sub] = np.arange(sub.shape[0])
        con2 = dict(zip(CONTACT_FIELDS, contact_candidates(self.state.position_m, self.state.radius_m, speed[sub],
                                                           idx[sub], row_in_sub[pairs], self.walls, self._wall_owner,
                                                           p.contact_tolerance_m, h)))
        con2["a"], con2["b"] = renumber_rows(sub, con2["a"], con2["b"])
        n = idx.shape[0]
        n_seg = self.walls.shape[0]
        near = row_in_sub[con["a"]] >= 0  # a known candidate matching a new one has its row a in sub
        new = ~np.isin(_contact_keys(con2["a"], con2["b"], con2["wall"], n, n_seg),
                       _contact_keys(con["a"][near], con["b"][near], con["wall"][near], n, n_seg),
                       assume_unique=True)
        if not new.any():
            return None
        return {k: np.concatenate([con[k], con2[k][new]]) for k in con}

    def _active_links(self, idx):
        st = self.state
        if st.links.shape[0] == 0:
            z = np.zeros(0, np.int64)
            e = np.zeros((0, 2))
            return z, z, e, e, e
        keep = st.active[st.links[:, 0]] & st.active[st.links[:, 1]]
        links = st.links[keep]
        offsets = st.link_offsets_m[keep]
        dvec, gi, gj = link_geometry(st.position_m, st.heading_rad, links, offsets)
        rank = np.full(st.n, -1, np.int64)
        rank[idx] = np.arange(idx.shape[0])
        return rank[links[:, 0]], rank[links[:, 1]], dvec, gi, gj

    def min_gap_m(self) -> float:
        """Smallest gap between two active pedestrians or a pedestrian and a wall (negative = overlap)."""
        idx = self.active_index
        st = self.state
        best = float("inf")
        if idx.shape[0] >= 2:
            pairs = self.neighbor_pairs(2.0 * float(st.radius_m[idx].max()) + 0.05)
            if pairs.shape[0]:
                d = np.linalg.norm(st.position_m[idx[pairs[:, 0]]] - st.position_m[idx[pairs[:, 1]]], axis=1)
                best = float(np.min(d - st.radius_m[idx[pairs[:, 0]]] - st.radius_m[idx[pairs[:, 1]]]))
        if self.walls.shape[0] and idx.shape[0]:
            _, _, gap, *_ = self.wall_proximity(0.05)
            if gap.shape[0]:
                best = min(best, float(gap.min()))
        return best


def _contact_keys(a, b, wall, n, n_walls):
    """One int64 per contact, equal for the same pair (a < b, pedestrian numbers below ``n``) or the
    same pedestrian and wall segment (b < 0, segment ``wall`` of ``n_walls``) wherever it stands in a
    candidate list: matches contacts across lists (re-detection, the previous step's projection).
    A candidate list holds each pair and each pedestrian-segment contact once, so its keys are unique
    (``np.isin(..., assume_unique=True)``, 5× faster on door jams; ``tests/test_simulator.py``)."""
    a = np.asarray(a, np.int64)
    return np.where(b >= 0, a * n + b, n * n + a * max(1, n_walls) + wall)


_EMPTY_1D = np.zeros(0)
_EMPTY_2D = np.zeros((0, 2))
_NO_PAIRS = np.zeros((0, 2), np.int64)
