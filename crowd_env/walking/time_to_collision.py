"""Time-to-collision interaction: the anticipatory power law of Karamouzas, Skinner & Guy (2014), an addition
to Kabalan et al. 2016.

Karamouzas, Skinner & Guy (2014, Phys. Rev. Lett. 113:238701) measured, in outdoor and laboratory crowds,
that the interaction energy of two pedestrians depends on their *time to collision* τ, not on their distance:

    E(τ) = k m τ⁻² exp(−τ/τ0),

with τ the first time at which the two disks, each extrapolated at its current velocity, would touch:
‖x + v τ‖ = r_i + r_j with x = x_i − x_j, v = u_i − u_j. Writing a = v·v, b = −x·v and c = x·x − (r_i + r_j)²,

    τ = (b − √(b² − a c)) / a      (b² − a c > 0 and τ > 0; otherwise no collision ahead: no interaction).

The force on i is f = −∇_x E (the gradient in the relative position, the velocities held):

    f = k m e^(−τ/τ0) / (a τ²) · (2/τ + 1/τ0) · (−v + (a x + b v) / √(b² − a c)).

Constants (:class:`TimeToCollision`, the model's ``ttc_<field>`` parameters): k = ``strength_m2_s2`` (the paper's
fit: 1.5 m²/s², per unit mass; 0, the default, switches the interaction off), τ0 = ``horizon_s`` (3 s, the paper's
interaction horizon), neighbours whose centres lie within ``range_m``, and the force per unit mass capped at
``max_accel_m_s2``: E diverges as τ → 0 at contact, where the core's Frémond contacts keep the
bodies apart anyway. Two pedestrians at the same velocity (a = 0) or moving apart never interact, so the
interaction slows a walker that closes on a slower one and deflects walkers that would collide; pedestrians
who already touch (c ≤ 0) leave it to the contacts. The force is antisymmetric (f_ji = −f_ij for equal
masses), like the social force of Eq. 16, and enters the agent's intent the same way, u_int += (τ_i/m_i) f.
"""
from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np

from ..core.params import check_parameter
from ..core.periodic import minimum_image_dx

__all__ = ["TimeToCollision", "time_to_collision_s", "ttc_acceleration", "total_ttc_accelerations"]


class TimeToCollision(NamedTuple):
    """The interaction's constants (module docstring; the model's ``ttc_<field>`` parameters)."""

    strength_m2_s2: float = 0.0
    horizon_s: float = 3.0
    range_m: float = 3.0
    max_accel_m_s2: float = 5.0

    def checked(self) -> "TimeToCollision":
        """This group, once checked (:class:`~crowd_env.errors.ParameterError` naming the model parameter)."""
        check_parameter("ttc_strength_m2_s2", self.strength_m2_s2, minimum=0.0)
        for name in ("horizon_s", "range_m", "max_accel_m_s2"):
            check_parameter(f"ttc_{name}", getattr(self, name), positive=True)
        return self

    def resolved(self) -> "TimeToCollision":
        """Plain numbers for the kernels."""
        return TimeToCollision(*(float(value) for value in self))


@nb.njit(cache=True)
def time_to_collision_s(x, y, vx, vy, radius_sum_m):
    """τ (s) at which two disks touch, relative position (x, y) = x_i − x_j and velocity (vx, vy) = u_i − u_j,
    both extrapolated at constant velocity; ``inf`` when they never will (moving apart, parallel, passing
    beside), and 0 when they already touch or overlap and close in."""
    a = vx * vx + vy * vy
    b = -(x * vx + y * vy)
    c = x * x + y * y - radius_sum_m * radius_sum_m
    if c <= 0.0:
        return 0.0 if b > 0.0 else np.inf
    if a == 0.0 or b <= 0.0:
        return np.inf
    disc = b * b - a * c
    if disc <= 0.0:
        return np.inf
    return c / (b + np.sqrt(disc))  # = (b − √disc)/a without the cancellation


@nb.njit(cache=True)
def ttc_acceleration(x, y, vx, vy, radius_sum_m, strength_m2_s2, horizon_s, max_accel_m_s2):
    """f/m on pedestrian i (module docstring), relative position (x, y) = x_i − x_j and velocity (vx, vy) =
    u_i − u_j; (0, 0) when no collision lies ahead (τ infinite, :func:`time_to_collision_s`) or the disks already
    touch (τ = 0). Capped at ``max_accel_m_s2``."""
    tau = time_to_collision_s(x, y, vx, vy, radius_sum_m)
    if not 0.0 < tau < np.inf:
        return 0.0, 0.0
    a = vx * vx + vy * vy
    b = -(x * vx + y * vy)
    root = np.sqrt(b * b - a * (x * x + y * y - radius_sum_m * radius_sum_m))
    scale = strength_m2_s2 * np.exp(-tau / horizon_s) / (a * tau * tau) * (2.0 / tau + 1.0 / horizon_s)
    fx = scale * (-vx + (a * x + b * vx) / root)
    fy = scale * (-vy + (a * y + b * vy) / root)
    norm = np.sqrt(fx * fx + fy * fy)
    if norm > max_accel_m_s2:
        fx *= max_accel_m_s2 / norm
        fy *= max_accel_m_s2 / norm
    return fx, fy


@nb.njit(cache=True)
def total_ttc_accelerations(position, velocity, radius, index, pairs, period_m, ttc):
    """Σ_j f_ij/m_i (n, 2) on the pedestrians ``index`` from every pair of ``pairs`` (rows into ``index``)
    whose centres lie within the :class:`TimeToCollision` ``ttc``'s range (minimum image along x when ``period_m``
    > 0)."""
    range_m = ttc.range_m
    n = index.shape[0]
    out = np.zeros((n, 2))
    for p in range(pairs.shape[0]):
        a = pairs[p, 0]
        b = pairs[p, 1]
        i = index[a]
        j = index[b]
        x = minimum_image_dx(position[i, 0] - position[j, 0], period_m)
        y = position[i, 1] - position[j, 1]
        if x * x + y * y > range_m * range_m:
            continue
        fx, fy = ttc_acceleration(x, y, velocity[i, 0] - velocity[j, 0], velocity[i, 1] - velocity[j, 1],
                                  radius[i] + radius[j], ttc.strength_m2_s2, ttc.horizon_s, ttc.max_accel_m_s2)
        out[a, 0] += fx
        out[a, 1] += fy
        out[b, 0] -= fx
        out[b, 1] -= fy
    return out
