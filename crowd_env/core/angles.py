"""Angle helpers shared by the step's kernels, the environment and the walking model, compiled with numba.

The heading θ of a pedestrian (Kabalan 2016, Eq. 15) is kept in (−π, π]; headings computed outside the
kernels must round exactly as those computed inside them, so every module takes its angles from here.
"""
from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True)
def wrap_angle_scalar(angle):
    """Wrap an angle (rad) to (−π, π]."""
    return np.pi - np.mod(np.pi - angle, 2.0 * np.pi)


@nb.njit(cache=True)
def direction_angles_rad(vectors):
    """atan2(y, x) of each row of ``vectors`` ((n, 2)), in rad, by the same compiled atan2 as the kernels
    (numpy's vectorised ``np.arctan2`` can differ from it in the last bit, as numpy 2.4's does): headings
    computed here and inside a kernel (the baseline agent's θ_d, Eq. 15) agree bitwise, as
    ``test_equivalence_all_controlled_with_baseline_intents`` requires."""
    out = np.empty(vectors.shape[0])
    for i in range(vectors.shape[0]):
        out[i] = np.arctan2(vectors[i, 1], vectors[i, 0])
    return out
