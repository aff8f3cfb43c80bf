"""Hand-holding groups in the bottleneck (crowd_env.scenarios.groups): placed side by side, held together by
the links, bad inputs."""
import numpy as np
import pytest

from crowd_env.walking import ModelParams
from crowd_env.core.contacts import link_geometry
from crowd_env.scenarios import ScenarioError, make_scenario
from tests.scenarios.conftest import R, run_baseline


def shoulder_distance(st):
    d, _, _ = link_geometry(st.position_m, st.heading_rad, st.links, st.link_offsets_m)
    return np.hypot(d[:, 0], d[:, 1])


def test_groups_are_placed_side_by_side():
    # the point field (the placement's tolerance below is stated for it)
    sc = make_scenario("bottleneck_groups", n_pedestrians=30, n_pairs=3, n_triples=2, seed=4, hand_gap_m=0.05,
                       navigation_clearance_m=0.0)
    groups = sc.metadata["groups"]
    assert sorted(len(g) for g in groups) == [2, 2, 2, 3, 3]
    assert sc.links.shape == (3 * 1 + 2 * 2, 2)
    e_d = sc.navigation().direction(sc.position_m)
    for g in groups:
        p = sc.position_m[g]
        step = np.diff(p, axis=0)
        np.testing.assert_allclose(np.hypot(step[:, 0], step[:, 1]), 2 * R + 0.05, atol=1e-9)  # adjacent
        across = np.abs(step @ e_d[g[0]]) / np.hypot(step[:, 0], step[:, 1])
        assert np.all(across < np.sin(np.deg2rad(20.0)) + 1e-9)  # side by side across the walking direction
    assert len({i for g in groups for i in g}) == 12  # disjoint
    sc.validate()  # no overlap, inside, reachable


def test_groups_stay_linked_and_everyone_exits():
    sc = make_scenario("bottleneck_groups", n_pedestrians=30, n_pairs=3, n_triples=2, seed=4)

    def run(params):
        worst = np.zeros(sc.links.shape[0])

        def track(sim):
            st = sim.state
            both = st.active[st.links[:, 0]] & st.active[st.links[:, 1]]
            np.maximum(worst, np.where(both, shoulder_distance(st), 0.0), out=worst)

        sim = run_baseline(sc, 40.0, params=params, on_step=track)
        return sim, worst

    start = shoulder_distance(sc.make_state())
    sim, worst = run(ModelParams())
    assert not sim.state.active.any()
    # Hands held (K_v, Eq. 2): shoulders stay within 0.3 m of their start distance, even where a triple
    # (1.5 m abreast) squeezes through the 1.2 m bottleneck; without the link they drift metres apart.
    assert np.all(worst <= start + 0.3)
    _, free_worst = run(ModelParams(link_dissipation_kg_per_m2=0.0))
    assert np.count_nonzero(free_worst > start + 0.5) >= 3


def test_group_bad_inputs():
    with pytest.raises(ScenarioError, match="0 pairs and 7 triples need 21 pedestrians, but the crowd has 20"):
        make_scenario("bottleneck_groups", n_pedestrians=20, n_pairs=0, n_triples=7)
    with pytest.raises(ScenarioError, match="no room to form group"):
        make_scenario("bottleneck_groups", n_pedestrians=20, n_pairs=0, n_triples=6, hand_gap_m=0.3)
    with pytest.raises(ScenarioError, match="unknown option"):
        make_scenario("bottleneck_groups", n_quads=1)
    with pytest.raises(ScenarioError, match="n_pairs"):
        make_scenario("bottleneck_groups", n_pairs=-1)
