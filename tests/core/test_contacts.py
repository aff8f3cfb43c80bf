"""Contact detection between pedestrians (crowd_env.core.contacts): the candidate pairs against the full test
written independently with numpy. (Walls: tests/core/test_segments.py.)"""
import numpy as np
import pytest

from crowd_env.core.contacts import pair_candidates


@pytest.mark.parametrize("period_m", [0.0, 9.0])
def test_pair_candidates_are_the_full_tests_to_the_bit(period_m):
    """pair_candidates leaves a pair beyond its limit before the root: its candidates are those of the full test
    (gap = ‖x_i − x_j‖ − r_i − r_j ≤ m_i + m_j − ε, m = ε + 2h‖u‖), with the same gap, normal and distance to the
    bit, written here with numpy, on every pair of a crowd (most far apart, some at the limit ± 1 ulp)."""
    rng = np.random.default_rng(3)
    n = 120
    pos = rng.uniform(0.0, 9.0, (n, 2))
    radius = rng.uniform(0.2, 0.3, n)
    speed = rng.uniform(0.0, 2.0, n)
    eps, h = 0.02, 0.01
    margin = eps + 2.0 * h * speed
    for a in range(0, 40, 2):  # partner a + 1 at the limit exactly, and 1 ulp either side
        gap = margin[a] + margin[a + 1] - eps
        d = np.nextafter(gap + radius[a] + radius[a + 1], [-np.inf, 0.0, np.inf][a % 3])
        pos[a + 1] = pos[a] + [d, 0.0]
    pairs = np.array([(i, j) for i in range(n) for j in range(i + 1, n)], np.int64)
    idx = np.arange(n)
    got = pair_candidates(pos, radius, speed, pairs, idx, eps, h, np.empty(n), period_m)

    dx = pos[pairs[:, 0], 0] - pos[pairs[:, 1], 0]
    if period_m:
        dx = dx - period_m * np.floor(dx / period_m + 0.5)
    dy = pos[pairs[:, 0], 1] - pos[pairs[:, 1], 1]
    d = np.sqrt(dx * dx + dy * dy)
    gap = d - radius[pairs[:, 0]] - radius[pairs[:, 1]]
    keep = ~(gap > margin[pairs[:, 0]] + margin[pairs[:, 1]] - eps)
    want = (pairs[keep, 0], pairs[keep, 1], gap[keep], dx[keep] / d[keep], dy[keep] / d[keep], d[keep])
    assert 20 < keep.sum() < len(pairs) // 10  # the limit cases kept, most pairs left
    for x, y in zip(got, want):
        np.testing.assert_array_equal(np.asarray(x).view(np.int64), np.asarray(y).view(np.int64))
