"""Densities (crowd_env.analysis.density): in an area and per frame, stationary means, and the jam density of
the force balance (Eq. 14 and 16)."""
import numpy as np
import pytest

from crowd_env.analysis import density_in_area, density_time_series, stationary_mean


def test_density_on_grid():
    g = np.arange(0.25, 4.0, 0.5)  # 8 x 8 grid, no point on the box boundary
    xx, yy = np.meshgrid(g, g)
    pts = np.c_[xx.ravel(), yy.ravel()]
    box = (1.0, 1.0, 3.0, 3.0)  # 4 x 4 points inside, area 4 m²
    assert density_in_area(pts, box) == pytest.approx(16 / 4.0)
    frame = np.r_[np.zeros(64, int), np.ones(64, int)]
    x = np.r_[pts[:, 0], pts[:, 0] + 10.0]
    y = np.r_[pts[:, 1], pts[:, 1]]
    rho = density_time_series(frame, x, y, [[1, 1], [3, 1], [3, 3], [1, 3]], n_frames=3)
    np.testing.assert_allclose(rho, [4.0, 0.0, 0.0])


def test_stationary_mean():
    t = np.arange(0.0, 100.0, 1.0)
    v = np.zeros_like(t)
    v[10:90] = 2.0
    v[10:20] = np.linspace(0, 2, 10)  # filling transient
    assert stationary_mean(v, t) == pytest.approx(2.0)
    assert stationary_mean(v, t, t_start_s=20.0, t_end_s=80.0) == pytest.approx(2.0)


def test_force_balance_jam_density():
    """Eq. 14 at rest = Eq. 16 head on: d = 2r + B ln(Aτ/(m‖u_d‖)); hexagonal packing 2/(√3 d²)."""
    from crowd_env.analysis import DensityError, force_balance_jam_density_per_m2, hexagonal_density_per_m2

    assert hexagonal_density_per_m2(0.46) == pytest.approx(5.4570, abs=1e-4)  # densest packing, r = 0.23 m
    assert hexagonal_density_per_m2(1.0) == pytest.approx(2.0 / np.sqrt(3.0))
    d = 0.46 + 0.08 * np.log(790.0 * 0.5 / (83.0 * 1.34))
    assert force_balance_jam_density_per_m2(790.0, 0.08) == pytest.approx(2.0 / (np.sqrt(3.0) * d * d), rel=1e-12)
    assert force_balance_jam_density_per_m2(790.0, 0.08) == pytest.approx(3.66, abs=0.01)
    assert force_balance_jam_density_per_m2(1150.0, 0.2) == pytest.approx(1.86, abs=0.01)
    # repulsion at contact weaker than the drive (A < m‖u_d‖/τ = 222 N): the jam packs the disks
    assert force_balance_jam_density_per_m2(100.0, 0.08) == pytest.approx(hexagonal_density_per_m2(0.46))
    # broadcasting over A and B; density falls as A or B grows
    rho = force_balance_jam_density_per_m2(np.array([400.0, 790.0, 1500.0]), 0.08)
    assert rho.shape == (3,) and np.all(np.diff(rho) < 0)
    for bad in ((0.0, 0.08), (790.0, np.nan), (790.0, -0.1)):
        with pytest.raises(DensityError, match="must be finite and > 0"):
            force_balance_jam_density_per_m2(*bad)
    with pytest.raises(DensityError, match="spacing_m"):
        hexagonal_density_per_m2(0.0)
