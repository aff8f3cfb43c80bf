"""Social repulsion (Kabalan Eq. 16): analytic cases, Newton's third law, cutoff, dense cross-check."""
import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from crowd_env.walking.social_force import (social_forces, social_forces_dense_reference, social_repulsion,
                                            wall_repulsion)
from crowd_env.walking import ModelParams
from crowd_env.core.segments import as_segments, endpoint_owners

A_N, B_M = 790.0, 0.08


def _pair_force(position, radius, desired, lam, cutoff_m=1.0, a=A_N, b=B_M):
    out = np.zeros((len(position), 2))
    pairs = np.array([[0, 1]], dtype=np.int64)
    return social_forces(np.asarray(position, float), np.asarray(radius, float), np.asarray(desired, float),
                         pairs, a, b, lam, cutoff_m, out)


def _wall_force(position, radius, desired, walls, lam, cutoff_m=1.0, a=A_N, b=B_M):
    seg = as_segments(walls)
    out = np.zeros((len(position), 2))
    return wall_repulsion(np.asarray(position, float), np.asarray(radius, float), np.asarray(desired, float),
                          seg, endpoint_owners(seg), a, b, lam, cutoff_m, out)


def test_two_pedestrians_isotropic():
    f = _pair_force([[0.0, 0.0], [0.6, 0.0]], [0.23, 0.23], [[1.0, 0.0], [-1.0, 0.0]], 1.0)
    mag = A_N * math.exp((0.46 - 0.6) / B_M)
    np.testing.assert_allclose(f, [[-mag, 0.0], [mag, 0.0]], rtol=1e-14)


def test_two_pedestrians_anisotropic():
    lam, phi = 0.3, math.pi / 3
    # i = 0 sees j along +x; its desired direction makes angle phi with it. j sees i straight behind.
    desired = [[math.cos(phi), math.sin(phi)], [1.0, 0.0]]
    pos = np.array([[1.0, 2.0], [1.0 + 0.5 * math.cos(0.0), 2.0]])
    f = _pair_force(pos, [0.2, 0.25], desired, lam)
    mag = A_N * math.exp((0.45 - 0.5) / B_M)
    w_i = lam + (1 - lam) * (1 + math.cos(phi)) / 2
    w_j = lam  # cos(pi) = -1
    np.testing.assert_allclose(f[0], [-mag * w_i, 0.0], rtol=1e-14, atol=1e-12)
    np.testing.assert_allclose(f[1], [mag * w_j, 0.0], rtol=1e-14, atol=1e-12)


def test_neighbour_ahead_counts_fully_behind_counts_lambda():
    lam = 0.2
    pos = [[0.0, 0.0], [0.0, 0.7]]  # j directly "north" of i
    ahead = _pair_force(pos, [0.23, 0.23], [[0.0, 1.0], [0.0, 1.0]], lam)
    iso = _pair_force(pos, [0.23, 0.23], [[0.0, 1.0], [0.0, 1.0]], 1.0)
    np.testing.assert_allclose(ahead[0], iso[0], rtol=1e-14)  # j ahead of i: weight 1
    np.testing.assert_allclose(ahead[1], lam * iso[1], rtol=1e-14)  # i behind j: weight lambda


def test_pedestrian_near_wall_analytic():
    lam = 0.5
    f = _wall_force([[0.5, 0.4]], [0.23], [[1.0, 0.0]], [[0.0, 0.0, 2.0, 0.0]], lam, a=300.0, b=0.1)
    w = lam + (1 - lam) * 0.5  # wall point straight to the side: cos(phi) = 0
    np.testing.assert_allclose(f[0], [0.0, 300.0 * math.exp(-0.17 / 0.1) * w], rtol=1e-13, atol=1e-12)
    # Walking straight at the wall: full weight.
    f = _wall_force([[0.5, 0.4]], [0.23], [[0.0, -1.0]], [[0.0, 0.0, 2.0, 0.0]], lam, a=300.0, b=0.1)
    np.testing.assert_allclose(f[0], [0.0, 300.0 * math.exp(-0.17 / 0.1)], rtol=1e-13, atol=1e-12)


@pytest.mark.parametrize("walls", [
    [[0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]],
    [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]],
    [[0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]],
])
def test_convex_corner_vertex_counted_once(walls):
    lam = 0.6
    pos, r = np.array([[-0.3, -0.4]]), 0.23  # both walls' closest point is the shared vertex (0, 0)
    desired = np.array([[1.0, 0.0]])
    f = _wall_force(pos, [r], desired, walls, lam)
    normal = np.array([-0.6, -0.8])
    w = lam + (1 - lam) * (1 + desired[0] @ (-normal)) / 2
    np.testing.assert_allclose(f[0], A_N * math.exp(-(0.5 - r) / B_M) * w * normal, rtol=1e-13)


def test_cutoff_respected():
    r, cutoff = 0.23, 0.3
    far = _pair_force([[0.0, 0.0], [2 * r + cutoff + 1e-9, 0.0]], [r, r], [[1, 0], [1, 0]], 1.0, cutoff)
    near = _pair_force([[0.0, 0.0], [2 * r + cutoff - 1e-9, 0.0]], [r, r], [[1, 0], [1, 0]], 1.0, cutoff)
    assert np.all(far == 0.0)
    assert np.all(near[:, 0] != 0.0)
    wall = [[-1.0, 0.0, 1.0, 0.0]]
    assert np.all(_wall_force([[0.0, r + cutoff + 1e-9]], [r], [[1, 0]], wall, 1.0, cutoff) == 0.0)
    assert _wall_force([[0.0, r + cutoff - 1e-9]], [r], [[1, 0]], wall, 1.0, cutoff)[0, 1] > 0.0


def _random_crowd(rng, n):
    """Non-overlapping disks in a 6 m x 4 m box (rejection sampling), random desired directions."""
    radius = rng.uniform(0.18, 0.28, n)
    pos = np.empty((n, 2))
    k = 0
    while k < n:
        p = rng.uniform([0.3, 0.3], [5.7, 3.7])
        if k == 0 or np.all(np.hypot(*(pos[:k] - p).T) > radius[:k] + radius[k]):
            pos[k] = p
            k += 1
    angle = rng.uniform(-np.pi, np.pi, n)
    return pos, radius, np.c_[np.cos(angle), np.sin(angle)]


def _pairs(pos, radius, cutoff_m):
    return cKDTree(pos).query_pairs(2 * radius.max() + cutoff_m, output_type="ndarray").astype(np.int64)


def test_newton_third_law_isotropic():
    rng = np.random.default_rng(1)
    pos, radius, desired = _random_crowd(rng, 60)
    out = np.zeros((60, 2))
    social_forces(pos, radius, desired, _pairs(pos, radius, 1.0), A_N, B_M, 1.0, 1.0, out)
    scale = np.abs(out).sum()
    assert scale > 0
    assert np.all(np.abs(out.sum(axis=0)) <= 1e-9 * scale)


# Room walls, a square pillar (closed polygon: four shared corners) and a reversed-orientation wall.
WALLS = np.array([
    [0.0, 0.0, 6.0, 0.0], [6.0, 0.0, 6.0, 4.0], [6.0, 4.0, 0.0, 4.0], [0.0, 4.0, 0.0, 0.0],
    [2.5, 1.5, 3.5, 1.5], [3.5, 1.5, 3.5, 2.5], [3.5, 2.5, 2.5, 2.5], [2.5, 2.5, 2.5, 1.5],
    [4.5, 3.2, 4.5, 2.9],
])


def _groups(params):
    """The social force's and the walls' groups of ``params`` (what social_repulsion takes)."""
    return params.walking.social, params.walking.wall_social


@pytest.mark.parametrize("seed,lam,cutoff", [(2, 1.0, 1.0), (3, 0.3, 0.5), (4, 0.0, 2.0)])
def test_kernel_matches_dense_reference(seed, lam, cutoff):
    rng = np.random.default_rng(seed)
    pos, radius, desired = _random_crowd(rng, 40)
    inside_pillar = (pos[:, 0] > 2.5 - radius) & (pos[:, 0] < 3.5 + radius) & \
                    (pos[:, 1] > 1.5 - radius) & (pos[:, 1] < 2.5 + radius)
    pos, radius, desired = pos[~inside_pillar], radius[~inside_pillar], desired[~inside_pillar]
    desired[::7] = 0.0  # pedestrians without a desired direction
    params = ModelParams(social_strength_n=A_N, social_range_m=B_M, social_anisotropy=lam, social_cutoff_m=cutoff,
                         wall_social_strength_n=500.0, wall_social_range_m=0.12)
    seg = as_segments(WALLS)
    got = social_repulsion(pos, radius, desired, _pairs(pos, radius, cutoff), seg, endpoint_owners(seg), *_groups(params))
    want = social_forces_dense_reference(pos, radius, desired, seg, A_N, B_M, lam, cutoff,
                                         wall_strength_n=500.0, wall_range_m=0.12)
    scale = np.abs(want).max()
    assert scale > 0
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * scale)


def test_wall_repulsion_index_subset_and_empty_inputs():
    pos = np.array([[0.5, 0.4], [1.0, 0.4]])
    seg = as_segments([[0.0, 0.0, 2.0, 0.0]])
    out = np.zeros((2, 2))
    wall_repulsion(pos, np.full(2, 0.23), np.zeros((2, 2)), seg, endpoint_owners(seg), A_N, B_M, 1.0, 1.0, out,
                   index=np.array([1]))
    assert np.all(out[0] == 0.0) and out[1, 1] > 0.0
    none = social_repulsion(pos, np.full(2, 0.23), np.zeros((2, 2)), np.zeros((0, 2), np.int64),
                            as_segments([]), endpoint_owners(as_segments([])), *_groups(ModelParams()))
    assert np.all(none == 0.0)
    as_set = social_repulsion(pos, np.full(2, 0.23), np.zeros((2, 2)), {(0, 1)}, as_segments([]),
                              endpoint_owners(as_segments([])), *_groups(ModelParams()))
    assert as_set[0, 0] < 0.0 < as_set[1, 0]
    with pytest.raises(ValueError, match="outside"):
        social_repulsion(pos, np.full(2, 0.23), np.zeros((2, 2)), [[0, 2]], as_segments([]),
                         endpoint_owners(as_segments([])), *_groups(ModelParams()))


def test_lateral_range_scale_shortens_the_range_beside_only():
    """B(φ) = B √(cos²φ + s² sin²φ): a neighbour straight ahead feels B, one straight beside s B, one at 60° the
    ellipse's range between them; s = 1 is Eq. 16 to the bit."""
    s, lam = 0.4, 0.3
    out = lambda pos, desired, scale: social_forces(np.asarray(pos, float), np.array([0.23, 0.23]),
                                                     np.asarray(desired, float), np.array([[0, 1]], np.int64),
                                                     A_N, B_M, lam, 1.0, np.zeros((2, 2)), 0.0, scale)
    gap = 0.6 - 0.46
    beside = out([[0.0, 0.0], [0.6, 0.0]], [[0.0, 1.0], [0.0, 1.0]], s)  # each sees the other at 90°
    w = lam + (1 - lam) * 0.5
    np.testing.assert_allclose(beside, [[-A_N * math.exp(-gap / (s * B_M)) * w, 0.0],
                                        [A_N * math.exp(-gap / (s * B_M)) * w, 0.0]], rtol=1e-13)
    ahead = out([[0.0, 0.0], [0.0, 0.6]], [[0.0, 1.0], [0.0, 1.0]], s)  # j ahead of i, i behind j: B for both
    np.testing.assert_array_equal(ahead, out([[0.0, 0.0], [0.0, 0.6]], [[0.0, 1.0], [0.0, 1.0]], 1.0))
    phi = math.pi / 3
    oblique = out([[0.0, 0.0], [0.6 * math.sin(phi), 0.6 * math.cos(phi)]], [[0.0, 1.0], [0.0, 1.0]], s)
    b_i = B_M * math.sqrt(math.cos(phi) ** 2 + s ** 2 * math.sin(phi) ** 2)
    w_i = lam + (1 - lam) * (1 + math.cos(phi)) / 2
    assert np.hypot(*oblique[0]) == pytest.approx(A_N * math.exp(-gap / b_i) * w_i, rel=1e-13)
    rng = np.random.default_rng(4)
    pos = rng.uniform(0, 3, (12, 2))
    radius = np.full(12, 0.2)
    desired = rng.normal(size=(12, 2))
    desired /= np.linalg.norm(desired, axis=1)[:, None]
    pairs = np.array(sorted(cKDTree(pos).query_pairs(1.4)), np.int64)
    got = social_forces(pos, radius, desired, pairs, A_N, B_M, lam, 1.0, np.zeros((12, 2)), 0.0, s)
    ref = social_forces_dense_reference(pos, radius, desired, np.zeros((0, 4)), A_N, B_M, lam, 1.0,
                                        lateral_range_scale=s)
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12)
    with pytest.raises(ValueError, match="social_lateral_range_scale"):
        ModelParams(social_lateral_range_scale=1.5)
    assert ModelParams(social_lateral_range_scale=0.5).walking.social.lateral_range_scale == 0.5
