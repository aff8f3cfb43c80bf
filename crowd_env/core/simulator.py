"""One time step of the Kabalan et al. (2016) model (collision-problem.md, "Recommended time step").

1. smooth update (Eq. 3, 14, 15): u* = u + h/τ (u_intent − u) + h f_ext/m,
   ω* = ω + h (−k wrap(θ − θ_d) − c ω)/I;
2. candidate contacts with a speculative margin ε + 2h(|u_i| + |u_j|) (k-d tree broad phase, exact
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
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import shapely
from scipy.spatial import cKDTree

from .collision import (MAX_DENSE_BODIES, MAX_DENSE_PROJECTION_ROWS, MAX_DENSE_ROWS, STATUS_OK, project_gaps,
                        project_gaps_large, resolve_impacts, solve_clusters, solve_rows_qp, solve_rows_sparse)
from .contacts import detect_contacts, link_geometry
from .params import ModelParams, ParameterError
from .segments import as_segments, endpoint_owners, wall_proximity
from .state import CrowdState, StateError


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


def wrap_angle(angle):
    """Wrap to (−π, π]."""
    return np.pi - np.mod(np.pi - angle, 2.0 * np.pi)


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
        self.destination = self._check_destination(destination, state.n)
        state.validate()
        self._check_walls(state)
        self.state = state
        self.time_s = 0.0
        self.step_count = 0
        self.n_fallback_solves = 0
        self.n_redetections = 0  # steps where faster post-impact speeds called for more candidates
        self.n_sparse_solves = 0  # impact clusters / projections too large for the dense path
        # Size limits of the dense (compiled) solvers; larger problems take the sparse path. Exposed so
        # that tests can force either path; both are exact, so results agree to round-off.
        self.max_dense_rows = MAX_DENSE_ROWS
        self.max_dense_bodies = MAX_DENSE_BODIES
        self.max_dense_projection_rows = MAX_DENSE_PROJECTION_ROWS
        self._skip_pivoting = 0
        self.profile = profile
        self._tree_key = -1
        self._tree = None
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

    def _at_destination(self, points, destination) -> np.ndarray:
        """(n,) bool: each point lies in exit ``destination`` (any exit for -1; the caller checked that)."""
        ok = destination < 0
        for d in np.unique(destination[~ok]):
            sel = destination == d
            ok[sel] = shapely.contains_xy(self.geometry.exits[int(d)], points[sel, 0], points[sel, 1])
        return ok

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

        Built once per step from a k-d tree; a later call with a smaller radius reuses the list
        (a superset: callers filter by distance).
        """
        if self._tree_key != self.step_count:
            self._tree_key = self.step_count
            idx = self.active_index
            self._tree = cKDTree(self.state.position_m[idx]) if idx.size else None
            self._pairs = None
            self._pairs_radius = -1.0
        if self._tree is None:
            return np.zeros((0, 2), np.int64)
        if radius_m > self._pairs_radius:
            self._pairs = self._tree.query_pairs(radius_m, output_type="ndarray").astype(np.int64, copy=False)
            self._pairs_radius = radius_m
        return self._pairs

    def wall_proximity(self, margin_m: float):
        """Wall neighbours of the active pedestrians within ``margin_m`` of their surface
        (see :func:`crowd_env.core.segments.wall_proximity`)."""
        idx = self.active_index
        return wall_proximity(self.state.position_m, self.state.radius_m, idx, self.walls, self._wall_owner,
                              np.full(idx.shape[0], margin_m))

    # ------------------------------------------------------------------ stepping
    def _check_input(self, name, value, shape):
        arr = np.asarray(value, dtype=np.float64)
        if arr.shape != shape:
            raise ValueError(f"{name} must have shape {shape} (one row per pedestrian), got {arr.shape}")
        finite = np.isfinite(arr).reshape(shape[0], -1).all(axis=1)
        if not finite.all():
            bad = np.flatnonzero(~finite)
            raise ValueError(f"{name} is not finite for pedestrian(s) {bad[:10].tolist()}")
        return arr

    def step(self, intents_m_s, *, desired_heading_rad=None, external_force_n=None) -> StepResult:
        """Advance one step of ``params.dt_s``.

        ``intents_m_s`` (N, 2): velocity intent of every pedestrian (rows of inactive ones are ignored).
        ``desired_heading_rad`` (N,): θ_d of Eq. 15; by default the direction of the intent (the
        current heading where the intent is zero). ``external_force_n`` (N, 2): added forces.
        """
        st = self.state
        p = self.params
        n_all = st.n
        h = p.dt_s
        intents = self._check_input("intents_m_s", intents_m_s, (n_all, 2))
        if desired_heading_rad is not None:
            desired_heading_rad = self._check_input("desired_heading_rad", desired_heading_rad, (n_all,))
        if external_force_n is not None:
            external_force_n = self._check_input("external_force_n", external_force_n, (n_all, 2))
        timings = {}
        t0 = time.perf_counter()
        idx = self.active_index
        n = idx.shape[0]
        # 1. smooth update (explicit Euler on the velocity, semi-implicit on positions)
        vel = np.empty((n, 3))
        u = st.velocity_m_s[idx]
        tau = st.tau_s[idx]
        acc = (intents[idx] - u) / tau[:, None]
        if external_force_n is not None:
            acc += external_force_n[idx] / st.mass_kg[idx, None]
        vel[:, :2] = u + h * acc
        if p.rotation:
            theta = st.heading_rad[idx]
            if desired_heading_rad is None:
                it = intents[idx]
                speed = np.hypot(it[:, 0], it[:, 1])
                theta_d = np.where(speed > 1e-12, np.arctan2(it[:, 1], it[:, 0]), theta)
            else:
                theta_d = desired_heading_rad[idx]
            omega = st.angular_velocity_rad_s[idx]
            torque = -st.heading_stiffness[idx] * wrap_angle(theta - theta_d) - st.heading_damping[idx] * omega
            vel[:, 2] = omega + h * torque / st.inertia_kg_m2[idx]
        else:
            vel[:, 2] = 0.0
        t1 = time.perf_counter()
        timings["smooth"] = t1 - t0
        # 2. contact candidates
        vmax = float(np.sqrt((vel[:, :2] ** 2).sum(axis=1).max())) if n else 0.0
        r_max = float(st.radius_m[idx].max()) if n else 0.0
        pairs = self.neighbor_pairs(2.0 * r_max + p.contact_tolerance_m + 4.0 * h * vmax)
        t2 = time.perf_counter()
        timings["neighbors"] = t2 - t1
        # Compact copies for the kernels.
        pos = st.position_m
        con = detect_contacts(pos, st.radius_m, vel_full_view(vel, idx, n_all), idx, pairs, self.walls,
                              self._wall_owner, p.contact_tolerance_m, h)
        links_a, links_b, dvec, gi, gj = self._active_links(idx)
        t3 = time.perf_counter()
        timings["contacts"] = t3 - t2
        mass = st.mass_kg[idx]
        inertia = st.inertia_kg_m2[idx]
        ke0 = kinetic_energy(vel, mass, inertia)
        speed_star = np.hypot(vel[:, 0], vel[:, 1])
        # 3. impacts
        cluster_args = (con["a"], con["b"], con["nx"], con["ny"], con["rho_a"], con["rho_b"], links_a, links_b,
                        dvec, gi, gj, p.normal_dissipation_kg, p.tangential_dissipation_kg,
                        p.link_dissipation_kg_per_m2, p.rotation)
        p_n, p_t, in_impact, root, unsolved, n_clusters, max_cluster = resolve_impacts(
            vel, mass, inertia, con["a"], con["b"], con["gap"], con["nx"], con["ny"], con["rho_a"], con["rho_b"],
            links_a, links_b, dvec, gi, gj, p.normal_dissipation_kg, p.tangential_dissipation_kg,
            p.link_dissipation_kg_per_m2, p.contact_tolerance_m, 1e-9, p.rotation,
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
        # projecting, and after it if needed) and project from the post-impact velocities again.
        v_impact = vel[:, :2].copy()
        det_speed = speed_star
        lam_p = None
        for _ in range(MAX_REDETECT + 1):
            speed = np.hypot(vel[:, 0], vel[:, 1])
            grown = np.flatnonzero(speed > 2.0 * det_speed + 0.5 * p.contact_tolerance_m / h)
            if grown.size:
                det_speed = np.maximum(det_speed, speed)
                merged = self._redetect(con, det_speed, grown, idx, n_all, r_max, h)
                if merged is not None:
                    extra = merged["a"].shape[0] - con["a"].shape[0]
                    con = merged
                    p_n = np.concatenate([p_n, np.zeros(extra)])
                    p_t = np.concatenate([p_t, np.zeros(extra)])
                    in_impact = np.concatenate([in_impact, np.zeros(extra, dtype=bool)])
                    vel[:, :2] = v_impact
                    lam_p = None
                    self.n_redetections += 1
            if lam_p is not None:
                break
            lam_p = self._project(vel, mass, con, h, idx)
        ke2 = kinetic_energy(vel, mass, inertia)
        t5 = time.perf_counter()
        timings["projection"] = t5 - t4
        # 5. integrate and leave at exits
        st.velocity_m_s[idx] = vel[:, :2]
        st.angular_velocity_rad_s[idx] = vel[:, 2]
        st.position_m[idx] += h * vel[:, :2]
        if p.rotation:
            st.heading_rad[idx] = wrap_angle(st.heading_rad[idx] + h * vel[:, 2])
        exited = np.zeros(0, np.int64)
        if self._exit_test is not None and n:
            out = np.asarray(self._exit_test(st.position_m[idx]), dtype=bool)
            if self.destination is not None and out.any():  # in an exit: is it the pedestrian's own?
                hit = idx[out]
                out[out] = self._at_destination(st.position_m[hit], self.destination[hit])
            if out.any():
                exited = idx[out]
                st.active[exited] = False
        self.time_s += h
        self.step_count += 1
        timings["integrate"] = time.perf_counter() - t5
        keep = in_impact | (lam_p > 0)
        return StepResult(
            time_s=self.time_s,
            contact_i=idx[con["a"][keep]],
            contact_j=np.where(con["b"][keep] >= 0, idx[np.maximum(con["b"][keep], 0)], -1),
            contact_wall=con["wall"][keep],
            percussion_normal=(p_n + lam_p)[keep],
            percussion_tangent=p_t[keep],
            n_impact_clusters=int(n_clusters),
            max_cluster_size=int(max_cluster),
            kinetic_energy_before_impact_j=ke0,
            kinetic_energy_after_impact_j=ke1,
            kinetic_energy_after_projection_j=ke2,
            exited=exited,
            timings_s=timings,
        )

    def _solve_large_cluster(self, *rows):
        """Impact of a cluster too large for the dense path: sparse pivoting, Clarabel if that fails."""
        self.n_sparse_solves += 1
        v_plus, lam, status = solve_rows_sparse(*rows)
        if status != STATUS_OK:
            self.n_fallback_solves += 1
            v_plus, lam = solve_rows_qp(*rows)
        return v_plus, lam

    def _project(self, vel, mass, con, h, idx):
        """Gap projection (step 4) in place on ``vel``; returns the projection percussion per contact.

        Components of active constraints small enough are solved densely (:func:`project_gaps`);
        otherwise the whole projection goes to :func:`project_gaps_large` (sparse pivoting; Clarabel
        and a polish where degenerate jams make pivoting cycle).
        """
        v_impact = vel[:, :2].copy()
        lam_p, _, status = project_gaps(vel, mass, con["a"], con["b"], con["gap"], con["nx"], con["ny"], h, 1e-10,
                                        self.max_dense_projection_rows)
        if status != STATUS_OK:
            vel[:, :2] = v_impact
            self.n_sparse_solves += 1
            # In a persistent jam pivoting keeps cycling: after a fallback go straight to the interior
            # point solver (and its polish) for a while, trying pivoting again every 10th time.
            pivot_first = self._skip_pivoting <= 0
            lam_p, path = project_gaps_large(vel, mass, con["a"], con["b"], con["gap"], con["nx"], con["ny"], h,
                                             pivot_first)
            self._skip_pivoting = 9 if path > 0 and pivot_first else self._skip_pivoting - 1
            self.n_fallback_solves += int(path > 0)
        return lam_p

    def _redetect(self, con, speed, grown, idx, n_all, r_max, h):
        """Candidates with margins from the speeds ``speed`` (compact, (n,)) appended to ``con``;
        None when there is no new one. Only pairs involving a pedestrian whose margin grew
        (compact rows ``grown``) can be new: the k-d tree of this step is queried around them only."""
        p = self.params
        self.neighbor_pairs(0.0)  # the tree of this step (positions have not moved yet)
        reach = 2.0 * r_max + p.contact_tolerance_m + 2.0 * h * (float(speed[grown].max()) + float(speed.max()))
        lists = self._tree.query_ball_point(self.state.position_m[idx[grown]], reach)
        counts = np.fromiter((len(x) for x in lists), dtype=np.int64, count=len(lists))
        if counts.sum():
            js = np.concatenate([np.asarray(x, dtype=np.int64) for x in lists])
            ia = np.repeat(grown, counts)
            other = js != ia
            pairs = np.unique(np.stack([np.minimum(ia, js)[other], np.maximum(ia, js)[other]], axis=1), axis=0)
        else:
            pairs = np.zeros((0, 2), np.int64)
        as_velocity = np.zeros((n_all, 2))
        as_velocity[idx, 0] = speed  # detect_contacts only uses the norm of each velocity
        con2 = detect_contacts(self.state.position_m, self.state.radius_m, as_velocity, idx, pairs, self.walls,
                               self._wall_owner, p.contact_tolerance_m, h)
        n = idx.shape[0]
        n_seg = max(1, self.walls.shape[0])

        def key(c):
            return np.where(c["b"] >= 0, c["a"] * n + c["b"], n * n + c["a"] * n_seg + c["wall"])

        new = ~np.isin(key(con2), key(con))
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


def vel_full_view(vel_compact, idx, n_all):
    """Scatter compact (n, 3) velocities into a full (N, 2) array for kernels indexed globally."""
    full = np.zeros((n_all, 2))
    full[idx] = vel_compact[:, :2]
    return full


def kinetic_energy(vel, mass, inertia) -> float:
    """½ Σ (m |u|² + I ω²) in joules for compact (n, 3) velocities."""
    return float(0.5 * (mass @ (vel[:, 0] ** 2 + vel[:, 1] ** 2) + inertia @ vel[:, 2] ** 2))
