"""Speed along the way: how fast pedestrians move at each stretch of a passage (where a crowd gathers speed).

:func:`speed_profile` averages, in bins of position along a direction d, the velocity of every row of long-format
trajectories (:class:`~crowd_env.analysis.trajectories.Trajectories`, recorded or simulated): a pedestrian seen at
frame f and at every frame from f − s to f + s has at f the centred velocity (p(f + s) − p(f − s)) × frame rate /
(2 s) (s = ``frame_step``; PedPy's notebooks use s = 5 at 16 frames/s), counted at its position at f, projected on
d. Rows without all 2 s frames around them have none. Either the velocity's component along d or its magnitude, the
speed, is averaged; only rows whose time lies in ``window_s`` and whose position lies in or on ``area`` count.
:func:`~crowd_env.analysis.corridor_runs.approach_profile` measures the queue before an exit with it.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
import shapely

from crowd_env.errors import AnalysisError

from .density import as_polygon

__all__ = ["SpeedProfile", "centred_velocities_m_s", "speed_profile"]


class SpeedProfile(NamedTuple):
    """``speed_m_s`` (B,): the mean in each bin between ``edges_m`` (B + 1,), NaN where no row fell; ``rows`` (B,): how
    many rows each mean holds."""

    edges_m: np.ndarray
    speed_m_s: np.ndarray
    rows: np.ndarray


def centred_velocities_m_s(trajectories, *, frame_step: int) -> np.ndarray:
    """(N, 2) the centred velocity of every row of ``trajectories`` (module docstring; rows in its order, sorted by
    walker, then frame), NaN where the walker is not seen at every frame from f − s to f + s (s = ``frame_step``,
    an integer >= 1)."""
    if isinstance(frame_step, bool) or not isinstance(frame_step, (int, np.integer)) or frame_step < 1:
        raise AnalysisError(f"frame_step must be an integer >= 1, got {frame_step!r}")
    traj, s = trajectories, int(frame_step)
    velocity = np.full((len(traj), 2), np.nan)
    k = np.arange(s, len(traj) - s)  # 2 s rows apart and 2 s frames apart: the same walker at every frame between
    k = k[(traj.id[k + s] == traj.id[k - s]) & (traj.frame[k + s] - traj.frame[k - s] == 2 * s)]
    scale = traj.frame_rate_per_s / (2 * s)
    velocity[k, 0] = (traj.x_m[k + s] - traj.x_m[k - s]) * scale
    velocity[k, 1] = (traj.y_m[k + s] - traj.y_m[k - s]) * scale
    return velocity


def speed_profile(trajectories, *, direction, edges_m, frame_step: int = 1, window_s: tuple | None = None,
                  area=None, magnitude: bool = False) -> SpeedProfile:
    """The mean velocity along ``direction`` (a vector, normalised here), or with ``magnitude`` the mean speed, in
    bins ``edges_m`` (increasing, m) of the position along it (module docstring), over the rows of ``trajectories``
    whose time lies in ``window_s`` = (start, end) s, both included (None: all), and whose position lies in or on
    ``area`` (a polygon, vertices or a box (x_min, y_min, x_max, y_max); None: anywhere); ``frame_step`` s ≥ 1.
    :class:`AnalysisError` naming a bad argument."""
    d = np.asarray(direction, dtype=np.float64)
    norm = float(np.hypot(*d)) if d.shape == (2,) and np.all(np.isfinite(d)) else 0.0
    if norm <= 0.0:
        raise AnalysisError(f"direction must be a finite non-zero vector (dx, dy), got {direction!r}")
    d = d / norm
    edges = np.asarray(edges_m, dtype=np.float64)
    if edges.ndim != 1 or edges.size < 2 or not np.all(np.isfinite(edges)) or np.any(np.diff(edges) <= 0.0):
        raise AnalysisError(f"edges_m must be at least two finite, increasing positions (m), got {edges_m!r}")
    if window_s is not None:
        start, end = (float(v) for v in window_s)
        if not (np.isfinite(start) and np.isfinite(end) and start <= end):
            raise AnalysisError(f"window_s must be a time span (start, end) with start <= end, got {window_s!r}")
    traj = trajectories
    velocity = centred_velocities_m_s(traj, frame_step=frame_step)
    k = np.flatnonzero(np.isfinite(velocity[:, 0]))
    value = np.hypot(velocity[k, 0], velocity[k, 1]) if magnitude else velocity[k] @ d
    x, y = traj.x_m[k], traj.y_m[k]
    keep = np.ones(k.shape, bool)
    if window_s is not None:
        t = traj.time_s[k]
        keep &= (t >= start) & (t <= end)
    if area is not None:
        keep &= shapely.intersects_xy(as_polygon(area), x, y)
    bins = np.digitize(x[keep] * d[0] + y[keep] * d[1], edges) - 1
    inside = (bins >= 0) & (bins < edges.size - 1)
    rows = np.bincount(bins[inside], minlength=edges.size - 1)
    total = np.bincount(bins[inside], weights=value[keep][inside], minlength=edges.size - 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        speed = np.where(rows > 0, total / rows, np.nan)
    return SpeedProfile(edges, speed, rows)
