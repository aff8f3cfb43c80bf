"""CrowdState: defaults (Kabalan Table 2), broadcasting, validation with errors that name the problem,
overlap queries, desired speeds (Henderson 1971)."""
import numpy as np
import pytest

from crowd_env.core import CrowdState, PedestrianDefaults, StateError, min_gap_m, sample_desired_speeds
from crowd_env.core.state import first_overlap


def test_defaults_follow_table2():
    st = CrowdState.create([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], rng=np.random.default_rng(0))
    d = PedestrianDefaults()
    assert st.n == 3
    np.testing.assert_array_equal(st.mass_kg, d.mass_kg)
    np.testing.assert_array_equal(st.radius_m, d.radius_m)
    np.testing.assert_array_equal(st.tau_s, d.tau_s)
    np.testing.assert_allclose(st.inertia_kg_m2, 0.5 * d.mass_kg * d.radius_m ** 2)  # solid disk
    zeta = st.heading_damping / (2.0 * np.sqrt(st.inertia_kg_m2 * st.heading_stiffness))
    np.testing.assert_allclose(zeta, 1.0)  # critically damped (Section 2.3)
    assert 0.5 <= d.heading_stiffness_n_m_per_rad <= 18.5
    assert st.active.all() and st.links.shape == (0, 2) and st.link_offsets_m.shape == (0, 4)
    np.testing.assert_array_equal(st.velocity_m_s, 0.0)
    for arr in (st.position_m, st.velocity_m_s, st.mass_kg):
        assert arr.flags.c_contiguous and arr.dtype == np.float64


def test_broadcasting_and_explicit_values():
    st = CrowdState.create([[0, 0], [1, 0]], heading_rad=0.5, mass_kg=[60, 70], radius_m=0.2, tau_s=0.3,
                           inertia_kg_m2=[1.0, 2.0], heading_stiffness=4.0, heading_damping=[0.1, 0.2],
                           desired_speed_m_s=[1.0, 1.2])
    np.testing.assert_array_equal(st.heading_rad, [0.5, 0.5])
    np.testing.assert_array_equal(st.inertia_kg_m2, [1.0, 2.0])
    np.testing.assert_array_equal(st.heading_damping, [0.1, 0.2])
    np.testing.assert_array_equal(st.desired_speed_m_s, [1.0, 1.2])


def test_desired_speeds_are_truncated_normal_and_reproducible():
    rng = np.random.default_rng(1)
    s = sample_desired_speeds(20000, rng)
    assert s.min() >= 1.34 - 2 * 0.26 - 1e-12 and s.max() <= 1.34 + 2 * 0.26 + 1e-12
    assert s.mean() == pytest.approx(1.34, abs=0.01)
    a = CrowdState.create([[0, 0], [1, 0]], rng=np.random.default_rng(5)).desired_speed_m_s
    b = CrowdState.create([[0, 0], [1, 0]], rng=np.random.default_rng(5)).desired_speed_m_s
    np.testing.assert_array_equal(a, b)
    c = CrowdState.create([[0, 0], [1, 0]]).desired_speed_m_s  # no rng: a fixed default seed
    np.testing.assert_array_equal(c, CrowdState.create([[0, 0], [1, 0]]).desired_speed_m_s)


def test_overlap_error_names_the_pair():
    with pytest.raises(StateError, match=r"pedestrians 1 and 2 overlap by 0\.06 m at start"):
        CrowdState.create([[0.0, 0.0], [2.0, 0.0], [2.4, 0.0]])
    # touching is allowed; overlaps below the tolerance too
    CrowdState.create([[0.0, 0.0], [0.46, 0.0]])
    CrowdState.create([[0.0, 0.0], [0.4599, 0.0]], overlap_tolerance_m=1e-3)
    # inactive pedestrians are not checked
    st = CrowdState.create([[0.0, 0.0], [3.0, 0.0]])
    st.active[1] = False
    st.position_m[1] = [0.1, 0.0]
    st.validate()


@pytest.mark.parametrize("field,value,message", [
    ("mass_kg", [80.0, 0.0], r"mass_kg must be > 0; pedestrian 1 has"),
    ("mass_kg", [-1.0, 80.0], r"mass_kg must be > 0; pedestrian 0 has"),
    ("radius_m", [0.2, -0.2], r"radius_m must be > 0; pedestrian 1"),
    ("radius_m", 0.0, r"radius_m must be > 0; pedestrian 0"),
    ("tau_s", [0.5, 0.0], r"tau_s must be > 0; pedestrian 1"),
    ("inertia_kg_m2", [0.0, 1.0], r"inertia_kg_m2 must be > 0; pedestrian 0"),
    ("desired_speed_m_s", [1.0, -0.1], r"desired_speed_m_s must be >= 0; pedestrian 1"),
    ("heading_stiffness", [-1.0, 1.0], r"heading_stiffness must be >= 0; pedestrian 0"),
    ("heading_damping", [1.0, -1.0], r"heading_damping must be >= 0; pedestrian 1"),
    ("mass_kg", [80.0, np.nan], r"mass_kg has non-finite values for pedestrian\(s\) \[1\]"),
    ("velocity_m_s", [[0.0, np.inf], [0.0, 0.0]], r"velocity_m_s has non-finite values for pedestrian\(s\) \[0\]"),
    ("heading_rad", [0.0, 1.0, 2.0], r"heading_rad must have shape \(2,\), got \(3,\)"),
    ("velocity_m_s", [1.0, 2.0], r"velocity_m_s must have shape \(2, 2\), got \(2,\)"),
    ("mass_kg", ["a", "b"], r"mass_kg must be numeric"),
])
def test_bad_values_are_named(field, value, message):
    with pytest.raises(StateError, match=message):
        CrowdState.create([[0.0, 0.0], [1.0, 0.0]], **{field: value})


def test_bad_positions_and_links():
    with pytest.raises(StateError, match=r"position_m must have shape \(N, 2\), got \(3,\)"):
        CrowdState.create([0.0, 1.0, 2.0])
    with pytest.raises(StateError, match=r"position_m has non-finite values for pedestrian\(s\) \[1\]"):
        CrowdState.create([[0.0, 0.0], [np.nan, 1.0]])
    with pytest.raises(StateError, match="position_m must be numeric"):
        CrowdState.create([["x", 0.0]])
    with pytest.raises(StateError, match=r"link_offsets_m must have shape \(1, 4\)"):
        CrowdState.create([[0, 0], [1, 0]], links=[[0, 1]])
    with pytest.raises(StateError, match=r"links refer to pedestrian indices outside \[0, 2\)"):
        CrowdState.create([[0, 0], [1, 0]], links=[[0, 2]], link_offsets_m=[[0, 0, 0, 0]])
    with pytest.raises(StateError, match="a link joins a pedestrian to itself"):
        CrowdState.create([[0, 0], [1, 0]], links=[[1, 1]], link_offsets_m=[[0, 0, 0, 0]])


def test_empty_crowd_is_valid():
    st = CrowdState.create(np.zeros((0, 2)))
    assert st.n == 0
    assert min_gap_m(st.position_m, st.radius_m) == np.inf


def test_copy_is_deep():
    st = CrowdState.create([[0, 0], [1, 0]], links=[[0, 1]], link_offsets_m=[[0, 0.2, 0, -0.2]])
    cp = st.copy()
    cp.position_m[0, 0] = 9.0
    cp.links[0, 0] = 1
    cp.active[0] = False
    assert st.position_m[0, 0] == 0.0 and st.links[0, 0] == 0 and st.active[0]


def test_gap_queries():
    pos = np.array([[0.0, 0.0], [0.5, 0.0], [3.0, 0.0]])
    r = np.array([0.23, 0.25, 0.23])
    assert min_gap_m(pos, r) == pytest.approx(0.02)
    assert first_overlap(pos, r) is None
    pos[1, 0] = 0.4
    i, j, ov = first_overlap(pos, r)
    assert (i, j) == (0, 1) and ov == pytest.approx(0.08)
    assert min_gap_m(pos[:1], r[:1]) == np.inf
