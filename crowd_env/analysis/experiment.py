"""Experimental reference: Seyfried et al. (2009) bottleneck runs (= Kabalan et al. 2016, Table 1).

Only the N = 60 row is known exactly (shipped CSV). For N = 20 and 40 only facts are known: all values
lie in [1.77, 2.31] 1/(m s), and the residual norms of linear fits J(b) (Kabalan Table 3).
"""
from __future__ import annotations

from crowd_env.errors import ExperimentError

from dataclasses import dataclass
from functools import lru_cache
from importlib import resources

import numpy as np

WIDTHS_M = (0.8, 0.9, 1.0, 1.1, 1.2)
GROUP_SIZES = (20, 40, 60)
# All ten N = 20 / N = 40 specific flows lie in this closed range, 1/(m s).
SPECIFIC_FLOW_RANGE_N20_N40_PER_M_S = (1.77, 2.31)
# J_s(b = 1.1 m, N = 20) is a local dip below its neighbours.
DIP_N20_WIDTH_M = 1.1
# Norms of residuals of least-squares lines J = a b + c through the experimental flows (Kabalan Table 3).
RESIDUAL_NORM_BY_GROUP = {20: 0.436, 40: 0.237, 60: 0.098}
# Other N = 60 observations (Seyfried et al. 2009; docs/validation/bottleneck.md): density in the jam 1 m in front of
# the entrance, stationary density and speed inside the bottleneck, over all widths.
FRONT_DENSITY_RANGE_PER_M2 = (4.0, 6.0)
INSIDE_DENSITY_RANGE_PER_M2 = (1.42, 1.73)
INSIDE_SPEED_RANGE_M_S = (0.94, 1.22)
# The published two-decimal N = 60 specific flows (Seyfried 2009 Table 2); the CSV holds full precision.
PUBLISHED_SPECIFIC_FLOW_N60_PER_M_S = (1.61, 1.86, 1.90, 1.93, 1.97)

_CSV_NAME = "seyfried2009_bottleneck.csv"


@dataclass(frozen=True)
class ExperimentTable:
    """Bottleneck runs, one row per (b, N): width b, group size N, Δt first-to-last passage,
    flow J = N / Δt and specific flow J_s = J / b (Eq. 22)."""

    width_m: np.ndarray
    n_pedestrians: np.ndarray
    dt_s: np.ndarray
    flow_per_s: np.ndarray
    specific_flow_per_m_s: np.ndarray
    source: str = ""

    @classmethod
    def from_arrays(cls, width_m, n_pedestrians, specific_flow_per_m_s, dt_s=None, source: str = "") -> "ExperimentTable":
        """Build a reference table (e.g. another data set); Δt and J are derived when not given."""
        b = np.asarray(width_m, dtype=np.float64).ravel()
        n = np.asarray(n_pedestrians, dtype=np.int64).ravel()
        js = np.asarray(specific_flow_per_m_s, dtype=np.float64).ravel()
        if not (b.shape == n.shape == js.shape):
            raise ExperimentError(f"width_m, n_pedestrians and specific_flow_per_m_s must have equal lengths, "
                                  f"got {b.shape[0]}, {n.shape[0]}, {js.shape[0]}")
        if np.any(~np.isfinite(b)) or np.any(b <= 0) or np.any(~np.isfinite(js)) or np.any(js <= 0):
            raise ExperimentError("widths and specific flows must be finite and > 0")
        flow = js * b
        dt = n / flow if dt_s is None else np.asarray(dt_s, dtype=np.float64).ravel()
        if dt.shape != b.shape:
            raise ExperimentError(f"dt_s must have length {b.shape[0]}, got {dt.shape[0]}")
        return cls(b, n, dt, flow, js, source)

    def __len__(self) -> int:
        return int(self.width_m.shape[0])

    def group(self, n_pedestrians: int) -> "ExperimentTable":
        """Rows of one group size N."""
        sel = self.n_pedestrians == int(n_pedestrians)
        if not np.any(sel):
            raise ExperimentError(f"no experimental rows for N = {n_pedestrians}; available: "
                                  f"{sorted(set(self.n_pedestrians.tolist()))}")
        return ExperimentTable(self.width_m[sel], self.n_pedestrians[sel], self.dt_s[sel], self.flow_per_s[sel],
                               self.specific_flow_per_m_s[sel], self.source)

    def lookup(self, width_m, n_pedestrians, atol_m: float = 1e-6) -> np.ndarray:
        """Row index for each (b, N) query; raises :class:`ExperimentError` naming the first missing point."""
        b = np.atleast_1d(np.asarray(width_m, dtype=np.float64))
        n = np.broadcast_to(np.atleast_1d(np.asarray(n_pedestrians, dtype=np.int64)), b.shape)
        match = (np.abs(b[:, None] - self.width_m[None, :]) <= atol_m) & (n[:, None] == self.n_pedestrians[None, :])
        missing = np.flatnonzero(~match.any(axis=1))
        if missing.size:
            k = int(missing[0])
            raise ExperimentError(f"no experimental point for b = {b[k]:g} m, N = {int(n[k])} "
                                  f"({missing.size} unmatched run(s)); reference has "
                                  f"{sorted(zip(self.width_m.tolist(), self.n_pedestrians.tolist()))}")
        return match.argmax(axis=1)


@lru_cache(maxsize=1)
def _load() -> ExperimentTable:
    text = resources.files("crowd_env.analysis").joinpath("data", _CSV_NAME).read_text(encoding="utf-8")
    comments = [ln[1:].strip() for ln in text.splitlines() if ln.startswith("#")]
    rows = [ln for ln in text.splitlines() if ln.strip() and not ln.startswith("#")]
    header = rows[0].split(",")
    expected = ["b_m", "n_pedestrians", "dt_s", "flow_per_s", "specific_flow_per_m_s"]
    if header != expected:
        raise ExperimentError(f"{_CSV_NAME}: expected columns {expected}, got {header}")
    data = np.array([[float(v) for v in ln.split(",")] for ln in rows[1:]])
    table = ExperimentTable(data[:, 0], data[:, 1].astype(np.int64), data[:, 2], data[:, 3], data[:, 4],
                            source=" ".join(c for c in comments if not c.startswith("Columns:")) or _CSV_NAME)
    for arr in (table.width_m, table.n_pedestrians, table.dt_s, table.flow_per_s, table.specific_flow_per_m_s):
        arr.setflags(write=False)
    return table


def seyfried_2009() -> ExperimentTable:
    """The shipped Seyfried et al. (2009) table (N = 60 rows, read-only arrays) with its source string."""
    return _load()
