"""RiMEA test 15: a large crowd round a corner, against the same crowd in two straight corridors.

RiMEA 4.1.1 (A4, Fig. 19): three scenarios, (1) a 20 m x 81.4 m straight corridor, (2) the corner, (3) a
20 m x 50 m straight corridor; the time for all persons to reach the destination is compared. 500 persons.
Coordinates are jpscore v0.8's ``test_15/geometry.xml`` (each scenario its own floor here):

* long: x 0-20, y 0-81.4, exit across the 20 m end at y = 0, start block y 75.4-81.4;
* short: x 21-41, y 0-50, exit at y = 0, start block y 44-50;
* corner: (42,60) (42,10) (52,0) (72,0) (72,20) (62,20) (62,60): a 20 m wide corridor 50 m down, then a
  90° left turn into a 10 m stub, the outer corner cut by a 45° chamfer (42,10)-(52,0); exit x = 72,
  y 0-20; start block x 42-62, y 54-60.

The start blocks are 6 m deep across the full 20 m (jpscore's); 500 pedestrians there are 4.2 /m², which
:func:`~crowd_env.scenarios.placement.place_pedestrians` reaches on its lattice. ``desired_speed_m_s`` None: the
preset's distribution (RiMEA asks for no particular speed here).
"""
from __future__ import annotations
from ..checks import check_count, check_positive
from ..registry import register_scenario
from ..scenario import Scenario, ScenarioError
from .base import rimea_scenario

__all__ = ["rimea_15_corridor", "rimea_15_corner", "LONG_M", "SHORT_M", "CORRIDOR_WIDTH_M", "START_DEPTH_M",
           "CORNER_POLYGON"]

LONG_M = 81.4
SHORT_M = 50.0
CORRIDOR_WIDTH_M = 20.0
START_DEPTH_M = 6.0
CORNER_POLYGON = [(42.0, 60.0), (42.0, 10.0), (52.0, 0.0), (72.0, 0.0), (72.0, 20.0), (62.0, 20.0), (62.0, 60.0)]


def rimea_15_corridor(seed: int = 0, length_m: float = LONG_M, n_pedestrians: int = 500,
                      desired_speed_m_s=None) -> Scenario:
    """Test 15, scenarios 1 and 3: a 20 m wide straight corridor ``length_m`` long (81.4 m or 50 m), the
    crowd in its far 6 m, the exit across the 20 m end at y = 0. The 81.4 m corridor lies at x 0-20 and
    every other at x 21-41 (jpscore's placement)."""
    n = check_count("n_pedestrians", n_pedestrians)
    check_positive(length_m=length_m)
    if length_m <= START_DEPTH_M:
        raise ScenarioError(f"the corridor ({length_m} m) must be longer than the start block ({START_DEPTH_M} m)")
    x0 = 0.0 if abs(length_m - LONG_M) < 1e-9 else 21.0
    x1 = x0 + CORRIDOR_WIDTH_M
    walk = [(x0, 0.0), (x1, 0.0), (x1, length_m), (x0, length_m)]
    spawn = [(x0, length_m - START_DEPTH_M), (x1, length_m - START_DEPTH_M), (x1, length_m), (x0, length_m)]
    name = "long" if x0 == 0.0 else ("short" if abs(length_m - SHORT_M) < 1e-9 else f"{length_m:g}m")
    return rimea_scenario(f"rimea_15_{name}", walk, [[(x0, 0.0), (x1, 0.0)]], spawn, n, seed=seed,
                          desired_speed_m_s=desired_speed_m_s, measurement_lines={"exit": [(x0, 0.0), (x1, 0.0)]},
                          metadata={"rimea_test": "15", "variant": name, "length_m": float(length_m),
                                    "width_m": CORRIDOR_WIDTH_M})


def rimea_15_corner(seed: int = 0, n_pedestrians: int = 500, desired_speed_m_s=None) -> Scenario:
    """Test 15, scenario 2: jpscore v0.8's corner (:data:`CORNER_POLYGON`), the crowd in the top 6 m of the
    50 m leg (x 42-62, y 54-60), the exit the 20 m door at x = 72, y 0-20."""
    n = check_count("n_pedestrians", n_pedestrians)
    spawn = [(42.0, 60.0 - START_DEPTH_M), (62.0, 60.0 - START_DEPTH_M), (62.0, 60.0), (42.0, 60.0)]
    door = [(72.0, 0.0), (72.0, 20.0)]
    return rimea_scenario("rimea_15_corner", CORNER_POLYGON, [door], spawn, n, seed=seed,
                          desired_speed_m_s=desired_speed_m_s, measurement_lines={"exit": door},
                          metadata={"rimea_test": "15", "variant": "corner", "width_m": CORRIDOR_WIDTH_M})


register_scenario("rimea_15_corridor", rimea_15_corridor)
register_scenario("rimea_15_corner", rimea_15_corner)
