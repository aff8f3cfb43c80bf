"""Invariant checks, adversarial policies and memory probes for soak and fault tests.

Shared by ``scripts/soak.py`` and ``tests/test_reliability.py``. An :class:`InvariantChecker` is an
environment sub-step hook (``env.substep_hooks``): after every simulator step it checks, on the
pedestrians still on the floor,

- ``non_finite``: positions, velocities and angular velocities are finite;
- ``pedestrian_overlap`` / ``wall_overlap``: no pair of pedestrians and no pedestrian and wall overlap
  by more than ``overlap_tolerance_m`` (1e-3 m, the contact tolerance);
- ``outside_walkable``: every centre lies in the (closed) walkable area;
- ``impact_energy_increase``: the kinetic energy ½ Σ (m |u|² + I ω²) does not grow across the impact
  stage (``StepResult.kinetic_energy_before_impact_j`` → ``..._after_impact_j``);
- ``projection_energy_increase``: nor across the gap projection (``..._after_impact_j`` →
  ``..._after_projection_j``);
- ``energy_report_mismatch``: the reported post-projection energy equals the energy of the final
  velocities recomputed here from the state (so the reported energies are the simulated ones).

The checks read the state only; they never call the simulator (whose per-step neighbour caches they
would otherwise touch), so a checked run is bitwise the same as an unchecked one.
"""
from __future__ import annotations

import gc
import hashlib
import os
import resource
import tracemalloc
from collections import Counter
from dataclasses import dataclass, field

import numpy as np
import shapely
from scipy.spatial import cKDTree

from .core.state import first_overlap, min_gap_m
from .scenarios import list_scenarios, scenario_options

__all__ = ["OVERLAP_TOLERANCE_M", "VIOLATION_KINDS", "InvariantChecker", "MemoryProbe", "ACTION_MODES",
           "EXAMPLE_OPTIONS", "distinct_scenarios", "required_options", "soak_options", "max_intent_toward",
           "random_actions", "toward_neighbour_actions", "toward_wall_actions", "trajectory_hashes"]

OVERLAP_TOLERANCE_M = 1e-3
# Energies are compared to round-off: the impact and projection solvers are exact (pivoting) or polished
# interior-point solutions, so an increase above this is a defect, not noise.
ENERGY_RELATIVE_TOLERANCE = 1e-9
ENERGY_ABSOLUTE_TOLERANCE_J = 1e-9
VIOLATION_KINDS = ("non_finite", "pedestrian_overlap", "wall_overlap", "outside_walkable", "impact_energy_increase",
                   "projection_energy_increase", "energy_report_mismatch")


def distinct_scenarios() -> list:
    """Registered scenario names, one per factory (aliases dropped), sorted.

    Two names are aliases when :func:`crowd_env.scenarios.base._lookup` returns the same factory; the
    name kept is the factory's own ``__name__`` when it is registered, else the longest one.
    """
    from .scenarios.base import _lookup

    by_factory = {}
    for name in list_scenarios():
        by_factory.setdefault(id(_lookup(name)), []).append(name)
    names = []
    for group in by_factory.values():
        own = getattr(_lookup(group[0]), "__name__", None)
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
        overlap = -min_gap_m(pos, rad)
        self.max_overlap_m = max(self.max_overlap_m, overlap)
        if overlap > self.overlap_tolerance_m:
            pair = first_overlap(pos, rad, self.overlap_tolerance_m)  # None when no pair is within 2 r
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
    from .envs import crowd_v0

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
