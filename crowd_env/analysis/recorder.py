"""Trajectory recording into preallocated chunks (one row per pedestrian and frame)."""
from __future__ import annotations

from crowd_env.errors import RecorderError

import numpy as np


class TrajectoryRecorder:
    """Stores time, ids, positions (N, 2), headings and active mask of every recorded step.

    Rows go into float/int chunks of ``chunk_rows`` rows each (no per-pedestrian Python work);
    ``only_active=True`` stores only active pedestrians. :meth:`to_arrays` returns long-format
    ``frame, id, x, y, heading`` (plus ``active``, ``time``) arrays; :attr:`frame_time_s` the time per frame.
    """

    def __init__(self, chunk_rows: int = 1 << 16, only_active: bool = False):
        if chunk_rows < 1:
            raise RecorderError(f"chunk_rows must be >= 1, got {chunk_rows}")
        self.chunk_rows = int(chunk_rows)
        self.only_active = bool(only_active)
        self._float: list[np.ndarray] = []  # (rows, 3): x, y, heading
        self._int: list[np.ndarray] = []  # (rows, 3): frame, id, active
        self._fill = 0  # rows used in the last chunk
        self._times: list[float] = []

    def _new_chunk(self, rows: int) -> None:
        size = max(self.chunk_rows, rows)
        self._float.append(np.empty((size, 3)))
        self._int.append(np.empty((size, 3), dtype=np.int64))
        self._fill = 0

    def record(self, time_s: float, position_m, heading_rad=None, active=None, ids=None) -> None:
        """Append one frame. ``heading_rad`` defaults to NaN, ``active`` to all, ``ids`` to 0..N-1."""
        pos = np.asarray(position_m, dtype=np.float64)
        if pos.ndim != 2 or pos.shape[1] != 2:
            raise RecorderError(f"position_m must have shape (N, 2), got {pos.shape}")
        n = pos.shape[0]
        head = np.full(n, np.nan) if heading_rad is None else np.asarray(heading_rad, dtype=np.float64)
        act = np.ones(n, dtype=bool) if active is None else np.asarray(active, dtype=bool)
        pid = np.arange(n, dtype=np.int64) if ids is None else np.asarray(ids, dtype=np.int64)
        for name, arr in (("heading_rad", head), ("active", act), ("ids", pid)):
            if arr.shape != (n,):
                raise RecorderError(f"{name} must have shape ({n},), got {arr.shape}")
        if self.only_active:
            pos, head, pid, act = pos[act], head[act], pid[act], act[act]
        rows = pos.shape[0]
        frame = len(self._times)
        self._times.append(float(time_s))
        if rows == 0:
            return
        if not self._float or self._fill + rows > self._float[-1].shape[0]:
            if self._float:  # trim the finished chunk
                self._float[-1] = self._float[-1][: self._fill]
                self._int[-1] = self._int[-1][: self._fill]
            self._new_chunk(rows)
        f = self._float[-1][self._fill: self._fill + rows]
        i = self._int[-1][self._fill: self._fill + rows]
        f[:, :2] = pos
        f[:, 2] = head
        i[:, 0] = frame
        i[:, 1] = pid
        i[:, 2] = act
        self._fill += rows

    @property
    def n_frames(self) -> int:
        return len(self._times)

    @property
    def frame_time_s(self) -> np.ndarray:
        """Time (s) of each frame, indexed by frame number."""
        return np.asarray(self._times, dtype=np.float64)

    def _stack(self):
        if not self._float:
            return np.empty((0, 3)), np.empty((0, 3), dtype=np.int64)
        fl = self._float[:-1] + [self._float[-1][: self._fill]]
        it = self._int[:-1] + [self._int[-1][: self._fill]]
        return np.concatenate(fl), np.concatenate(it)

    def to_arrays(self, active_only: bool = True) -> dict:
        """Long-format arrays ``frame, id, x, y, heading, active, time`` (one row per pedestrian-frame)."""
        fl, it = self._stack()
        keep = it[:, 2].astype(bool) if active_only else np.ones(it.shape[0], dtype=bool)
        frame = it[keep, 0]
        return {
            "frame": frame,
            "id": it[keep, 1],
            "x": fl[keep, 0],
            "y": fl[keep, 1],
            "heading": fl[keep, 2],
            "active": it[keep, 2].astype(bool),
            "time": self.frame_time_s[frame],
        }


class ResampledRecorder(TrajectoryRecorder):
    """A :class:`TrajectoryRecorder` whose frames fall at t = k / ``frame_rate_per_s`` (k = 0, 1, ...) whatever
    the times it is given: called at every step of h (e.g. 16 frames/s from h = 0.01 s, 6.25 steps a frame),
    it interpolates positions and headings linearly between the two calls that bracket each frame time. A
    pedestrian is in a frame when it is active at both calls (one that leaves within the interval is not); the
    calls must give the same ids in the same order."""

    def __init__(self, frame_rate_per_s: float, chunk_rows: int = 1 << 16, only_active: bool = False):
        super().__init__(chunk_rows, only_active)
        if not (isinstance(frame_rate_per_s, (int, float, np.integer, np.floating)) and np.isfinite(frame_rate_per_s)
                and frame_rate_per_s > 0):
            raise RecorderError(f"frame_rate_per_s must be a positive finite number, got {frame_rate_per_s!r}")
        self.frame_rate_per_s = float(frame_rate_per_s)
        self._last = None  # (time, positions, headings, active, ids) of the previous call

    def record(self, time_s: float, position_m, heading_rad=None, active=None, ids=None) -> None:
        """Take the state at ``time_s`` (non-decreasing) and append every frame whose time lies in (the previous
        call's time, ``time_s``] (the first call: a frame when ``time_s`` is a frame time)."""
        pos = np.array(position_m, dtype=np.float64)
        n = pos.shape[0] if pos.ndim == 2 else -1
        head = np.full(n, np.nan) if heading_rad is None else np.array(heading_rad, dtype=np.float64)
        act = np.ones(n, dtype=bool) if active is None else np.array(active, dtype=bool)
        pid = np.arange(n, dtype=np.int64) if ids is None else np.array(ids, dtype=np.int64)
        t = float(time_s)
        fps = self.frame_rate_per_s
        if self._last is None:
            k = round(t * fps)
            if abs(k / fps - t) <= 1e-9 * max(1.0, abs(t)):
                super().record(k / fps, pos, head, act, pid)
            self._last = (t, pos, head, act, pid)
            return
        t0, p0, h0, a0, i0 = self._last
        if t < t0 or pos.shape != p0.shape or not np.array_equal(pid, i0):
            raise RecorderError(f"ResampledRecorder needs non-decreasing times and the same ids at every call "
                                f"(got t = {t:g} s after {t0:g} s, {pos.shape} after {p0.shape})")
        k = int(np.floor(t0 * fps + 1e-9)) + 1
        while k / fps <= t + 1e-9 * max(1.0, abs(t)):
            w = (k / fps - t0) / (t - t0) if t > t0 else 1.0
            turn = np.angle(np.exp(1j * (head - h0)))  # the shorter way round
            super().record(k / fps, p0 + w * (pos - p0), h0 + w * turn, a0 & act, pid)
            k += 1
        self._last = (t, pos, head, act, pid)
