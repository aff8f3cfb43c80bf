"""Learned policies driving pedestrians outside the environment's step: the same observation, decision interval
and action frame as an agent of :mod:`crowd_env.envs.crowd_v0` gets, for any pedestrians of a scenario.

:func:`observing_driver` makes the environment's own :class:`~crowd_env.envs.background.ObservingBackground` for an
observation policy (a policy file, a shipped trained policy) and a mask of pedestrians, its options being the
policy's ``env_overrides`` over the environment's defaults, checked as the environment checks its own; the
environment drives its learned background with it, and :class:`MixedDriver` drives a crowd for the runner
(:func:`crowd_env.experiments.running.runner.run_scenario`): the learned pedestrians by the policy, the others by the
calibrated agent (Kabalan et al. 2016, Eq. 14-16), so that a learned policy goes through the experiment's
instruments as the calibrated model does.
"""
from __future__ import annotations

import numpy as np

from crowd_env.errors import PolicyError

from ..core.angles import direction_angles_rad
from .background import OBSERVATION_POLICY_OPTIONS, ObservingBackground
from .config import ENV_DEFAULTS, observation_policy_options

__all__ = ["observing_driver", "intents_and_headings", "check_social_force_gate", "MixedDriver"]


def observing_driver(policy, scenario, *, navigation, mask, dt_s: float, velocity_bound_m_s: float,
                     travel_time_bound_s: float, what: str = "background policy: ") -> ObservingBackground:
    """The driver of the pedestrians ``mask`` (N,) by the observation policy ``policy`` on ``scenario`` with
    ``navigation``; ``dt_s``: the simulator step; the bounds only set the declared observation space."""
    options = observation_policy_options({k: policy.env_overrides.get(k, ENV_DEFAULTS[k])
                                          for k in OBSERVATION_POLICY_OPTIONS}, what=what)
    return ObservingBackground(policy, options, navigation=navigation, walls=scenario.geometry.walls,
                               background_mask=mask, dt_s=dt_s, velocity_bound_m_s=velocity_bound_m_s,
                               travel_time_bound_s=travel_time_bound_s, period_m=scenario.geometry.period_x_m)


def intents_and_headings(out, state) -> tuple:
    """A policy's output ``intents`` or ``(intents, headings)`` as float64 arrays ``(N, 2)``, ``(N,)``; without
    headings, θ_d is the angle of the intent (the current heading for a zero intent). :class:`PolicyError`
    naming the shapes otherwise."""
    n = state.n
    intents, heading = out if isinstance(out, tuple) else (out, None)
    intents = np.array(intents, dtype=np.float64)
    if intents.shape != (n, 2):
        raise PolicyError(f"background policy returned intents of shape {intents.shape}, expected ({n}, 2)")
    if heading is None:
        speed = np.hypot(intents[:, 0], intents[:, 1])
        heading = np.where(speed > 1e-12, direction_angles_rad(intents), state.heading_rad)
    else:
        heading = np.array(heading, dtype=np.float64)
        if heading.shape != (n,):
            raise PolicyError(f"background policy returned headings of shape {heading.shape}, expected ({n},)")
    return intents, heading


def check_social_force_gate(social_force: bool, below_m_s) -> float | None:
    """``below_m_s`` as a float (None stays None), or :class:`PolicyError` naming it: the gate of the social force
    added to a learned policy's intents (:class:`MixedDriver`) is a speed in m/s > 0, with ``social_force`` on."""
    if below_m_s is None:
        return None
    if not social_force or isinstance(below_m_s, bool) or not isinstance(below_m_s, (int, float)) \
            or not (np.isfinite(below_m_s) and below_m_s > 0.0):
        raise PolicyError(f"social_force_below_m_s gates the social force added to a learned policy: a speed in m/s "
                          f"> 0, with social_force on; got {below_m_s!r}")
    return float(below_m_s)


class MixedDriver:
    """``policy(sim) -> (intents, headings)`` for the runner: the pedestrians ``learned_mask`` (N,) driven by the
    observation policy ``policy``, the others by ``calibrated`` (a ``policy(sim)``, the calibrated agent).
    Every pedestrian learned (the mask all true) is the policy alone. With ``social_force`` the learned
    pedestrians' intents get, every step, the model's social force as the calibrated agent adds it to its own,
    (τ/m) Σ f_social (Kabalan Eq. 14, 16; ``calibrated.social_force``): learned walking, the model's push apart
    between walkers close to touching. With ``social_force_below_m_s`` u_g as well, only a walker nearly standing
    gets it, in full at rest and not at all from u_g on: the share max(0, 1 − ‖u‖/u_g) of it."""

    def __init__(self, policy, scenario, calibrated, learned_mask, *, dt_s: float, social_force: bool = False,
                 social_force_below_m_s: float | None = None):
        self.learned_mask = np.asarray(learned_mask, bool)
        self.calibrated = calibrated
        self.social_force = bool(social_force)
        self.social_force_below_m_s = check_social_force_gate(social_force, social_force_below_m_s)
        navigation = getattr(calibrated, "navigation", None) or scenario.navigation()
        self.learned = observing_driver(policy, scenario, navigation=navigation, mask=self.learned_mask, dt_s=dt_s,
                                        velocity_bound_m_s=20.0, travel_time_bound_s=navigation.max_travel_time_s + 1.0,
                                        what="scored policy: ")
        self.name = getattr(policy, "name", type(policy).__name__)

    def __call__(self, sim):
        intents, heading = intents_and_headings(self.learned(sim), sim.state)
        if self.social_force and sim.active_index.size:
            idx = sim.active_index
            force = self.calibrated.social_force(sim, self.calibrated.desired_direction(sim, idx))
            st = sim.state
            learned = self.learned_mask[idx]
            rows = idx[learned]
            share = st.tau_s[rows] / st.mass_kg[rows]
            if self.social_force_below_m_s is not None:  # nearly standing: in full at rest, none from u_g on
                share = share * np.clip(1.0 - np.hypot(*st.velocity_m_s[rows].T) / self.social_force_below_m_s,
                                        0.0, 1.0)
            intents[rows] += share[:, None] * force[learned]
        if not self.learned_mask.all():
            base, base_heading = intents_and_headings(self.calibrated(sim), sim.state)
            rows = ~self.learned_mask
            intents[rows] = base[rows]
            heading[rows] = base_heading[rows]
        return intents, heading
