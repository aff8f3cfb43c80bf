"""The external interior point projection (crowd_env.core.solvers.external.project_gaps_ipm, PIQP) on
degenerate jammed packings, against the augmented Lagrangian's exact projection."""
import numpy as np
import pytest

from crowd_env.core.solvers.external import IPM_TOL_M_S, project_gaps_ipm
from tests.core.conftest import H, gap_residual, jam_and_exact_projection, percussion


@pytest.mark.parametrize("seed", range(4))
def test_interior_point_projection_agrees_with_the_exact_one(seed):
    """project_gaps_ipm (PIQP) on degenerate jams: feasible to its tolerance, multipliers ≥ 0 that satisfy
    stationarity M (v − v') = B_nᵀ λ, and v within 1e-6 m/s of the augmented Lagrangian's exact v."""
    vel, mass, a, b, gap, nx, ny, v_exact = jam_and_exact_projection(seed)
    v = vel.copy()
    lam, ok = project_gaps_ipm(v, mass, a, b, gap, nx, ny, H)
    assert ok
    assert gap_residual(v, a, b, gap, nx, ny).min() >= -IPM_TOL_M_S
    np.testing.assert_allclose(v, v_exact, atol=1e-6)
    assert lam.min() >= 0.0
    np.testing.assert_allclose(mass[:, None] * (v[:, :2] - vel[:, :2]), percussion(v.shape[0], lam, a, b, nx, ny),
                               atol=1e-6 * mass.max())
    np.testing.assert_array_equal(v[:, 2], vel[:, 2])  # rotation untouched


def test_interior_point_projection_without_candidates():
    v = np.ones((3, 3))
    lam, ok = project_gaps_ipm(v, np.ones(3), np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0), np.zeros(0),
                               np.zeros(0), H)
    assert ok and lam.shape == (0,) and np.all(v == 1.0)
