"""The room with a pillar in front of its door (crowd_env.scenarios.room)."""
import numpy as np
import pytest
import shapely

from crowd_env.core.geometry import GeometryError
from crowd_env.scenarios import ScenarioError, make_scenario
from tests.scenarios.conftest import R, run_baseline


@pytest.mark.parametrize("shape", ["circle", "square"])
def test_room_pillar_evacuates_around_the_pillar(shape):
    sc = make_scenario("room_pillar", n_pedestrians=20, seed=0, pillar_shape=shape)
    pillar = shapely.from_wkt(sc.metadata["pillar"])
    assert len(sc.geometry.walkable_area.interiors) == 1  # the pillar is a hole
    assert sc.geometry.walkable_area.intersection(pillar).area == pytest.approx(0.0, abs=1e-9)
    # in front of the door, on its axis
    assert pillar.centroid.x == pytest.approx(8.0 - 1.2) and pillar.centroid.y == pytest.approx(0.0)
    worst = [np.inf]

    def clearance(sim):
        pos = sim.state.position_m[sim.state.active]
        if pos.size:
            worst[0] = min(worst[0], float(shapely.distance(pillar, shapely.points(pos)).min()))

    sim = run_baseline(sc, 45.0, on_step=clearance)
    assert not sim.state.active.any()
    assert worst[0] >= R - 1e-3  # nobody overlaps the pillar
    assert worst[0] < R + 0.3  # and people did pass close to it


def test_room_pillar_bad_inputs():
    with pytest.raises(GeometryError, match="pillar .* must lie inside the room"):
        make_scenario("room_pillar", pillar_distance_m=0.1)
    with pytest.raises(ScenarioError, match="pillar_shape"):
        make_scenario("room_pillar", pillar_shape="hexagon")
    with pytest.raises(ScenarioError, match="spawn_depth_m .* reaches the pillar"):
        make_scenario("room_pillar", spawn_depth_m=6.8)
    with pytest.raises(GeometryError, match="door width"):
        make_scenario("room_pillar", door_width_m=0.4)
