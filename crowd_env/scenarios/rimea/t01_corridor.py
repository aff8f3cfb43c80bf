"""RiMEA test 1: one pedestrian in a 40 m x 2 m corridor."""
from __future__ import annotations

import numpy as np

from ..checks import check_positive
from ..registry import register_scenario
from ..scenario import Scenario
from .base import RIMEA_RADIUS_M, rimea_scenario


def rimea_1_corridor(seed: int = 0, length_m: float = 40.0, width_m: float = 2.0,
                     desired_speed_m_s: float = 1.33) -> Scenario:
    """Test 1: one pedestrian walks a corridor ``length_m`` × ``width_m`` (40 m × 2 m) at a constant desired
    speed (1.33 m/s). It starts with its back touching the wall at x = 0 (centre at x = r), heading along
    the corridor, and leaves through the far end (the door at x = ``length_m``)."""
    check_positive(length_m=length_m, width_m=width_m, desired_speed_m_s=desired_speed_m_s)
    r = RIMEA_RADIUS_M
    walk = [(0.0, 0.0), (length_m, 0.0), (length_m, width_m), (0.0, width_m)]
    spawn = [(0.0, 0.0), (2.0, 0.0), (2.0, width_m), (0.0, width_m)]
    return rimea_scenario("rimea_1_corridor", walk, [[(length_m, 0.0), (length_m, width_m)]], spawn, 1, seed=seed,
                          position_m=[[r, 0.5 * width_m]], heading_rad=np.zeros(1),
                          desired_speed_m_s=float(desired_speed_m_s),
                          metadata={"rimea_test": "1", "length_m": float(length_m), "width_m": float(width_m)})


register_scenario("rimea_1_corridor", rimea_1_corridor)
