"""Periodic boundary along x (the periodic corridor): the minimum-image convention.

A simulation with ``period_m`` L > 0 identifies x and x + L: positions are kept in [0, L) and every
displacement between two bodies is taken to its nearest image, dx − L·round(dx / L), so a contact, a
social force or a neighbour across the seam x = 0 ≡ L is the same as the one away from it. L = 0 means
no periodicity (the displacement is returned unchanged). Every kernel that measures a pedestrian-pedestrian
displacement goes through :func:`minimum_image_dx`.
"""
from __future__ import annotations

import numba as nb
import numpy as np

__all__ = ["minimum_image_dx", "wrap_x", "wrap_positions"]


@nb.njit(cache=True, inline="always")
def minimum_image_dx(dx, period_m):
    """The x displacement ``dx`` taken to its nearest periodic image (``period_m`` ≤ 0: unchanged)."""
    if period_m > 0.0:
        return dx - period_m * np.floor(dx / period_m + 0.5)
    return dx


@nb.njit(cache=True, inline="always")
def wrap_x(x, period_m):
    """``x`` brought into [0, ``period_m``) (``period_m`` ≤ 0: unchanged)."""
    if period_m > 0.0:
        x = x - period_m * np.floor(x / period_m)
        if x >= period_m:  # rounding of a tiny negative x
            x -= period_m
    return x


@nb.njit(cache=True)
def wrap_positions(position, period_m):
    """Bring the x column of ``position`` (N, 2) into [0, ``period_m``) in place (:func:`wrap_x`); returns it."""
    for i in range(position.shape[0]):
        position[i, 0] = wrap_x(position[i, 0], period_m)
    return position
