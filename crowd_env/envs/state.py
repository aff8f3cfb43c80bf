"""The global state of the crowd environment for centralised critics (PettingZoo's ``state()``).

A fixed-size ``float32`` vector of ``11 N + 1 + 2 E`` entries for a scenario of N pedestrians and E
exits, whatever happens during the episode (:data:`STATE_FIELDS`, :func:`state_layout`):

=====================  ======  ===========================================================================
block                  size    meaning (units)
=====================  ======  ===========================================================================
``pedestrians``        11 N    per pedestrian i = 0 … N−1 (all of them, controlled or background), 11
                               entries: ``present`` (1 on the floor, 0 once it has left), ``controlled``
                               (1 for an agent), position (x, y) in m, velocity (u_x, u_y) in m/s,
                               heading (cos θ, sin θ), e_d (unit vector; Eq. 13), travel time T in s;
                               every entry but ``controlled`` is 0 once the pedestrian has left
``episode_fraction``   1       environment steps taken / ``max_steps``
``exits``              2 E     the centre of each exit polygon (x, y) in m
=====================  ======  ===========================================================================

Frames, as the observations (the environment's ``observation_frame``): ``"world"`` gives positions
and vectors in the scenario's own axes; ``"egocentric"`` in the *scenario frame*, which a rotation or a
shift of the scenario carries along, so the state does not depend on either: origin at the centroid of
the walkable area, x axis from there towards the centre of the first exit (world x when they coincide).
"""
from __future__ import annotations

import numpy as np
import shapely
from gymnasium import spaces

from .observations import check_frame, to_body_frame

__all__ = ["PEDESTRIAN_STATE_FIELDS", "STATE_FIELDS", "GlobalStateBuilder", "state_layout", "state_size",
           "scenario_frame"]

PEDESTRIAN_STATE_FIELDS = ("present", "controlled", "x", "y", "u_x", "u_y", "cos_heading", "sin_heading",
                           "e_d_x", "e_d_y", "travel_time")
STATE_FIELDS = ("pedestrians", "episode_fraction", "exits")
_F = len(PEDESTRIAN_STATE_FIELDS)


def state_layout(n_pedestrians: int, n_exits: int) -> dict:
    """Block name -> ``slice`` into the state vector (``pedestrians`` reshapes to (N, 11))."""
    n, e = int(n_pedestrians), int(n_exits)
    return {"pedestrians": slice(0, _F * n), "episode_fraction": slice(_F * n, _F * n + 1),
            "exits": slice(_F * n + 1, _F * n + 1 + 2 * e)}


def state_size(n_pedestrians: int, n_exits: int) -> int:
    """Length of the state vector: 11 N + 1 + 2 E."""
    return _F * int(n_pedestrians) + 1 + 2 * int(n_exits)


def scenario_frame(geometry) -> tuple:
    """``(origin (2,), cos φ, sin φ)`` of the scenario frame: origin at the walkable area's centroid, x axis
    at angle φ towards the first exit's centre (φ = 0 when the two coincide, or without exits: a periodic
    corridor's frame is its own axes centred on it)."""
    origin = np.array(geometry.walkable_area.centroid.coords[0], dtype=np.float64)
    if not geometry.exits:
        return origin, 1.0, 0.0
    d = np.array(geometry.exits[0].centroid.coords[0], dtype=np.float64) - origin
    norm = float(np.hypot(d[0], d[1]))
    if norm < 1e-9:
        return origin, 1.0, 0.0
    return origin, d[0] / norm, d[1] / norm


class GlobalStateBuilder:
    """Builds the state vector of a :class:`~crowd_env.core.state.CrowdState` (see the module docstring).

    ``navigation``: the scenario's field (``sample(points)`` or ``sample(points, index)`` when
    ``per_pedestrian``); ``controlled_mask`` (N,) bool; ``velocity_bound_m_s`` and
    ``travel_time_bound_s`` set the declared bounds only.
    """

    def __init__(self, navigation, geometry, controlled_mask, *, frame: str, velocity_bound_m_s: float,
                 travel_time_bound_s: float):
        self.frame = check_frame(frame)
        self.navigation = navigation
        self.controlled = np.asarray(controlled_mask, dtype=bool).copy()
        n = self.controlled.shape[0]
        exits = np.array([e.centroid.coords[0] for e in geometry.exits], dtype=np.float64).reshape(-1, 2)
        if self.frame == "world":
            self.origin, self.cos, self.sin = np.zeros(2), 1.0, 0.0
        else:
            self.origin, self.cos, self.sin = scenario_frame(geometry)
        self.layout = state_layout(n, exits.shape[0])
        self.size = state_size(n, exits.shape[0])
        self._exits = self._to_frame(exits).astype(np.float32).ravel()
        # Bounds: every position lies in the navigable area, within ρ of the frame's origin.
        hull = np.asarray(shapely.convex_hull(geometry.navigable_area).exterior.coords)
        rho = float(np.max(np.hypot(*(hull - self.origin).T))) + 1.0
        v, t = float(velocity_bound_m_s), float(travel_time_bound_s)
        low_ped = np.array([0, 0, -rho, -rho, -v, -v, -1, -1, -1, -1, 0], np.float32)
        high_ped = np.array([1, 1, rho, rho, v, v, 1, 1, 1, 1, t], np.float32)
        low = np.concatenate([np.tile(low_ped, n), [0.0], np.full(self._exits.size, -rho)]).astype(np.float32)
        high = np.concatenate([np.tile(high_ped, n), [1.0], np.full(self._exits.size, rho)]).astype(np.float32)
        self.space = spaces.Box(low, high, dtype=np.float32)

    def _to_frame(self, points: np.ndarray) -> np.ndarray:
        if self.frame == "world":
            return points
        c, s = np.full(points.shape[0], self.cos), np.full(points.shape[0], self.sin)
        return to_body_frame(points - self.origin, c, s)

    def _rotate(self, vectors: np.ndarray) -> np.ndarray:
        if self.frame == "world":
            return vectors
        c, s = np.full(vectors.shape[0], self.cos), np.full(vectors.shape[0], self.sin)
        return to_body_frame(vectors, c, s)

    def build(self, state, episode_fraction: float) -> np.ndarray:
        """The state vector (float32) of ``state`` at ``episode_fraction`` of the episode."""
        n = self.controlled.shape[0]
        ped = np.zeros((n, _F))
        ped[:, 1] = self.controlled
        idx = state.active.nonzero()[0]
        if idx.size:
            pos = state.position_m[idx]
            if getattr(self.navigation, "per_pedestrian", False):
                e_d, travel = self.navigation.sample(pos, idx)
            else:
                e_d, travel = self.navigation.sample(pos)
            theta = state.heading_rad[idx]
            ped[idx, 0] = 1.0
            ped[idx, 2:4] = self._to_frame(pos)
            ped[idx, 4:6] = self._rotate(state.velocity_m_s[idx])
            # the heading as a unit vector in the frame: angle θ − φ
            ped[idx, 6:8] = self._rotate(np.stack((np.cos(theta), np.sin(theta)), axis=1))
            ped[idx, 8:10] = self._rotate(e_d)
            ped[idx, 10] = travel
        out = np.empty(self.size, np.float32)
        out[self.layout["pedestrians"]] = ped.ravel()
        out[self.layout["episode_fraction"]] = episode_fraction
        out[self.layout["exits"]] = self._exits
        return out
