"""Reference data of the RiMEA fundamental-diagram tests: Weidmann's speed-density curve (test 4) and the
single-file speed percentiles (test 16), with the 1D measures the latter is read with.

- :func:`weidmann_speed_m_s`: v(ρ) = v0 (1 − exp(−γ (1/ρ − 1/ρ_max))), v0 = 1.34 m/s, γ = 1.913 /m²,
  ρ_max = 5.4 /m² (Weidmann 1993, IVT Schriftenreihe 90, as quoted by secondary sources: docs.rs
  rustsim-crowd ``WeidmannCurve::WEIDMANN_1993``; Seyfried et al. 2005 quote ρ_max = 5.4 /m²; the primary
  text was not accessed). RiMEA sets no tolerance against it: it is shown, never a pass criterion.
- :func:`single_file_percentiles`: the 10/50/90 % speed percentiles per 1D density of RiMEA 4.1.1 Fig. 20,
  from ``data/rimea16_percentiles.csv`` (source and provenance in the file's header).
- :func:`loop_headway_density_per_m`: 1D Voronoi density on a closed loop (ρ_i = 1 / (½ (d_front + d_back)),
  the measure of JuPedSim's RiMEA 16 test, ``jupedsim-web-community:scripts/scenario_builders/rimea16_loop.py``).
"""
from __future__ import annotations

from functools import lru_cache
from importlib import resources

import numpy as np

from crowd_env.errors import InputError

__all__ = ["WEIDMANN_V0_M_S", "WEIDMANN_GAMMA_PER_M2", "WEIDMANN_RHO_MAX_PER_M2", "weidmann_speed_m_s",
           "SingleFilePercentiles", "single_file_percentiles", "loop_headway_density_per_m"]

WEIDMANN_V0_M_S = 1.34
WEIDMANN_GAMMA_PER_M2 = 1.913
WEIDMANN_RHO_MAX_PER_M2 = 5.4

_PERCENTILE_CSV = "rimea16_percentiles.csv"


def weidmann_speed_m_s(density_per_m2, v0_m_s: float = WEIDMANN_V0_M_S, gamma_per_m2: float = WEIDMANN_GAMMA_PER_M2,
                       rho_max_per_m2: float = WEIDMANN_RHO_MAX_PER_M2) -> np.ndarray:
    """Weidmann's speed (m/s) at ``density_per_m2`` (array): v0 (1 − exp(−γ (1/ρ − 1/ρ_max))), 0 for
    ρ >= ρ_max, v0 at ρ = 0."""
    rho = np.asarray(density_per_m2, dtype=np.float64)
    with np.errstate(divide="ignore"):
        inv = np.where(rho > 0, 1.0 / np.where(rho > 0, rho, 1.0), np.inf)
    v = v0_m_s * (1.0 - np.exp(-gamma_per_m2 * (inv - 1.0 / rho_max_per_m2)))
    return np.where(rho >= rho_max_per_m2, 0.0, v)


class SingleFilePercentiles:
    """The test-16 reference: ``density_per_m`` (K,) and the speed percentiles ``p10``, ``p50``, ``p90``
    (K,) in m/s; :meth:`at` interpolates them linearly (clamped at the table's ends)."""

    def __init__(self, density_per_m, p10, p50, p90, source: str = ""):
        self.density_per_m = np.asarray(density_per_m, dtype=np.float64)
        self.p10 = np.asarray(p10, dtype=np.float64)
        self.p50 = np.asarray(p50, dtype=np.float64)
        self.p90 = np.asarray(p90, dtype=np.float64)
        self.source = source
        if not (self.density_per_m.shape == self.p10.shape == self.p50.shape == self.p90.shape) \
                or np.any(np.diff(self.density_per_m) <= 0):
            raise InputError("percentile table: equal lengths and strictly increasing densities required")

    def at(self, density_per_m) -> tuple:
        """``(p10, p50, p90)`` arrays at ``density_per_m``."""
        d = np.asarray(density_per_m, dtype=np.float64)
        return tuple(np.interp(d, self.density_per_m, p) for p in (self.p10, self.p50, self.p90))


@lru_cache(maxsize=1)
def single_file_percentiles() -> SingleFilePercentiles:
    """The RiMEA 4.1.1 Fig. 20 envelope (``data/rimea16_percentiles.csv``)."""
    text = resources.files("crowd_env.analysis").joinpath("data", _PERCENTILE_CSV).read_text(encoding="utf-8")
    comments = [ln[1:].strip() for ln in text.splitlines() if ln.startswith("#")]
    rows = [ln for ln in text.splitlines() if ln and not ln.startswith("#")]
    data = np.array([[float(x) for x in ln.split(",")] for ln in rows[1:]])
    return SingleFilePercentiles(data[:, 0], data[:, 1], data[:, 2], data[:, 3], source=" ".join(comments[:4]))


def loop_headway_density_per_m(arc_length_m, length_m: float) -> np.ndarray:
    """1D Voronoi density (1/m) of pedestrians at arc lengths ``arc_length_m`` (n,) on a closed loop of length
    ``length_m``: each one's cell is half the gap to the one ahead plus half the gap to the one behind (wrapping
    round the loop), ρ_i = 1 / cell. One pedestrian alone has the whole loop (ρ = 1/L)."""
    s = np.mod(np.asarray(arc_length_m, dtype=np.float64).reshape(-1), length_m)
    n = s.shape[0]
    if n == 0:
        return np.zeros(0)
    if not (np.isfinite(length_m) and length_m > 0) or not np.all(np.isfinite(s)):
        raise InputError("arc lengths must be finite and the loop length positive")
    order = np.argsort(s, kind="stable")
    ss = s[order]
    front = np.roll(ss, -1) - ss
    front[-1] += length_m
    back = ss - np.roll(ss, 1)
    back[0] += length_m
    cell = 0.5 * (front + back)
    out = np.empty(n)
    with np.errstate(divide="ignore"):
        out[order] = 1.0 / cell
    return out
