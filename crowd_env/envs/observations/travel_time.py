"""``travel_time``: T at the own position (1), the remaining travel time to the nearest exit (to the own
destination exit with destinations), s at the field's wavefront speed; 0 inside an exit."""
from __future__ import annotations

from dataclasses import dataclass

import numba as nb

from .base import ObservationComponent, ObservationField

__all__ = ["TravelTime", "write_column"]


@dataclass(frozen=True)
class TravelTime(ObservationComponent):
    """T; bounds [0, ``travel_time_bound_s``]."""

    name = "travel_time"
    fields = (ObservationField("travel_time", "1", "remaining travel time T to the nearest exit (the own destination "
                                                   "exit with destinations), s at the field's speed (1 m/s: the "
                                                   "geodesic distance in m); 0 inside an exit"),)

    def bounds(self, spec):
        return 0.0, spec.travel_time_bound_s

    def write(self, ctx, obs, col, size):
        write_column(ctx.travel_time_s, obs, col)


@nb.njit(cache=True)
def write_column(values, obs, col):
    """``obs[:, col] = values`` (m,), cast to the output's dtype."""
    for a in range(values.shape[0]):
        obs[a, col] = values[a]
