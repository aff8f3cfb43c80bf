"""The experiment's table (crowd_env.analysis.experiment): Seyfried 2009 as shipped and the residual norms of
the linear fits J(b) (Kabalan Table 3)."""
import numpy as np
import pytest

from crowd_env.analysis import (PUBLISHED_SPECIFIC_FLOW_N60_PER_M_S, RESIDUAL_NORM_BY_GROUP, linear_fit,
                                linear_fit_residual_norm, seyfried_2009)


def test_shipped_table_and_residual_norms():
    t = seyfried_2009()
    assert "Seyfried" in t.source and len(t) == 5 and set(t.n_pedestrians.tolist()) == {60}
    np.testing.assert_allclose(t.flow_per_s, 60 / t.dt_s, rtol=1e-8)
    np.testing.assert_allclose(t.specific_flow_per_m_s, t.flow_per_s / t.width_m, rtol=1e-8)
    np.testing.assert_allclose(np.round(t.specific_flow_per_m_s, 2), PUBLISHED_SPECIFIC_FLOW_N60_PER_M_S, atol=1e-9)
    # Kabalan Table 3 (0.098) is reproduced by J = b * (published two-decimal J_s): 0.0978.
    published_flow = t.width_m * np.asarray(PUBLISHED_SPECIFIC_FLOW_N60_PER_M_S)
    assert linear_fit_residual_norm(t.width_m, published_flow) == pytest.approx(0.0978, abs=1e-3)
    assert linear_fit_residual_norm(t.width_m, published_flow) == pytest.approx(RESIDUAL_NORM_BY_GROUP[60], abs=1e-3)
    # The full-precision flows N / Δt give 0.0997 (still within 2e-3 of Table 3).
    fit = linear_fit(t.width_m, t.flow_per_s)
    assert fit.residual_norm == pytest.approx(0.0997, abs=1e-3)
    assert fit.slope == pytest.approx(2.60, abs=0.01)
