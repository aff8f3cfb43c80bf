"""Heading angles (crowd_env.core.angles): the compiled atan2."""
import math

import numpy as np


def test_direction_angles_are_the_compiled_atan2_bitwise():
    """direction_angles_rad (the env's and the baseline's headings) is C's atan2 element by element, bit
    for bit (numpy's vectorised arctan2 need not be), on every quadrant, the axes and the zero vector."""
    from crowd_env.core.angles import direction_angles_rad

    rng = np.random.default_rng(5)
    vectors = np.concatenate([rng.normal(size=(20_000, 2)), [[0.0, 0.0], [1.0, 0.0], [-1.0, 0.0], [0.0, -2.0]]])
    angles = direction_angles_rad(vectors)
    expected = np.array([math.atan2(y, x) for x, y in vectors])
    assert np.array_equal(angles, expected)
    assert angles[-4] == 0.0 and angles[-2] == math.pi and angles[-1] == -math.pi / 2
    np.testing.assert_allclose(angles, np.arctan2(vectors[:, 1], vectors[:, 0]), rtol=0, atol=1e-15)
