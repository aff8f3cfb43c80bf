"""Passages through a measurement line, specific flow (Kabalan Eq. 22) and linear J(b) fits.

A :class:`MeasurementLine` is a segment with a positive crossing direction. :func:`line_crossings`
works step by step inside a simulation loop (interpolating the passage time linearly within the
step); :class:`PassageCounter` keeps each pedestrian's first passage; :func:`trajectory_crossings`
does the same on a recorded long-format trajectory.
"""
from __future__ import annotations

from crowd_env.errors import FlowError

from dataclasses import dataclass

import numba as nb
import numpy as np


@dataclass(frozen=True)
class MeasurementLine:
    """Segment ``start``-``end`` (m) counted in the positive ``direction``.

    ``direction`` defaults to the segment's clockwise normal: a line drawn from (0, -1) to (0, 1)
    counts passages towards +x. Any direction not parallel to the segment works; only its side matters.
    """

    start: tuple
    end: tuple
    direction: tuple | None = None

    def __post_init__(self) -> None:
        a = np.asarray(self.start, dtype=np.float64)
        b = np.asarray(self.end, dtype=np.float64)
        if a.shape != (2,) or b.shape != (2,) or not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
            raise FlowError(f"measurement line end points must be finite (x, y) pairs, got {self.start}, {self.end}")
        t = b - a
        length = float(np.hypot(*t))
        if length <= 1e-12:
            raise FlowError(f"measurement line has zero length: {self.start} -> {self.end}")
        normal = np.array([t[1], -t[0]]) / length
        if self.direction is not None:
            d = np.asarray(self.direction, dtype=np.float64)
            if d.shape != (2,) or not np.all(np.isfinite(d)):
                raise FlowError(f"direction must be a finite (x, y) vector, got {self.direction}")
            s = float(d @ normal)
            if abs(s) <= 1e-9 * max(float(np.hypot(*d)), 1e-300):
                raise FlowError(f"direction {self.direction} is parallel to the measurement line")
            normal = normal if s > 0 else -normal
        object.__setattr__(self, "_a", a)
        object.__setattr__(self, "_t", t)
        object.__setattr__(self, "_normal", normal)

    @property
    def normal(self) -> np.ndarray:
        """Unit normal pointing to the positive side."""
        return self._normal.copy()

    @property
    def start_m(self) -> np.ndarray:
        """The segment's start point (2,)."""
        return self._a.copy()

    @property
    def segment_m(self) -> np.ndarray:
        """The vector from start to end (2,)."""
        return self._t.copy()

    @property
    def length_m(self) -> float:
        return float(np.hypot(*self._t))

    def signed_distance_m(self, position) -> np.ndarray:
        """Signed distance (m) of points (K, 2) to the line's supporting line, positive on the positive side."""
        return (np.asarray(position, dtype=np.float64) - self._a) @ self._normal

    def crossing_fraction(self, prev_pos, new_pos) -> np.ndarray:
        """For straight moves prev -> new (K, 2): fraction α ∈ [0, 1) at which the segment is crossed
        in the positive direction, NaN where it is not (half-open: start strictly behind, end on or past)."""
        p0 = np.ascontiguousarray(prev_pos, dtype=np.float64)
        p1 = np.ascontiguousarray(new_pos, dtype=np.float64)
        return _crossing_fraction(p0, p1, self._a, self._t, self._normal)


@nb.njit(cache=True, inline="always")
def crossing_alpha(x0, y0, x1, y1, a, t, normal):
    """Fraction α ∈ [0, 1) of the straight move (x0, y0) → (x1, y1) at which it crosses the segment
    a → a + t in the positive direction ``normal``; nan where it does not (start strictly behind, end
    on or past, the crossing point on the segment). The one kernel of every passage count."""
    s0 = (x0 - a[0]) * normal[0] + (y0 - a[1]) * normal[1]
    s1 = (x1 - a[0]) * normal[0] + (y1 - a[1]) * normal[1]
    if s0 < 0.0 and s1 >= 0.0:
        alpha = s0 / (s0 - s1)
        px = x0 + alpha * (x1 - x0)
        py = y0 + alpha * (y1 - y0)
        u = ((px - a[0]) * t[0] + (py - a[1]) * t[1]) / (t[0] * t[0] + t[1] * t[1])
        if 0.0 <= u <= 1.0:
            return alpha
    return np.nan


@nb.njit(cache=True)
def _crossing_fraction(p0, p1, a, t, normal):
    """Kernel of :meth:`MeasurementLine.crossing_fraction` (segment a → a + t, positive side ``normal``)."""
    out = np.empty(p0.shape[0])
    for k in range(p0.shape[0]):
        out[k] = crossing_alpha(p0[k, 0], p0[k, 1], p1[k, 0], p1[k, 1], a, t, normal)
    return out


def line_crossings(prev_pos, new_pos, t_prev_s, t_new_s, line: MeasurementLine, ids=None):
    """Pedestrians that crossed ``line`` positively between two steps, with interpolated times.

    ``prev_pos``/``new_pos`` (N, 2) positions at ``t_prev_s``/``t_new_s`` (scalars or (N,) arrays).
    Returns ``(ids, time_s)`` of the crossers (``ids`` defaults to row indices). Positions are assumed
    to move on a straight line at constant speed within the step, so the time is exact for that motion.
    """
    p0 = np.asarray(prev_pos, dtype=np.float64)
    p1 = np.asarray(new_pos, dtype=np.float64)
    if p0.shape != p1.shape or p0.ndim != 2 or p0.shape[1] != 2:
        raise FlowError(f"prev_pos and new_pos must both have shape (N, 2), got {p0.shape} and {p1.shape}")
    alpha = line.crossing_fraction(p0, p1)
    rows = np.flatnonzero(~np.isnan(alpha))
    who = rows if ids is None else np.asarray(ids)[rows]
    if rows.size == 0:
        return who, np.zeros(0)
    t0 = np.broadcast_to(np.asarray(t_prev_s, dtype=np.float64), alpha.shape)[rows]
    t1 = np.broadcast_to(np.asarray(t_new_s, dtype=np.float64), alpha.shape)[rows]
    return who, t0 + alpha[rows] * (t1 - t0)


class PassageCounter:
    """Incremental first-passage times of a measurement line, for use inside a simulation loop."""

    def __init__(self, line: MeasurementLine):
        self.line = line
        self._ids: list = []
        self._times: list = []
        self._seen: set = set()

    def update(self, prev_pos, new_pos, t_prev_s, t_new_s, ids=None) -> int:
        """Record first passages during one step; returns how many new pedestrians passed."""
        who, times = line_crossings(prev_pos, new_pos, t_prev_s, t_new_s, self.line, ids)
        new = 0
        for k, t in zip(who.tolist(), times.tolist()):  # only the few crossers of this step
            if k not in self._seen:
                self._seen.add(k)
                self._ids.append(k)
                self._times.append(t)
                new += 1
        return new

    @property
    def ids(self) -> np.ndarray:
        return np.asarray(self._ids)

    @property
    def times_s(self) -> np.ndarray:
        return np.asarray(self._times, dtype=np.float64)

    def __len__(self) -> int:
        return len(self._times)


def trajectory_crossings(frame, ids, x, y, frame_time_s, line: MeasurementLine, first_only: bool = True):
    """Positive passages in a long-format trajectory (rows: frame, id, x, y, e.g. from the recorder).

    Consecutive frames of the same id form a straight step; ``frame_time_s[f]`` is the time of frame
    f. Returns ``(ids, time_s)`` sorted by time; with ``first_only`` each id's first passage only.
    """
    frame = np.asarray(frame, dtype=np.int64)
    ids = np.asarray(ids)
    pos = np.column_stack([np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)])
    ftime = np.asarray(frame_time_s, dtype=np.float64)
    if not (frame.shape[0] == ids.shape[0] == pos.shape[0]):
        raise FlowError("frame, ids, x and y must have equal lengths")
    order = np.lexsort((frame, ids))
    frame, ids, pos = frame[order], ids[order], pos[order]
    step = (ids[1:] == ids[:-1]) & (frame[1:] == frame[:-1] + 1)
    a = np.flatnonzero(step)
    alpha = line.crossing_fraction(pos[a], pos[a + 1])
    hit = ~np.isnan(alpha)
    a = a[hit]
    t0 = ftime[frame[a]]
    times = t0 + alpha[hit] * (ftime[frame[a + 1]] - t0)
    who = ids[a]
    by_time = np.argsort(times, kind="stable")
    who, times = who[by_time], times[by_time]
    if first_only and who.size:
        _, first = np.unique(who, return_index=True)
        first = np.sort(first)
        who, times = who[first], times[first]
    return who, times


@dataclass(frozen=True)
class FlowResult:
    """Eq. 22: N passages, Δt first to last passage, J = N / Δt (not (N-1)/Δt), J_s = J / b."""

    n: int
    dt_s: float
    flow_per_s: float
    specific_flow_per_m_s: float
    width_m: float


def specific_flow(crossing_times_s, width_m: float, n: int | None = None) -> FlowResult:
    """Specific flow J_s = N / (Δt b) (Kabalan Eq. 22; Seyfried 2009 convention J = N / Δt).

    ``n`` defaults to the number of passages (set it to the group size if some were not recorded).
    """
    t = np.asarray(crossing_times_s, dtype=np.float64).ravel()
    if not np.all(np.isfinite(t)):
        raise FlowError("crossing times contain non-finite values")
    if t.size < 2:
        raise FlowError(f"need at least two passages to define a flow, got {t.size}")
    if not (np.isfinite(width_m) and width_m > 0):
        raise FlowError(f"width_m must be > 0, got {width_m!r}")
    dt = float(t.max() - t.min())
    if dt <= 0:
        raise FlowError("all passages happen at the same instant: Δt = 0")
    n = int(t.size) if n is None else int(n)
    flow = n / dt
    return FlowResult(n=n, dt_s=dt, flow_per_s=flow, specific_flow_per_m_s=flow / width_m, width_m=float(width_m))


@dataclass(frozen=True)
class LinearFit:
    """Least-squares line J = slope · b + intercept and the 2-norm of its residuals (Kabalan Table 3)."""

    slope: float
    intercept: float
    residual_norm: float


def linear_fit(widths_m, flows_per_s) -> LinearFit:
    """Least-squares line through (b, J) points (Kabalan Section 4.1.3, Fig. 13)."""
    b = np.asarray(widths_m, dtype=np.float64).ravel()
    j = np.asarray(flows_per_s, dtype=np.float64).ravel()
    if b.shape != j.shape:
        raise FlowError(f"widths and flows must have equal lengths, got {b.size} and {j.size}")
    if np.unique(b).size < 2:
        raise FlowError("a line needs at least two distinct widths")
    design = np.column_stack([b, np.ones_like(b)])
    coef, *_ = np.linalg.lstsq(design, j, rcond=None)
    return LinearFit(float(coef[0]), float(coef[1]), float(np.linalg.norm(j - design @ coef)))


def linear_fit_residual_norm(widths_m, flows_per_s) -> float:
    """Norm of residuals of the least-squares line J = a b + c (Kabalan Table 3)."""
    return linear_fit(widths_m, flows_per_s).residual_norm
