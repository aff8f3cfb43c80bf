"""The compiled Cholesky kernels (crowd_env.core.solvers.linalg) against numpy's LAPACK on random envelopes."""
import numpy as np
import pytest

from crowd_env.core.solvers.linalg import cholesky, cholesky_solve, dot_range, envelope_cholesky, envelope_solve, profile_cholesky


def random_envelope_spd(n, rng, paired=False):
    """SPD matrix whose row i is zero left of first[i] (a random non-decreasing envelope). ``paired``:
    rows 2k and 2k + 1 start at the same column (the x and y of one body in the projection), which
    sends :func:`envelope_cholesky` through its 2×2 blocks."""
    first = np.minimum(np.maximum.accumulate(rng.integers(0, n, n)), np.arange(n))
    if paired:
        first[1::2] = first[0::2][: n // 2]
    A = np.zeros((n, n))
    for i in range(n):
        A[i, first[i]:i] = rng.standard_normal(i - first[i])
    A = A + A.T
    A += np.diag(np.abs(A).sum(axis=1) + 1.0)  # diagonally dominant: SPD
    return A, first


@pytest.mark.parametrize("paired", [False, True])
@pytest.mark.parametrize("n", [1, 2, 7, 33, 80])
def test_profile_and_envelope_cholesky_match_lapack(n, paired):
    rng = np.random.default_rng(n)
    A, first = random_envelope_spd(n, rng, paired)
    if paired and n > 2:  # the 2×2 blocks are really taken
        assert np.count_nonzero(first[1:] == first[:-1]) >= n // 3
    L_ref = np.linalg.cholesky(A)
    np.testing.assert_allclose(profile_cholesky(A, first), L_ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(cholesky(A), L_ref, rtol=1e-12, atol=1e-12)
    off = np.concatenate([[0], np.cumsum(np.arange(n) - first + 1)])
    env = np.concatenate([A[i, first[i]:i + 1] for i in range(n)])
    envelope_cholesky(env, off, first)
    for i in range(n):
        np.testing.assert_allclose(env[off[i]:off[i + 1]], L_ref[i, first[i]:i + 1], rtol=1e-12, atol=1e-12)
    b = rng.standard_normal(n)
    x_ref = np.linalg.solve(A, b)
    np.testing.assert_allclose(cholesky_solve(L_ref, b), x_ref, rtol=1e-10, atol=1e-12)
    x = b.copy()
    envelope_solve(env, off, first, x)
    np.testing.assert_allclose(x, x_ref, rtol=1e-10, atol=1e-12)


def test_non_positive_definite_matrix_raises():
    with pytest.raises(ValueError, match="not positive definite"):
        cholesky(np.array([[1.0, 2.0], [2.0, 1.0]]))


def test_dot_range_offsets_and_empty_ranges():
    a = np.arange(10.0)
    b = np.arange(10.0, 20.0)
    assert dot_range(a, 3, b, 5, 4) == pytest.approx(sum(a[3 + t] * b[5 + t] for t in range(4)))
    assert dot_range(a, 3, b, 5, 0) == 0.0
    assert dot_range(a, 3, b, 5, -2) == 0.0
