"""Calibration errors of the specific flow (Kabalan Eq. 23-24) and range checks for N = 20 / 40.

Only the N = 60 experimental values are known exactly, so by default ε_T averages over the runs that
match the shipped N = 60 rows; pass ``reference`` to use another table. A model run with no matching
experimental point is an error, never silently dropped.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .experiment import SPECIFIC_FLOW_RANGE_N20_N40_PER_M_S, ExperimentError, ExperimentTable, seyfried_2009


class CalibrationError(ValueError):
    """Model runs and reference table do not match."""


def _runs(width_m, n_pedestrians, specific_flow_per_m_s):
    b = np.atleast_1d(np.asarray(width_m, dtype=np.float64)).ravel()
    js = np.atleast_1d(np.asarray(specific_flow_per_m_s, dtype=np.float64)).ravel()
    n = np.broadcast_to(np.atleast_1d(np.asarray(n_pedestrians, dtype=np.int64)).ravel(), b.shape)
    if b.shape != js.shape:
        raise CalibrationError(f"width_m and specific_flow_per_m_s must have equal lengths, got {b.size}, {js.size}")
    if b.size == 0:
        raise CalibrationError("no model runs given")
    if not np.all(np.isfinite(js)):
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
