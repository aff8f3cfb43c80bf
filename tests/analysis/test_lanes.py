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


def test_lane_order_parameter_is_one_for_pure_lanes_and_reads_a_mix_against_its_shuffle():
    from crowd_env.analysis import lane_order_parameter, mixed_lane_order_parameter

    rng = np.random.default_rng(0)
    # four lanes 0.45 m apart (band 0.3 m), alternating directions: every lane-mate walks one's own way
    y = np.repeat([0.0, 0.45, 0.9, 1.35], 10) + rng.uniform(-0.05, 0.05, 40)
    east = np.repeat([True, False, True, False], 10)
    assert lane_order_parameter(y_m=y, eastbound=east, band_m=0.3) == 1.0
    # the same people with the directions shuffled: no lanes, Φ near the permutation reference, far below 1
    mixed = rng.permutation(east)
    phi = lane_order_parameter(y_m=y, eastbound=mixed, band_m=0.3)
    reference = mixed_lane_order_parameter(y_m=y, eastbound=east, band_m=0.3)
    assert phi < 0.5 and abs(phi - reference) < 0.25 and reference < 0.3
    # one walker alone in its band and everybody else in one lane of one direction: only lane-mates count
    assert lane_order_parameter(y_m=[0.0, 0.0, 5.0], eastbound=[True, True, False], band_m=0.3) == 1.0
    assert np.isnan(lane_order_parameter(y_m=[0.0, 5.0], eastbound=[True, False], band_m=0.3))


def test_lane_order_parameter_by_hand():
    from crowd_env.analysis import lane_order_parameter

    # three in one band, two east one west: each east walker sees (1 same, 1 opposite): φ = 0; the west one
    # sees (0 same, 2 opposite): φ = 1; Φ = 1/3
    assert lane_order_parameter(y_m=[0.0, 0.1, 0.05], eastbound=[True, True, False], band_m=0.5) == 1.0 / 3.0


def test_lane_order_parameter_names_bad_input():
    from crowd_env.analysis import LaneError, lane_order_parameter

    with pytest.raises(LaneError, match="band_m"):
        lane_order_parameter(y_m=[0.0, 1.0], eastbound=[True, False], band_m=0.0)
    with pytest.raises(LaneError, match="one shape"):
        lane_order_parameter(y_m=[0.0, 1.0], eastbound=[True], band_m=0.3)
    with pytest.raises(LaneError, match="non-finite"):
        lane_order_parameter(y_m=[0.0, np.nan], eastbound=[True, False], band_m=0.3)
