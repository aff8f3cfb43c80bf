"""RiMEA test 5: ten persons in an 8 m x 5 m room start walking at their premovement times."""
from __future__ import annotations

import numpy as np

from ..checks import check_count
from ..registry import register_scenario
from ..scenario import Scenario
from .base import rimea_scenario

PREMOVEMENT_RANGE_S = (10.0, 100.0)


def rimea_5_premovement(seed: int = 0, n_pedestrians: int = 10) -> Scenario:
    """Test 5: an 8 m x 5 m room with a 1 m door centred on one 5 m wall (x = 0, y 2-3); ``n_pedestrians``
    (10) placed in x 5.5-7.5, y 1-4 (JuPedSim's placement), premovement times drawn uniformly in
    10-100 s from ``seed``; desired speeds from the preset."""
    n = check_count("n_pedestrians", n_pedestrians)
    rng = np.random.default_rng([seed, 5])
    premovement = rng.uniform(*PREMOVEMENT_RANGE_S, size=n)
    walk = [(0.0, 0.0), (8.0, 0.0), (8.0, 5.0), (0.0, 5.0)]
    spawn = [(5.5, 1.0), (7.5, 1.0), (7.5, 4.0), (5.5, 4.0)]
    return rimea_scenario("rimea_5_premovement", walk, [[(0.0, 2.0), (0.0, 3.0)]], spawn, n, seed=seed,
                          premovement_s=premovement, metadata={"rimea_test": "5"})


register_scenario("rimea_5_premovement", rimea_5_premovement)
