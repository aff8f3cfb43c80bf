"""``local_density`` (1, off by default): pedestrians per m² around the own centre, (1 + n) / (π ρ²) with n the
others on the floor within ρ = ``radius_m`` (1 m by default; at most ``max_count`` are counted); the same in
both frames. A disc estimate of the density of the fundamental diagram, cheaper and noisier than the
Voronoi density of :mod:`crowd_env.analysis.density`."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb

from ...core.neighbors import grid_k_nearest
from ...core.checks import check_integer, check_number
from crowd_env.errors import EnvOptionError
from .base import ObservationComponent, ObservationField

__all__ = ["LocalDensity", "write_density"]


@dataclass(frozen=True)
class LocalDensity(ObservationComponent):
    """Disc density of radius ``radius_m``; bounds [0, (1 + ``max_count``) / (π ρ²)]. Name it
    (``"local_density"``) or give an instance (``LocalDensity(radius_m=2.0)``) in ``observation_components``."""

    radius_m: float = 1.0
    max_count: int = 32

    name = "local_density"
    fields = (ObservationField("local_density", "1", "pedestrians per m² within radius_m of the own centre, the own "
                                                     "one included"),)

    def __post_init__(self):
        check_number("LocalDensity.radius_m", self.radius_m, error=EnvOptionError, positive=True)
        check_integer("LocalDensity.max_count", self.max_count, error=EnvOptionError, minimum=1)

    def bounds(self, spec):
        return 0.0, (1 + self.max_count) / (math.pi * self.radius_m ** 2)

    def write(self, ctx, obs, col, size):
        near = grid_k_nearest(ctx.state.position_m, ctx.active_index, ctx.index, int(self.max_count),
                              float(self.radius_m), ctx.spec.period_m)
        write_density(near, self.per_area, obs, col)

    @property
    def per_area(self) -> float:
        """1 / (π ρ²), the density of one pedestrian in the disc (1/m²)."""
        return 1.0 / (math.pi * self.radius_m ** 2)


@nb.njit(cache=True)
def write_density(near, per_area, obs, col):
    """(1 + the real slots of ``near`` (m, k), rows into the active pedestrians, −1: none) × ``per_area`` into
    column ``col``."""
    for a in range(near.shape[0]):
        n = 1
        for slot in range(near.shape[1]):
            n += near[a, slot] >= 0
        obs[a, col] = n * per_area
