"""Model parameters of the Kabalan et al. (2016) crowd model.

Defaults are the paper's Table 2 (K_n = 1e5 kg, K_tg = 0, h = 0.01 s) and its validation point of the
social repulsion (A = 790 N, B = 0.08 m, Section 4.1.3). Every field carries its unit in its name.
"""
from __future__ import annotations

from crowd_env.errors import ParameterError

import dataclasses
import math
from dataclasses import dataclass, field, fields

import numpy as np

SOLVERS = ("dual", "cvxpy")


@dataclass(frozen=True)
class ModelParams:
    """Global parameters of the dynamics (per-pedestrian ones live in :class:`CrowdState`).

    Collision (Eq. 7-8): ``normal_dissipation_kg`` K_n, ``tangential_dissipation_kg`` K_tg,
    ``link_dissipation_kg_per_m2`` K_v. Social repulsion (Eq. 16): ``social_strength_n`` A,
    ``social_range_m`` B, ``social_anisotropy`` λ (1 = isotropic), applied between pedestrians whose
    surface gap is below ``social_cutoff_m`` and from walls closer than that.

    Vision (an addition to Kabalan et al., :mod:`crowd_env.walking.vision`): with
    ``vision_time_gap_s`` T > 0 the calibrated agent walks at v = min(v0, max(0, (f − ``vision_jam_gap_m``)/T))
    in the direction of a fan of ``vision_rays`` directions within ±``vision_half_angle_rad`` of e_d that
    brings it closest to its goal, f being the free distance before touching someone or a wall in that
    direction (Moussaïd, Helbing, Theraulaz 2011; with one ray, the collision-free speed rule of Tordeux,
    Chraibi, Seyfried 2016); a neighbour blocks a direction within ``vision_body_scale`` κ (r_i + r_j) of its
    centre. T = 0 (the default) is the paper's model.
    """

    dt_s: float = 0.01
    normal_dissipation_kg: float = 1.0e5
    tangential_dissipation_kg: float = 0.0
    link_dissipation_kg_per_m2: float = 1.0e5
    # Contacts: a pair "touches" when its gap is below this (projection leaves O(h^2 v^2 / R) residue).
    contact_tolerance_m: float = 1.0e-3
    # Social repulsion (Helbing, Farkas, Vicsek 2000; Kabalan Eq. 16).
    social_strength_n: float = 790.0
    social_range_m: float = 0.08
    social_anisotropy: float = 1.0
    social_cutoff_m: float = 1.0
    wall_social_strength_n: float | None = None  # None: same A as between pedestrians
    wall_social_range_m: float | None = None  # None: same B as between pedestrians
    social_forces: bool = True
    vision_time_gap_s: float = 0.0  # T of the vision rule; 0: off (the paper's walking model)
    vision_jam_gap_m: float = 0.0  # free distance at which the vision rule's speed reaches 0
    vision_half_angle_rad: float = 0.0  # half-width of the fan of directions (0: along e_d only)
    vision_rays: int = 1  # directions in the fan (odd: e_d itself is one of them)
    vision_body_scale: float = 1.0  # κ: a neighbour blocks a direction within κ (r_i + r_j) of its centre
    vision_body_scale_standing: float | None = None  # κ_0 at rest (κ at the desired speed); None: κ always
    vision_anticipation: float = 0.0  # w: the others move on at w times their velocity (0: they stand)
    vision_leader_time_s: float = 0.0  # T_a: the speed rule reads the gap T_a ahead, the leader walking on (0: off)
    vision_right_of_way: bool = False  # True: a neighbour farther from the exit (larger T, Eq. 11) never blocks
    # Time-to-collision interaction (Karamouzas, Skinner & Guy 2014; crowd_env.walking.time_to_collision).
    ttc_strength_m2_s2: float = 0.0  # k per unit mass (the paper's fit 1.5); 0: off (the paper's walking model)
    ttc_horizon_s: float = 3.0  # τ0, the interaction horizon (the paper's fit)
    ttc_range_m: float = 3.0  # neighbours whose centres lie within this interact
    ttc_max_accel_m_s2: float = 5.0  # cap on the force per unit mass (E diverges at contact, τ -> 0)
    rotation: bool = True  # False: headings frozen (paper Section 4.1.1, "without rotation")
    solver: str = "dual"
    extra: dict = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self) -> None:
        if self.extra:
            raise ParameterError(f"unknown model parameter(s): {sorted(self.extra)}")
        positive = ("dt_s", "normal_dissipation_kg", "contact_tolerance_m", "social_range_m", "social_cutoff_m",
                    "ttc_horizon_s", "ttc_range_m", "ttc_max_accel_m_s2")
        non_negative = ("tangential_dissipation_kg", "link_dissipation_kg_per_m2", "social_strength_n",
                        "vision_time_gap_s", "vision_jam_gap_m", "vision_half_angle_rad", "vision_leader_time_s",
                        "ttc_strength_m2_s2")
        for name in positive + non_negative:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
                    or not math.isfinite(value):
                raise ParameterError(f"{name} must be a finite number, got {value!r}")
            if name in positive and value <= 0:
                raise ParameterError(f"{name} must be > 0, got {value!r}")
            if name in non_negative and value < 0:
                raise ParameterError(f"{name} must be >= 0, got {value!r}")
        if isinstance(self.social_anisotropy, bool) or not isinstance(self.social_anisotropy, (int, float, np.floating)) \
                or not 0.0 <= self.social_anisotropy <= 1.0:
            raise ParameterError(f"social_anisotropy (lambda) must lie in [0, 1], got {self.social_anisotropy!r}")
        for name in ("wall_social_strength_n", "wall_social_range_m"):
            value = getattr(self, name)
            if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating))
                                      or not math.isfinite(value) or value < 0 or (name.endswith("_m") and value == 0)):
                raise ParameterError(f"{name} must be a positive finite number or None, got {value!r}")
        if isinstance(self.vision_body_scale, bool) or not isinstance(self.vision_body_scale, (int, float, np.floating)) \
                or not 0.0 < self.vision_body_scale <= 1.0:
            raise ParameterError(f"vision_body_scale (kappa) must lie in (0, 1], got {self.vision_body_scale!r}")
        standing = self.vision_body_scale_standing
        if standing is not None and (isinstance(standing, bool) or not isinstance(standing, (int, float, np.floating))
                                     or not 0.0 < standing <= 1.0):
            raise ParameterError(f"vision_body_scale_standing (kappa_0) must lie in (0, 1] or be None, got {standing!r}")
        if isinstance(self.vision_anticipation, bool) or not isinstance(self.vision_anticipation, (int, float, np.floating)) \
                or not 0.0 <= self.vision_anticipation <= 1.0:
            raise ParameterError(f"vision_anticipation must lie in [0, 1], got {self.vision_anticipation!r}")
        if self.vision_half_angle_rad > math.pi:
            raise ParameterError(f"vision_half_angle_rad must lie in [0, pi], got {self.vision_half_angle_rad!r}")
        if isinstance(self.vision_rays, bool) or not isinstance(self.vision_rays, (int, np.integer)) \
                or self.vision_rays < 1 or self.vision_rays % 2 == 0:
            raise ParameterError(f"vision_rays must be an odd integer >= 1, got {self.vision_rays!r}")
        if self.vision_rays > 1 and self.vision_half_angle_rad == 0:
            raise ParameterError(f"vision_rays = {self.vision_rays} needs vision_half_angle_rad > 0 (a fan of "
                                 f"directions); with one direction set vision_rays = 1")
        for name in ("social_forces", "rotation", "vision_right_of_way"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise ParameterError(f"{name} must be True or False, got {getattr(self, name)!r}")
        if self.solver not in SOLVERS:
            raise ParameterError(f"unknown solver {self.solver!r}; choose one of {SOLVERS}")

    @property
    def wall_strength_n(self) -> float:
        return self.social_strength_n if self.wall_social_strength_n is None else self.wall_social_strength_n

    @property
    def wall_range_m(self) -> float:
        return self.social_range_m if self.wall_social_range_m is None else self.wall_social_range_m

    @classmethod
    def from_dict(cls, values: dict) -> "ModelParams":
        """Build from a mapping, rejecting unknown keys by name."""
        known = {f.name for f in fields(cls)} - {"extra"}
        unknown = sorted(set(values) - known)
        if unknown:
            raise ParameterError(f"unknown model parameter(s): {unknown}; known: {sorted(known)}")
        return cls(**values)

    def replace(self, **changes) -> "ModelParams":
        """A copy with some fields changed (unknown names raise :class:`ParameterError`)."""
        known = {f.name for f in fields(self)} - {"extra"}
        unknown = sorted(set(changes) - known)
        if unknown:
            raise ParameterError(f"unknown model parameter(s): {unknown}; known: {sorted(known)}")
        return dataclasses.replace(self, **changes)


@dataclass(frozen=True)
class PedestrianDefaults:
    """Per-pedestrian defaults (Kabalan Table 2; Henderson 1971 speeds)."""

    radius_m: float = 0.23
    mass_kg: float = 83.0
    tau_s: float = 0.5
    desired_speed_mean_m_s: float = 1.34
    desired_speed_std_m_s: float = 0.26
    # Desired speeds are drawn from N(mean, std) truncated to [mean - 2 std, mean + 2 std] = [0.82, 1.86].
    desired_speed_truncation_sigma: float = 2.0
    heading_stiffness_n_m_per_rad: float = 5.0  # k, inside the paper's range [0.5, 18.5]
    heading_damping_ratio: float = 1.0  # zeta = c / (2 sqrt(I k)); 1 = critically damped (Section 2.3)
