"""A corridor with a 90° left turn (L shape); the exit is at the end of the second leg.

Coordinates (metres): the first leg spans x in [0, leg1_length], y in [0, width]; the second leg
x in [leg1_length - width, leg1_length], y in [0, leg2_length], so the corner square is shared and the
turn is to the left (+y). Pedestrians start in the first ``spawn_depth_m`` of the first leg and leave
when their centre crosses the far end of the second leg (:func:`~crowd_env.scenarios.doors.door_exit`).
Measurement lines: ``"turn_in"`` where the first leg enters the corner square, ``"turn_out"`` where
the second leg leaves it, ``"exit"`` at the end.
"""
from __future__ import annotations

import numpy as np
from shapely.geometry import Polygon, box
from shapely.ops import unary_union

from ..core.geometry import Geometry
from .checks import check_clearance, check_count, check_positive
from .doors import door_exit
from .placement import place_pedestrians
from .registry import register_scenario
from .scenario import Measurement, Scenario, ScenarioError

__all__ = ["corner_90"]


@register_scenario("corner_90", aliases=("corner",))
def corner_90(leg1_length_m: float = 8.0, leg2_length_m: float = 6.0, width_m: float = 2.0, n_pedestrians: int = 20,
              seed: int | None = 0, spawn_depth_m: float = 3.0, radius_m: float = 0.23,
              density_per_m2: float | None = None, exit_depth_m: float = 0.5,
              navigation_clearance_m: float | None = None, navigation_resolution_m: float = 0.05) -> Scenario:
    """``n_pedestrians`` walking round a 90° corner of a ``width_m`` wide corridor to the exit.

    Raises :class:`ScenarioError` naming the problem (a leg shorter than the corridor is wide, spawn
    block reaching the corner, corridor narrower than a pedestrian, more pedestrians than fit).
    """
    check_positive(leg1_length_m=leg1_length_m, leg2_length_m=leg2_length_m, width_m=width_m,
                   spawn_depth_m=spawn_depth_m, radius_m=radius_m, exit_depth_m=exit_depth_m)
    n = check_count("n_pedestrians", n_pedestrians)
    if density_per_m2 is not None:
        check_positive(density_per_m2=density_per_m2)
    if width_m <= 2.0 * radius_m:
        raise ScenarioError(f"corridor width {width_m} m is not wider than a pedestrian (diameter {2 * radius_m} m)")
    for name, value in (("leg1_length_m", leg1_length_m), ("leg2_length_m", leg2_length_m)):
        if value <= width_m:
            raise ScenarioError(f"{name} {value} m must exceed the corridor width {width_m} m (the corner square)")
    x_turn = leg1_length_m - width_m
    if spawn_depth_m > x_turn:
        raise ScenarioError(f"spawn_depth_m {spawn_depth_m} m reaches into the corner (the first leg is straight "
                            f"for {x_turn} m)")
    area = Polygon(unary_union([box(0.0, 0.0, leg1_length_m, width_m),
                                box(x_turn, 0.0, leg1_length_m, leg2_length_m)]).exterior)
    end = [(x_turn, leg2_length_m), (leg1_length_m, leg2_length_m)]
    geometry = Geometry(area, exits=[door_exit(end, area, exit_depth_m, "end of the second leg")],
                        measurement_lines={"turn_in": [(x_turn, 0.0), (x_turn, width_m)],
                                           "turn_out": [(x_turn, width_m), (leg1_length_m, width_m)],
                                           "exit": end},
                        name=f"corner_90_w{width_m:g}")
    spawn = box(0.0, 0.0, spawn_depth_m, width_m)
    position = place_pedestrians(spawn, n, radius_m, np.random.default_rng(seed), density_per_m2=density_per_m2)
    metadata = {"leg1_length_m": float(leg1_length_m), "leg2_length_m": float(leg2_length_m),
                "corridor_width_m": float(width_m), "n_pedestrians": n, "seed": seed}
    return Scenario(geometry=geometry, position_m=position, pedestrian_params={"radius_m": float(radius_m)},
                    spawn_area=spawn, name="corner_90", metadata=metadata, seed=seed,
                    navigation_resolution_m=navigation_resolution_m,
                    navigation_clearance_m=check_clearance(navigation_clearance_m, radius_m),
                    measurement=Measurement("turn_in"))
