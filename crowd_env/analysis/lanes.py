"""Lane formation inside the bottleneck (Kabalan Section 4.2, Fig. 14), and in counterflow.

Histogram of lateral positions in 0.01 m bins as probabilities X_i / Σ X_j, and a peak detector that
counts lanes (one lane at b = 0.8 m, two for b ≥ 0.9 m in the experiment). For bidirectional flow,
:func:`lane_order_parameter`: the lane order parameter of Rex & Löwen (2007).
"""
from __future__ import annotations

from crowd_env.errors import LaneError

from dataclasses import dataclass

import numpy as np
import shapely
from scipy.ndimage import gaussian_filter1d

from .density import as_polygon


@dataclass(frozen=True)
class LateralHistogram:
    """Bin centres (m, along ``lateral_direction`` from the origin), counts X_i and probabilities X_i / Σ X_j."""

    centers_m: np.ndarray
    counts: np.ndarray
    probability: np.ndarray


def lateral_histogram(x, y, region, lateral_direction=(0.0, 1.0), bin_width_m: float = 0.01) -> LateralHistogram:
    """Histogram of lateral positions of centres inside ``region`` (Polygon, vertices or box).

    The lateral coordinate is the projection onto ``lateral_direction`` (default: y); bins of
    ``bin_width_m`` span the region's extent along it. Pass all frames' rows at once (e.g. from the
    recorder's long-format arrays, several runs concatenated).
    """
    poly = as_polygon(region)
    if not (np.isfinite(bin_width_m) and bin_width_m > 0):
        raise LaneError(f"bin_width_m must be > 0, got {bin_width_m!r}")
    d = np.asarray(lateral_direction, dtype=np.float64)
    if d.shape != (2,) or not np.hypot(*d) > 0:
        raise LaneError(f"lateral_direction must be a non-zero (x, y) vector, got {lateral_direction}")
    d = d / np.hypot(*d)
    x = np.asarray(x, dtype=np.float64).ravel()
    y = np.asarray(y, dtype=np.float64).ravel()
    inside = shapely.contains_xy(poly, x, y)
    lateral = x[inside] * d[0] + y[inside] * d[1]
    if lateral.size == 0:
        raise LaneError("no pedestrian centres inside the lane region")
    extent = np.asarray(poly.exterior.coords) @ d
    lo, hi = float(extent.min()), float(extent.max())
    n_bins = max(1, int(np.ceil((hi - lo) / bin_width_m - 1e-9)))
    edges = lo + bin_width_m * np.arange(n_bins + 1)
    counts, _ = np.histogram(lateral, bins=edges)
    return LateralHistogram(0.5 * (edges[:-1] + edges[1:]), counts, counts / counts.sum())


@dataclass(frozen=True)
class LaneResult:
    """Number of lanes, their peak positions (m) and the smoothed probability used to find them."""

    n_lanes: int
    peak_positions_m: np.ndarray
    smoothed: np.ndarray


def detect_lanes(centers_m, probability, smoothing_m: float = 0.02, min_prominence: float = 0.2) -> LaneResult:
    """Count lanes as peaks of the Gaussian-smoothed lateral distribution.

    ``smoothing_m`` is the Gaussian σ (0 disables); a peak counts when its prominence is at least
    ``min_prominence`` times the highest smoothed value. The series is zero-padded so that a peak at
    the edge of the region is found.
    """
    c = np.asarray(centers_m, dtype=np.float64).ravel()
    p = np.asarray(probability, dtype=np.float64).ravel()
    if c.shape != p.shape or c.size == 0:
        raise LaneError(f"centers_m and probability must be non-empty and of equal length, got {c.size}, {p.size}")
    if not 0 < min_prominence <= 1:
        raise LaneError(f"min_prominence must lie in (0, 1], got {min_prominence}")
    bin_m = float(np.median(np.diff(c))) if c.size > 1 else 1.0
    sigma_bins = smoothing_m / bin_m if smoothing_m > 0 else 0.0
    smooth = gaussian_filter1d(p, sigma_bins, mode="constant") if sigma_bins > 0 else p.copy()
    top = smooth.max()
    if top <= 0:
        raise LaneError("the lateral distribution is zero everywhere")
    padded = np.concatenate([[0.0], smooth, [0.0]])
    from scipy.signal import find_peaks  # imported on use: scipy.signal takes ~1.7 s to import

    peaks, _ = find_peaks(padded, prominence=min_prominence * top)
    peaks = peaks - 1
    return LaneResult(int(peaks.size), c[peaks], smooth)


def pooled_lanes(records) -> LaneResult:
    """Lanes in the channel from run records' lateral-position counts (``lane_counts`` over the bins
    ``lane_bin_edges_m`` = [first edge, bin width, number of edges]), pooled over the records."""
    records = list(records)
    if not records:
        raise LaneError("no run records to pool")
    counts = np.sum([r["lane_counts"] for r in records], axis=0).astype(float)
    start, step, n_edges = records[0]["lane_bin_edges_m"]
    centers = start + step * (np.arange(int(n_edges) - 1) + 0.5)
    return detect_lanes(centers, counts / max(counts.sum(), 1.0))


def lane_order_parameter(*, y_m, eastbound, band_m: float = 0.46) -> float:
    """The lane order parameter Φ of a counterflow (Rex & Löwen 2007, Phys. Rev. E 75, 051402; used for
    self-driven particles by Ikeda & Kim 2017): for each pedestrian i, the others whose lateral position lies
    within ``band_m`` / 2 of its own (its lane, one body wide by default), n_same walking its way and n_opp the
    other;

        φ_i = ((n_same − n_opp) / (n_same + n_opp))²,   Φ = mean of φ_i over the pedestrians with a lane-mate.

    Φ = 1 when every lane carries one direction; a well-mixed crowd with a fraction f walking one way gives
    about (1 − 2f)² plus a finite-size term (:func:`mixed_lane_order_parameter` draws it). ``y_m`` (N,) lateral
    positions of one frame, ``eastbound`` (N,) bool walking directions. NaN when nobody has a lane-mate.
    """
    y = np.asarray(y_m, dtype=np.float64)
    east = np.asarray(eastbound, dtype=bool)
    if y.ndim != 1 or east.shape != y.shape:
        raise LaneError(f"y_m and eastbound must be (N,) arrays of one shape, got {y.shape} and {east.shape}")
    if not np.all(np.isfinite(y)):
        raise LaneError("y_m holds non-finite positions")
    if not (np.isfinite(band_m) and band_m > 0):
        raise LaneError(f"band_m must be > 0, got {band_m!r}")
    same_lane = np.abs(y[:, None] - y[None, :]) < 0.5 * band_m
    np.fill_diagonal(same_lane, False)
    same_dir = east[:, None] == east[None, :]
    n_same = (same_lane & same_dir).sum(axis=1)
    n_opp = (same_lane & ~same_dir).sum(axis=1)
    n = n_same + n_opp
    has = n > 0
    if not has.any():
        return float("nan")
    return float(np.mean(((n_same[has] - n_opp[has]) / n[has]) ** 2))


def mixed_lane_order_parameter(*, y_m, eastbound, band_m: float = 0.46, draws: int = 200, seed: int = 0) -> float:
    """Φ of the same positions with the walking directions shuffled (``draws`` permutations, mean): the value
    of a crowd with no lanes at this density and mix, the reference a measured Φ is read against."""
    rng = np.random.default_rng(seed)
    east = np.asarray(eastbound, dtype=bool)
    return float(np.nanmean([lane_order_parameter(y_m=y_m, eastbound=rng.permutation(east), band_m=band_m)
                             for _ in range(int(draws))]))
