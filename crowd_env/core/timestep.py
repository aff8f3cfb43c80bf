"""The time step h (``PhysicsParams.dt_s``) a crowd can be stepped with: the stability limit, and the safe step.

The step (:mod:`crowd_env.core.step`) integrates the smooth dynamics explicitly (Kabalan et al. 2016 use
h = 0.01 s, Table 2), so h has two bounds, both derived from the crowd's own parameters:

**Stability limit** (:func:`stability_limit_s`; :func:`check_time_step` refuses a larger h with a
:class:`~crowd_env.errors.ParameterError`). Beyond it the explicit update no longer settles, whatever the
contacts do:

- the driving relaxation (Eq. 14), u ← u + h/τ (u_int − u), multiplies u − u_int by 1 − h/τ: it diverges for
  h > 2τ (the speed grows geometrically until the kinetic energy overflows);
- the heading (Eq. 15), ω ← ω + h (−k θ − c ω)/I and then θ ← θ + h ω, is stable while
  h² k + 2 h c < 4 I (the update's matrix has determinant 1 − h c/I and trace 2 − h c/I − h² k/I; Jury's
  test), i.e. h < (√(c² + 4 k I) − c)/k: 0.549 s for the default pedestrian (k = 5 N m/rad, critically
  damped, I = 2.2 kg m²). Just beyond it a heading never settles (at 1.02 times the limit it spins at
  about 11 rad/s instead of turning to θ_d; θ is wrapped, which bounds ω while ``|1 − h c/I| < 1``), and
  beyond h = 2 I/c (0.66 s) ω grows geometrically: a run at h = 1 s spun headings to ω ≈ 1e90 rad/s
  within 300 steps.

**Safe step** (:func:`safe_time_step_s`; :func:`check_time_step` warns with a :class:`TimeStepWarning`
above it), the smallest of

- τ/10: the explicit relaxation then relaxes at the rate −ln(1 − h/τ)/h, at most 5.4 % faster than 1/τ
  (0.05 s for τ = 0.5 s);
- a tenth of the heading's stability limit (0.055 s for the default pedestrian);
- √(2 ε (2 r)) / v₀: the gap projection keeps a pair from overlapping along the normal of the step's start,
  so a pedestrian walking at its desired speed v₀ past a standing one of the same radius r, touching, ends
  the step (h v₀)² / (4 r) apart; beyond this h that exceeds the contact tolerance ε
  (``contact_tolerance_m``): sliding contacts open within a step, no longer count as touching, and fall out
  of the Frémond impacts (Eq. 4-8) (0.016 s for r = 0.23 m, ε = 1 mm and the fastest default walker,
  v₀ = 1.86 m/s).

The paper's h = 0.01 s lies below both for the default crowd.

**Smallest step** (:data:`MIN_TIME_STEP_S`, 1e-4 s, a hundredth of the paper's; :func:`check_time_step_floor`
refuses a smaller h, for the simulator and for the environment at construction). Nothing in the model is
faster than the safe step above (contacts are impacts, instantaneous, Eq. 4-8), so a smaller h resolves nothing
more and only multiplies the steps, while what a run or an episode covers shrinks with it: at h = 1e-9 s an
episode of 600 decisions of 10 steps covered 6 µs and nobody moved. The runner refuses runs of too many steps
on its own (``crowd_env.experiments.running.runner.check_step_limit``).
"""
from __future__ import annotations

import math
import warnings

import numpy as np

from crowd_env.errors import ParameterError

from .checks import _error_class

__all__ = ["TimeStepWarning", "stability_limit_s", "safe_time_step_s", "check_time_step", "check_time_step_floor",
           "PAPER_TIME_STEP_S", "MIN_TIME_STEP_S"]

PAPER_TIME_STEP_S = 0.01  # Kabalan et al. (2016), Table 2
MIN_TIME_STEP_S = PAPER_TIME_STEP_S / 100.0  # the smallest step taken (module docstring)


class TimeStepWarning(UserWarning):
    """``dt_s`` is stable but above the crowd's safe time step (:func:`safe_time_step_s`)."""


def _heading_limits_s(stiffness, damping, inertia) -> np.ndarray:
    """Per pedestrian, the h at which h² k + 2 h c = 4 I (inf where k = c = 0)."""
    k = np.asarray(stiffness, dtype=float)
    c = np.asarray(damping, dtype=float)
    inertia = np.asarray(inertia, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        spring = (np.sqrt(c * c + 4.0 * k * inertia) - c) / k
        damped = 2.0 * inertia / c
    return np.where(k > 0, spring, np.where(c > 0, damped, np.inf))


def stability_limit_s(state, params) -> tuple:
    """``(h_max, reason)``: the largest stable time step of the active pedestrians of ``state`` (module
    docstring) and what sets it, naming the pedestrian; ``(inf, "")`` when nobody is active."""
    idx = np.flatnonzero(state.active)
    if not idx.size:
        return math.inf, ""
    relax = 2.0 * state.tau_s[idx]
    i = int(np.argmin(relax))
    best, reason = float(relax[i]), (f"2 tau = {relax[i]:.4g} s of pedestrian {int(idx[i])} (the explicit driving "
                                     f"relaxation of Eq. 14, u <- u + h/tau (u_int - u), diverges for h > 2 tau)")
    if params.rotation:
        turn = _heading_limits_s(state.heading_stiffness[idx], state.heading_damping[idx], state.inertia_kg_m2[idx])
        j = int(np.argmin(turn))
        if turn[j] < best:
            p = int(idx[j])
            best = float(turn[j])
            reason = (f"{turn[j]:.4g} s for pedestrian {p} (k = {state.heading_stiffness[p]:.4g} N m/rad, "
                      f"c = {state.heading_damping[p]:.4g} N m s/rad, I = {state.inertia_kg_m2[p]:.4g} kg m^2; the "
                      f"explicit heading update of Eq. 15 is unstable where h^2 k + 2 h c > 4 I)")
    return best, reason


def safe_time_step_s(state, params) -> tuple:
    """``(h_safe, reason)``: the largest time step at which the explicit update stays accurate and contacts
    stay closed for the active pedestrians of ``state`` (module docstring); ``(inf, "")`` when nobody is
    active."""
    idx = np.flatnonzero(state.active)
    if not idx.size:
        return math.inf, ""
    tau = float(state.tau_s[idx].min())
    best, reason = tau / 10.0, f"tau / 10 = {tau / 10.0:.4g} s (explicit driving relaxation, Eq. 14, within 5.4 %)"
    if params.rotation:
        turn = float(_heading_limits_s(state.heading_stiffness[idx], state.heading_damping[idx],
                                       state.inertia_kg_m2[idx]).min()) / 10.0
        if turn < best:
            best, reason = turn, f"a tenth of the heading's stability limit = {turn:.4g} s (Eq. 15)"
    v0 = float(state.desired_speed_m_s[idx].max())
    if v0 > 0.0:
        r = float(state.radius_m[idx].min())
        contact = math.sqrt(4.0 * params.contact_tolerance_m * r) / v0
        if contact < best:
            best, reason = contact, (f"sqrt(2 eps (2 r)) / v0 = {contact:.4g} s (a walker at v0 = {v0:.3g} m/s sliding "
                                     f"past one of radius r = {r:.3g} m opens their contact by (h v0)^2 / (4 r) in a "
                                     f"step; beyond contact_tolerance_m eps = {params.contact_tolerance_m:g} m sliding "
                                     f"contacts fall out of the Frémond impacts, Eq. 4-8)")
    return best, reason


def check_time_step_floor(dt_s, error=ParameterError, name: str = "dt_s") -> float:
    """``dt_s`` as a float; raise ``error`` naming ``name`` when it is below :data:`MIN_TIME_STEP_S`."""
    h = float(dt_s)
    if h < MIN_TIME_STEP_S:
        raise _error_class(error)(f"{name} = {h:g} s is below the smallest time step crowd_env takes, {MIN_TIME_STEP_S:g} s (a "
                    f"hundredth of the paper's h = {PAPER_TIME_STEP_S:g} s): no process of the model is that fast, "
                    f"and a second of simulated time would take {1.0 / h:,.0f} steps, so that nobody moves in what a "
                    f"run or an episode covers; use the paper's h = {PAPER_TIME_STEP_S:g} s")
    return h


def check_time_step(state, params) -> None:
    """Raise :class:`~crowd_env.errors.ParameterError` when ``params.dt_s`` is below :data:`MIN_TIME_STEP_S` or
    exceeds the stability limit of ``state``'s crowd; warn (:class:`TimeStepWarning`) when it exceeds the safe step
    (module docstring)."""
    h = check_time_step_floor(params.dt_s)
    limit, why = stability_limit_s(state, params)
    if h > limit:
        raise ParameterError(f"dt_s = {h:g} s is beyond the stability limit {why}; use a step below "
                             f"{limit:.4g} s (the paper's h = {PAPER_TIME_STEP_S:g} s)")
    safe, why = safe_time_step_s(state, params)
    if h > safe:
        warnings.warn(f"dt_s = {h:g} s is above this crowd's safe time step {why}; results depend on the step "
                      f"(the paper's h = {PAPER_TIME_STEP_S:g} s)", TimeStepWarning, stacklevel=3)
