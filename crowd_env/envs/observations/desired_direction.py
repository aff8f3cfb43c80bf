"""``desired_direction``: e_d = −∇T/‖∇T‖ (Eq. 13) of the own destination's eikonal field at the own position
(2, a unit vector), in the observation frame."""
from __future__ import annotations

from dataclasses import dataclass

from .base import ObservationComponent, ObservationField
from .velocity import write_in_frame

__all__ = ["DesiredDirection"]


@dataclass(frozen=True)
class DesiredDirection(ObservationComponent):
    """e_d, sampled once per step for all components (:class:`~.base.ObservationContext`); bounds ±1."""

    name = "desired_direction"
    fields = (ObservationField("desired_direction", "2", "e_d of the eikonal field at the own position (unit vector)"),)
    egocentric_fields = (ObservationField("desired_direction", "2", "e_d of the eikonal field at the own position, "
                                                                    "body frame (unit vector)"),)

    def bounds(self, spec):
        return -1.0, 1.0

    def write(self, ctx, obs, col, size):
        write_in_frame(ctx.desired_direction, ctx.cos_heading, ctx.sin_heading, ctx.world, obs, col)
