"""Circulating navigation: walking round a closed loop that has no exit (a ring corridor).

The eikonal navigation (:mod:`crowd_env.walking.navigation`) sends everybody to an exit; on a ring such
as RiMEA test 16's single-file oval there is none, and a desired direction that circulates is not the
gradient of any travel time (its circulation round the loop is the loop's length, not 0). A
:class:`CirculationNavigation` is the loop's own navigation: a closed centreline, walked in the order
of its vertices, gives each point

- its arc length s ∈ [0, L) along the centreline (of the nearest centreline point, the projection);
- the desired direction e_d: with ``lookahead_m`` ℓ = 0 the centreline's unit tangent at the projection
  (interpolated between vertex tangents, so continuous), with ℓ > 0 the unit vector from the point to the
  centreline point ℓ further on (a walker heading for a waypoint ℓ ahead: it steers back to the
  centreline with gain 1/ℓ and, on a bend of radius R, turns into it by about ℓ/(2R), which offsets
  the outward lag τ v/R of the driving force's relaxation when ℓ ≈ 2 τ v);
- a travel time T = (L − s)/V (``speed_m_s`` V, 1 m/s by default as for the eikonal field, so T is the
  distance still to walk to the loop's start, in m): T decreases along the loop at rate 1/V, from L/V
  just after the start point (vertex 0) to 0 just before it, where it jumps back to L/V once per lap.

It has the navigation protocol of :class:`~crowd_env.walking.navigation.NavigationField` that the agent,
the RL observations and state use (``sample(points) -> (e_d, T)``, ``direction``, ``travel_time``,
``max_travel_time_s``, ``check_reachable``, ``per_pedestrian = False``), so a scenario built with it as
``navigation_field`` runs with :class:`~crowd_env.walking.agent.SocialForceAgent` and as an RL environment.
In an RL environment a progress reward ΔT (the default reward's ``progress_s``) sees the jump once per
lap: −L/V at the start point; a reward for circulation should use the arc length (:meth:`arc_length`)
unwrapped, or the speed along e_d. The compiled rollout does not know this navigation (it samples grids),
so runs with it step from Python.
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np
import shapely

from ..core.checks import check_number
from ..core.segments import GeometryError

__all__ = ["CirculationNavigation", "oval_centreline", "project_onto_loop"]


@nb.njit(cache=True)
def project_onto_loop(points, vertices, cumulative_m):
    """For each point the nearest point of the closed polyline ``vertices`` (K, 2) (segment k joins vertex
    k to vertex k + 1 mod K; ``cumulative_m`` (K + 1,) the arc length at each vertex, the last the loop's
    length L). Returns ``(s (n,) arc length in [0, L), segment (n,), u (n,) position on the segment in
    [0, 1], distance (n,))``; a non-finite point gets s = nan and distance = inf."""
    n = points.shape[0]
    k_count = vertices.shape[0]
    length = cumulative_m[k_count]
    s = np.empty(n)
    seg = np.zeros(n, np.int64)
    u_out = np.zeros(n)
    dist = np.empty(n)
    for a in range(n):
        px = points[a, 0]
        py = points[a, 1]
        if not (np.isfinite(px) and np.isfinite(py)):
            s[a] = np.nan
            dist[a] = np.inf
            continue
        best = np.inf
        best_k = 0
        best_u = 0.0
        for k in range(k_count):
            ax = vertices[k, 0]
            ay = vertices[k, 1]
            nk = k + 1 if k + 1 < k_count else 0
            dx = vertices[nk, 0] - ax
            dy = vertices[nk, 1] - ay
            ll = dx * dx + dy * dy
            u = ((px - ax) * dx + (py - ay) * dy) / ll if ll > 0.0 else 0.0
            u = min(max(u, 0.0), 1.0)
            qx = ax + u * dx - px
            qy = ay + u * dy - py
            d2 = qx * qx + qy * qy
            if d2 < best:
                best = d2
                best_k = k
                best_u = u
        seg[a] = best_k
        u_out[a] = best_u
        sa = cumulative_m[best_k] + best_u * (cumulative_m[best_k + 1] - cumulative_m[best_k])
        s[a] = sa - length if sa >= length else sa
        dist[a] = math.sqrt(best)
    return s, seg, u_out, dist


def oval_centreline(straight_m: float = 4.0, radius_m: float = 3.0, spacing_m: float = 0.05) -> np.ndarray:
    """Vertices (K, 2) of an oval (stadium) centreline walked anticlockwise: two straights of ``straight_m``
    (y = ∓``radius_m``, x from 0 to ``straight_m``) joined by half circles of ``radius_m`` centred at (0, 0)
    and (``straight_m``, 0), vertices about ``spacing_m`` apart; vertex 0 is (0, −``radius_m``), the start of
    the lower straight. Length 2 ``straight_m`` + 2π ``radius_m``."""
    for name, value in (("straight_m", straight_m), ("radius_m", radius_m), ("spacing_m", spacing_m)):
        check_number(name, value, error=GeometryError, positive=True)
    n_straight = max(1, int(math.ceil(straight_m / spacing_m)))
    n_arc = max(8, int(math.ceil(math.pi * radius_m / spacing_m)))
    xs = np.linspace(0.0, straight_m, n_straight, endpoint=False)
    lower = np.column_stack((xs, np.full(n_straight, -radius_m)))
    phi = np.linspace(-0.5 * math.pi, 0.5 * math.pi, n_arc, endpoint=False)
    right = np.column_stack((straight_m + radius_m * np.cos(phi), radius_m * np.sin(phi)))
    upper = np.column_stack((straight_m - xs, np.full(n_straight, radius_m)))
    left = np.column_stack((radius_m * np.cos(phi + math.pi), radius_m * np.sin(phi + math.pi)))
    return np.vstack((lower, right, upper, left))


class CirculationNavigation:
    """Navigation round a closed centreline (see the module docstring).

    ``centreline``: (K, 2) vertices of a closed simple polyline in walking order (K >= 3; the closing
    segment from the last vertex back to the first is implied; a repeated first vertex at the end is
    dropped). ``lookahead_m``: ℓ >= 0 (0: the tangent). ``speed_m_s``: V of T = (L − s)/V.
    ``half_width_m``: when given, the corridor's half width: :meth:`check_reachable` rejects points
    farther than it from the centreline (the walkable corridor), and it must be smaller than the
    smallest radius of curvature of the centreline for the projection to be unique; when None, any
    finite point is accepted.
    """

    per_pedestrian = False  # one navigation serves every pedestrian

    def __init__(self, centreline, *, lookahead_m: float = 0.0, speed_m_s: float = 1.0, half_width_m=None):
        v = np.array(centreline, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 2 or not np.all(np.isfinite(v)):
            raise GeometryError(f"centreline must be finite (K, 2) vertices, got shape {v.shape}")
        if v.shape[0] >= 2 and np.allclose(v[0], v[-1]):
            v = v[:-1]
        if v.shape[0] < 3:
            raise GeometryError(f"a closed centreline needs at least 3 distinct vertices, got {v.shape[0]}")
        seg = np.roll(v, -1, axis=0) - v
        seg_len = np.hypot(seg[:, 0], seg[:, 1])
        if np.any(seg_len <= 1e-12):
            k = int(np.flatnonzero(seg_len <= 1e-12)[0])
            raise GeometryError(f"centreline vertices {k} and {(k + 1) % v.shape[0]} coincide")
        if not shapely.LinearRing(v).is_simple:
            raise GeometryError("the centreline crosses itself: a loop to circulate on must be a simple closed curve")
        check_number("lookahead_m", lookahead_m, error=GeometryError, minimum=0.0)
        check_number("speed_m_s", speed_m_s, error=GeometryError, positive=True)
        self.vertices = v
        self.vertices.setflags(write=False)
        self.cumulative_m = np.concatenate(([0.0], np.cumsum(seg_len)))
        self.cumulative_m.setflags(write=False)
        self.length_m = float(self.cumulative_m[-1])
        self.segment_tangent = seg / seg_len[:, None]
        vt = self.segment_tangent + np.roll(self.segment_tangent, 1, axis=0)  # vertex k: segments k-1 and k
        norm = np.hypot(vt[:, 0], vt[:, 1])
        if np.any(norm <= 1e-9):
            raise GeometryError("the centreline turns back on itself at a vertex (a 180° reversal)")
        self.vertex_tangent = vt / norm[:, None]
        self.lookahead_m = float(lookahead_m)
        self.speed_m_s = float(speed_m_s)
        self.half_width_m = None if half_width_m is None else check_number("half_width_m", half_width_m,
                                                                           error=GeometryError, positive=True)
        if self.half_width_m is not None:
            r_min = self.min_radius_of_curvature_m()
            if self.half_width_m >= r_min:
                raise GeometryError(f"half_width_m {self.half_width_m:g} m is not below the centreline's smallest radius "
                                    f"of curvature {r_min:.4g} m: points of the corridor would have no unique "
                                    "nearest centreline point")

    # -- geometry of the loop -------------------------------------------------------------------------
    def min_radius_of_curvature_m(self) -> float:
        """The smallest radius of curvature of the centreline, from the turn at each vertex over the mean
        length of its two segments (inf for a polygon with straight stretches only is impossible: a
        closed loop turns by 2π)."""
        seg_len = np.diff(self.cumulative_m)
        t = self.segment_tangent
        prev = np.roll(t, 1, axis=0)
        turn = np.abs(np.arctan2(prev[:, 0] * t[:, 1] - prev[:, 1] * t[:, 0], (prev * t).sum(axis=1)))
        ds = 0.5 * (seg_len + np.roll(seg_len, 1))
        with np.errstate(divide="ignore"):
            r = np.where(turn > 1e-12, ds / turn, np.inf)
        return float(r.min())

    def point_at(self, s_m) -> np.ndarray:
        """Centreline points (n, 2) at arc lengths ``s_m`` (taken modulo L)."""
        s = np.mod(np.asarray(s_m, dtype=np.float64).reshape(-1), self.length_m)
        k = np.clip(np.searchsorted(self.cumulative_m, s, side="right") - 1, 0, self.vertices.shape[0] - 1)
        u = (s - self.cumulative_m[k]) / (self.cumulative_m[k + 1] - self.cumulative_m[k])
        nxt = (k + 1) % self.vertices.shape[0]
        return self.vertices[k] + u[:, None] * (self.vertices[nxt] - self.vertices[k])

    def _project(self, points):
        pts = np.ascontiguousarray(points, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 2:
            raise GeometryError(f"points must have shape (N, 2), got {pts.shape}")
        s, seg, u, dist = project_onto_loop(pts, self.vertices, self.cumulative_m)
        bad = np.flatnonzero(~np.isfinite(s))
        if bad.size:
            raise GeometryError(f"point {int(bad[0])} at {pts[bad[0]].tolist()} is not finite")
        return pts, s, seg, u, dist

    def arc_length(self, points) -> np.ndarray:
        """Arc length s (n,) in [0, L) of each point's projection onto the centreline."""
        return self._project(points)[1]

    def offset(self, points) -> np.ndarray:
        """Signed distance (n,) of each point from the centreline, positive to the left of the walking
        direction."""
        pts, s, seg, u, dist = self._project(points)
        foot = self.point_at(s)
        t = self.segment_tangent[seg]
        d = pts - foot
        return np.sign(t[:, 0] * d[:, 1] - t[:, 1] * d[:, 0]) * dist

    # -- the navigation protocol -----------------------------------------------------------------------
    @property
    def max_travel_time_s(self) -> float:
        """Largest travel time: one loop, L/V."""
        return self.length_m / self.speed_m_s

    def sample(self, points):
        """Desired directions e_d (N, 2) (unit vectors) and travel times T (N,) = (L − s)/V at ``points``.
        Raises :class:`~crowd_env.core.segments.GeometryError` for non-finite points."""
        pts, s, seg, u, _ = self._project(points)
        n = pts.shape[0]
        if self.lookahead_m > 0.0:
            d = self.point_at(s + self.lookahead_m) - pts
        else:
            nxt = (seg + 1) % self.vertices.shape[0]
            d = (1.0 - u)[:, None] * self.vertex_tangent[seg] + u[:, None] * self.vertex_tangent[nxt]
        norm = np.hypot(d[:, 0], d[:, 1])
        e = np.empty((n, 2))
        ok = norm > 1e-12
        e[ok] = d[ok] / norm[ok, None]
        e[~ok] = self.segment_tangent[seg[~ok]]  # a point exactly on its target: the tangent
        return e, (self.length_m - s) / self.speed_m_s

    def direction(self, points) -> np.ndarray:
        """Desired directions e_d (N, 2) only."""
        return self.sample(points)[0]

    def travel_time(self, points) -> np.ndarray:
        """Travel times T (N,) in s only."""
        return self.sample(points)[1]

    def check_reachable(self, points, what: str = "point") -> None:
        """Raise :class:`~crowd_env.core.segments.GeometryError` naming the first of ``points`` that is not
        finite or, with ``half_width_m``, lies farther than it from the centreline (outside the loop's
        corridor, where the circulation is not defined)."""
        pts = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 2)
        s, _, _, dist = project_onto_loop(pts, self.vertices, self.cumulative_m)
        bad = ~np.isfinite(s)
        if self.half_width_m is not None:
            bad |= dist > self.half_width_m + 1e-9
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise GeometryError(f"{what} {i} at {pts[i].tolist()} is not on the loop: it lies {dist[i]:.4g} m from "
                                f"the centreline (half width {self.half_width_m}) or is not finite")
