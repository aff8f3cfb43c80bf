"""Experimental fundamental diagrams: the Jülich corridor, single file, and Weidmann's handbook curve.

- :func:`juelich_corridor`: unidirectional flow in a 1.8 m corridor (Zhang, Klingsch, Schadschneider,
  Seyfried 2011, J. Stat. Mech. P06004), binned from PedPy's Voronoi density and speed in a 2 m measurement
  area (``data/juelich_uo_corridor_1.8m_fd.csv``: ρ (1/m²), v (m/s), spread, J_s, frames per bin);
- :func:`single_file`: single file on an oval ring (Seyfried, Steffen, Klingsch, Boltes 2005, J. Stat. Mech.
  P10002), speed against the 1D density ρ = 1/headway (``data/single_file_seyfried2005.csv``); the
  least-squares headway relation over its samples is d = a + b v with a = 0.34 m, b = 1.08 s
  (:data:`SINGLE_FILE_HEADWAY_FIT`);
- :func:`weidmann_speed_m_s`: Weidmann (1993), v(ρ) = 1.34 [1 − exp(−1.913 (1/ρ − 1/5.4))] m/s, the curve
  RiMEA test 4 refers to.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from importlib import resources

import numpy as np

from crowd_env.errors import ExperimentError

__all__ = ["FDTable", "juelich_corridor", "single_file", "weidmann_speed_m_s", "SINGLE_FILE_HEADWAY_FIT",
           "JUELICH_CORRIDOR_WIDTH_M"]

JUELICH_CORRIDOR_WIDTH_M = 1.8
# d = a + b v fitted over the single-file samples with v > 0.05 m/s (shared data README): a (m), b (s).
SINGLE_FILE_HEADWAY_FIT = (0.34, 1.08)
# Weidmann (1993): free speed (m/s), gamma (1/m²), jam density (1/m²).
WEIDMANN = (1.34, 1.913, 5.4)


@dataclass(frozen=True)
class FDTable:
    """Binned speed against density: ``density`` (1/m² or, for single file, 1/m), ``speed_m_s``, ``spread_m_s``
    (nan where unknown), ``count`` (frames or samples per bin) and ``source``."""

    density: np.ndarray
    speed_m_s: np.ndarray
    spread_m_s: np.ndarray
    count: np.ndarray
    source: str

    def speed_at(self, density) -> np.ndarray:
        """The experiment's speed at ``density``, linear between bins; nan outside the binned range."""
        d = np.asarray(density, dtype=np.float64)
        return np.interp(d, self.density, self.speed_m_s, left=np.nan, right=np.nan)


def _read(name: str, columns: list) -> np.ndarray:
    text = resources.files("crowd_env.analysis").joinpath("data", name).read_text(encoding="utf-8")
    rows = [ln for ln in text.splitlines() if ln.strip() and not ln.startswith("#")]
    header = rows[0].split(",")
    if header != columns:
        raise ExperimentError(f"{name}: expected columns {columns}, got {header}")
    return np.array([[float(v) for v in ln.split(",")] for ln in rows[1:]])


@lru_cache(maxsize=1)
def juelich_corridor() -> FDTable:
    """The Jülich 1.8 m corridor bins (module docstring)."""
    d = _read("juelich_uo_corridor_1.8m_fd.csv", ["rho_per_m2", "v_m_s", "v_sd_m_s", "Js_per_m_s", "n_frames"])
    return FDTable(d[:, 0], d[:, 1], d[:, 2], d[:, 4].astype(np.int64),
                   "Zhang et al. (2011), unidirectional 1.8 m corridor, PedPy Voronoi density and speed")


@lru_cache(maxsize=1)
def single_file() -> FDTable:
    """The single-file bins (module docstring); density in 1/m."""
    d = _read("single_file_seyfried2005.csv", ["rho_per_m", "v_m_s", "n_samples"])
    return FDTable(d[:, 0], d[:, 1], np.full(d.shape[0], np.nan), d[:, 2].astype(np.int64),
                   "Seyfried et al. (2005), single file on a ring, speed against 1/headway")


def weidmann_speed_m_s(density_per_m2) -> np.ndarray:
    """Weidmann's v(ρ) (module docstring); 0 at and above the jam density 5.4 /m²."""
    v0, gamma, jam = WEIDMANN
    rho = np.asarray(density_per_m2, dtype=np.float64)
    with np.errstate(divide="ignore"):
        v = v0 * (1.0 - np.exp(-gamma * (1.0 / rho - 1.0 / jam)))
    return np.clip(v, 0.0, None)
