"""Measurements of a periodic corridor (:mod:`crowd_env.scenarios.periodic_corridor`): one point of the
fundamental diagram, and trajectories unwrapped across the seam.

In a corridor periodic along x with period L and width W, N pedestrians stay inside for good, so the global
density ρ = N / (L W) is fixed and exact. The speed is measured along each pedestrian's own walking direction
d_i = ±1 (east/west): from the recorded velocities when given (the mean of d_i u_x,i over the frames of the
window and the pedestrians), else from the positions, v = mean_i d_i (x_i(t1) − x_i(t0)) / (t1 − t0) with x
unwrapped (the time mean of the same quantity, exact over the window). The specific flow is J_s = ρ v.

Recorded positions are wrapped into [0, L). :func:`unwrap_x` and :func:`unwrap_trajectories` add k L at each
seam crossing (every frame-to-frame move is taken to its nearest image, so frames must be less than L/2 of
walking apart), so that PedPy's speeds by differences and the export see continuous trajectories.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from crowd_env.errors import AnalysisError

from ..core.checks import check_number
from ..core.periodic import minimum_image_dx
from .trajectories import Trajectories

__all__ = ["PeriodicCorridorPoint", "unwrap_x", "unwrap_trajectories", "periodic_corridor_point", "trajectory_frames",
           "headway_fit", "MIN_FIT_SPEED_M_S"]

MIN_FIT_SPEED_M_S = 0.05  # the single-file experiment's fit takes the samples above this speed (shared data README)


@dataclass(frozen=True)
class PeriodicCorridorPoint:
    """One point of the fundamental diagram of a periodic corridor (units in the names). ``speed_m_s``: mean
    speed along the walking direction; ``speed_by_direction_m_s``: the same for those walking ``"east"`` and
    ``"west"`` (nan for a direction nobody walks); ``window_s``: the (t0, t1) measured over."""

    density_per_m2: float
    speed_m_s: float
    specific_flow_per_m_s: float
    n_pedestrians: int
    window_s: tuple
    speed_by_direction_m_s: dict


def _period(period_m) -> float:
    return check_number("period_m", period_m, error=AnalysisError, positive=True)


def unwrap_x(x_m, period_m: float) -> np.ndarray:
    """(F, ...) x positions of consecutive frames, recorded wrapped into [0, L), made continuous: each
    frame-to-frame move taken to its nearest image and accumulated from the first frame."""
    x = np.asarray(x_m, dtype=np.float64)
    if x.ndim < 1:
        raise AnalysisError(f"x_m must have a frame axis first, got shape {x.shape}")
    period = _period(period_m)
    if x.shape[0] < 2:
        return x.copy()
    moves = minimum_image_dx(np.ascontiguousarray(np.diff(x, axis=0)), period)
    return np.concatenate([x[:1], x[:1] + np.cumsum(moves, axis=0)])


def unwrap_trajectories(trajectories: Trajectories, period_m: float) -> Trajectories:
    """``trajectories`` with each pedestrian's x unwrapped over its frames (:func:`unwrap_x`; rows sorted by
    id, then frame, as :class:`Trajectories` keeps them): for PedPy and speeds by differences."""
    period = _period(period_m)
    x, ids = trajectories.x_m, trajectories.id
    first = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])  # each pedestrian's first row
    moves = np.zeros(x.shape[0])
    if x.shape[0] > 1:
        moves[1:] = minimum_image_dx(np.ascontiguousarray(np.diff(x)), period)
    moves[first] = 0.0
    travelled = np.cumsum(moves)
    owner = np.repeat(first, np.diff(np.r_[first, x.shape[0]]))
    unwrapped = x[owner] + (travelled - travelled[owner])
    return Trajectories(trajectories.frame, ids, unwrapped, trajectories.y_m, trajectories.heading_rad,
                        trajectories.frame_rate_per_s)


def trajectory_frames(trajectories: Trajectories) -> tuple:
    """``(time_s (F,), position_m (F, N, 2), ids (N,))`` of trajectories in which every pedestrian appears in
    every frame (a periodic corridor's: nobody leaves); raises :class:`AnalysisError` otherwise."""
    frames = np.unique(trajectories.frame)
    ids = np.unique(trajectories.id)
    if len(trajectories) != frames.size * ids.size:
        raise AnalysisError(f"trajectories must hold every one of the {ids.size} pedestrians in each of the "
                            f"{frames.size} frames, got {len(trajectories)} rows")
    position = np.stack([trajectories.x_m, trajectories.y_m], axis=1).reshape(ids.size, frames.size, 2)
    return frames / trajectories.frame_rate_per_s, np.ascontiguousarray(position.transpose(1, 0, 2)), ids


def periodic_corridor_point(time_s, position_m, *, period_m: float, width_m: float, direction_x,
                            window_s=None, velocity_m_s=None) -> PeriodicCorridorPoint:
    """ρ, v and J_s (module docstring) of a periodic corridor run recorded at ``time_s`` (F,): ``position_m``
    (F, N, 2) wrapped into [0, L), ``direction_x`` (N,) +1 east / −1 west (``Scenario.metadata['direction_x']``
    of the periodic corridor), ``window_s`` (t0, t1) the steady state to average over (default: the whole
    record), ``velocity_m_s`` (F, N, 2) optional (else the speed comes from the unwrapped positions)."""
    period = _period(period_m)
    width = check_number("width_m", width_m, error=AnalysisError, positive=True)
    t = np.asarray(time_s, dtype=np.float64).reshape(-1)
    pos = np.asarray(position_m, dtype=np.float64)
    if pos.ndim != 3 or pos.shape[2] != 2 or pos.shape[0] != t.shape[0]:
        raise AnalysisError(f"position_m must have shape ({t.shape[0]}, N, 2) (one row per frame of time_s), "
                            f"got {pos.shape}")
    n = pos.shape[1]
    sign = np.asarray(direction_x, dtype=np.float64).reshape(-1)
    if sign.shape != (n,) or not np.all(np.abs(sign) == 1.0):
        raise AnalysisError(f"direction_x must hold +1 or -1 for each of the {n} pedestrians, got shape {sign.shape}")
    t0, t1 = (t[0], t[-1]) if window_s is None else (float(v) for v in window_s)
    inside = (t >= t0 - 1e-9) & (t <= t1 + 1e-9)
    if np.count_nonzero(inside) < 2 or not t1 > t0:
        raise AnalysisError(f"window_s {window_s!r} must hold at least two frames of time_s "
                            f"[{t[0]:.4g}, {t[-1]:.4g}] s and end after it starts")
    if velocity_m_s is None:
        x = unwrap_x(pos[:, :, 0], period)[inside]
        each = sign * (x[-1] - x[0]) / (t[inside][-1] - t[inside][0])
    else:
        vel = np.asarray(velocity_m_s, dtype=np.float64)
        if vel.shape != pos.shape:
            raise AnalysisError(f"velocity_m_s must have the shape of position_m {pos.shape}, got {vel.shape}")
        each = (sign * vel[inside, :, 0]).mean(axis=0)
    density = n / (period * width)
    speed = float(each.mean()) if n else float("nan")
    by_direction = {name: float(each[sign == s].mean()) if np.any(sign == s) else float("nan")
                    for name, s in (("east", 1.0), ("west", -1.0))}
    return PeriodicCorridorPoint(density_per_m2=density, speed_m_s=speed, specific_flow_per_m_s=density * speed,
                                 n_pedestrians=n, window_s=(float(t[inside][0]), float(t[inside][-1])),
                                 speed_by_direction_m_s=by_direction)


def headway_fit(headway_m, speed_m_s, min_speed_m_s: float = MIN_FIT_SPEED_M_S) -> tuple:
    """Least-squares line d = a + b v through the samples with v > ``min_speed_m_s``: ``(a m, b s, samples)``
    (nan, nan, k when fewer than 2 samples or no spread in v). The single file's headway relation, fitted as the
    experiment's own (:data:`crowd_env.analysis.fd_reference.SINGLE_FILE_HEADWAY_FIT`)."""
    d = np.asarray(headway_m, dtype=np.float64).ravel()
    v = np.asarray(speed_m_s, dtype=np.float64).ravel()
    keep = np.isfinite(d) & np.isfinite(v) & (v > min_speed_m_s)
    if keep.sum() < 2 or np.ptp(v[keep]) == 0.0:
        return float("nan"), float("nan"), int(keep.sum())
    b, a = np.polyfit(v[keep], d[keep], 1)
    return float(a), float(b), int(keep.sum())
