"""The 90° corner (crowd_env.scenarios.corner)."""
import numpy as np
import pytest

from crowd_env.scenarios import ScenarioError, make_scenario
from tests.scenarios.conftest import run_baseline


def test_corner_pedestrians_turn_the_corner():
    sc = make_scenario("corner_90", n_pedestrians=20, seed=0)
    assert sc.position_m[:, 0].max() < 3.0 and sc.position_m[:, 1].max() < 2.0  # start in the first leg
    gaps = []
    sim = run_baseline(sc, 40.0, on_step=lambda s: gaps.append(s.min_gap_m()))
    assert not sim.state.active.any()
    assert min(gaps) > -1e-3  # nobody overlaps a wall (or another) on the way
    end = sim.state.position_m
    assert np.all(end[:, 1] >= 6.0) and np.all((end[:, 0] > 6.0) & (end[:, 0] < 8.0))  # left at the second leg's end
    with pytest.raises(ScenarioError, match="leg2_length_m"):
        make_scenario("corner_90", leg2_length_m=1.5)
