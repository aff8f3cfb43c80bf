"""Lanes (crowd_env.analysis.lanes): the lateral histogram in the channel and its peaks."""
import numpy as np
import pytest

from crowd_env.analysis import detect_lanes, lateral_histogram


def _channel_samples(rng, centres, n=20000, half_width=0.4):
    y = rng.normal(rng.choice(centres, n), 0.06)
    y = y[np.abs(y) < half_width]
    return rng.uniform(0.0, 2.8, y.size), y


@pytest.mark.parametrize("centres,expected", [((0.0,), 1), ((-0.2, 0.2), 2), ((-0.35, 0.15), 2)])
def test_lanes_unimodal_vs_bimodal(centres, expected):
    rng = np.random.default_rng(7)
    x, y = _channel_samples(rng, centres)
    hist = lateral_histogram(x, y, (0.0, -0.4, 2.8, 0.4))
    assert hist.centers_m.size == 80 and np.diff(hist.centers_m) == pytest.approx(0.01)
    assert hist.probability.sum() == pytest.approx(1.0)
    lanes = detect_lanes(hist.centers_m, hist.probability)
    assert lanes.n_lanes == expected
    np.testing.assert_allclose(lanes.peak_positions_m, centres, atol=0.03)
