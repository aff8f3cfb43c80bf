"""RiMEA test 9: a crowd leaves a large public room through four exits, then through two."""
from __future__ import annotations
from ..checks import check_count
from ..registry import register_scenario
from ..scenario import Scenario, ScenarioError
from .base import rimea_scenario

DOORS = {"exit_1": [(4.0, 0.0), (5.0, 0.0)], "exit_2": [(25.0, 0.0), (26.0, 0.0)],
         "exit_3": [(4.0, 20.0), (5.0, 20.0)], "exit_4": [(25.0, 20.0), (26.0, 20.0)]}


def rimea_9_large_room(seed: int = 0, n_pedestrians: int = 1000, open_exits: int = 4) -> Scenario:
    """Test 9: a 30 m x 20 m room with four 1 m doors, two on each long wall (x 4-5 and 25-26 at y = 0 and
    y = 20, JuPedSim's transcription of RiMEA's figure); ``n_pedestrians`` (1000) spread evenly over
    x 2-28, y 2-18; desired speeds from the preset (adults), no premovement. ``open_exits`` = 2 closes
    the two doors of one long wall (y = 20: exits 3 and 4 become wall)."""
    n = check_count("n_pedestrians", n_pedestrians)
    if open_exits not in (2, 4):
        raise ScenarioError(f"open_exits must be 4 or 2, got {open_exits!r}")
    doors = DOORS if open_exits == 4 else {k: v for k, v in DOORS.items() if k in ("exit_1", "exit_2")}
    walk = [(0.0, 0.0), (30.0, 0.0), (30.0, 20.0), (0.0, 20.0)]
    spawn = [(2.0, 2.0), (28.0, 2.0), (28.0, 18.0), (2.0, 18.0)]
    return rimea_scenario(f"rimea_9_large_room_{open_exits}_exits", walk, doors, spawn, n, seed=seed,
                          metadata={"rimea_test": "9", "open_exits": open_exits})


register_scenario("rimea_9_large_room", rimea_9_large_room)
