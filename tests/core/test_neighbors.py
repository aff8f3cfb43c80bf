"""The cell-grid broad phase (crowd_env.core.neighbors) against brute force: pairs within a radius, the k
nearest, and the pairs around a few pedestrians."""
import numpy as np
import pytest


@pytest.mark.parametrize("layout", ["uniform", "clustered", "spread", "duplicates"])
def test_grid_pairs_match_brute_force(layout):
    """The cell-grid broad phase returns exactly the pairs within the radius (each once, i < j)."""
    from crowd_env.core.neighbors import grid_pairs

    rng = np.random.default_rng(7)
    if layout == "uniform":
        pos = rng.uniform(0, 10, (400, 2))
    elif layout == "clustered":
        pos = np.concatenate([rng.normal(c, 0.3, (80, 2)) for c in ([0, 0], [5, 5], [5.2, 5.1])])
    elif layout == "spread":  # thin crowd over a huge area: the grid must coarsen, not explode
        pos = np.concatenate([rng.uniform(0, 1e5, (50, 2)), rng.uniform(0, 1, (50, 2))])
    else:
        pos = np.repeat(rng.uniform(0, 2, (30, 2)), 3, axis=0)
    index = np.sort(rng.choice(pos.shape[0], pos.shape[0] * 3 // 4, replace=False)).astype(np.int64)
    radius = 0.6
    got = grid_pairs(pos, index, radius)
    d = np.linalg.norm(pos[index][:, None] - pos[index][None], axis=-1)
    ii, jj = np.nonzero(np.triu(d <= radius, k=1))
    assert np.all(got[:, 0] < got[:, 1])
    assert sorted(map(tuple, got.tolist())) == sorted(zip(ii.tolist(), jj.tolist()))
    assert grid_pairs(pos, index[:1], radius).shape == (0, 2)
    assert grid_pairs(pos, index, 0.0).shape == (0, 2)


@pytest.mark.parametrize("layout", ["uniform", "clustered", "spread", "duplicates"])
@pytest.mark.parametrize("k", [1, 6, 40])
def test_grid_k_nearest_matches_brute_force(layout, k):
    """The ring search on the cell grid returns, for every query, the k nearest others within the radius,
    nearest first (as distances: ties may come in either order), −1 padding where fewer are in reach;
    queries may lie outside the searched set and outside its bounding box."""
    from crowd_env.core.neighbors import grid_k_nearest

    rng = np.random.default_rng(11)
    if layout == "uniform":
        pos = rng.uniform(0, 10, (400, 2))
    elif layout == "clustered":
        pos = np.concatenate([rng.normal(c, 0.3, (80, 2)) for c in ([0, 0], [5, 5], [5.2, 5.1])])
    elif layout == "spread":
        pos = np.concatenate([rng.uniform(0, 1e5, (50, 2)), rng.uniform(0, 1, (50, 2))])
    else:
        pos = np.repeat(rng.uniform(0, 2, (30, 2)), 3, axis=0)
    pos = np.concatenate([pos, [[-3.0, -3.0], [20.0, 4.0]]])  # two queries outside every bounding box
    n = pos.shape[0]
    index = np.sort(rng.choice(n - 2, (n - 2) * 3 // 4, replace=False)).astype(np.int64)
    query = np.concatenate([rng.choice(n - 2, 60), [n - 2, n - 1]]).astype(np.int64)
    radius = 1.5
    got = grid_k_nearest(pos, index, query, k, radius)
    assert got.shape == (query.size, k)
    for a, q in enumerate(query):
        d = np.linalg.norm(pos[index] - pos[q], axis=1)
        others = (index != q) & (d <= radius)
        want = np.sort(d[others])[:k]
        rows = got[a][got[a] >= 0]
        assert np.all(got[a][rows.size:] == -1)
        assert not np.any(index[rows] == q)
        np.testing.assert_allclose(d[rows], want, rtol=0, atol=1e-12)
    assert np.all(grid_k_nearest(pos, index[:0], query, k, radius) == -1)
    far = np.concatenate([pos, [[np.nan, 1.0], [np.inf, 0.0]]])
    assert np.all(grid_k_nearest(far, index, np.array([n, n + 1]), k, radius) == -1)
    assert np.all(grid_k_nearest(pos, index, query, k, 0.0) == -1)


def test_grid_pairs_around_match_the_full_list():
    """The neighbours of a few pedestrians equal the pairs of the full list that involve them."""
    from crowd_env.core.neighbors import grid_pairs, grid_pairs_around

    rng = np.random.default_rng(11)
    pos = rng.uniform(0, 12, (600, 2))
    index = np.sort(rng.choice(600, 500, replace=False)).astype(np.int64)
    full = grid_pairs(pos, index, 0.7)
    for rows in (np.array([3], np.int64), np.sort(rng.choice(500, 40, replace=False)).astype(np.int64),
                 np.arange(500, dtype=np.int64)):
        marked = np.zeros(500, bool)
        marked[rows] = True
        want = sorted(map(tuple, full[marked[full[:, 0]] | marked[full[:, 1]]].tolist()))
        assert sorted(map(tuple, grid_pairs_around(pos, index, rows, 0.7).tolist())) == want
    assert grid_pairs_around(pos, index, np.zeros(0, np.int64), 0.7).shape == (0, 2)
