"""Wall segments (crowd_env.core.segments): a vertex shared by two segments counts once, whatever their
order and orientation, in the wall repulsion, the wall proximity query and the contact detection."""
import math

import numpy as np
import pytest

from crowd_env.core.contacts import detect_contacts
from crowd_env.core.segments import as_segments, endpoint_owners, wall_proximity
from crowd_env.walking.social_force import wall_repulsion


CORNER_WALLS = [[0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]


def _corner_force(walls, pos):
    seg = as_segments(walls)
    out = np.zeros((len(pos), 2))
    return wall_repulsion(np.asarray(pos, float), np.full(len(pos), 0.23), np.zeros((len(pos), 2)), seg,
                          endpoint_owners(seg), 790.0, 0.08, 1.0, 1.0, out)


def _all_orders(walls):
    walls = np.asarray(walls, float)
    out = []
    for perm in ([0, 1], [1, 0]):
        for flip in ((False, False), (True, False), (False, True), (True, True)):
            w = walls[perm].copy()
            for k, f in enumerate(flip):
                if f:
                    w[k] = w[k][[2, 3, 0, 1]]
            out.append(w)
    return out


def test_corner_contacts_do_not_depend_on_segment_order():
    """The example of the issue: facing segment A at (0.3, −0.2) while B's closest point is the
    shared vertex. Only A's interior contact counts, whatever the order and orientation."""
    rng = np.random.default_rng(0)
    pts = np.concatenate([[[0.3, -0.2], [-0.2, 0.3], [-0.1, -0.15], [0.5, 0.5], [-0.15, -0.15], [1.1, 0.1]],
                          rng.uniform(-0.5, 1.5, (200, 2))])
    ref = _corner_force(CORNER_WALLS, pts)
    a_only = np.zeros((1, 2))
    seg_a = as_segments(CORNER_WALLS[:1])
    wall_repulsion(np.array([[0.3, -0.2]]), np.array([0.23]), np.zeros((1, 2)), seg_a, endpoint_owners(seg_a),
                   790.0, 0.08, 1.0, 1.0, a_only)
    np.testing.assert_allclose(ref[0], a_only[0], rtol=1e-14)
    for w in _all_orders(CORNER_WALLS):
        np.testing.assert_allclose(_corner_force(w, pts), ref, rtol=1e-12, atol=1e-12)


def test_corner_vertex_counted_once_outside_convex_corner():
    seg = as_segments(CORNER_WALLS)
    pos = np.array([[-0.15, -0.15]])  # both segments' closest point is the corner
    ped, sid, gap, nx, ny, cx, cy = wall_proximity(pos, np.array([0.23]), np.array([0]), seg, endpoint_owners(seg),
                                                   np.array([1.0]))
    assert ped.size == 1 and cx[0] == 0.0 and cy[0] == 0.0
    assert gap[0] == pytest.approx(math.hypot(0.15, 0.15) - 0.23)


def test_closed_polygon_and_contact_detection_order_independent():
    """A square pillar (four shared corners) in every cyclic order and orientation: identical
    contact sets (gap, normal) for the detector used by the simulator."""
    sq = np.array([[0, 0, 1, 0], [1, 0, 1, 1], [1, 1, 0, 1], [0, 1, 0, 0]], float)
    rng = np.random.default_rng(1)
    pts = rng.uniform(-0.6, 1.6, (400, 2))
    pts = pts[~((pts > 0).all(axis=1) & (pts < 1).all(axis=1))]
    radius = np.full(len(pts), 0.23)
    idx = np.arange(len(pts))

    def contacts(walls):
        walls = as_segments(walls)
        con = detect_contacts(pts, radius, np.zeros((len(pts), 2)), idx, np.zeros((0, 2), np.int64), walls,
                              endpoint_owners(walls), 0.3, 0.01)
        key = np.lexsort((con["ny"].round(12), con["nx"].round(12), con["a"]))
        return np.stack([con["a"][key], con["gap"][key], con["nx"][key], con["ny"][key]], axis=1)

    ref = contacts(sq)
    assert ref.shape[0] > 50
    for perm in ([1, 2, 3, 0], [3, 2, 1, 0], [2, 0, 3, 1]):
        for flip in (False, True):
            w = sq[perm]
            if flip:
                w = w[:, [2, 3, 0, 1]]
            np.testing.assert_allclose(contacts(w), ref, atol=1e-12)
    # no pedestrian gets two contacts at the same point (a corner counted twice)
    pts_a = ref[:, 0]
    for a in np.unique(pts_a):
        normals = ref[pts_a == a, 2:]
        assert len(np.unique(normals.round(9), axis=0)) == len(normals)


def test_wall_proximity_box_skip_changes_nothing(monkeypatch):
    """The bounding-box skip of wall_proximity (before the division and the root) keeps exactly the pairs of
    the full test, to the bit: compiled with the skip against the same loop in Python without it, on random
    walls and centres (far, near, on a wall, NaN), margins from negative to infinite."""
    from crowd_env.core import segments

    rng = np.random.default_rng(7)
    walls = as_segments(np.concatenate([rng.uniform(-5, 5, (30, 4)), [[0, 0, 3, 0], [3, 0, 3, 3], [0, 0, 0, 0.5]]]))
    owner = endpoint_owners(walls)
    pos = np.concatenate([rng.uniform(-7, 7, (300, 2)), walls[:10, :2], [[1.5, 1e-13], [np.nan, 1.0], [np.inf, 0.0]]])
    radius = rng.uniform(0.15, 0.3, len(pos))
    idx = np.arange(len(pos))
    margins = [rng.uniform(0, 0.5, len(pos)), np.full(len(pos), 1e-12), np.full(len(pos), -0.2), np.full(len(pos), 40.0),
               np.full(len(pos), np.inf), np.full(len(pos), -1.0)]

    def run(fill, margin):
        cap = 40 * len(pos)
        ped, seg, out = np.empty(cap, np.int64), np.empty(cap, np.int64), np.empty((cap, 5))
        m = fill(pos, radius, idx, walls, owner, margin, ped, seg, out)
        return ped[:m], seg[:m], out[:m].view(np.int64)

    kept = 0
    for margin in margins:
        fast = run(segments._fill_wall_proximity, margin)
        with monkeypatch.context() as patch:
            patch.setattr(segments, "_box_distances2", lambda px, py, boxes, out: out.fill(-1.0))  # never skip
            full = run(segments._fill_wall_proximity.py_func, margin)
        for x, y in zip(fast, full):
            np.testing.assert_array_equal(x, y)
        kept += len(fast[0])
    assert 0 < kept < len(margins) * len(pos) * len(walls)  # some pairs kept, some skipped

