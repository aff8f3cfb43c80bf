"""The arrays and numbers the compiled step takes, in named bundles defined once.

The kernels of :mod:`crowd_env.core.step` (the fused step, :func:`~crowd_env.core.step.advance`) and the
compiled rollout built on them take the crowd, the world and the step's parameters as these
:class:`typing.NamedTuple` s instead of dozens of positional arguments. numba compiles a named tuple of
arrays and numbers into a struct passed by value: reading a field inside a kernel costs nothing at run time.
Each bundle is built in one place:

- :class:`Bodies`: :meth:`CrowdState.arrays() <crowd_env.core.state.CrowdState.arrays>` (the state's own
  arrays, not copies: kernels write positions, velocities, headings and ``active`` in place);
- :class:`World`: :attr:`Simulator.world <crowd_env.core.simulator.Simulator.world>` (walls, exits, the
  periodicity);
- :class:`StepParams`: :attr:`Simulator.step_params <crowd_env.core.simulator.Simulator.step_params>` (h,
  ε, the dissipations of Eq. 4-8, the dense solvers' limits);
- :class:`StepInputs`: what a step is given (the intent of Eq. 14, θ_d of Eq. 15, external forces), by
  :meth:`Simulator.step <crowd_env.core.simulator.Simulator.step>` or by a compiled decision;
- :class:`Candidates`: a step's contact candidates, by
  :func:`~crowd_env.core.contacts.contact_candidates` (and grown by the re-detection of stage 5);
- :class:`Links`: the hand links between active pedestrians with their geometry, by
  :func:`~crowd_env.core.contacts.active_links`.

Every field has one numba type whatever the caller (floats as float64, counts as int64, arrays C-contiguous
and writeable), so that each kernel is compiled once (``crowd_env.compilation``: the first run compiles).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["Bodies", "World", "StepParams", "StepInputs", "Candidates", "Links", "empty_exits"]


class Bodies(NamedTuple):
    """The pedestrians' arrays of a :class:`~crowd_env.core.state.CrowdState` (same names, same arrays;
    N pedestrians, L hand links)."""

    position_m: np.ndarray  # (N, 2)
    heading_rad: np.ndarray  # (N,)
    velocity_m_s: np.ndarray  # (N, 2)
    angular_velocity_rad_s: np.ndarray  # (N,)
    mass_kg: np.ndarray  # (N,)
    inertia_kg_m2: np.ndarray  # (N,)
    radius_m: np.ndarray  # (N,)
    desired_speed_m_s: np.ndarray  # (N,)
    tau_s: np.ndarray  # (N,) relaxation time of Eq. 14
    heading_stiffness: np.ndarray  # (N,) k of Eq. 15, N m/rad
    heading_damping: np.ndarray  # (N,) c of Eq. 15, N m s/rad
    active: np.ndarray  # (N,) bool: still in the simulation
    links: np.ndarray  # (L, 2) int64 pedestrians holding hands (Eq. 2)
    link_offsets_m: np.ndarray  # (L, 4) shoulder points in the body frames
    premovement_s: np.ndarray  # (N,) when each starts to walk (read by the walking model only)


class World(NamedTuple):
    """What the pedestrians move in: the walls, the exits (packed polygons,
    :class:`~crowd_env.core.polygons.PackedPolygons`; none: :func:`empty_exits`) with each pedestrian's
    exit, and the periodicity along x."""

    walls: np.ndarray  # (S, 4) segments x0, y0, x1, y1
    wall_owner: np.ndarray  # (S, 2, D) int64, crowd_env.core.segments.endpoint_owners
    exit_vertices: np.ndarray  # (V, 2)
    exit_ring_start: np.ndarray  # (R + 1,) int64
    exit_ring_owner: np.ndarray  # (R,) int64
    exit_boxes: np.ndarray  # (K, 4)
    exit_destination: np.ndarray  # (N,) int64: each pedestrian's exit, -1 any
    period_m: float  # L along x, 0: not periodic


class StepParams(NamedTuple):
    """The numbers of a step: h, the contact tolerance ε, the dissipations K_n, K_tg, K_v of the Frémond
    impact (Eq. 4-8), heading dynamics on or off, the dense solvers' limits of the
    :class:`~crowd_env.core.solvers.cascade.SolverCascade` (rows −1: every cluster to the cascade) and the bodies'
    depth (:mod:`crowd_env.core.body`; 0: the paper's disks)."""

    dt_s: float
    contact_tolerance_m: float
    normal_dissipation_kg: float
    tangential_dissipation_kg: float
    link_dissipation_kg_per_m2: float
    rotation: bool
    max_dense_rows: int
    max_dense_bodies: int
    max_dense_projection_rows: int
    body_depth_m: float


class StepInputs(NamedTuple):
    """What a step is given: the velocity intents u_int (N, 2) of Eq. 14, the desired headings θ_d (N,) of
    Eq. 15 (used when ``has_desired_heading``; else the intent's direction) and external forces (N, 2) in N
    (used when ``has_external_force``; an unused array may be empty)."""

    intents_m_s: np.ndarray
    desired_heading_rad: np.ndarray
    has_desired_heading: bool
    external_force_n: np.ndarray
    has_external_force: bool


class Candidates(NamedTuple):
    """Contact candidates of a step, one entry per contact (pedestrian pairs, then walls): ``a``/``b`` rows into the
    step's active index (b = −1 for a wall), ``gap`` (m), ``nx``/``ny`` (the unit normal from b to a),
    ``rho_a``/``rho_b`` (the contact point's distances from the two circles' centres; ρ = r against a wall), ``wall``
    (segment id or −1), ``sub`` (which circles of the two bodies touch, :mod:`crowd_env.core.body`; 0 for disks) and
    ``arm_a``/``arm_b`` (the circles' centres from the bodies' centres, (C, 2); zero for disks). The fields are
    :data:`crowd_env.core.contacts.CONTACT_FIELDS`."""

    a: np.ndarray  # (C,) int64
    b: np.ndarray  # (C,) int64
    gap: np.ndarray  # (C,)
    nx: np.ndarray  # (C,)
    ny: np.ndarray  # (C,)
    rho_a: np.ndarray  # (C,)
    rho_b: np.ndarray  # (C,)
    wall: np.ndarray  # (C,) int64
    sub: np.ndarray  # (C,) int64
    arm_a: np.ndarray  # (C, 2)
    arm_b: np.ndarray  # (C, 2)


class Links(NamedTuple):
    """Hand links (Eq. 2) whose two pedestrians are active: ``a``/``b`` rows into the step's active index, and the
    shoulder geometry, ``d_m`` = A_a − A_b and the arms ``g_a_m`` = A_a − x_a, ``g_b_m`` = A_b − x_b (L, 2)."""

    a: np.ndarray  # (L,) int64
    b: np.ndarray  # (L,) int64
    d_m: np.ndarray  # (L, 2)
    g_a_m: np.ndarray  # (L, 2)
    g_b_m: np.ndarray  # (L, 2)


def empty_exits() -> tuple:
    """``(vertices, ring_start, ring_owner, boxes)`` of no exit at all, typed as packed exits are."""
    return np.zeros((0, 2)), np.zeros(1, np.int64), np.zeros(0, np.int64), np.zeros((0, 4))
