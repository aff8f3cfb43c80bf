"""A user's observation component, in a module of its own: ``tests/envs/test_components.py`` names it in the
environment's options as ``"tests.envs.user_component:VelocityError"``; nothing else is edited to add it."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from crowd_env.envs.observations import ObservationComponent, ObservationField


@dataclass(frozen=True)
class VelocityError(ObservationComponent):
    """v0 e_d − u (m/s), how far the own velocity is from walking at ``speed_m_s`` along e_d, in the
    observation frame (2), and its norm (1)."""

    speed_m_s: float = 1.34

    name = "velocity_error"
    fields = (ObservationField("velocity_error", "2", "v0 e_d − u, m/s, observation frame"),
              ObservationField("velocity_error_norm", "1", "‖v0 e_d − u‖, m/s"))

    def bounds(self, spec):
        v = spec.velocity_bound_m_s + self.speed_m_s
        return np.array([-v, -v, 0.0]), np.array([v, v, v])

    def compute(self, ctx, out):
        error = self.speed_m_s * ctx.desired_direction - ctx.velocity_m_s
        out[:, :2] = ctx.in_frame(error)
        out[:, 2] = np.hypot(error[:, 0], error[:, 1])
