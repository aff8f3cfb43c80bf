"""Placement of start positions: hexagonal or square lattices in a region, relaxed hard disks, hand-holding groups
(Kabalan et al. 2016, Section 4: the Seyfried crowd and its groups)."""
from __future__ import annotations

from crowd_env.errors import ScenarioError

import math

import numpy as np
import shapely
import shapely.affinity
from scipy.spatial import cKDTree

from ..core.geometry import as_polygon
from .checks import check_count, check_positive

__all__ = ["place_pedestrians", "form_groups"]


def _lattice(inner, nx: int, ny: int, hexagonal: bool):
    """Sites of an nx x ny lattice stretched over ``inner``'s bounding box (hex: odd rows shifted by sx/2)."""
    x0, y0, x1, y1 = inner.bounds
    w, h = x1 - x0, y1 - y0
    sx = w / (nx - 1) if nx > 1 else math.inf
    sy = h / (ny - 1) if ny > 1 else math.inf
    xs = x0 + np.arange(nx) * sx if nx > 1 else np.array([0.5 * (x0 + x1)])
    ys = y0 + np.arange(ny) * sy if ny > 1 else np.array([0.5 * (y0 + y1)])
    if hexagonal and nx > 1:
        pts = [np.column_stack([xs if r % 2 == 0 else xs[:-1] + 0.5 * sx, np.full(nx - (r % 2), y)])
               for r, y in enumerate(ys)]
        pts = np.vstack(pts)
        spacing = min(sx, math.hypot(0.5 * sx, sy))
    else:
        xx, yy = np.meshgrid(xs, ys, indexing="ij")
        pts = np.column_stack([xx.ravel(), yy.ravel()])
        spacing = min(sx, sy)
    keep = shapely.intersects_xy(inner, pts[:, 0], pts[:, 1])
    return pts[keep], spacing


def _best_lattice(inner, n: int, spacing_min: float):
    """The lattice with at least n sites in ``inner`` whose closest pair is farthest apart, or the capacity."""
    x0, y0, x1, y1 = inner.bounds
    w, h = x1 - x0, y1 - y0
    max_rows = int(h / (spacing_min * math.sqrt(3) / 2) + 1e-9) + 1
    max_cols = int(w / spacing_min + 1e-9) + 1
    best, best_spacing, capacity = None, -1.0, 0
    for ny in range(1, max_rows + 1):
        for hexagonal in (False, True):
            nx = max(1, min(math.ceil(n / ny), max_cols))  # from the widest admissible row when n is too many
            while nx <= max_cols + 1:
                pts, spacing = _lattice(inner, nx, ny, hexagonal)
                if spacing < spacing_min - 1e-12:
                    break
                capacity = max(capacity, pts.shape[0])
                if pts.shape[0] >= n:
                    if spacing > best_spacing:
                        best, best_spacing = pts, spacing
                    break
                nx += 1
    return best, best_spacing, capacity


def place_pedestrians(region, n: int | None = None, radius_m: float = 0.23, rng: np.random.Generator | None = None, *,
                      density_per_m2: float | None = None, min_gap_m: float = 0.0, margin_m: float | None = None,
                      toward=None, relax_sweeps: int = 40) -> np.ndarray:
    """Centres (n, 2) of n non-overlapping disks of radius ``radius_m`` inside ``region``, seeded by ``rng``.

    Give ``n``, ``density_per_m2`` (then n = round(density x region area)) or both: then the lattice has
    round(density x area) sites and n <= that of them are occupied (random ones, or the nearest to
    ``toward``), i.e. n pedestrians at that local density. Disks stay ``margin_m`` (default: their
    radius, i.e. entirely) inside the region and at least ``min_gap_m`` apart. Method: the lattice
    (rectangular or hexagonal, stretched over the region) with enough sites whose closest pair is
    farthest apart; then ``relax_sweeps`` sweeps of hard-disk Monte Carlo moves to disorder it. This
    succeeds at densities above the random-sequential-addition jamming limit (3.3 /m² of r = 0.23 m
    disks is packing fraction 0.55 > 0.547). Raises :class:`ScenarioError` naming the
    numbers when n disks do not fit.
    """
    poly = as_polygon(region, "placement region")
    rng = np.random.default_rng() if rng is None else rng
    for name, value in (("radius_m", radius_m),):
        if not (np.isfinite(value) and value > 0):
            raise ScenarioError(f"{name} must be > 0, got {value!r}")
    if not (np.isfinite(min_gap_m) and min_gap_m >= 0):
        raise ScenarioError(f"min_gap_m must be >= 0, got {min_gap_m!r}")
    if density_per_m2 is not None:
        if not (np.isfinite(density_per_m2) and density_per_m2 > 0):
            raise ScenarioError(f"density_per_m2 must be > 0, got {density_per_m2!r}")
        n_sites = int(round(density_per_m2 * poly.area))
        if n is None:
            n = n_sites
        elif n > density_per_m2 * poly.area + 0.5:
            raise ScenarioError(f"{n} pedestrians in a region of {poly.area:.4g} m² exceed the requested density "
                                f"{density_per_m2:.4g} /m² (at most {n_sites} pedestrians)")
    if n is None:
        raise ScenarioError("give the number of pedestrians n or density_per_m2")
    n = check_count("the number of pedestrians n", n, minimum=0)
    n_sites = n if density_per_m2 is None else max(n, n_sites)
    if n == 0:
        return np.zeros((0, 2))
    margin = radius_m if margin_m is None else float(margin_m)
    inner = poly.buffer(-margin, join_style="mitre") if margin > 0 else poly
    if inner.is_empty:
        raise ScenarioError(f"more pedestrians than fit in the holding area: {n} requested, but the region "
                            f"({poly.area:.4g} m²) is too small for even one disk of radius {radius_m} m")
    shapely.prepare(inner)
    spacing_min = 2.0 * radius_m + min_gap_m
    sites, spacing, capacity = _best_lattice(inner, n_sites, spacing_min)
    if sites is None:
        raise ScenarioError(f"more pedestrians than fit in the holding area: {n_sites} requested at "
                            f"{n_sites / poly.area:.4g} /m² in {poly.area:.4g} m², but at most {capacity} disks of radius "
                            f"{radius_m} m fit there (min gap {min_gap_m} m)")
    if toward is None:
        chosen = rng.choice(sites.shape[0], size=n, replace=False)
    else:
        target = np.asarray(toward, dtype=np.float64).reshape(2)
        d = np.linalg.norm(sites - target, axis=1)
        chosen = np.lexsort((rng.random(sites.shape[0]), np.round(d, 9)))[:n]
    pos = np.array(sites[chosen], dtype=np.float64)
    step = max(spacing - spacing_min, 0.05 * spacing_min)
    if not math.isfinite(step):  # a single site (spacing inf): moves up to the size of the region
        x0, y0, x1, y1 = inner.bounds
        step = max(x1 - x0, y1 - y0, 0.05 * spacing_min)
    pos = _relax_hard_disks(pos, inner, spacing_min, step, rng, int(relax_sweeps))
    return pos


def form_groups(position_m, sizes, radius_m: float, region, rng: np.random.Generator, *, walking_direction=(1.0, 0.0),
                gap_m: float = 0.05, min_gap_m: float = 0.0, max_turn_deg: float = 20.0):
    """Turn some of the placed pedestrians ``position_m`` (N, 2) into hand-holding groups standing side by side.

    ``sizes``: one entry per group (2 = pair, 3 = triple, ...), formed largest first. A group is a row
    of disks with centres ``2 radius_m + gap_m`` apart across the walking direction
    (``walking_direction``: a (2,) vector, or ``f(points (n, 2)) -> (n, 2)`` unit vectors such as an
    eikonal field's e_d), turned by at most ``max_turn_deg``. For each group a random unassigned
    pedestrian keeps its place as one member of the row and the unassigned pedestrians nearest to the
    other places of the row move there; the row is accepted only if every disk lies inside ``region``
    and at least ``min_gap_m`` from every other pedestrian, else other rows and pedestrians are tried.
    Returns the new positions (a copy), the groups (index arrays, in row order) and the hand links
    (L, 2): neighbours in each row (a triple's middle member holds both others, Eq. 2). Raises
    :class:`ScenarioError` when a group finds no room.
    """
    pos = np.array(position_m, dtype=np.float64)
    n = pos.shape[0]
    check_positive(radius_m=radius_m)
    if not (np.isfinite(gap_m) and gap_m >= 0) or not (np.isfinite(min_gap_m) and min_gap_m >= 0):
        raise ScenarioError(f"gap_m and min_gap_m must be finite and >= 0, got {gap_m!r}, {min_gap_m!r}")
    sizes = [check_count("group size", s, 2) for s in sizes]
    if sum(sizes) > n:
        raise ScenarioError(f"groups of sizes {sizes} need {sum(sizes)} pedestrians, but only {n} are placed")
    inner = as_polygon(region, "group region").buffer(-radius_m, join_style="mitre")
    shapely.prepare(inner)
    if callable(walking_direction):
        forward = np.asarray(walking_direction(pos), dtype=np.float64).reshape(n, 2)
    else:
        fixed = np.asarray(walking_direction, dtype=np.float64).reshape(2)
        if not np.all(np.isfinite(fixed)) or np.hypot(*fixed) <= 0:
            raise ScenarioError(f"walking_direction must be a non-zero (2,) vector or a callable, got {walking_direction!r}")
        forward = np.broadcast_to(fixed / np.hypot(*fixed), (n, 2))
    turns = np.deg2rad(float(max_turn_deg)) * np.array([0.0, 0.5, -0.5, 1.0, -1.0])
    spacing = 2.0 * radius_m + gap_m
    clearance = 2.0 * radius_m + min_gap_m - 1e-12
    free = np.ones(n, dtype=bool)
    groups, links = [], []
    for k, size in sorted(enumerate(sizes), key=lambda t: -t[1]):
        members = _fit_row(pos, free, size, spacing, clearance, inner, forward, turns, rng)
        if members is None:
            raise ScenarioError(f"no room to form group {k} of {size} side by side (gap {gap_m} m) among the "
                                f"{int(free.sum())} pedestrians not yet grouped; lower the density or the number "
                                "of groups")
        members, slots = members
        pos[members] = slots
        free[members] = False
        groups.append(members)
        links.extend(zip(members[:-1].tolist(), members[1:].tolist()))
    return pos, groups, np.array(links, dtype=np.int64).reshape(-1, 2)


def _fit_row(pos, free, size, spacing, clearance, inner, forward, turns, rng):
    """(members in row order, their new positions) of the first row that fits, or None (see form_groups)."""
    offsets = np.arange(size) * spacing
    for anchor in rng.permutation(np.flatnonzero(free)):
        cand = np.flatnonzero(free)
        cand = cand[cand != anchor]
        f = forward[anchor]
        for turn in turns:
            c, s_ = np.cos(turn), np.sin(turn)
            lateral = np.array([-(s_ * f[0] + c * f[1]), c * f[0] - s_ * f[1]])  # f turned by 90° + turn
            for j in range(size):  # the anchor's place in the row
                slots = pos[anchor] + np.outer(offsets - offsets[j], lateral)
                if not shapely.contains_xy(inner, slots[:, 0], slots[:, 1]).all():
                    continue
                members = np.empty(size, np.int64)
                members[j] = anchor
                left = cand
                for q in (q for q in range(size) if q != j):
                    nearest = int(np.argmin(np.linalg.norm(pos[left] - slots[q], axis=1)))
                    members[q] = left[nearest]
                    left = np.delete(left, nearest)
                others = np.ones(pos.shape[0], dtype=bool)
                others[members] = False
                d = np.linalg.norm(pos[others][:, None, :] - slots[None, :, :], axis=2)
                if d.size == 0 or d.min() >= clearance:
                    return members, slots
    return None


def _relax_hard_disks(pos, inner, spacing_min, step, rng, sweeps):
    """Hard-disk Monte Carlo: simultaneous random moves, each accepted if it stays inside ``inner`` and
    keeps at least ``spacing_min`` to every other disk's old and new position (so any accepted set is
    valid). The step adapts towards ~40 % acceptance, capped at twice its start so that a partly
    filled lattice does not spread out."""
    n = pos.shape[0]
    max_step = 2.0 * step
    for _ in range(sweeps):
        prop = pos + rng.uniform(-step, step, size=(n, 2))
        ok = shapely.intersects_xy(inner, prop[:, 0], prop[:, 1])
        if n > 1:
            conflict = np.zeros(n, dtype=bool)
            tree_new = cKDTree(prop)
            pairs = tree_new.query_pairs(spacing_min, output_type="ndarray")
            if pairs.size:
                close = np.linalg.norm(prop[pairs[:, 0]] - prop[pairs[:, 1]], axis=1) < spacing_min
                conflict[pairs[close].ravel()] = True
            sdm = tree_new.sparse_distance_matrix(cKDTree(pos), spacing_min, output_type="ndarray")
            bad = (sdm["i"] != sdm["j"]) & (sdm["v"] < spacing_min)
            conflict[sdm["i"][bad]] = True
            ok &= ~conflict
        pos[ok] = prop[ok]
        rate = ok.mean()
        step *= 1.25 if rate > 0.5 else (0.75 if rate < 0.3 else 1.0)
        step = min(step, max_step)
    return pos
