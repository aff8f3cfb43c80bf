"""RiMEA test 11: a crowd packed on the left of a room chooses between a near and a far exit."""
from __future__ import annotations
from ..checks import check_count
from ..registry import register_scenario
from ..scenario import Scenario
from .base import rimea_scenario

DOORS = {"exit_1": [(21.0, 20.0), (22.0, 20.0)], "exit_2": [(27.0, 20.0), (28.0, 20.0)]}


def rimea_11_route_choice(seed: int = 0, n_pedestrians: int = 1000, route_choice: str | None = "quickest") -> Scenario:
    """Test 11: a 30 m x 20 m room with two 1 m doors on the same long wall (y = 20; exit 1 at x 21-22,
    exit 2 at x 27-28, JuPedSim's transcription); ``n_pedestrians`` (1000, RiMEA 4.1.1's "maximum
    density") packed in x 2-15, y 2-18. ``route_choice``: "quickest" (default; each re-chooses the exit
    it expects to leave by soonest, :class:`~crowd_env.walking.route_choice.QuickestExitNavigation`) or
    None (everybody walks to the nearest exit)."""
    n = check_count("n_pedestrians", n_pedestrians)
    walk = [(0.0, 0.0), (30.0, 0.0), (30.0, 20.0), (0.0, 20.0)]
    spawn = [(2.0, 2.0), (15.0, 2.0), (15.0, 18.0), (2.0, 18.0)]
    return rimea_scenario("rimea_11_route_choice", walk, DOORS, spawn, n, seed=seed, route_choice=route_choice,
                          metadata={"rimea_test": "11"})


register_scenario("rimea_11_route_choice", rimea_11_route_choice)
