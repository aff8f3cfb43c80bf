"""``heading``: (cos θ, sin θ) of the own heading θ (2); left out in the egocentric frame, which it defines."""
from __future__ import annotations

from dataclasses import dataclass

import numba as nb

from .base import ObservationComponent, ObservationField

__all__ = ["Heading", "write_heading"]


@dataclass(frozen=True)
class Heading(ObservationComponent):
    """The own heading as a unit vector; bounds ±1."""

    name = "heading"
    fields = (ObservationField("heading", "2", "(cos θ, sin θ) of the own heading"),)
    egocentric_fields = ()

    def bounds(self, spec):
        return -1.0, 1.0

    def write(self, ctx, obs, col, size):
        write_heading(ctx.cos_heading, ctx.sin_heading, obs, col)


@nb.njit(cache=True)
def write_heading(cos_t, sin_t, obs, col):
    for a in range(cos_t.shape[0]):
        obs[a, col] = cos_t[a]
        obs[a, col + 1] = sin_t[a]
