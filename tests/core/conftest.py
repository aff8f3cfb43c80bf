"""Shared helpers of the core tests: degenerate jammed packings and the checks of a gap projection on them
(tests/core/test_large_projection.py, test_external.py, test_cascade_jams.py)."""
import numpy as np

from crowd_env.core.solvers.large_projection import project_gaps_alm
from crowd_env.core.solvers.status import STATUS_OK


H = 0.01


def hex_jam(rows, cols, rng, squeeze=0.0):
    """Disks of radius 0.25 m on a slightly jittered (1e-9 m) triangular lattice in a box, all touching,
    pushed together: about three contacts per disk, degenerate. (A perfect lattice with gaps exactly 0
    makes the ALM multipliers stall: it then reports STATUS_MAX_ITER and the simulator falls back.)"""
    r = 0.25
    pos = np.array([[2 * r * c + (r if k % 2 else 0.0), np.sqrt(3) * r * k] for k in range(rows) for c in range(cols)])
    pos += rng.normal(0.0, 1e-9, pos.shape)
    n = pos.shape[0]
    a, b, gap, nx, ny = [], [], [], [], []
    for i in range(n):
        for j in range(i + 1, n):
            d = pos[i] - pos[j]
            dist = np.hypot(*d)
            if dist < 2 * r + 0.05:
                a.append(i), b.append(j), gap.append(dist - 2 * r - squeeze * rng.random() * 1e-13)
                nx.append(d[0] / dist), ny.append(d[1] / dist)
    lo, hi = pos.min(axis=0) - r, pos.max(axis=0) + r
    for i in range(n):  # walls: left, right, bottom, top (normals into the box)
        for g, (ux, uy) in ((pos[i, 0] - r - lo[0], (1, 0)), (hi[0] - pos[i, 0] - r, (-1, 0)),
                            (pos[i, 1] - r - lo[1], (0, 1)), (hi[1] - pos[i, 1] - r, (0, -1))):
            if g < 0.05:
                a.append(i), b.append(-1), gap.append(g), nx.append(ux), ny.append(uy)
    vel = np.zeros((n, 3))
    vel[:, :2] = rng.normal(0.0, 1.0, (n, 2)) + [1.5, 0.5]  # towards a corner
    mass = rng.uniform(50.0, 100.0, n)
    return vel, mass, np.array(a), np.array(b), np.array(gap), np.array(nx), np.array(ny)


def gap_residual(v, a, b, gap, nx, ny):
    vb = np.where((b >= 0)[:, None], v[np.maximum(b, 0), :2], 0.0)
    return gap / H + ((v[a, :2] - vb) * np.stack([nx, ny], axis=1)).sum(axis=1)


def percussion(n, lam, a, b, nx, ny):
    """B_nᵀ λ (n, 2): what stationarity M (v − v') = B_nᵀ λ asks the velocity change to be."""
    out = np.zeros((n, 2))
    normal = np.stack([nx, ny], axis=1)
    np.add.at(out, a, lam[:, None] * normal)
    np.add.at(out, b[b >= 0], -(lam[b >= 0, None] * normal[b >= 0]))
    return out


def jam_and_exact_projection(seed):
    """A degenerate jam of (8 + seed) × 10 disks (squeezed for odd seeds) and the augmented
    Lagrangian's exact projected velocities: ``(vel, mass, a, b, gap, nx, ny, v_exact)``."""
    rng = np.random.default_rng(seed)
    vel, mass, a, b, gap, nx, ny = hex_jam(8 + seed, 10, rng, squeeze=float(seed % 2))
    v_exact = vel.copy()
    _, _, status = project_gaps_alm(v_exact, mass, a, b, gap, nx, ny, H, np.zeros(a.shape[0]), 400)
    assert status == STATUS_OK
    return vel, mass, a, b, gap, nx, ny, v_exact
