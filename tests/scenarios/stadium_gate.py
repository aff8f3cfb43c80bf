"""A new scenario as a contributor writes it: this one module (in ``crowd_env/scenarios/`` it would be
``crowd_env/scenarios/stadium_gate.py``) and its test (``tests/scenarios/test_new_scenario.py``); nothing else is
edited. ``docs/architecture/layers.md`` shows it ("A new scenario")."""
from __future__ import annotations

import numpy as np
from shapely.geometry import box

from crowd_env.core.geometry import Geometry
from crowd_env.scenarios import Measurement, Scenario, register_scenario
from crowd_env.scenarios.doors import door_exit
from crowd_env.scenarios.placement import place_pedestrians


@register_scenario("stadium_gate", aliases=("gate",))
def stadium_gate(n_pedestrians: int = 12, gate_width_m: float = 1.2, seed: int | None = 0) -> Scenario:
    """A 6 m x 4 m forecourt emptied through a gate in its east wall, measured at the gate."""
    area = box(0.0, 0.0, 6.0, 4.0)
    gate = [(6.0, 2.0 - gate_width_m / 2), (6.0, 2.0 + gate_width_m / 2)]
    geometry = Geometry(area, exits=[door_exit(gate, area)], measurement_lines={"gate": gate},
                        measurement_areas={"forecourt": box(3.0, 0.0, 6.0, 4.0)}, name="stadium_gate")
    position = place_pedestrians(box(0.5, 0.5, 3.0, 3.5), n_pedestrians, 0.23, np.random.default_rng(seed))
    return Scenario(geometry, position, seed=seed, name="stadium_gate", pedestrian_params={"radius_m": 0.23},
                    metadata={"width_m": gate_width_m}, measurement=Measurement("gate", ("forecourt",)))
