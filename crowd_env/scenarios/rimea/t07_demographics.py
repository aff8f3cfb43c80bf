"""RiMEA test 7: 50 adults whose desired speeds follow Weidmann's speeds by age."""
from __future__ import annotations

import numpy as np

from ..registry import register_scenario
from ..scenario import Scenario
from ..demographics import RIMEA_ADULTS, ages_of_population, desired_speeds_for_ages
from .base import RIMEA_RADIUS_M, rimea_scenario

SPACING_M = 1.0  # between neighbours abreast at the start


def rimea_7_demographics(seed: int = 0, length_m: float = 30.0) -> Scenario:
    """Test 7: the 50 adults of :data:`~crowd_env.scenarios.demographics.RIMEA_ADULTS`, desired speeds drawn
    in their age's Weidmann band, start abreast in one rank (``SPACING_M`` apart, ages shuffled) at the
    left end of a hall ``length_m`` long and 51 m wide and walk in parallel lanes to an exit spanning
    the right end: nobody walks behind anybody, so each can keep its own speed (RiMEA sets no geometry
    for this test). Ages are in ``metadata["ages_years"]`` (the order of the pedestrians)."""
    ages = ages_of_population(RIMEA_ADULTS)
    rng = np.random.default_rng([seed, 7])
    order = rng.permutation(ages.size)  # ages spread over the grid, not row by row
    ages = ages[order]
    speeds = desired_speeds_for_ages(ages, rng)
    width_m = (ages.size + 1) * SPACING_M
    pos = np.array([(1.0, (k + 1) * SPACING_M) for k in range(ages.size)])
    walk = [(0.0, 0.0), (length_m, 0.0), (length_m, width_m), (0.0, width_m)]
    spawn = [(RIMEA_RADIUS_M, RIMEA_RADIUS_M), (3.0, RIMEA_RADIUS_M), (3.0, width_m - RIMEA_RADIUS_M),
             (RIMEA_RADIUS_M, width_m - RIMEA_RADIUS_M)]
    return rimea_scenario("rimea_7_demographics", walk, [[(length_m, 0.0), (length_m, width_m)]], spawn, ages.size,
                          seed=seed, position_m=pos, heading_rad=np.zeros(ages.size), desired_speed_m_s=speeds,
                          metadata={"rimea_test": "7", "ages_years": ages.tolist()})


register_scenario("rimea_7_demographics", rimea_7_demographics)
