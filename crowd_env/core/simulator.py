"""The Simulator: owns the crowd, the walls and the parameters, and advances one time step at a time.

The step's stages (Kabalan et al. 2016: the smooth dynamics Eq. 3, 14, 15; the Frémond impacts
Eq. 4-8; the gap projection; the integration) are listed and compiled in :mod:`crowd_env.core.step`;
the choice of solver for each impact cluster and projection is the
:class:`~crowd_env.core.solvers.cascade.SolverCascade`'s (``Simulator.cascade``). Positions advance with
the final velocities; pedestrians whose centre enters an exit leave (with per-pedestrian
``destination``: only through their own destination exit).

The velocity intent ``(N, 2)`` in m/s is the only behavioural input; external forces (for example
Helbing's social repulsion, Eq. 16) can be added per step. The core knows nothing of RL.

By default a step runs as one compiled call (:func:`crowd_env.core.step.advance`: the hand links, the fused
step, the exit test and the clock, the kernel the compiled rollouts run too); steps that need a solver beyond the
dense ones, and every step of a ``Simulator(profile=True)`` (which times each stage into
``StepResult.timings_s``), run the same compiled stages one by one from Python (:meth:`Simulator._staged_step`).
The kernels take the state, the world and the step's numbers as the named bundles of
:mod:`crowd_env.core.bundles` (:meth:`CrowdState.arrays`, :attr:`Simulator.world`, :attr:`Simulator.step_params`).

Periodic along x (``Simulator.period_m`` L > 0, from ``Geometry(period_x_m=L)``): x and x + L are the same
place; positions are kept in [0, L) and every pedestrian-pedestrian displacement is taken to its nearest image
(:mod:`crowd_env.core.periodic`), so a contact or a neighbour across the seam is the same as away from it.
"""
from __future__ import annotations

from crowd_env.errors import InputError

import functools
import time
from dataclasses import dataclass, field

import numpy as np

from .body import body_circles, body_gaps, check_body_depth, circle_count
from .contacts import active_links, contact_candidates, turning_gaps
from .neighbors import grid_pairs
from .params import DEFAULT_INTERACTION_REACH_M, ParameterError, PhysicsParams
from .checks import check_number
from .periodic import wrap_positions
from .polygons import PackedPolygons, pack_polygons
from .segments import as_segments, endpoint_owners, wall_proximity
from .solvers.cascade import SolverCascade
from .solvers.graph import contact_keys
from .solvers.impact import solve_clusters
from .state import CrowdState, StateError, first_overlap, pair_distances
from .timestep import check_time_step
from .bundles import Links, StepInputs, StepParams, World, empty_exits
from .step import (FUSED_OK, MAX_INPUT_SPEED_M_S, MAX_REDETECT, advance, compact_bodies, detection_reach,
                   finish_step, first_out_of_bound, grown_margins, impact_stage, kinetic_energy, leave_at_exits,
                   redetection_round, smooth_update)



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
    """Owns a :class:`CrowdState`, the walls and the parameters; advances with :meth:`step`.

    ``params``: the core's :class:`~crowd_env.core.params.PhysicsParams` (default), or any object that carries them
    as ``params.physics`` (the model a preset names, :class:`crowd_env.walking.model.ModelParams`, whose walking
    parameters the calibrated agent reads from :attr:`params`); the step reads :attr:`physics` only.

    ``geometry`` may be any object with ``walls`` ((S, 4) segments) and ``in_exit(points)``
    (bool mask); or pass ``walls`` directly and optionally ``exit_test``. ``destination``: None (a
    pedestrian leaves through any exit) or (N,) int indices into ``geometry.exits``, -1 for any exit:
    pedestrian i then leaves only when its centre enters exit ``destination[i]`` (another exit is floor
    for it; see :class:`~crowd_env.scenarios.Scenario`). ``period_m``: the periodicity L along x (module
    docstring; None: the geometry's ``period_x_m``, 0 without one); it must exceed 2 (2 r_max + reach), the reach
    being how far beyond the bodies the behaviour's forces act: ``params.interaction_reach_m`` (a ModelParams: its
    ``social_cutoff_m``), :data:`~crowd_env.core.params.DEFAULT_INTERACTION_REACH_M` for physics alone; so that the
    nearest image is the only one any interaction reaches. The start
    positions are brought into [0, L) (in place) and checked for overlaps across the seam.
    """

    period_m = 0.0  # the periodicity along x (set per instance; simulators pickled before it existed have none)

    def __init__(self, state: CrowdState, *, geometry=None, walls=None, exit_test=None,
                 params=None, profile: bool = False, destination=None, period_m=None):
        if not isinstance(state, CrowdState):
            raise StateError(f"state must be a CrowdState, got {type(state).__name__}")
        self.params = PhysicsParams() if params is None else params
        self.physics = self.params if isinstance(self.params, PhysicsParams) else getattr(self.params, "physics", None)
        if not isinstance(self.physics, PhysicsParams):
            raise ParameterError(f"params must be a ModelParams (crowd_env.walking) or the core's PhysicsParams (any "
                                 f"object carrying one as .physics), got {type(self.params).__name__}")
        if geometry is not None and walls is not None:
            raise ParameterError("give either geometry or walls, not both")
        self.geometry = geometry
        self.walls = as_segments(geometry.walls if geometry is not None else ([] if walls is None else walls))
        self._wall_owner = endpoint_owners(self.walls)
        self._exit_test = geometry.in_exit if geometry is not None else exit_test
        # The exits as packed polygons for the compiled exit test (a duck-typed geometry without
        # ``exits`` and a bare ``exit_test`` use the callable on the end points instead).
        self._exits = None
        if geometry is not None and getattr(geometry, "exits", None) is not None and \
                (len(geometry.exits) or getattr(geometry, "period_x_m", 0.0) > 0.0):
            self._exits = pack_polygons(geometry.exits)  # none at all in a periodic geometry
        self.destination = self._check_destination(destination, state.n)
        self._exit_destination = np.full(state.n, -1, np.int64) if self.destination is None else self.destination
        check_body_depth(self.physics.body_depth_m, state.radius_m)
        if self.physics.body_depth_m > 0.0:  # bodies of three circles may stand closer than their disks
            state.validate(overlap_tolerance_m=np.inf)
            self._check_bodies(state)
        else:
            state.validate()
        self.period_m = self._check_period(period_m, state)
        self._check_walls(state)
        check_time_step(state, self.physics)  # refuses an unstable dt_s, warns above the safe step (timestep.py)
        self.state = state
        self.time_s = 0.0
        self.step_count = 0
        self.n_redetections = 0  # steps where faster post-impact speeds called for more candidates
        self.n_staged_steps = 0  # steps run stage by stage (profiling, large problems, re-detection)
        # The choice of solver, its size limits, budgets, warm starts and counters: see SolverCascade.
        self.cascade = SolverCascade(reference=self.physics.solver == "cvxpy")
        self.profile = profile
        self._pairs_key = -1
        self._pairs = None
        self._pairs_radius = -1.0
        self._index = None
        self._index_key = -1

    def _check_period(self, period_m, state, tolerance_m: float = 1e-9) -> float:
        """The periodicity L (module docstring) checked against the geometry's and the crowd's size; wraps the
        start positions into [0, L) and raises :class:`StateError` naming a pair that overlaps across the seam."""
        own = float(getattr(self.geometry, "period_x_m", 0.0) or 0.0)
        if period_m is None:
            period = own
        else:
            period = check_number("period_m", period_m, error=ParameterError, minimum=0.0)
            if own and period != own:
                raise ParameterError(f"period_m = {period_m!r} differs from the geometry's period_x_m = {own!r}")
        if period == 0.0:
            return 0.0
        idx = np.flatnonzero(state.active)
        interaction = float(getattr(self.params, "interaction_reach_m", DEFAULT_INTERACTION_REACH_M))
        reach = 2.0 * (2.0 * float(state.radius_m.max(initial=0.0)) + interaction)
        if period <= reach:
            raise ParameterError(f"period_m = {period:g} m must exceed 2 (2 r_max + the interactions' reach "
                                 f"{interaction:g} m, social_cutoff_m) = {reach:g} m: the nearest image must be the "
                                 "only one an interaction reaches")
        wrap_positions(state.position_m, period)
        pair = first_overlap(state.position_m[idx], state.radius_m[idx], tolerance_m, period)
        if pair is not None:
            i, j = int(idx[pair[0]]), int(idx[pair[1]])
            raise StateError(f"pedestrians {i} and {j} overlap by {pair[2]:.4g} m at start (positions "
                             f"{state.position_m[i].tolist()} and {state.position_m[j].tolist()}, period {period:g} m "
                             "along x)")
        return period

    def _check_bodies(self, state, tolerance_m: float = 1e-9) -> None:
        """Raise :class:`StateError` naming the pair when two active bodies of three circles overlap (the start check
        of :meth:`CrowdState.validate <crowd_env.core.state.CrowdState.validate>` for disks, with the bodies' own
        gaps, :func:`~crowd_env.core.body.body_gaps`; across a periodic seam the disks' check stays, stricter)."""
        idx = np.flatnonzero(state.active)
        if idx.size < 2:
            return
        pairs = idx[grid_pairs(state.position_m, idx, 2.0 * float(state.radius_m[idx].max()))]
        if not pairs.size:
            return
        gaps = body_gaps(state.position_m, state.heading_rad, state.radius_m, self.physics.body_depth_m, pairs)
        k = int(np.argmin(gaps))
        if gaps[k] < -tolerance_m:
            i, j = int(pairs[k, 0]), int(pairs[k, 1])
            raise StateError(f"pedestrians {i} and {j} overlap by {-gaps[k]:.4g} m at start (bodies of three circles, "
                             f"positions {state.position_m[i].tolist()} and {state.position_m[j].tolist()})")

    def _check_walls(self, state, tolerance_m: float = 1e-9) -> None:
        """Raise :class:`StateError` naming the pedestrian and the wall when one's body overlaps a wall."""
        idx = np.flatnonzero(state.active)
        if not self.walls.shape[0] or not idx.size:
            return
        ped, seg, gap = self._wall_gaps(state, idx, 0.0)
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

    @property
    def n_sparse_solves(self) -> int:
        """Impact clusters and projections too large for the dense solvers (``cascade.n_sparse_solves``)."""
        return self.cascade.n_sparse_solves

    @property
    def n_fallback_solves(self) -> int:
        """Solves handed to the last-resort solvers (``cascade.n_fallback_solves``)."""
        return self.cascade.n_fallback_solves

    @property
    def wall_owner(self) -> np.ndarray:
        """Shared wall vertices, :func:`~crowd_env.core.segments.endpoint_owners` of :attr:`walls`: what
        wall contacts and wall repulsion need so that a vertex shared by segments counts once."""
        return self._wall_owner

    # ------------------------------------------------------------------ compiled rollouts
    @property
    def exit_polygons(self) -> PackedPolygons | None:
        """The exits packed for the compiled exit test (None without a geometry with exits)."""
        return self._exits

    @property
    def exit_destination(self) -> np.ndarray:
        """(N,) int64: each pedestrian's exit (−1: any), as the compiled exit test reads it."""
        return self._exit_destination

    @property
    def world(self) -> World:
        """The walls, the exits (packed; none: empty) with each pedestrian's exit and the periodicity, as the
        compiled step takes them (:class:`~crowd_env.core.bundles.World`; built once)."""
        world = self.__dict__.get("_world")
        if world is None:
            exits = self._exits.arrays if self._exits is not None else empty_exits()
            world = World(self.walls, self._wall_owner, *exits, np.array(self._exit_destination, np.int64),
                          float(self.period_m))
            self._world = world
        return world

    @property
    def step_params(self) -> StepParams:
        """h, ε, the dissipations and the dense solvers' limits (the cascade's, read now) as the compiled step
        takes them (:class:`~crowd_env.core.bundles.StepParams`)."""
        return StepParams._make(self._step_fields())

    def _step_fields(self) -> tuple:
        """:attr:`step_params` as a plain tuple (as :func:`~crowd_env.core.step.advance` takes it), kept while the
        params object and the cascade's limits stay the same."""
        p, c = self.physics, self.cascade
        key = (c.reference, c.max_dense_rows, c.max_dense_bodies, c.max_dense_projection_rows)
        kept = self.__dict__.get("_step_kept")
        if kept is None or kept[0] is not p or kept[1] != key:
            max_rows, max_bodies = c.impact_limits()
            fields = (float(p.dt_s), float(p.contact_tolerance_m), float(p.normal_dissipation_kg),
                      float(p.tangential_dissipation_kg), float(p.link_dissipation_kg_per_m2), bool(p.rotation),
                      int(max_rows), int(max_bodies), int(c.max_dense_projection_rows), float(p.body_depth_m))
            kept = self._step_kept = (p, key, fields)
        return kept[2]

    def world_fields(self) -> tuple:
        """:attr:`world` as a plain tuple (as :func:`~crowd_env.core.step.advance` takes it; kept)."""
        fields = self.__dict__.get("_world_kept")
        if fields is None:
            fields = self._world_kept = tuple(self.world)
        return fields

    def fused_ready(self) -> bool:
        """Whether the next step may be tried as one compiled call (:func:`~crowd_env.core.step.advance`):
        not when profiling, nor when the cascade wants its general path (:meth:`SolverCascade.dense_only`).
        A compiled rollout runs fused steps only while this holds, and it holds on after a fused step."""
        return not self.profile and self.cascade.dense_only(self.step_count)

    def advanced(self, n_steps: int, time_s: float, n_redetections: int = 0) -> None:
        """Account for ``n_steps`` fused steps that a compiled rollout ran on :attr:`state` (the same
        kernels as :meth:`step`), reaching the clock ``time_s`` (accumulated as :meth:`step` does), with
        ``n_redetections`` re-detection rounds among them."""
        self.step_count += int(n_steps)
        self.time_s = float(time_s)
        self.n_redetections += int(n_redetections)

    # ------------------------------------------------------------------ neighbours
    @property
    def active_index(self) -> np.ndarray:
        """Indices of the pedestrians still in the simulation."""
        if self._index_key != self.step_count:  # pedestrians leave only at the end of a step
            self._index_key = self.step_count
            self._index = self.state.active.nonzero()[0]  # = np.flatnonzero, without its 0.8 µs of dispatch
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
            self._pairs = grid_pairs(self.state.position_m, self.active_index, float(radius_m), self.period_m)
            self._pairs_radius = radius_m
        return self._pairs

    def built_pairs(self):
        """``(pairs, radius_m)``: the pairs :meth:`neighbor_pairs` built this step and their radius, or an empty list
        with radius −1."""
        if self._pairs_key == self.step_count and self._pairs is not None:
            return self._pairs, float(self._pairs_radius)
        return _NO_PAIRS, -1.0

    def keep_pairs(self, pairs: np.ndarray, radius_m: float) -> None:
        """Keep ``pairs`` built by compiled code this step as :meth:`neighbor_pairs` would build them
        (:func:`~crowd_env.core.neighbors.grid_pairs` of the active rows within ``radius_m``, which must exceed
        :meth:`built_pairs`' radius): :meth:`neighbor_pairs` and the step reuse them."""
        if self._pairs_key == self.step_count and radius_m <= self._pairs_radius:
            raise InputError(f"keep_pairs: pairs within {radius_m} m are already covered by those within "
                             f"{self._pairs_radius} m this step")
        self._pairs_key, self._pairs, self._pairs_radius = self.step_count, pairs, radius_m

    def _wall_gaps(self, state, idx, margin_m: float):
        """The walls within ``margin_m`` of the bodies ``idx`` of ``state`` (their circles, :mod:`crowd_env.core.body`;
        the disks for the paper's bodies; :func:`crowd_env.core.segments.wall_proximity`): ``(rows into idx,
        segments, gaps)``."""
        depth_m = self.physics.body_depth_m
        centre, rad, _ = body_circles(state.position_m, state.heading_rad, state.radius_m, idx, depth_m)
        ped, seg, gap, *_ = wall_proximity(centre, rad, np.arange(rad.shape[0]), self.walls, self._wall_owner,
                                           np.full(rad.shape[0], margin_m))
        return ped // circle_count(depth_m), seg, gap

    # ------------------------------------------------------------------ stepping
    def _check_input(self, name, value, shape, scale=None, bound=np.inf, unit="", bounds=True):
        """``value`` as a contiguous float64 array of ``shape``; raises :class:`InputError` naming ``name``
        and what was given unless it is an array of numbers of that shape, finite, with every row's norm
        times ``scale[row]`` (empty: 1) at most ``bound`` (:data:`~crowd_env.core.step.MAX_INPUT_SPEED_M_S`);
        ``bounds`` False: the shape and type only (the caller's compiled step checks the rest)."""
        if not bounds and type(value) is np.ndarray and value.dtype is _F64 and value.shape == shape \
                and value.flags.c_contiguous:
            return value  # what the step's callers pass: nothing to check or convert here
        arr = value if isinstance(value, np.ndarray) else None
        if arr is None:
            try:
                arr = np.asarray(value)
            except (TypeError, ValueError):  # ragged nesting, objects numpy cannot hold in one array
                arr = None
        if arr is None or arr.dtype.kind not in "biuf":
            raise InputError(f"{name} must be an array of numbers of shape {shape} (one row per pedestrian), got "
                             f"{_describe(value)}")
        if arr.shape != shape:
            given = "an array" if isinstance(value, np.ndarray) else f"a {type(value).__name__}"
            raise InputError(f"{name} must have shape {shape} (one row per pedestrian), got {given} of shape {arr.shape}")
        arr = np.ascontiguousarray(arr, dtype=np.float64)
        if not bounds:
            return arr
        scale = _EMPTY_1D if scale is None else scale
        first = first_out_of_bound(arr, scale, bound)
        if first >= 0:
            rows = arr.reshape(shape[0], -1)
            bad = np.flatnonzero(~np.isfinite(rows).all(axis=1))
            if bad.size:
                raise InputError(f"{name} is not finite for pedestrian(s) {bad[:10].tolist()}")
            norm = np.hypot(rows[:, 0], rows[:, 1])
            limit = bound / scale if scale.shape[0] else np.full(shape[0], bound)
            bad = np.flatnonzero(norm * (scale if scale.shape[0] else 1.0) > bound)
            bad = bad if bad.size else np.array([first])  # hypot and the kernel's root may differ in the last bit
            i = int(first)
            rule = (f"{bound:g} m/s" if not scale.shape[0] else
                    f"m u_max / tau = {limit[i]:.4g} {unit} (the force whose speed tau |f| / m is u_max = {bound:g} m/s)")
            raise InputError(f"{name} of pedestrian {i} has magnitude {norm[i]:.4g} {unit}; the step accepts at most "
                             f"{rule}, the bound crowd_env.core.step.MAX_INPUT_SPEED_M_S that keeps the contact "
                             f"detection's rounding below its tolerance (pedestrian(s) over it: {bad[:10].tolist()})")
        return arr

    def step(self, intents_m_s, *, desired_heading_rad=None, external_force_n=None) -> StepResult:
        """Advance one step of ``params.dt_s``.

        ``intents_m_s`` (N, 2): velocity intent of every pedestrian (rows of inactive ones are ignored).
        ``desired_heading_rad`` (N,): θ_d of Eq. 15; by default the direction of the intent (the
        current heading where the intent is zero). ``external_force_n`` (N, 2): added forces.

        Every input must be finite; an intent may be at most
        :data:`~crowd_env.core.step.MAX_INPUT_SPEED_M_S` (1e3 m/s) in norm and an external force at most
        m u_max / τ (the force equivalent to such an intent in Eq. 14; 1.66e5 N for m = 83 kg, τ = 0.5 s).
        Anything else raises :class:`~crowd_env.errors.InputError` naming the argument, the pedestrian and
        the bound, before the state changes.
        """
        given = (intents_m_s, desired_heading_rad, external_force_n)
        # The cascade says when the dense solvers alone may serve (not right after a large projection, whose
        # staged step skips the dense projection: the fused step waits too, so fused and staged runs stay
        # bitwise equal). The compiled step checks the bounds itself (first_bad_input) and refuses out-of-bound
        # inputs before it writes anything; the full checks below then raise naming them.
        if not self.profile and self.active_index.shape[0] and self.cascade.dense_only(self.step_count):
            result = self._fused_step(self._inputs(*given, bounds=False))
            if result is not None:
                return result
        return self._staged_step(self._inputs(*given))

    def _inputs(self, intents_m_s, desired_heading_rad, external_force_n, bounds: bool = True) -> tuple:
        """The step's inputs checked by :meth:`_check_input` (its bounds too unless ``bounds`` is False), as the
        fields of :class:`~crowd_env.core.bundles.StepInputs`."""
        n_all = self.state.n
        intents = self._check_input("intents_m_s", intents_m_s, (n_all, 2), bound=MAX_INPUT_SPEED_M_S, unit="m/s",
                                    bounds=bounds)
        theta_d = _EMPTY_1D if desired_heading_rad is None else \
            self._check_input("desired_heading_rad", desired_heading_rad, (n_all,), bounds=bounds)
        force = _EMPTY_2D if external_force_n is None else \
            self._check_input("external_force_n", external_force_n, (n_all, 2),
                              self.state.tau_s / self.state.mass_kg if bounds else None, MAX_INPUT_SPEED_M_S, "N",
                              bounds=bounds)
        return intents, theta_d, desired_heading_rad is not None, force, external_force_n is not None

    def _fused_step(self, inputs):
        """The whole step as one compiled call (:func:`~crowd_env.core.step.advance`); None when a stage needs the
        general path (nothing changed)."""
        idx = self.active_index
        t0 = time.perf_counter()
        status, contacts, ke0, ke1, ke2, n_clusters, max_cluster, min_gap, n_redetect, exited, time_s = advance(
            self.state.array_fields(), self.world_fields(), self._step_fields(), inputs, idx, *self.built_pairs(),
            self.time_s)
        if status != FUSED_OK:
            return None
        if contacts is None:  # none carried a percussion: empty arrays of their own, made here (cheaper)
            contacts = (np.empty(0, np.int64), np.empty(0, np.int64), np.empty(0, np.int64), np.empty(0), np.empty(0))
        if exited is None:
            exited = np.empty(0, np.int64)
        self.n_redetections += n_redetect
        exited = self._exit_by_test(idx, exited)
        self._tick(time_s)
        return self._result(contacts, ke0, ke1, ke2, n_clusters, max_cluster, exited,
                            {"fused": time.perf_counter() - t0}, min_gap)

    def _staged_step(self, inputs) -> StepResult:
        """The stages of :mod:`crowd_env.core.step` one by one, in the same order and with the same
        functions as :func:`~crowd_env.core.step.fused_step`, timed, with the solver cascade for the
        problems beyond the dense limits and the re-detection loop of stage 5 (:meth:`_staged_projection`)."""
        self.n_staged_steps += 1
        st = self.state
        p = self.physics
        h, eps_m = p.dt_s, p.contact_tolerance_m
        bodies, world, params = st.arrays(), self.world, self.step_params
        timings = {}
        t0 = time.perf_counter()
        idx = self.active_index
        # 1. smooth
        vel = smooth_update(bodies, StepInputs(*inputs), idx, params)
        t1 = time.perf_counter()
        timings["smooth"] = t1 - t0
        # 2. neighbors
        speed_star, r_max, reach = detection_reach(vel, st.radius_m, idx, eps_m, h, p.body_depth_m)
        pairs = self.neighbor_pairs(reach)
        t2 = time.perf_counter()
        timings["neighbors"] = t2 - t1
        # 3. contacts
        candidates = contact_candidates(st.position_m, st.heading_rad, st.radius_m, p.body_depth_m, speed_star, idx,
                                        pairs, self.walls, self._wall_owner, eps_m, h, self.period_m)
        links = self._active_links(idx)
        mass, inertia = compact_bodies(st.mass_kg, st.inertia_kg_m2, idx)
        t3 = time.perf_counter()
        timings["contacts"] = t3 - t2
        # 4. impacts: the dense ones compiled, the clusters they leave by the cascade
        ke0, p_n, p_t, in_impact, root, unsolved, n_clusters, max_cluster = impact_stage(vel, mass, inertia, candidates,
                                                                                         links, params)
        if unsolved.shape[0]:
            solve_clusters(unsolved, root, vel, mass, inertia, in_impact, candidates, links, params,
                           self.cascade.solve_impact_cluster, p_n, p_t)
        ke1 = kinetic_energy(vel, mass, inertia)
        t4 = time.perf_counter()
        timings["impacts"] = t4 - t3
        # 5. projection
        candidates, percussions, lam_p = self._staged_projection(bodies, vel, mass, candidates, (p_n, p_t, in_impact),
                                                                 speed_star, idx)
        ke2 = kinetic_energy(vel, mass, inertia)
        t5 = time.perf_counter()
        timings["projection"] = t5 - t4
        # 6. integrate and leave at exits
        previous = st.position_m[idx]
        min_gap, contacts = finish_step(bodies, world, params, idx, vel, candidates, percussions, lam_p)
        exited = self._leave_at_exits(idx, previous)
        self._tick(self.time_s + p.dt_s)
        timings["integrate"] = time.perf_counter() - t5
        return self._result(contacts, ke0, ke1, ke2, n_clusters, max_cluster, exited, timings, min_gap)

    def _staged_projection(self, bodies, vel, mass, candidates, percussions, speed_star, idx):
        """Stage 5 of the staged step, in place on ``vel``: ``(candidates, percussions, lam_p)`` with the
        candidates the re-detection added. The loop of the fused step (:func:`~crowd_env.core.step.fused_step`)
        with the solver cascade's projection: each round is :func:`~crowd_env.core.step.redetection_round` (its
        docstring says why candidates are detected again), and a projection repeated after a new candidate
        bound starts from the last one's multipliers (``lam_warm``)."""
        world, params = self.world, self.step_params
        v_impact = vel[:, :2].copy()
        det_speed = speed_star
        lam_p = _EMPTY_1D
        projected = once = False
        for _ in range(MAX_REDETECT + 1):
            grown = grown_margins(vel, det_speed, params.contact_tolerance_m, params.dt_s, bodies.radius_m, idx,
                                  params.body_depth_m)
            if grown.shape[0]:
                det_speed, candidates, percussions, lam_p, added, projected = redetection_round(
                    bodies, idx, world, params, vel, v_impact, det_speed, grown, candidates, percussions, lam_p,
                    projected)
                self.n_redetections += added
            if projected:
                break
            con = candidates._asdict()  # a projection again: a new candidate bound (lam_p extended)
            con["gap"] = turning_gaps(candidates, vel, params.dt_s, params.body_depth_m)[0]
            lam_p = self.cascade.project(vel, mass, con, params.dt_s, self.step_count,
                                         functools.partial(self._candidate_keys, idx, con), lam_p if once else None)
            projected = once = True
        return candidates, percussions, lam_p

    def _leave_at_exits(self, idx, previous_m) -> np.ndarray:
        """Deactivate pedestrians whose centre's straight path of the step, from ``previous_m`` ((n, 2)
        compact), met their exit (:func:`~crowd_env.core.step.leave_at_exits` through the exits of :attr:`world`,
        as in the compiled step :func:`~crowd_env.core.step.advance`). Returns their indices. With a bare
        ``exit_test`` callable (no geometry) only the end points are tested (:meth:`_exit_by_test`)."""
        exited = _NO_INDEX
        if idx.shape[0] and self._exits is not None:
            w = self.world
            exited = leave_at_exits(self.state.position_m, self.state.active, idx, previous_m, w.exit_destination,
                                    w.exit_vertices, w.exit_ring_start, w.exit_ring_owner, w.exit_boxes)
        return self._exit_by_test(idx, exited)

    def _exit_by_test(self, idx, exited) -> np.ndarray:
        """``exited``, or, without packed exits but with a bare ``exit_test`` callable, the pedestrians ``idx``
        whose centre it says is in an exit, deactivated."""
        if self._exits is None and self._exit_test is not None and idx.shape[0]:
            out = np.asarray(self._exit_test(self.state.position_m[idx]), dtype=bool)
            exited = idx[out]
            self.state.active[exited] = False
        return exited

    def _tick(self, time_s: float) -> None:
        """The clock after a step: ``time_s`` (t + h, accumulated step by step) and one more step."""
        self.time_s = float(time_s)
        self.step_count += 1

    def _result(self, contacts, ke0, ke1, ke2, n_clusters, max_cluster, exited, timings, min_gap) -> StepResult:
        # positional, in the order of the fields (keywords cost 0.4 µs more per step)
        return StepResult(self.time_s, *contacts, int(n_clusters), int(max_cluster), float(ke0), float(ke1),
                          float(ke2), exited, timings, float(min_gap))

    def _candidate_keys(self, idx, con):
        """:func:`~crowd_env.core.solvers.graph.contact_keys` of the candidates ``con`` (rows into ``idx``):
        the same key for the same contact in every step, as the cascade's warm starts need."""
        return contact_keys(idx[con["a"]], np.where(con["b"] >= 0, idx[np.maximum(con["b"], 0)], -1), con["wall"],
                            con["sub"], self.state.n, self.walls.shape[0], circle_count(self.physics.body_depth_m) ** 2)

    def _active_links(self, idx):
        """Hand links between active pedestrians, rows into ``idx``, with their shoulder geometry
        (:func:`~crowd_env.core.contacts.active_links`)."""
        st = self.state
        if st.links.shape[0] == 0:
            return _NO_LINKS
        return active_links(st.position_m, st.heading_rad, st.active, idx, st.links, st.link_offsets_m, self.period_m)

    def min_gap_m(self) -> float:
        """Smallest gap between two active pedestrians' bodies or a body and a wall (negative = overlap), between
        the bodies' circles (:mod:`crowd_env.core.body`; the disks' d − r_i − r_j for the paper's disks)."""
        idx = self.active_index
        st = self.state
        depth_m = self.physics.body_depth_m
        best = float("inf")
        if idx.shape[0] >= 2:
            pairs = self.neighbor_pairs(2.0 * float(st.radius_m[idx].max()) + 0.05)
            if pairs.shape[0]:
                if depth_m > 0.0:
                    best = float(np.min(body_gaps(st.position_m, st.heading_rad, st.radius_m, depth_m, idx[pairs],
                                                  self.period_m)))
                else:
                    d = pair_distances(st.position_m, idx[pairs], self.period_m)
                    best = float(np.min(d - st.radius_m[idx[pairs[:, 0]]] - st.radius_m[idx[pairs[:, 1]]]))
        if self.walls.shape[0] and idx.shape[0]:
            _, _, gap = self._wall_gaps(st, idx, 0.05)
            if gap.shape[0]:
                best = min(best, float(gap.min()))
        return best


def _describe(value) -> str:
    """What a step input was, for an error message: the array's shape and dtype, or the object's repr (cut)."""
    if value is None:
        return "None"
    if isinstance(value, np.ndarray):
        return f"an array of shape {value.shape} and dtype {value.dtype}"
    text = repr(value)
    return f"{type(value).__name__} {text if len(text) <= 60 else text[:57] + '...'}"


_F64 = np.dtype(np.float64)
_EMPTY_1D = np.zeros(0)
_NO_INDEX = np.zeros(0, np.int64)
_NO_LINKS = Links(_NO_INDEX, _NO_INDEX, np.zeros((0, 2)), np.zeros((0, 2)), np.zeros((0, 2)))
_EMPTY_2D = np.zeros((0, 2))
_NO_PAIRS = np.zeros((0, 2), np.int64)
