"""Soak and fault testing: invariant checks, adversarial policies, memory probes and the soak itself.

The checks are the model's invariants (no overlap beyond the contact tolerance, Kabalan et al. 2016
Eq. 17-21; no kinetic energy created by the impact law, Eq. 4-8, or by the projection). Shared by
``crowd-soak`` (:func:`soak`) and ``tests/experiments/validation/test_soak.py``. An :class:`InvariantChecker` is an
environment sub-step hook (``env.substep_hooks``): after every simulator step it checks, on the
pedestrians still on the floor,

- ``non_finite``: positions, velocities and angular velocities are finite;
- ``pedestrian_overlap`` / ``wall_overlap``: no pair of pedestrians and no pedestrian and wall overlap
  by more than ``overlap_tolerance_m`` (1e-3 m, the contact tolerance);
- ``outside_walkable``: every centre lies in the (closed) walkable area;
- ``impact_energy_increase``: the kinetic energy ½ Σ (m ‖u‖² + I ω²) does not grow across the impact
  stage (``StepResult.kinetic_energy_before_impact_j`` → ``..._after_impact_j``);
- ``projection_energy_increase``: nor across the gap projection (``..._after_impact_j`` →
  ``..._after_projection_j``);
- ``energy_report_mismatch``: the reported post-projection energy equals the energy of the final
  velocities recomputed here from the state (so the reported energies are the simulated ones).

The checks read the state only; they never call the simulator (whose per-step neighbour caches they
would otherwise touch), so a checked run is bitwise the same as an unchecked one.

High pressure (:data:`PRESSURE_CASES`, :func:`pressure_soak`): hundreds of pedestrians on the calibrated
baseline agent pressing into a door (a widened Seyfried bottleneck and a packed room), with the paper's
parameters and with a strong push (desired speeds doubled), checked step by step by the same
:class:`InvariantChecker`. The environment soak's crowds stay small (its largest impact cluster is about
17 pedestrians); here the contacts that carry force join 100-350 pedestrians and the projection runs on
the large (sparse, interior point) path.
"""
from __future__ import annotations

from crowd_env.errors import SoakError

import gc
import hashlib
import os
import resource
import time
import tracemalloc
from collections import Counter
from dataclasses import dataclass, field

import numpy as np
import shapely
from scipy.spatial import cKDTree

from ...core.geometry import Geometry
from ...walking.model import ModelParams
from ...core.state import first_overlap, min_gap_m
from ...envs import crowd_v0
from ...scenarios import list_scenarios, make_scenario, scenario_options
from ...scenarios.placement import place_pedestrians
from ...scenarios.registry import scenario_factory
from ...scenarios.scenario import Scenario
from ...walking.agent import SocialForceAgent

__all__ = ["OVERLAP_TOLERANCE_M", "VIOLATION_KINDS", "InvariantChecker", "MemoryProbe", "ACTION_MODES",
           "EXAMPLE_OPTIONS", "distinct_scenarios", "required_options", "soak_options", "max_intent_toward",
           "random_actions", "toward_neighbour_actions", "toward_wall_actions", "trajectory_hashes",
           "PressureCase", "PRESSURE_CASES", "pressure_scenario", "run_pressure_episode", "pressure_soak",
           "largest_contact_group", "SoakError", "DEFAULT_AGENT_STEPS", "soak"]

OVERLAP_TOLERANCE_M = 1e-3
DEFAULT_AGENT_STEPS = 1_000_000
# Energies are compared to round-off: the impact and projection solvers are exact (pivoting) or polished
# interior-point solutions, so an increase above this is a defect, not noise.
ENERGY_RELATIVE_TOLERANCE = 1e-9
ENERGY_ABSOLUTE_TOLERANCE_J = 1e-9
VIOLATION_KINDS = ("non_finite", "pedestrian_overlap", "wall_overlap", "outside_walkable", "impact_energy_increase",
                   "projection_energy_increase", "energy_report_mismatch")


def distinct_scenarios() -> list:
    """Registered scenario names, one per factory (aliases dropped), sorted.

    Two names are aliases when :func:`crowd_env.scenarios.registry.scenario_factory` returns the same factory; the
    name kept is the factory's own ``__name__`` when it is registered, else the longest one.
    """
    by_factory = {}
    for name in list_scenarios():
        by_factory.setdefault(id(scenario_factory(name)), []).append(name)
    names = []
    for group in by_factory.values():
        own = getattr(scenario_factory(group[0]), "__name__", None)
        names.append(own if own in group else max(group, key=lambda n: (len(n), n)))
    return sorted(names)


# Values for options that a scenario factory requires (no default), by option name: a non-convex user
# polygon with a door in its right wall and a spawn area at its far end.
EXAMPLE_OPTIONS = {
    "walkable_area": [(0.0, 0.0), (9.0, 0.0), (9.0, 7.0), (5.0, 7.0), (3.0, 4.0), (0.0, 4.0)],
    "exits": [[(9.0, 1.0), (9.0, 3.0)]],
    "spawn_area": [(0.0, 0.0), (3.0, 0.0), (3.0, 4.0), (0.0, 4.0)],
    "n_pedestrians": 20,
}


def required_options(name: str) -> list:
    """Options of the scenario ``name`` that have no default."""
    import inspect

    return [k for k, v in scenario_options(name).items() if v is inspect.Parameter.empty]


def soak_options(name: str):
    """Options to build ``name`` for a soak: its required ones from :data:`EXAMPLE_OPTIONS`; None when a
    required option has no example value."""
    need = required_options(name)
    if not set(need) <= set(EXAMPLE_OPTIONS):
        return None
    return {k: EXAMPLE_OPTIONS[k] for k in need}


def largest_contact_group(result, n: int) -> int:
    """Pedestrians in the largest group joined by pedestrian-pedestrian contacts that carried a percussion
    in the step of ``result`` (impact or projection; ``StepResult.contact_i/j``), ``n`` the crowd's size:
    the jam through which one step's pushes were passed (0 when no pair touched)."""
    pair = result.contact_j >= 0
    if not pair.any():
        return 0
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    i, j = result.contact_i[pair], result.contact_j[pair]
    _, label = connected_components(coo_matrix((np.ones(i.shape[0]), (i, j)), shape=(n, n)), directed=False)
    return int(np.bincount(label[np.union1d(i, j)]).max())


def _kinetic_energy_j(state, index) -> float:
    m, inertia = state.mass_kg[index], state.inertia_kg_m2[index]
    u, w = state.velocity_m_s[index], state.angular_velocity_rad_s[index]
    return float(0.5 * (m @ (u[:, 0] ** 2 + u[:, 1] ** 2) + inertia @ w ** 2))


@dataclass
class InvariantChecker:
    """Sub-step hook checking the invariants above; counts violations by kind and keeps extremes.

    ``max_overlap_m`` is the largest overlap seen (pedestrian pairs and walls; ≤ 0 means none),
    ``max_impact_energy_increase_j`` / ``max_projection_energy_increase_j`` the largest energy change
    across each stage (negative = always dissipated), ``examples`` the first violations in words.
    ``max_cluster_size``: the largest impact cluster (``StepResult.max_cluster_size``);
    ``max_contact_group``: the largest group of pedestrians joined by contacts that carried a percussion
    in one step (:func:`largest_contact_group`; resting contacts held by the projection included).
    """

    overlap_tolerance_m: float = OVERLAP_TOLERANCE_M
    energy_relative_tolerance: float = ENERGY_RELATIVE_TOLERANCE
    energy_absolute_tolerance_j: float = ENERGY_ABSOLUTE_TOLERANCE_J
    max_examples: int = 20
    counts: Counter = field(default_factory=Counter)
    n_checked_steps: int = 0
    max_overlap_m: float = -np.inf
    max_wall_overlap_m: float = -np.inf
    max_impact_energy_increase_j: float = -np.inf
    max_projection_energy_increase_j: float = -np.inf
    max_impact_energy_increase_rel: float = -np.inf
    n_impact_steps: int = 0  # steps with at least one impact cluster (the energy check had work to do)
    max_cluster_size: int = 0
    max_contact_group: int = 0
    examples: list = field(default_factory=list)
    label: str = ""

    def __call__(self, env, result, prev_position_m=None, prev_time_s=None) -> None:
        """The ``env.substep_hooks`` signature: check ``env.sim`` right after the step that gave ``result``."""
        self.check(env.sim, env.geometry, result)

    @property
    def n_violations(self) -> int:
        return int(sum(self.counts.values()))

    def _flag(self, kind: str, sim, message: str) -> None:
        self.counts[kind] += 1
        if len(self.examples) < self.max_examples:
            self.examples.append(f"[{self.label}] step {sim.step_count} (t = {sim.time_s:.2f} s) {kind}: {message}")

    def check(self, sim, geometry, result) -> None:
        """Check the state of ``sim`` (walls and walkable area of ``geometry``) after the step of ``result``."""
        st = sim.state
        self.n_checked_steps += 1
        idx = np.flatnonzero(st.active)
        before = np.union1d(idx, result.exited)  # on the floor during the step
        pos, rad = st.position_m[idx], st.radius_m[idx]
        finite = (np.isfinite(pos).all(axis=1) & np.isfinite(st.velocity_m_s[idx]).all(axis=1)
                  & np.isfinite(st.angular_velocity_rad_s[idx]))
        if not finite.all():
            self._flag("non_finite", sim, f"pedestrian(s) {idx[~finite][:10].tolist()}")
            return  # the geometric checks below are meaningless on NaN
        # pedestrian pairs
        overlap = -min_gap_m(pos, rad, sim.period_m)  # across the seam of a periodic corridor too
        self.max_overlap_m = max(self.max_overlap_m, overlap)
        if overlap > self.overlap_tolerance_m:
            pair = first_overlap(pos, rad, self.overlap_tolerance_m, sim.period_m)  # None when no pair is within 2 r
            who = f"pedestrians {idx[pair[0]]} and {idx[pair[1]]}" if pair is not None else "two pedestrians"
            self._flag("pedestrian_overlap", sim, f"{who} overlap by {overlap:.3g} m")
        # walls
        if geometry.walls.shape[0] and idx.size:
            gap = geometry.distance_to_walls(pos) - rad
            k = int(np.argmin(gap))
            self.max_wall_overlap_m = max(self.max_wall_overlap_m, -float(gap[k]))
            self.max_overlap_m = max(self.max_overlap_m, self.max_wall_overlap_m)
            if -gap[k] > self.overlap_tolerance_m:
                self._flag("wall_overlap", sim, f"pedestrian {idx[k]} at {pos[k].tolist()} overlaps a wall by "
                                                f"{-gap[k]:.3g} m")
        # walkable area (closed: a centre on the boundary of an exit opening is still inside)
        inside = shapely.intersects_xy(geometry.walkable_area, pos[:, 0], pos[:, 1])
        if not inside.all():
            k = int(np.flatnonzero(~inside)[0])
            self._flag("outside_walkable", sim, f"pedestrian {idx[k]} centre at {pos[k].tolist()} is outside the "
                                                f"walkable area ({int((~inside).sum())} in all)")
        self.max_contact_group = max(self.max_contact_group, largest_contact_group(result, st.n))
        # energies
        e0, e1, e2 = (result.kinetic_energy_before_impact_j, result.kinetic_energy_after_impact_j,
                      result.kinetic_energy_after_projection_j)
        d_impact, d_projection = e1 - e0, e2 - e1
        if result.n_impact_clusters:  # extremes over steps with impacts (elsewhere the change is exactly 0)
            self.n_impact_steps += 1
            self.max_cluster_size = max(self.max_cluster_size, result.max_cluster_size)
            self.max_impact_energy_increase_j = max(self.max_impact_energy_increase_j, d_impact)
            if e0 > 0:
                self.max_impact_energy_increase_rel = max(self.max_impact_energy_increase_rel, d_impact / e0)
        self.max_projection_energy_increase_j = max(self.max_projection_energy_increase_j, d_projection)
        if d_impact > self.energy_relative_tolerance * e0 + self.energy_absolute_tolerance_j:
            self._flag("impact_energy_increase", sim, f"{e0:.9g} J -> {e1:.9g} J (+{d_impact:.3g} J)")
        if d_projection > self.energy_relative_tolerance * e1 + self.energy_absolute_tolerance_j:
            self._flag("projection_energy_increase", sim, f"{e1:.9g} J -> {e2:.9g} J (+{d_projection:.3g} J)")
        e_state = _kinetic_energy_j(st, before)
        if abs(e_state - e2) > self.energy_relative_tolerance * max(e2, e_state) + self.energy_absolute_tolerance_j:
            self._flag("energy_report_mismatch", sim, f"StepResult says {e2:.12g} J after projection, the state "
                                                      f"holds {e_state:.12g} J")

    def merge(self, other: "InvariantChecker") -> None:
        """Add ``other``'s counts and extremes to this one."""
        self.counts.update(other.counts)
        self.n_checked_steps += other.n_checked_steps
        self.n_impact_steps += other.n_impact_steps
        self.max_cluster_size = max(self.max_cluster_size, other.max_cluster_size)
        self.max_contact_group = max(self.max_contact_group, other.max_contact_group)
        for name in ("max_overlap_m", "max_wall_overlap_m", "max_impact_energy_increase_j",
                     "max_projection_energy_increase_j", "max_impact_energy_increase_rel"):
            setattr(self, name, max(getattr(self, name), getattr(other, name)))
        self.examples.extend(other.examples[:max(0, self.max_examples - len(self.examples))])


# ---------------------------------------------------------------------------------------------- actions
def max_intent_toward(direction, action_max_m_s: float) -> np.ndarray:
    """The largest intent of ``Box(-a, a)`` along each row of ``direction`` (n, 2): the direction scaled
    until its larger component reaches ``a`` (zero rows stay zero)."""
    d = np.asarray(direction, dtype=np.float64)
    big = np.abs(d).max(axis=1, keepdims=True)
    scaled = np.divide(action_max_m_s * d, big, out=np.zeros_like(d), where=big > 0)
    return np.clip(scaled, -action_max_m_s, action_max_m_s)  # a / big * big may round above a


def _agent_rows(env) -> np.ndarray:
    return np.fromiter((int(a[4:]) for a in env.agents), dtype=np.int64, count=len(env.agents))


def random_actions(env, rng) -> dict:
    """Uniform intents in the action Box for every live agent."""
    a = env.action_max_m_s
    return dict(zip(env.agents, rng.uniform(-a, a, size=(len(env.agents), 2))))


def toward_neighbour_actions(env, rng=None) -> dict:
    """Every live agent pushes at maximum intent toward its nearest pedestrian still on the floor."""
    st = env.sim.state
    rows = _agent_rows(env)
    idx = np.flatnonzero(st.active)
    if idx.size < 2:
        return random_actions(env, rng if rng is not None else np.random.default_rng(0))
    _, nearest = cKDTree(st.position_m[idx]).query(st.position_m[rows], k=2)
    other = idx[nearest[:, 1]]  # the first hit is the agent itself (no two centres coincide)
    return dict(zip(env.agents, max_intent_toward(st.position_m[other] - st.position_m[rows], env.action_max_m_s)))


def toward_wall_actions(env, rng=None) -> dict:
    """Every live agent pushes at maximum intent toward the closest point of the nearest wall."""
    st = env.sim.state
    rows = _agent_rows(env)
    _, normal = env.geometry.distance_to_walls(st.position_m[rows], return_normal=True)
    return dict(zip(env.agents, max_intent_toward(-normal, env.action_max_m_s)))


ACTION_MODES = {"random": random_actions, "toward_neighbour": toward_neighbour_actions,
                "toward_wall": toward_wall_actions}


# ---------------------------------------------------------------------------------------------- memory
def rss_bytes() -> int:
    """Resident set size of this process now (Linux /proc; elsewhere the peak from getrusage)."""
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except OSError:  # pragma: no cover - not Linux
        return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * 1024


@dataclass
class MemoryProbe:
    """Samples RSS (and tracemalloc's traced memory when ``trace``) against a progress counter.

    :meth:`slope_bytes_per` fits a line to the samples after the first ``warmup_fraction`` of the run
    (imports, compiled kernels and caches fill up first).
    """

    trace: bool = False
    samples: list = field(default_factory=list)  # (progress, rss_bytes, traced_bytes)

    def start(self) -> None:
        if self.trace and not tracemalloc.is_tracing():
            tracemalloc.start()

    def stop(self) -> None:
        if self.trace and tracemalloc.is_tracing():
            tracemalloc.stop()

    def sample(self, progress: float) -> None:
        gc.collect()
        traced = tracemalloc.get_traced_memory()[0] if tracemalloc.is_tracing() else -1
        self.samples.append((float(progress), rss_bytes(), traced))

    def slope_bytes_per(self, column: str = "rss", warmup_fraction: float = 0.25) -> float:
        """Least-squares growth in bytes per unit of progress after the warm-up (NaN with < 3 samples)."""
        s = np.array(self.samples, dtype=np.float64).reshape(-1, 3)
        col = {"rss": 1, "traced": 2}[column]
        if s.shape[0] and s[0, col] < 0:
            return float("nan")
        x_end = s[-1, 0] if s.shape[0] else 0.0
        s = s[s[:, 0] >= warmup_fraction * x_end]
        if s.shape[0] < 3 or np.ptp(s[:, 0]) == 0:
            return float("nan")
        return float(np.polyfit(s[:, 0], s[:, col], 1)[0])

    def window(self, warmup_fraction: float = 0.25) -> float:
        """Progress covered by the fit of :meth:`slope_bytes_per`."""
        if not self.samples:
            return 0.0
        x_end = self.samples[-1][0]
        xs = [x for x, *_ in self.samples if x >= warmup_fraction * x_end]
        return float(xs[-1] - xs[0]) if xs else 0.0


# ---------------------------------------------------------------------------------------------- determinism
def trajectory_hashes(seed: int, n_steps: int = 1000, n_pedestrians: int = 8, mode: str = "toward_neighbour",
                      scenario: str = "seyfried_bottleneck") -> list:
    """SHA-256 of the (N, 2) position array (and the active mask) after each of ``n_steps`` environment steps.

    Everything random is seeded by ``seed``: the environment (start positions, desired speeds) and the
    actions, which alternate between ``mode`` and random ones so that there are contacts. A module-level
    function so that spawned worker processes can run it.
    """
    env = crowd_v0.parallel_env(scenario=scenario, scenario_options={"n_pedestrians": n_pedestrians},
                                controlled="all", max_steps=n_steps)
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    push = ACTION_MODES[mode]
    out = []
    for k in range(n_steps):
        if not env.agents:
            break
        env.step(push(env, rng) if k % 2 else random_actions(env, rng))
        st = env.sim.state
        out.append(hashlib.sha256(st.position_m.tobytes() + st.active.tobytes()).hexdigest())
    return out


# ---------------------------------------------------------------------------------------------- high pressure
@dataclass(frozen=True)
class PressureCase:
    """A high-pressure jam: ``n_pedestrians`` on the calibrated baseline agent pressing into a door.

    ``geometry``: ``"bottleneck"`` (Seyfried's, widened: corridor ``corridor_width_m``, channel
    ``channel_length_m``, entrance ``door_width_m``) or ``"room"`` (a square room packed at
    ``room_density_per_m2`` with a door of ``door_width_m`` in the middle of its right wall, the jam of
    ``benchmarks/scaling.py``). ``speed_factor`` multiplies the drawn desired speeds (1: the paper's
    N(1.34, 0.26) m/s; 2: a strong push). ``params``: :class:`ModelParams` changes as ``(name, value)``
    pairs (none: the ``paper`` preset, with the paper's point navigation field, clearance 0).
    An episode lasts ``max_time_s`` or until everybody has left.
    """

    name: str
    geometry: str
    n_pedestrians: int
    door_width_m: float
    speed_factor: float = 1.0
    params: tuple = ()
    max_time_s: float = 20.0
    corridor_width_m: float = 7.0
    channel_length_m: float = 4.0
    room_density_per_m2: float = 3.0

    def model_params(self):
        return ModelParams().replace(**dict(self.params))


PRESSURE_CASES = (
    PressureCase("bottleneck_paper", "bottleneck", 220, 1.0),
    PressureCase("bottleneck_push", "bottleneck", 250, 0.9, speed_factor=2.0),
    PressureCase("room_paper", "room", 300, 1.0),
    PressureCase("room_push", "room", 400, 0.8, speed_factor=2.0),
)


def pressure_scenario(case: PressureCase, seed: int):
    """The :class:`~crowd_env.scenarios.Scenario` of ``case`` with start positions (and desired speeds)
    from ``seed``."""
    import math

    if case.geometry == "bottleneck":
        return make_scenario("seyfried_bottleneck", width_m=case.door_width_m, n_pedestrians=case.n_pedestrians,
                             seed=seed, corridor_width_m=case.corridor_width_m,
                             channel_length_m=case.channel_length_m, navigation_clearance_m=0.0)
    if case.geometry == "room":
        side = math.sqrt(case.n_pedestrians / case.room_density_per_m2) + 0.6  # the outer 0.3 m holds no centre
        y0, y1 = 0.5 * (side - case.door_width_m), 0.5 * (side + case.door_width_m)
        geometry = Geometry([(0, 0), (side, 0), (side, side), (0, side)],
                            [[(side, y0), (side + 0.5, y0), (side + 0.5, y1), (side, y1)]], name=f"room_{case.name}")
        position = place_pedestrians(geometry.walkable_area, case.n_pedestrians, 0.23, np.random.default_rng(seed))
        return Scenario(geometry, position, name=case.name, seed=seed, navigation_resolution_m=0.1)
    raise SoakError(f"unknown pressure geometry {case.geometry!r}; known: 'bottleneck', 'room'")


def run_pressure_episode(case: PressureCase, seed: int, checker: InvariantChecker, max_agent_steps=None) -> dict:
    """One episode of ``case`` (seed ``seed``) with every step checked by ``checker``; stops at
    ``case.max_time_s``, when everybody has left, or after ``max_agent_steps`` (pedestrians on the floor
    summed over steps). Returns its counts and the simulator's solver counters."""
    scenario = pressure_scenario(case, seed)
    state = scenario.make_state()
    state.desired_speed_m_s *= case.speed_factor
    sim = scenario.make_simulator(state, case.model_params())
    agent = SocialForceAgent(scenario.navigation())
    agent_steps = 0
    n_steps = int(round(case.max_time_s / sim.params.dt_s))
    for _ in range(n_steps):
        n_live = int(sim.active_index.shape[0])
        if n_live == 0 or (max_agent_steps is not None and agent_steps >= max_agent_steps):
            break
        intents, heading = agent(sim)
        result = sim.step(intents, desired_heading_rad=heading)
        checker.check(sim, scenario.geometry, result)
        agent_steps += n_live
    return {"agent_steps": agent_steps, "sim_steps": sim.step_count, "time_s": sim.time_s,
            "left": int(state.n - state.active.sum()), "n_pedestrians": state.n,
            "large_solves": sim.n_sparse_solves, "fallback_solves": sim.n_fallback_solves}


def pressure_soak(agent_steps: int, *, cases=None, seed: int = 0, overlap_tolerance_m: float = OVERLAP_TOLERANCE_M,
                  progress=None) -> dict:
    """The high-pressure phase of the soak: ``agent_steps`` split evenly over ``cases`` (names or
    :class:`PressureCase`; default :data:`PRESSURE_CASES`), each running episodes with seeds ``seed``,
    ``seed + 1``, ... until its share is spent. Returns a JSON-able summary with the merged
    :class:`InvariantChecker` under ``"checker"`` (not JSON) and one entry per case."""

    known = {c.name: c for c in PRESSURE_CASES}
    chosen = []
    for c in (PRESSURE_CASES if cases is None else cases):
        if isinstance(c, str):
            if c not in known:
                raise SoakError(f"unknown pressure case {c!r}; known: {sorted(known)}")
            c = known[c]
        chosen.append(c)
    if not chosen:
        raise SoakError("no pressure case to run")
    share = int(np.ceil(agent_steps / len(chosen)))
    total = InvariantChecker(overlap_tolerance_m=overlap_tolerance_m)
    per_case = {}
    t0 = time.perf_counter()
    for case in chosen:
        checker = InvariantChecker(overlap_tolerance_m=overlap_tolerance_m, label=f"pressure/{case.name}")
        t_case = time.perf_counter()
        done, episodes, counts = 0, 0, Counter()
        while done < share:
            ep = run_pressure_episode(case, seed + episodes, checker, max_agent_steps=share - done)
            done += ep["agent_steps"]
            episodes += 1
            counts.update({k: ep[k] for k in ("sim_steps", "left", "n_pedestrians", "large_solves",
                                              "fallback_solves")})
            if ep["agent_steps"] == 0:
                break  # cannot happen with pedestrians on the floor; never loop forever
        per_case[case.name] = {
            "agent_steps": done, "sim_steps": checker.n_checked_steps, "episodes": episodes,
            "pedestrians": counts["n_pedestrians"], "left": counts["left"],
            "large_solves": counts["large_solves"], "fallback_solves": counts["fallback_solves"],
            "max_cluster_size": checker.max_cluster_size, "max_contact_group": checker.max_contact_group,
            "violations": dict(checker.counts), "max_overlap_m": checker.max_overlap_m,
            "max_wall_overlap_m": checker.max_wall_overlap_m, "wall_s": time.perf_counter() - t_case}
        total.merge(checker)
        if progress is not None:
            r = per_case[case.name]
            progress(f"pressure/{case.name}: {done} agent-steps, {r['sim_steps']} simulator steps, {episodes} "
                     f"episodes ({r['left']} of {r['pedestrians']} pedestrians left), largest impact cluster "
                     f"{r['max_cluster_size']}, largest contact group {r['max_contact_group']}, "
                     f"{r['large_solves']} large (sparse) solves, violations {r['violations'] or 0}, "
                     f"max overlap {r['max_overlap_m']:.3g} m ({r['wall_s']:.0f} s)")
    return {"agent_steps": sum(r["agent_steps"] for r in per_case.values()), "sim_steps": total.n_checked_steps,
            "cases": [c.name for c in chosen], "violations": dict(total.counts), "n_violations": total.n_violations,
            "max_cluster_size": total.max_cluster_size, "max_contact_group": total.max_contact_group,
            "max_overlap_m": total.max_overlap_m, "max_wall_overlap_m": total.max_wall_overlap_m,
            "max_impact_energy_increase_j": total.max_impact_energy_increase_j,
            "max_projection_energy_increase_j": total.max_projection_energy_increase_j,
            "examples": total.examples, "per_case": per_case, "wall_s": time.perf_counter() - t0, "checker": total}


# ---------------------------------------------------------------------------------------------- the soak
def soak(agent_steps: int = DEFAULT_AGENT_STEPS, *, scenarios=None, modes=None, seed: int = 0, max_steps: int = 200,
         frame_skip: int = 1, fixed_start: bool = False, trace_memory: bool = False,
         memory_tolerance_mib: float = 16.0, overlap_tolerance_m: float = 1e-3, scenario_options: dict | None = None,
         pressure_agent_steps: int = 0, pressure_cases=None, progress=print) -> dict:
    """Run the soak; returns a JSON-able summary (see ``crowd-soak``'s ``format_summary``). ``agent_steps`` = 0 skips
    the environment phase; ``pressure_agent_steps`` > 0 adds the high-pressure phase
    (:func:`pressure_soak` over ``pressure_cases``, default all)."""
    modes = list(modes) if modes else list(ACTION_MODES)
    unknown = sorted(set(modes) - set(ACTION_MODES))
    if unknown:
        raise SoakError(f"unknown mode(s) {unknown}; known: {list(ACTION_MODES)}")
    names, scenario_options, skipped = _soak_scenarios(scenarios, scenario_options or {})
    pairs = [(n, m) for n in names for m in modes] if agent_steps > 0 else []
    share = int(np.ceil(agent_steps / max(len(pairs), 1)))
    total = InvariantChecker()
    memory = MemoryProbe(trace=trace_memory)
    memory.start()
    memory.sample(0)
    done_agent_steps = env_steps = episodes = 0
    per_pair = {}
    rng = np.random.default_rng(seed)
    t0 = time.perf_counter()
    for name, mode in pairs:
        options = dict(scenario_options.get(name, {}))
        if fixed_start:
            options.setdefault("seed", seed)
        checker = InvariantChecker(overlap_tolerance_m=overlap_tolerance_m, label=f"{name}/{mode}")
        record = _soak_pair(name, ACTION_MODES[mode], options, checker, share, rng, memory, done_agent_steps,
                            max_steps=max_steps, frame_skip=frame_skip)
        done_agent_steps += record["agent_steps"]
        env_steps += record.pop("env_steps")
        episodes += record["episodes"]
        per_pair[f"{name}/{mode}"] = record
        total.merge(checker)
        progress(f"{name}/{mode}: {record['agent_steps']} agent-steps, {checker.n_checked_steps} simulator steps "
                 f"({checker.n_impact_steps} with impacts), {record['episodes']} episodes, "
                 f"violations {dict(checker.counts) or 0}, max overlap {checker.max_overlap_m:.3g} m "
                 f"({record['wall_s']:.0f} s)")
    environment_cluster, environment_group = total.max_cluster_size, total.max_contact_group
    pressure = None
    if pressure_agent_steps > 0:
        pressure = pressure_soak(pressure_agent_steps, cases=pressure_cases, seed=seed,
                                 overlap_tolerance_m=overlap_tolerance_m, progress=progress)
        total.merge(pressure.pop("checker"))  # memory is judged on the environment phase only
    memory.stop()
    memory_summary = _memory_summary(memory, trace_memory, memory_tolerance_mib)
    violations = dict(total.counts)
    if not memory_summary["ok"]:
        violations["memory_growth"] = 1
    return {
        "agent_steps": done_agent_steps, "env_steps": env_steps, "sim_steps": total.n_checked_steps,
        "impact_steps": total.n_impact_steps, "max_cluster_size": total.max_cluster_size,
        "max_contact_group": total.max_contact_group, "environment_max_cluster_size": environment_cluster,
        "environment_max_contact_group": environment_group, "episodes": episodes, "pressure": pressure,
        "scenarios": names, "skipped_scenarios": skipped, "modes": modes, "per_pair": per_pair,
        "violations": violations, "n_violations": int(sum(violations.values())),
        "overlap_tolerance_m": overlap_tolerance_m, "max_overlap_m": total.max_overlap_m,
        "max_wall_overlap_m": total.max_wall_overlap_m,
        "max_impact_energy_increase_j": total.max_impact_energy_increase_j,
        "max_impact_energy_increase_rel": total.max_impact_energy_increase_rel,
        "max_projection_energy_increase_j": total.max_projection_energy_increase_j,
        "examples": total.examples, "memory": memory_summary, "wall_s": time.perf_counter() - t0,
    }


def _soak_scenarios(scenarios, given: dict) -> tuple:
    """(names, options per name, skipped name -> why): the scenarios to soak (default every distinct one) with
    their required options, given ones first, else the examples of EXAMPLE_OPTIONS; :class:`SoakError` if none."""
    names = list(scenarios) if scenarios else distinct_scenarios()
    options, skipped = {}, {}
    for n in names:
        missing = [k for k in required_options(n) if k not in given.get(n, {})]
        example = soak_options(n)
        if missing and example is None:
            skipped[n] = f"needs options {missing}"
        else:
            options[n] = {**(example or {}), **given.get(n, {})}
    names = [n for n in names if n not in skipped]
    if not names:
        raise SoakError("no scenario to soak")
    return names, options, skipped


def _soak_pair(name: str, act, options: dict, checker, share: int, rng, memory, done_agent_steps: int, *,
               max_steps: int, frame_skip: int) -> dict:
    """``share`` agent-steps of one (scenario, action mode) pair, episodes alternating all / half the pedestrians
    controlled, every simulator step checked by ``checker``; its record (with ``env_steps``, popped by the caller)."""
    envs = {}
    pair_steps, env_steps, pair_t0, k, first_sample = 0, 0, time.perf_counter(), 0, len(memory.samples)
    while pair_steps < share:
        controlled = "all" if k % 2 == 0 else 0.5
        if controlled not in envs:  # built when first needed (a short soak may never need the second)
            envs[controlled] = crowd_v0.parallel_env(scenario=name, scenario_options=options, controlled=controlled,
                                                     max_steps=max_steps, frame_skip=frame_skip)
            envs[controlled].substep_hooks.append(checker)
        env = envs[controlled]
        env.reset(seed=int(rng.integers(2**31 - 1)))
        while env.agents and pair_steps < share:
            n_live = len(env.agents)
            env.step(act(env, rng))
            pair_steps += n_live
            env_steps += 1
        k += 1
        memory.sample(done_agent_steps + pair_steps)
    return {"agent_steps": pair_steps, "sim_steps": checker.n_checked_steps, "impact_steps": checker.n_impact_steps,
            "episodes": k, "violations": dict(checker.counts), "max_overlap_m": checker.max_overlap_m,
            "rss_first_episode_end_mib": memory.samples[first_sample][1] / 2**20,
            "rss_end_mib": memory.samples[-1][1] / 2**20, "wall_s": time.perf_counter() - pair_t0,
            "env_steps": env_steps}


def _memory_summary(memory, trace_memory: bool, tolerance_mib: float) -> dict:
    """The memory probe's samples, slopes and growth over its fit window, judged on traced or RSS memory."""
    mib = 2.0**20
    window = memory.window()
    growth = {c: memory.slope_bytes_per(c) * window / mib for c in ("rss", "traced")}
    judged = "traced" if trace_memory else "rss"
    s = memory.samples
    return {"rss_start_mib": s[0][1] / mib, "rss_end_mib": s[-1][1] / mib,
            "traced_start_mib": s[0][2] / mib if trace_memory else None,
            "traced_end_mib": s[-1][2] / mib if trace_memory else None,
            "rss_slope_kib_per_1000_agent_steps": memory.slope_bytes_per("rss") * 1000 / 1024,
            "traced_slope_kib_per_1000_agent_steps": memory.slope_bytes_per("traced") * 1000 / 1024
            if trace_memory else None,
            "fit_window_agent_steps": window, "growth_over_window_mib": growth, "judged_on": judged,
            "tolerance_mib": tolerance_mib, "ok": not (growth[judged] > tolerance_mib), "n_samples": len(s),
            "samples": [(x, rss / mib, traced / mib if trace_memory else None) for x, rss, traced in s]}
