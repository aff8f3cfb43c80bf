"""Classical density in a measurement area (Kabalan Fig. 12): centres inside / area, per frame."""
from __future__ import annotations

from crowd_env.errors import DensityError

import numpy as np
import shapely
from shapely.geometry import Polygon


def as_polygon(area) -> Polygon:
    """A shapely polygon from a Polygon, a (K, 2) vertex array, or a box ``(x_min, y_min, x_max, y_max)``."""
    if isinstance(area, Polygon):
        poly = area
    else:
        arr = np.asarray(area, dtype=np.float64)
        if arr.shape == (4,):
            poly = shapely.box(*arr)
        elif arr.ndim == 2 and arr.shape[1] == 2 and arr.shape[0] >= 3:
            poly = Polygon(arr)
        else:
            raise DensityError(f"measurement area must be a Polygon, (K, 2) vertices or a 4-tuple box, got shape {arr.shape}")
    if not poly.is_valid or poly.area <= 0:
        raise DensityError(f"measurement area is invalid or has zero area: {poly.wkt[:120]}")
    shapely.prepare(poly)
    return poly


def density_in_area(position_m, area) -> float:
    """Pedestrians per m² in ``area`` for one frame of centres (N, 2) (boundary points excluded)."""
    poly = as_polygon(area)
    pos = np.asarray(position_m, dtype=np.float64).reshape(-1, 2)
    return float(np.count_nonzero(shapely.contains_xy(poly, pos[:, 0], pos[:, 1]))) / poly.area


def density_time_series(frame, x, y, area, n_frames: int | None = None) -> np.ndarray:
    """Density (1/m²) per frame from long-format rows (frame, x, y); frames without rows give 0.

    ``n_frames`` defaults to max(frame) + 1; index the result with the recorder's ``frame_time_s``.
    """
    poly = as_polygon(area)
    frame = np.asarray(frame, dtype=np.int64)
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if not (frame.shape == x.shape == y.shape):
        raise DensityError("frame, x and y must have equal shapes")
    if frame.size and frame.min() < 0:
        raise DensityError("frame numbers must be >= 0")
    n_frames = (int(frame.max()) + 1 if frame.size else 0) if n_frames is None else int(n_frames)
    inside = shapely.contains_xy(poly, x, y)
    return np.bincount(frame[inside], minlength=n_frames)[:n_frames] / poly.area


def stationary_mean(values, time_s=None, t_start_s: float | None = None, t_end_s: float | None = None,
                    trim_fraction: float = 0.2) -> float:
    """Mean of a series over its stationary phase.

    With ``t_start_s``/``t_end_s`` the window is explicit. Otherwise it is the occupied interval (first
    to last non-zero value) with ``trim_fraction`` of its length cut at each end (the filling and
    emptying transients).
    """
    v = np.asarray(values, dtype=np.float64).ravel()
    t = np.arange(v.size, dtype=np.float64) if time_s is None else np.asarray(time_s, dtype=np.float64).ravel()
    if t.shape != v.shape:
        raise DensityError(f"values and time_s must have equal lengths, got {v.size} and {t.size}")
    if not 0.0 <= trim_fraction < 0.5:
        raise DensityError(f"trim_fraction must lie in [0, 0.5), got {trim_fraction}")
    if t_start_s is None or t_end_s is None:
        occupied = np.flatnonzero(v != 0)
        if occupied.size == 0:
            raise DensityError("series is zero everywhere: no stationary phase")
        t0, t1 = t[occupied[0]], t[occupied[-1]]
        cut = trim_fraction * (t1 - t0)
        t_start_s = t0 + cut if t_start_s is None else t_start_s
        t_end_s = t1 - cut if t_end_s is None else t_end_s
    sel = (t >= t_start_s) & (t <= t_end_s)
    if not np.any(sel):
        raise DensityError(f"no samples in the stationary window [{t_start_s}, {t_end_s}] s")
    return float(v[sel].mean())


def hexagonal_density_per_m2(spacing_m) -> np.ndarray:
    """Density of a hexagonal (triangular) packing with centre-to-centre distance ``spacing_m``:
    2 / (√3 d²). For touching disks of radius r (d = 2r) it is the densest packing: 5.46 /m² at
    r = 0.23 m."""
    d = np.asarray(spacing_m, dtype=np.float64)
    if np.any(~np.isfinite(d)) or np.any(d <= 0.0):
        raise DensityError(f"spacing_m must be finite and > 0, got {spacing_m!r}")
    return 2.0 / (np.sqrt(3.0) * d * d)


def force_balance_jam_density_per_m2(social_strength_n, social_range_m, radius_m: float = 0.23,
                                     mass_kg: float = 83.0, desired_speed_m_s: float = 1.34,
                                     relaxation_time_s: float = 0.5) -> np.ndarray:
    """Density of a jam held apart by social repulsion alone: the estimate that explains the model's
    density in front of a bottleneck.

    A pedestrian at rest in a queue feels the driving force m ‖u_d‖ / τ (Eq. 14 at u = 0) and, head on
    (anisotropy weight 1), the repulsion A exp((2r − d)/B) of the one ahead (Eq. 16). They balance
    at the spacing d = 2r + B ln(A τ / (m ‖u_d‖)) (never below 2r: contact), and a hexagonal packing
    at that spacing has :func:`hexagonal_density_per_m2` (d). Arrays of A and B broadcast. With Table 2
    and A = 790 N, B = 0.08 m: d = 0.561 m, 3.66 /m²; with A = 1150 N, B = 0.2 m: 1.86 /m². Pushing
    from the rows behind compresses the front rows somewhat beyond this, contacts stop it at 2r.
    """
    a = np.asarray(social_strength_n, dtype=np.float64)
    b = np.asarray(social_range_m, dtype=np.float64)
    for name, v in (("social_strength_n", a), ("social_range_m", b), ("radius_m", radius_m), ("mass_kg", mass_kg),
                    ("desired_speed_m_s", desired_speed_m_s), ("relaxation_time_s", relaxation_time_s)):
        if np.any(~np.isfinite(v)) or np.any(np.asarray(v) <= 0.0):
            raise DensityError(f"{name} must be finite and > 0, got {v!r}")
    drive_n = mass_kg * desired_speed_m_s / relaxation_time_s
    spacing = 2.0 * radius_m + np.maximum(b * np.log(a / drive_n), 0.0)
    return hexagonal_density_per_m2(spacing)
