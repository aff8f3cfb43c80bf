"""The core's parameters of the Kabalan et al. (2016) crowd model and the per-pedestrian defaults.

:class:`PhysicsParams`: the step and the Frémond contacts, defaults the paper's Table 2 (K_n = 1e5 kg, K_tg = 0,
h = 0.01 s). :class:`PedestrianDefaults`: Table 2's body and Henderson's desired speeds. Every field carries its unit
in its name. The walking model's parameters are in :mod:`crowd_env.walking` (its groups, each beside its kernel,
and :class:`crowd_env.walking.model.ModelParams`, the pair a preset names).
"""
from __future__ import annotations

from crowd_env.errors import ParameterError

import dataclasses
import math
from dataclasses import dataclass, field, fields

import numpy as np

SOLVERS = ("dual", "cvxpy")
# How far beyond the bodies a behaviour's forces are taken to reach when a simulator's parameters do not say
# (``params.interaction_reach_m``; the walking model's ModelParams says its social cut-off): 1 m, the walking
# model's default cut-off. A periodic simulator must be longer than 2 (2 r_max + reach) (Simulator).
DEFAULT_INTERACTION_REACH_M = 1.0


@dataclass(frozen=True)
class PhysicsParams:
    """The core's parameters: the step and the Frémond contacts (Kabalan et al. 2016, Eq. 1-8; Table 2).

    ``dt_s`` the step h; ``normal_dissipation_kg`` K_n, ``tangential_dissipation_kg`` K_tg,
    ``link_dissipation_kg_per_m2`` K_v (Eq. 7-8); ``contact_tolerance_m``: a pair "touches" when its gap is below this
    (the projection leaves O(h² v² / R) residue); ``rotation`` False freezes the headings (Section 4.1.1, "without
    rotation"); ``solver``: ``"dual"`` (the compiled cascade) or ``"cvxpy"`` (the reference formulation);
    ``body_depth_m`` the body's depth from chest to back, 0 for the paper's disk (:mod:`crowd_env.core.body`: three
    circles across the shoulders, an addition; below 2 r, checked by the simulator). The walking
    model's parameters (the social force, vision, ...) are not the core's: they live beside their kernels in
    :mod:`crowd_env.walking` and a preset pairs them with these (:class:`crowd_env.walking.model.ModelParams`).
    """

    dt_s: float = 0.01
    normal_dissipation_kg: float = 1.0e5
    tangential_dissipation_kg: float = 0.0
    link_dissipation_kg_per_m2: float = 1.0e5
    contact_tolerance_m: float = 1.0e-3
    rotation: bool = True
    solver: str = "dual"
    body_depth_m: float = 0.0

    def __post_init__(self) -> None:
        for name in ("dt_s", "normal_dissipation_kg", "contact_tolerance_m"):
            check_parameter(name, getattr(self, name), positive=True)
        for name in ("tangential_dissipation_kg", "link_dissipation_kg_per_m2", "body_depth_m"):
            check_parameter(name, getattr(self, name), minimum=0.0)
        check_flag("rotation", self.rotation)
        if self.solver not in SOLVERS:
            raise ParameterError(f"unknown solver {self.solver!r}; choose one of {SOLVERS}")

    def replace(self, **changes) -> "PhysicsParams":
        """A copy with some fields changed (unknown names raise :class:`ParameterError`)."""
        known = {f.name for f in fields(self)}
        unknown = sorted(set(changes) - known)
        if unknown:
            raise ParameterError(f"unknown physics parameter(s): {unknown}; known: {sorted(known)}")
        return dataclasses.replace(self, **changes)


def check_parameter(name: str, value, *, positive: bool = False, minimum: float | None = None,
                    maximum: float | None = None) -> float:
    """``value`` as a float when it is a finite number (a bool is none) within the bounds: > 0 with ``positive``,
    ``minimum`` <= value <= ``maximum``; :class:`ParameterError` naming ``name`` otherwise. The one check of every
    model parameter, the core's and the walking model's groups'."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) or not math.isfinite(value):
        raise ParameterError(f"{name} must be a finite number, got {value!r}")
    if positive and value <= 0:
        raise ParameterError(f"{name} must be > 0, got {value!r}")
    if minimum is not None and value < minimum:
        raise ParameterError(f"{name} must be >= {minimum:g}, got {value!r}")
    if maximum is not None and value > maximum:
        raise ParameterError(f"{name} must be <= {maximum:g}, got {value!r}")
    return float(value)


def check_flag(name: str, value) -> bool:
    """``value`` when it is True or False (numpy's too); :class:`ParameterError` naming ``name`` otherwise."""
    if not isinstance(value, (bool, np.bool_)):
        raise ParameterError(f"{name} must be True or False, got {value!r}")
    return bool(value)


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
