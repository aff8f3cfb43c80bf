"""Route choice between exits: each pedestrian heads for the exit it expects to leave by soonest.

:class:`QuickestExitNavigation` is a per-pedestrian navigation (the interface of
:class:`~crowd_env.walking.navigation.DestinationNavigation`: pedestrian i follows the eikonal field of
its current exit, Eq. 11-13 with T = 0 on that exit only) whose choices change with the crowd. Every
``interval_s`` (on :meth:`update`, which the calibrated agent and the RL environment call once per
step) each pedestrian on the floor estimates, for every exit e,

    t_e = max(T_e(x) / v_d,  Q_e / (c w_e)),

the larger of its own walking time (T_e: the geodesic distance, v_d: its desired speed) and the time
the Q_e pedestrians bound for e and nearer to it (smaller T_e) need to pass a door of width w_e at the
specific flow c (``capacity_per_m_s``, default 1.3 /(m s), the SFPE handbook's maximum specific flow
through doors). It switches to the exit of least t_e when that saves more than ``switch_margin_s``
(hysteresis: no dithering between equal choices). At the start everybody heads for its nearest exit
(least T_e). This is the "quickest route" of evacuation models (e.g. RiMEA test 11: most choose the
near exit and queue there, a few take the farther one); pedestrians may leave through any exit.
"""
from __future__ import annotations

import numpy as np

from crowd_env.errors import GeometryError

from ..core.checks import check_number
from .navigation import DestinationNavigation

__all__ = ["QuickestExitNavigation", "DEFAULT_CAPACITY_PER_M_S"]

DEFAULT_CAPACITY_PER_M_S = 1.3  # SFPE Handbook: maximum specific flow through doors, persons/(m s)


class QuickestExitNavigation(DestinationNavigation):
    """Per-pedestrian navigation with quickest-exit route choice (module docstring).

    ``fields``: exit index -> its :class:`~crowd_env.walking.navigation.NavigationField` (T = 0 on that
    exit only), one per exit; ``door_widths_m``: (E,) the width of each exit's door; ``position_m``
    (N, 2): the start positions, from which the first choice (the nearest exit) is made.
    """

    def __init__(self, fields: dict, door_widths_m, position_m, *, capacity_per_m_s: float = DEFAULT_CAPACITY_PER_M_S,
                 interval_s: float = 1.0, switch_margin_s: float = 2.0):
        keys = sorted(fields)
        if keys != list(range(len(keys))) or len(keys) < 2:
            raise GeometryError(f"route choice needs one field per exit, keyed 0..E-1 with E >= 2, got keys {keys}")
        widths = np.asarray(door_widths_m, dtype=np.float64).reshape(-1)
        if widths.shape != (len(keys),) or not np.all(widths > 0):
            raise GeometryError(f"door_widths_m must be {len(keys)} positive widths, got {door_widths_m!r}")
        for name, value in (("capacity_per_m_s", capacity_per_m_s), ("interval_s", interval_s)):
            check_number(name, value, error=GeometryError, positive=True)
        check_number("switch_margin_s", switch_margin_s, error=GeometryError, minimum=0.0)
        self.door_widths_m = widths
        self.capacity_per_m_s = float(capacity_per_m_s)
        self.interval_s = float(interval_s)
        self.switch_margin_s = float(switch_margin_s)
        pos = np.asarray(position_m, dtype=np.float64).reshape(-1, 2)
        self.fields = dict(fields)
        super().__init__(fields, self._nearest(pos))
        self._run = None  # the simulator of the current run (a new one, or time running back, starts afresh)
        self._next_s = 0.0
        self._last_s = -np.inf
        self.n_switches = 0

    def _travel_times(self, pos) -> np.ndarray:
        return np.stack([self.fields[k].travel_time(pos) for k in range(len(self.fields))])  # (E, n)

    def _nearest(self, pos) -> np.ndarray:
        t = self._travel_times(pos)
        return np.argmin(np.where(np.isfinite(t), t, np.inf), axis=0).astype(np.int64)

    def _set(self, dest) -> None:
        dest = np.array(dest, dtype=np.int64)
        dest.setflags(write=False)
        self.destination = dest

    def expected_times_s(self, pos, desired_speed, choice) -> np.ndarray:
        """(E, n) the estimate t_e of each pedestrian at ``pos`` (module docstring) given the current
        ``choice`` of all of them."""
        t = self._travel_times(pos)
        walk = t / np.maximum(desired_speed, 1e-3)
        queue = np.zeros_like(t)
        for e in range(t.shape[0]):
            ahead = np.sort(t[e, choice == e])
            queue[e] = np.searchsorted(ahead, t[e], side="left")  # bound for e and strictly nearer to it
        wait = queue / (self.capacity_per_m_s * self.door_widths_m[:, None])
        return np.where(np.isfinite(t), np.maximum(walk, wait), np.inf)

    def update(self, sim) -> None:
        """Re-choose every ``interval_s`` of simulated time (idempotent within an interval)."""
        now = float(sim.time_s)
        if sim is not self._run or now < self._last_s:  # a new run: back to the nearest exits
            self._run = sim
            self._set(self._nearest(sim.state.position_m))
            self._next_s = now
            self.n_switches = 0
        self._last_s = now
        if now < self._next_s:
            return
        self._next_s = now + self.interval_s
        idx = sim.active_index
        if idx.size == 0:
            return
        st = sim.state
        choice = self.destination[idx]
        est = self.expected_times_s(st.position_m[idx], st.desired_speed_m_s[idx], choice)
        best = np.argmin(est, axis=0)
        current = est[choice, np.arange(idx.size)]
        switch = est[best, np.arange(idx.size)] < current - self.switch_margin_s
        if switch.any():
            dest = self.destination.copy()
            dest[idx[switch]] = best[switch]
            self.n_switches += int(switch.sum())
            self._set(dest)
