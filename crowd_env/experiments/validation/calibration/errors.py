"""Calibration errors of the specific flow (Kabalan Eq. 23-24), range checks for N = 20 / 40, and the
ε_T surface of Fig. 10 (grid axes, valley of minima, A(B) = a exp(c B) fit).

Only the N = 60 experimental values are known exactly, so by default ε_T averages over the runs that
match the shipped N = 60 rows; pass ``reference`` to use another table. A model run with no matching
experimental point is an error, never silently dropped.
"""
from __future__ import annotations

from crowd_env.errors import CalibrationError

from dataclasses import dataclass

import numpy as np

from ....core.checks import check_integer, check_number
from ....analysis.experiment import SPECIFIC_FLOW_RANGE_N20_N40_PER_M_S, ExperimentError, ExperimentTable, seyfried_2009


def _runs(width_m, n_pedestrians, specific_flow_per_m_s, allow_undefined: bool = False):
    """(b, N, J_s) as flat arrays of equal length; NaN flows are an error unless ``allow_undefined``."""
    b = np.atleast_1d(np.asarray(width_m, dtype=np.float64)).ravel()
    js = np.atleast_1d(np.asarray(specific_flow_per_m_s, dtype=np.float64)).ravel()
    n = np.broadcast_to(np.atleast_1d(np.asarray(n_pedestrians, dtype=np.int64)).ravel(), b.shape)
    if b.shape != js.shape:
        raise CalibrationError(f"width_m and specific_flow_per_m_s must have equal lengths, got {b.size}, {js.size}")
    if b.size == 0:
        raise CalibrationError("no model runs given")
    if not allow_undefined and not np.all(np.isfinite(js)):
        raise CalibrationError("model specific flows contain non-finite values")
    return b, n, js


def relative_squared_errors(width_m, n_pedestrians, specific_flow_per_m_s,
                            reference: ExperimentTable | None = None) -> np.ndarray:
    """(J_s,model / J_s,exp - 1)² per model run (the terms of Eq. 23-24)."""
    ref = seyfried_2009() if reference is None else reference
    b, n, js = _runs(width_m, n_pedestrians, specific_flow_per_m_s)
    try:
        rows = ref.lookup(b, n)
    except ExperimentError as err:
        raise CalibrationError(f"model run without experimental counterpart: {err}") from None
    return (js / ref.specific_flow_per_m_s[rows] - 1.0) ** 2


def epsilon_j(width_m, specific_flow_per_m_s, n_pedestrians: int, reference: ExperimentTable | None = None) -> float:
    """ε_j (Eq. 23): mean over the runs of group size N of (J_s,model / J_s,exp - 1)²."""
    return float(relative_squared_errors(width_m, int(n_pedestrians), specific_flow_per_m_s, reference).mean())


def epsilon_total(width_m, n_pedestrians, specific_flow_per_m_s, reference: ExperimentTable | None = None,
                  require_all_rows: bool = True) -> float:
    """ε_T (Eq. 24): mean over all model runs of (J_s,model / J_s,exp - 1)².

    Default reference: the shipped N = 60 rows. With one run per (b, N) this is Eq. 24 exactly; with
    replicates each run counts once. ``require_all_rows`` demands that every reference row has a run.
    """
    ref = seyfried_2009() if reference is None else reference
    err = relative_squared_errors(width_m, n_pedestrians, specific_flow_per_m_s, ref)
    if require_all_rows:
        b, n, _ = _runs(width_m, n_pedestrians, specific_flow_per_m_s)
        covered = np.zeros(len(ref), dtype=bool)
        covered[ref.lookup(b, n)] = True
        if not covered.all():
            missing = [(float(ref.width_m[k]), int(ref.n_pedestrians[k])) for k in np.flatnonzero(~covered)]
            raise CalibrationError(f"no model run for experimental point(s) (b, N) = {missing}; "
                                   f"pass require_all_rows=False to average over the runs given")
    return float(err.mean())


@dataclass(frozen=True)
class RangeCheck:
    """Which model values lie inside the known experimental range [low, high] (1/(m s))."""

    inside: np.ndarray
    all_inside: bool
    low: float
    high: float
    max_excess_per_m_s: float  # largest distance outside the range, 0 when all inside


def in_range_check(specific_flow_per_m_s, bounds=SPECIFIC_FLOW_RANGE_N20_N40_PER_M_S) -> RangeCheck:
    """Check N = 20 / 40 model specific flows against [1.77, 2.31] 1/(m s) (the only known facts)."""
    js = np.atleast_1d(np.asarray(specific_flow_per_m_s, dtype=np.float64)).ravel()
    if not np.all(np.isfinite(js)):
        raise CalibrationError("model specific flows contain non-finite values")
    low, high = float(bounds[0]), float(bounds[1])
    if not low <= high:
        raise CalibrationError(f"bounds must satisfy low <= high, got {bounds}")
    inside = (js >= low) & (js <= high)
    excess = np.maximum(low - js, js - high).clip(min=0.0)
    return RangeCheck(inside, bool(inside.all()), low, high, float(excess.max()) if js.size else 0.0)


# --- ε_T of one parameter point from its runs (Eq. 22-24 with replicates) ---------------------------

@dataclass(frozen=True)
class PointScore:
    """Calibration error of one parameter point, from all its (b, N, seed) runs.

    J_s is first averaged over seeds per (b, N) (the model's J_s(A, B, b, N) of Eq. 23); runs with fewer
    than two passages (J_s undefined) count as J_s = 0, i.e. a relative error of -1.
    ``epsilon_total``: Eq. 24 over the (b, N) that have an experimental value; ``epsilon_by_group``:
    Eq. 23 per such N; ``range_penalty``: for the (b, N) without one (N = 20, 40), the mean of
    (J_s / nearest bound - 1)² outside the known range (0 inside); ``objective`` =
    ``epsilon_total + range_weight * range_penalty``.
    """

    epsilon_total: float
    epsilon_by_group: dict
    range_penalty: float
    range_all_inside: bool
    objective: float
    width_m: np.ndarray  # (K,) distinct (b, N) of the runs
    n_pedestrians: np.ndarray  # (K,)
    mean_specific_flow_per_m_s: np.ndarray  # (K,) mean over seeds
    has_reference: np.ndarray  # (K,) bool
    n_runs: int
    n_undefined: int  # runs with J_s undefined (counted as 0)


def censored_specific_flow(specific_flow_per_m_s, n_pedestrians, n_passages, first_passage_s, time_limit_s,
                           width_m) -> np.ndarray:
    """J_s (Eq. 22) of runs in which not all N passed before the time limit T (a clog).

    The partial value (passages so far / their Δt) can look large; but Δt ≥ T − t_first, so the run's
    J_s = N / (Δt b) is at most N / ((T − t_first) b): that bound replaces it (t_first = 0 when nobody
    passed). Complete runs are returned unchanged. All arguments broadcast (vectorised).
    """
    js, n, k, t0, limit, b = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64) for x in (
        specific_flow_per_m_s, n_pedestrians, n_passages, first_passage_s, time_limit_s, width_m)))
    t0 = np.where(np.isfinite(t0) & (k > 0), t0, 0.0)
    with np.errstate(divide="ignore"):
        bound = n / (np.maximum(limit - t0, 1e-12) * b)
    return np.where(k < n, bound, js)


def reference_mask(ref: ExperimentTable, width_m, n_pedestrians, atol_m: float = 1e-6) -> np.ndarray:
    """True where (b, N) has an experimental counterpart in ``ref``."""
    b = np.atleast_1d(np.asarray(width_m, dtype=np.float64))
    n = np.atleast_1d(np.asarray(n_pedestrians, dtype=np.int64))
    return ((np.abs(b[:, None] - ref.width_m[None, :]) <= atol_m) & (n[:, None] == ref.n_pedestrians[None, :])).any(axis=1)


def point_error(width_m, n_pedestrians, specific_flow_per_m_s, reference: ExperimentTable | None = None,
                range_weight: float = 0.0, bounds=SPECIFIC_FLOW_RANGE_N20_N40_PER_M_S,
                range_sizes=(20, 40)) -> PointScore:
    """ε_T (Eq. 24), ε_j (Eq. 23) and the range penalty of one point from its runs.

    A (b, N) without experimental value must have N in ``range_sizes`` (the group sizes the range
    ``bounds`` is known for); any other is an error naming it.
    """
    ref = seyfried_2009() if reference is None else reference
    b, n, js = _runs(width_m, n_pedestrians, specific_flow_per_m_s, allow_undefined=True)
    check_number("range_weight", range_weight, error=CalibrationError, minimum=0.0)
    undefined = ~np.isfinite(js)
    js = np.where(undefined, 0.0, js)
    keys, inverse = np.unique(np.column_stack([np.round(b, 6), n]), axis=0, return_inverse=True)
    inverse = inverse.ravel()
    mean_js = np.bincount(inverse, weights=js) / np.bincount(inverse)
    kb, kn = keys[:, 0], keys[:, 1].astype(np.int64)
    has = reference_mask(ref, kb, kn)
    if not has.any():
        raise CalibrationError(f"no model run has an experimental counterpart (runs: N = {sorted(set(kn.tolist()))}; "
                               f"reference: N = {sorted(set(ref.n_pedestrians.tolist()))})")
    orphan = ~has & ~np.isin(kn, np.asarray(range_sizes, dtype=np.int64))
    if orphan.any():
        k = int(np.flatnonzero(orphan)[0])
        raise CalibrationError(f"model run without experimental counterpart or known range: b = {kb[k]:g} m, "
                               f"N = {kn[k]} (reference has {sorted(zip(ref.width_m.tolist(), ref.n_pedestrians.tolist()))}, "
                               f"range known for N = {list(range_sizes)})")
    eps_t = epsilon_total(kb[has], kn[has], mean_js[has], ref, require_all_rows=False)
    eps_j = {int(g): epsilon_j(kb[has & (kn == g)], mean_js[has & (kn == g)], int(g), ref)
             for g in np.unique(kn[has])}
    low, high = float(bounds[0]), float(bounds[1])
    free = mean_js[~has]
    if free.size:
        check = in_range_check(free, (low, high))
        rel = np.where(free < low, free / low - 1.0, np.where(free > high, free / high - 1.0, 0.0))
        penalty, inside = float(np.mean(rel ** 2)), check.all_inside
    else:
        penalty, inside = 0.0, True
    return PointScore(eps_t, eps_j, penalty, inside, eps_t + float(range_weight) * penalty, kb, kn, mean_js, has,
                      int(b.size), int(undefined.sum()))


# --- the ε_T surface (Fig. 10): grids, valley of minima, A(B) = a exp(c B) ---------------------------

def check_grid_values(values, name: str) -> np.ndarray:
    """A grid axis: non-empty, finite, > 0, strictly increasing; raises naming the problem."""
    v = np.atleast_1d(np.asarray(values, dtype=np.float64)).ravel()
    if v.size == 0:
        raise CalibrationError(f"{name} grid is empty")
    if not np.all(np.isfinite(v)) or np.any(v <= 0):
        raise CalibrationError(f"{name} grid values must be finite and > 0, got {v.tolist()}")
    if np.any(np.diff(v) <= 0):
        raise CalibrationError(f"{name} grid values must be strictly increasing without repeats, got {v.tolist()}")
    return v


def grid_axis(low: float, high: float, size: int, name: str, spacing: str = "linear") -> np.ndarray:
    """``size`` values from ``low`` to ``high`` (the paper: 20 linearly spaced values), ``spacing`` linear or log."""
    check_integer(f"{name} grid size", size, error=CalibrationError, minimum=1, whole_floats=True)
    if not (np.isfinite(low) and np.isfinite(high)) or low <= 0 or high <= 0:
        raise CalibrationError(f"{name} range must be finite and > 0, got [{low}, {high}]")
    if size > 1 and not low < high:
        raise CalibrationError(f"{name} range must satisfy low < high for {size} values, got [{low}, {high}]")
    if size == 1 and low != high:
        raise CalibrationError(f"{name} grid of size 1 needs low == high, got [{low}, {high}]")
    if spacing == "linear":
        return np.linspace(low, high, int(size))
    if spacing == "log":
        return np.geomspace(low, high, int(size))
    raise CalibrationError(f"spacing must be 'linear' or 'log', got {spacing!r}")


@dataclass(frozen=True)
class Valley:
    """For each B, the A minimising ε_T (red circles of Fig. 10); ``at_edge`` when that A is a grid end."""

    social_range_m: np.ndarray  # (M,) B values with at least one finite ε_T
    social_strength_n: np.ndarray  # (M,) A*(B)
    epsilon: np.ndarray  # (M,) ε_T at A*
    at_edge: np.ndarray  # (M,) bool


def valley_of_minima(social_strength_n, social_range_m, epsilon, refine: bool = True) -> Valley:
    """A*(B) = argmin_A ε_T(A, B) per column of ``epsilon`` (shape (n_A, n_B), nan = missing).

    ``refine``: for interior minima, the vertex of the parabola through the three points around the
    minimum in ln A (sub-grid resolution on coarse grids; exact for ε quadratic in ln A).
    """
    a = check_grid_values(social_strength_n, "A")
    b = check_grid_values(social_range_m, "B")
    eps = np.asarray(epsilon, dtype=np.float64)
    if eps.shape != (a.size, b.size):
        raise CalibrationError(f"epsilon must have shape (n_A, n_B) = {(a.size, b.size)}, got {eps.shape}")
    finite = np.isfinite(eps)
    cols = np.flatnonzero(finite.any(axis=0))
    e = np.where(finite, eps, np.inf)[:, cols]
    i = e.argmin(axis=0)
    j = np.arange(cols.size)
    a_star, e_star = a[i].copy(), e[i, j].copy()
    at_edge = (i == 0) | (i == a.size - 1)
    if refine and a.size >= 3:
        ok = ~at_edge
        ii = np.clip(i, 1, a.size - 2)
        x0, x1, x2 = np.log(a[ii - 1]), np.log(a[ii]), np.log(a[ii + 1])
        y0, y1, y2 = e[ii - 1, j], e[ii, j], e[ii + 1, j]
        ok &= np.isfinite(y0) & np.isfinite(y2)
        with np.errstate(invalid="ignore", divide="ignore"):
            # Newton divided differences: y = y0 + d1 (x - x0) + d2 (x - x0)(x - x1)
            d1 = (y1 - y0) / (x1 - x0)
            d2 = ((y2 - y1) / (x2 - x1) - d1) / (x2 - x0)
            xv = 0.5 * (x0 + x1) - d1 / (2.0 * d2)
            yv = y0 + d1 * (xv - x0) + d2 * (xv - x0) * (xv - x1)
        ok &= d2 > 0
        xv = np.clip(xv, x0, x2)
        a_star = np.where(ok, np.exp(xv), a_star)
        e_star = np.where(ok, np.clip(yv, 0.0, e_star), e_star)  # ε ≥ 0: a sharp valley can overshoot
    return Valley(b[cols], a_star, e_star, at_edge)


@dataclass(frozen=True)
class ExponentialFit:
    """A(B) = coefficient_n · exp(rate_per_m · B), least squares on ln A (the curve of Fig. 10)."""

    coefficient_n: float
    rate_per_m: float
    residual_norm_log: float  # ‖ln A - fit‖₂
    n_points: int

    def __call__(self, social_range_m):
        return self.coefficient_n * np.exp(self.rate_per_m * np.asarray(social_range_m, dtype=np.float64))


# Kabalan et al. (2016) Fig. 10: A = 1501 exp(-7.98 B).
PAPER_VALLEY_FIT = ExponentialFit(1501.0, -7.98, float("nan"), 0)


def fit_exponential_valley(social_range_m, social_strength_n) -> ExponentialFit:
    """Fit ln A = ln a + c B through valley points (Fig. 10's exponential fit); needs ≥ 2 distinct B."""
    b = np.atleast_1d(np.asarray(social_range_m, dtype=np.float64)).ravel()
    a = np.atleast_1d(np.asarray(social_strength_n, dtype=np.float64)).ravel()
    if a.shape != b.shape:
        raise CalibrationError(f"B and A must have equal lengths, got {b.size}, {a.size}")
    ok = np.isfinite(a) & np.isfinite(b) & (a > 0)
    if np.unique(b[ok]).size < 2:
        raise CalibrationError(f"the exponential fit needs valley points at >= 2 distinct B, got {np.unique(b[ok]).size}")
    coef = np.polyfit(b[ok], np.log(a[ok]), 1)
    resid = np.log(a[ok]) - np.polyval(coef, b[ok])
    return ExponentialFit(float(np.exp(coef[1])), float(coef[0]), float(np.linalg.norm(resid)), int(ok.sum()))


def best_grid_point(social_strength_n, social_range_m, epsilon) -> tuple:
    """(A, B, ε_T) of the smallest finite ε_T on the grid (Eq. 25 restricted to the grid)."""
    eps = np.asarray(epsilon, dtype=np.float64)
    if not np.isfinite(eps).any():
        raise CalibrationError("no grid point has a finite ε_T")
    i, j = np.unravel_index(np.nanargmin(np.where(np.isfinite(eps), eps, np.nan)), eps.shape)
    return float(np.asarray(social_strength_n)[i]), float(np.asarray(social_range_m)[j]), float(eps[i, j])
