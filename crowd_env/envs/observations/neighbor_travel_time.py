"""``neighbor_travel_time`` (k), a plug-in component (named by its import path,
``"crowd_env.envs.observations.neighbor_travel_time:NeighborTravelTime"``, as any user component): for each of
the k nearest others of :mod:`~crowd_env.envs.observations.neighbors`, in the same slots, how much nearer the exit
it is, T_j − T_i (s at the navigation field's speed; negative: it is nearer; with destinations, each one's to its
own), 0 in an empty slot. Two walkers beside each other at an opening see mirror images in ``neighbors``; this
tells which of them is ahead on the way out (Eq. 13's field itself, not its direction only)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import ObservationComponent, ObservationField

__all__ = ["NeighborTravelTime", "PATH"]

PATH = "crowd_env.envs.observations.neighbor_travel_time:NeighborTravelTime"


@dataclass(frozen=True)
class NeighborTravelTime(ObservationComponent):
    """T_j − T_i of the k nearest neighbours (one sampling of the field at their positions per step); bounds
    ±``travel_time_bound_s``; the same in both frames (a difference of scalars)."""

    name = "neighbor_travel_time"
    uses_neighbors = True
    fields = (ObservationField("neighbor_travel_time", "k", "T_j − T_i of the k nearest others in the slots of "
                                                            "neighbors (s; negative: nearer the exit); 0 padded"),)

    def bounds(self, spec):
        return -spec.travel_time_bound_s, spec.travel_time_bound_s

    def compute(self, ctx, out):
        near = ctx.neighbor_rows
        have = near >= 0
        if not have.any():
            return
        rows = ctx.active_index[near[have]]
        points = ctx.state.position_m[rows]
        navigation = ctx.navigation
        if getattr(navigation, "per_pedestrian", False):
            _, travel = navigation.sample(points, rows)
        else:
            _, travel = navigation.sample(points)
        own = np.broadcast_to(ctx.travel_time_s[:, None], near.shape)[have]
        out[have] = (np.asarray(travel, dtype=np.float64) - own).astype(out.dtype)
