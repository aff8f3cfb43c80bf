"""Structure-of-arrays state of N rigid-disk pedestrians (Kabalan et al. 2016, Section 2.1).

Every per-pedestrian quantity is one array with the pedestrian index first: positions are one
``(N, 2)`` array, headings one ``(N,)`` array, and so on. Hand-holding links (Eq. 2) are stored as
index pairs with the shoulder points given in each pedestrian's body frame.
"""
from __future__ import annotations

from crowd_env.errors import StateError

import operator
from dataclasses import dataclass, field

import numpy as np

from .bundles import Bodies
from .neighbors import grid_pairs
from .periodic import minimum_image_dx
from .params import ParameterError, PedestrianDefaults


def _as_array(name: str, value, shape: tuple, n: int) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise StateError(f"{name} must be numeric with shape {shape}: {exc}") from None
    if arr.ndim == 0 and shape == (n,):
        arr = np.full(n, float(arr))
    if arr.shape != shape:
        raise StateError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        bad = np.flatnonzero(~np.isfinite(arr.reshape(n, -1)).all(axis=1))
        raise StateError(f"{name} has non-finite values for pedestrian(s) {bad[:10].tolist()}")
    return np.array(arr, dtype=np.float64, order="C", copy=True)  # the state owns its arrays: never alias input


def sample_desired_speeds(n: int, rng: np.random.Generator, defaults: PedestrianDefaults = PedestrianDefaults()) -> np.ndarray:
    """Desired walking speeds ~ N(1.34, 0.26) m/s (Henderson 1971), truncated at ±2σ (0.82-1.86 m/s)."""
    k = defaults.desired_speed_truncation_sigma
    from scipy.stats import truncnorm  # imported on use: scipy.stats takes ~1.5 s to import

    return truncnorm.rvs(-k, k, loc=defaults.desired_speed_mean_m_s, scale=defaults.desired_speed_std_m_s,
                         size=n, random_state=rng)


@dataclass
class CrowdState:
    """Positions, headings, velocities and body parameters of N pedestrians.

    Units: metres, radians, seconds, kilograms. ``inertia_kg_m2`` defaults to a solid disk
    (m r^2 / 2). Heading damping defaults to critical damping c = 2 sqrt(I k) (Eq. 15, ζ = 1).
    ``links`` (L, 2) holds index pairs of pedestrians holding hands; ``link_offsets_m`` (L, 4) the
    shoulder points (x_i, y_i, x_j, y_j) in each one's body frame (x along the heading).
    ``premovement_s`` (N,): the time at which each pedestrian starts to walk (RiMEA's premovement time;
    0: at once). The core does not read it: the walking model holds a pedestrian still until then
    (:func:`crowd_env.walking.agent.hold_waiting`).
    """

    position_m: np.ndarray
    heading_rad: np.ndarray
    velocity_m_s: np.ndarray
    angular_velocity_rad_s: np.ndarray
    mass_kg: np.ndarray
    inertia_kg_m2: np.ndarray
    radius_m: np.ndarray
    desired_speed_m_s: np.ndarray
    tau_s: np.ndarray
    heading_stiffness: np.ndarray
    heading_damping: np.ndarray
    active: np.ndarray
    links: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))
    link_offsets_m: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    premovement_s: np.ndarray | None = None  # None: zeros (everybody walks at once)

    def __post_init__(self) -> None:
        if self.premovement_s is None:
            self.premovement_s = np.zeros(self.position_m.shape[0])

    @property
    def n(self) -> int:
        return self.position_m.shape[0]

    @classmethod
    def create(cls, position_m, *, heading_rad=0.0, velocity_m_s=None, angular_velocity_rad_s=0.0,
               mass_kg=None, radius_m=None, inertia_kg_m2=None, desired_speed_m_s=None, tau_s=None,
               heading_stiffness=None, heading_damping=None, links=None, link_offsets_m=None, premovement_s=0.0,
               rng: np.random.Generator | None = None, defaults: PedestrianDefaults = PedestrianDefaults(),
               overlap_tolerance_m: float = 1e-9) -> "CrowdState":
        """Build and validate a state; scalars broadcast, missing values take Table 2 defaults.

        Desired speeds not given are drawn with :func:`sample_desired_speeds` from ``rng``.
        Raises :class:`StateError` naming the problem (shape, non-finite or non-positive value,
        overlapping pair).
        """
        try:
            pos = np.asarray(position_m, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise StateError(f"position_m must be numeric with shape (N, 2): {exc}") from None
        if pos.ndim != 2 or pos.shape[1] != 2:
            raise StateError(f"position_m must have shape (N, 2), got {pos.shape}")
        n = pos.shape[0]
        pos = _as_array("position_m", pos, (n, 2), n)
        mass = _as_array("mass_kg", defaults.mass_kg if mass_kg is None else mass_kg, (n,), n)
        radius = _as_array("radius_m", defaults.radius_m if radius_m is None else radius_m, (n,), n)
        inertia = 0.5 * mass * radius**2 if inertia_kg_m2 is None else _as_array("inertia_kg_m2", inertia_kg_m2, (n,), n)
        if desired_speed_m_s is None:
            desired_speed_m_s = sample_desired_speeds(n, rng if rng is not None else np.random.default_rng(0), defaults)
        stiffness = _as_array("heading_stiffness", defaults.heading_stiffness_n_m_per_rad if heading_stiffness is None
                              else heading_stiffness, (n,), n)
        if heading_damping is None:
            with np.errstate(invalid="ignore"):  # a negative stiffness is reported by validate()
                damping = 2.0 * defaults.heading_damping_ratio * np.sqrt(inertia * stiffness)
        else:
            damping = _as_array("heading_damping", heading_damping, (n,), n)
        vel = np.zeros((n, 2)) if velocity_m_s is None else velocity_m_s
        state = cls(
            position_m=pos,
            heading_rad=_as_array("heading_rad", heading_rad, (n,), n),
            velocity_m_s=_as_array("velocity_m_s", vel, (n, 2), n),
            angular_velocity_rad_s=_as_array("angular_velocity_rad_s", angular_velocity_rad_s, (n,), n),
            mass_kg=mass, inertia_kg_m2=inertia, radius_m=radius,
            desired_speed_m_s=_as_array("desired_speed_m_s", desired_speed_m_s, (n,), n),
            tau_s=_as_array("tau_s", defaults.tau_s if tau_s is None else tau_s, (n,), n),
            heading_stiffness=stiffness, heading_damping=damping,
            active=np.ones(n, dtype=bool),
            links=np.zeros((0, 2), dtype=np.int64) if links is None else np.array(links, dtype=np.int64).reshape(-1, 2),
            link_offsets_m=np.zeros((0, 4)) if link_offsets_m is None else np.array(link_offsets_m, dtype=np.float64),
            premovement_s=_as_array("premovement_s", premovement_s, (n,), n),
        )
        state.validate(overlap_tolerance_m=overlap_tolerance_m)
        return state

    def validate(self, overlap_tolerance_m: float = 1e-9) -> None:
        """Check shapes, positivity and the absence of overlapping pairs among active pedestrians."""
        n = self.n
        for name in ("mass_kg", "radius_m", "tau_s", "inertia_kg_m2"):  # given values before derived ones
            arr = getattr(self, name)
            if arr.shape != (n,):
                raise StateError(f"{name} must have shape ({n},), got {arr.shape}")
            bad = np.flatnonzero(~(arr > 0))
            if bad.size:
                raise StateError(f"{name} must be > 0; pedestrian {int(bad[0])} has {float(arr[bad[0]])!r}")
        if self.premovement_s.shape != (n,):
            raise StateError(f"premovement_s must have shape ({n},), got {self.premovement_s.shape}")
        for name in ("heading_stiffness", "heading_damping", "desired_speed_m_s", "premovement_s"):
            arr = getattr(self, name)
            bad = np.flatnonzero(~(arr >= 0))
            if bad.size:
                raise StateError(f"{name} must be >= 0; pedestrian {int(bad[0])} has {float(arr[bad[0]])!r}")
        if self.links.ndim != 2 or self.links.shape[1] != 2:
            raise StateError(f"links must have shape (L, 2), got {self.links.shape}")
        if self.link_offsets_m.shape != (self.links.shape[0], 4):
            raise StateError(f"link_offsets_m must have shape ({self.links.shape[0]}, 4), got {self.link_offsets_m.shape}")
        if self.links.size:
            if self.links.min() < 0 or self.links.max() >= n:
                raise StateError(f"links refer to pedestrian indices outside [0, {n})")
            if np.any(self.links[:, 0] == self.links[:, 1]):
                raise StateError("a link joins a pedestrian to itself")
        pair = first_overlap(self.position_m[self.active], self.radius_m[self.active], overlap_tolerance_m)
        if pair is not None:
            idx = np.flatnonzero(self.active)
            i, j, overlap = idx[pair[0]], idx[pair[1]], pair[2]
            raise StateError(f"pedestrians {i} and {j} overlap by {overlap:.4g} m at start "
                             f"(positions {self.position_m[i].tolist()} and {self.position_m[j].tolist()})")

    def arrays(self) -> Bodies:
        """The state's arrays (the same objects, not copies) as the compiled step takes them
        (:class:`~crowd_env.core.bundles.Bodies`, fields named as here)."""
        return Bodies._make(_BODIES_FIELDS(self))

    def array_fields(self) -> tuple:
        """:meth:`arrays` as a plain tuple (as :func:`~crowd_env.core.step.advance` takes it: numba's dispatcher
        types a plain tuple fastest)."""
        return _BODIES_FIELDS(self)

    def copy(self) -> "CrowdState":
        return CrowdState(**{k: np.array(v, copy=True) for k, v in self.__dict__.items()})


_BODIES_FIELDS = operator.attrgetter(*Bodies._fields)  # the state's arrays in the order of Bodies


def _all_pairs_within(position_m, radius_m, period_m=0.0):
    position_m = np.ascontiguousarray(position_m, dtype=np.float64)
    return grid_pairs(position_m, np.arange(position_m.shape[0], dtype=np.int64), float(radius_m), float(period_m))


def pair_distances(position_m: np.ndarray, pairs: np.ndarray, period_m: float = 0.0) -> np.ndarray:
    """(P,) centre distances of the ``pairs`` (rows of ``position_m``), at the nearest image along x when
    ``period_m`` > 0 (:mod:`crowd_env.core.periodic`)."""
    diff = position_m[pairs[:, 0]] - position_m[pairs[:, 1]]
    if period_m > 0.0:
        diff[:, 0] = minimum_image_dx(np.ascontiguousarray(diff[:, 0]), float(period_m))
    return np.linalg.norm(diff, axis=1)


def first_overlap(position_m: np.ndarray, radius_m: np.ndarray, tolerance_m: float = 0.0, period_m: float = 0.0):
    """Return ``(i, j, overlap_m)`` of the most overlapping pair, or None when no pair overlaps (pairs at their
    nearest image with ``period_m`` > 0)."""
    if position_m.shape[0] < 2:
        return None
    pairs = _all_pairs_within(position_m, 2.0 * float(radius_m.max()), period_m)
    if pairs.size == 0:
        return None
    d = pair_distances(position_m, pairs, period_m)
    overlap = radius_m[pairs[:, 0]] + radius_m[pairs[:, 1]] - d
    k = int(np.argmax(overlap))
    if overlap[k] > tolerance_m:
        return int(pairs[k, 0]), int(pairs[k, 1]), float(overlap[k])
    return None


def min_gap_m(position_m: np.ndarray, radius_m: np.ndarray, period_m: float = 0.0) -> float:
    """Smallest surface gap between any two pedestrians (negative = overlap; nearest images with ``period_m``
    > 0); inf for N < 2."""
    if position_m.shape[0] < 2:
        return float("inf")
    pairs = _all_pairs_within(position_m, 2.0 * float(radius_m.max()) + 1.0, period_m)
    if pairs.size == 0:
        return float("inf")
    d = pair_distances(position_m, pairs, period_m)
    return float(np.min(d - radius_m[pairs[:, 0]] - radius_m[pairs[:, 1]]))


__all__ = ["CrowdState", "StateError", "ParameterError", "sample_desired_speeds", "first_overlap", "min_gap_m",
           "pair_distances"]
