"""The time-to-collision interaction (Karamouzas, Skinner & Guy 2014): τ against closed forms, the force against a
finite-difference gradient of E(τ), its symmetries, and the compiled rollout against stepping."""
import math

import numpy as np
import pytest

from crowd_env.walking import ModelParams
from crowd_env.errors import ParameterError
from crowd_env.walking.time_to_collision import (TimeToCollision, time_to_collision_s, total_ttc_accelerations,
                                                 ttc_acceleration)

K, TAU0, CAP = 1.5, 3.0, 1e9


def _energy(x, y, vx, vy, r, k=K, tau0=TAU0):
    tau = time_to_collision_s(x, y, vx, vy, r)
    return k / tau**2 * math.exp(-tau / tau0)


def test_time_to_collision_closed_forms():
    # head-on: 4 m apart, closing at 2 m/s, R = 0.46 -> (4 - 0.46) / 2
    assert time_to_collision_s(4.0, 0.0, -2.0, 0.0, 0.46) == pytest.approx(1.77)
    # offset by 0.3 m laterally: contact when the longitudinal gap is sqrt(R² - 0.09)
    assert time_to_collision_s(4.0, 0.3, -2.0, 0.0, 0.46) == pytest.approx((4.0 - math.sqrt(0.46**2 - 0.09)) / 2.0)
    assert time_to_collision_s(4.0, 0.5, -2.0, 0.0, 0.46) == math.inf  # passes beside
    assert time_to_collision_s(4.0, 0.0, 2.0, 0.0, 0.46) == math.inf  # moving apart
    assert time_to_collision_s(4.0, 0.0, 0.0, 0.0, 0.46) == math.inf  # same velocity
    assert time_to_collision_s(0.4, 0.0, -1.0, 0.0, 0.46) == 0.0  # overlapping and closing


@pytest.mark.parametrize("x, y, vx, vy", [(3.0, 0.2, -1.3, 0.1), (-2.0, 1.0, 1.0, -0.4), (1.2, -0.3, -0.5, 0.3)])
def test_force_is_minus_the_gradient_of_the_energy(x, y, vx, vy):
    r = 0.46
    fx, fy = ttc_acceleration(x, y, vx, vy, r, K, TAU0, CAP)
    h = 1e-6
    gx = (_energy(x + h, y, vx, vy, r) - _energy(x - h, y, vx, vy, r)) / (2 * h)
    gy = (_energy(x, y + h, vx, vy, r) - _energy(x, y - h, vx, vy, r)) / (2 * h)
    assert fx == pytest.approx(-gx, rel=1e-5) and fy == pytest.approx(-gy, rel=1e-5)
    # a head-on approach is pushed back along the line of centres, away from the other
    fx0, fy0 = ttc_acceleration(3.0, 0.0, -1.3, 0.0, r, K, TAU0, CAP)
    assert fx0 > 0.0 and fy0 == 0.0


def test_no_interaction_without_a_collision_ahead_and_the_cap():
    assert ttc_acceleration(3.0, 0.0, 1.0, 0.0, 0.46, K, TAU0, CAP) == (0.0, 0.0)  # moving apart
    assert ttc_acceleration(3.0, 0.0, 0.0, 0.0, 0.46, K, TAU0, CAP) == (0.0, 0.0)  # same velocity
    assert ttc_acceleration(3.0, 1.0, -1.0, 0.0, 0.46, K, TAU0, CAP) == (0.0, 0.0)  # passing beside
    assert ttc_acceleration(0.4, 0.0, -1.0, 0.0, 0.46, K, TAU0, CAP) == (0.0, 0.0)  # touching: the contacts' job
    fx, fy = ttc_acceleration(0.5, 0.0, -2.0, 0.0, 0.46, K, TAU0, 4.0)
    assert math.hypot(fx, fy) == pytest.approx(4.0)


def test_pair_sum_is_antisymmetric_and_range_limited():
    pos = np.array([[0.0, 0.0], [2.0, 0.1], [10.0, 0.0]])
    vel = np.array([[1.3, 0.0], [-1.0, 0.0], [-1.0, 0.0]])
    radius = np.full(3, 0.23)
    pairs = np.array([[0, 1], [0, 2], [1, 2]], np.int64)
    acc = total_ttc_accelerations(pos, vel, radius, np.arange(3), pairs, 0.0, TimeToCollision(K, TAU0, 3.0, CAP))
    fx, fy = ttc_acceleration(-2.0, -0.1, 2.3, 0.0, 0.46, K, TAU0, CAP)
    np.testing.assert_allclose(acc[0], [fx, fy])
    np.testing.assert_allclose(acc[1], [-fx, -fy])
    assert np.all(acc[2] == 0.0)  # 8 m from the nearest: beyond the range
    # across a periodic seam (period 12 m) the third is 2 m behind the first and closing: it interacts
    wrapped = total_ttc_accelerations(pos, np.array([[1.3, 0.0], [-1.0, 0.0], [2.0, 0.0]]), radius, np.arange(3),
                                      pairs, 12.0, TimeToCollision(K, TAU0, 3.0, CAP))
    assert wrapped[2, 0] < 0.0


def test_ttc_parameters_are_checked():
    with pytest.raises(ParameterError, match="ttc_strength_m2_s2"):
        ModelParams(ttc_strength_m2_s2=-1.0)
    with pytest.raises(ParameterError, match="ttc_horizon_s"):
        ModelParams(ttc_horizon_s=0.0)


def test_compiled_rollout_equals_stepping_with_ttc():
    """The compiled rollout and Python stepping run the same interaction, to the last bit, and it acts."""
    from crowd_env.walking.presets import get_preset

    from .rollout_check import assert_rollout_equals_stepping

    assert_rollout_equals_stepping(get_preset("calibrated").params(ttc_strength_m2_s2=1.5))
