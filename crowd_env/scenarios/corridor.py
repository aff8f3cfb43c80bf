"""Bidirectional corridor: two groups walk towards opposite ends (counterflow, lane formation).

Coordinates (metres): the corridor spans x in [0, length], y in [-width/2, width/2]. Two exits, named
``"west"`` (x < exit_depth) and ``"east"`` (x > length - exit_depth), are strips across the corridor
ends set ``EXIT_INSET_M`` inside the walls, so that the corridor stays closed: each pedestrian leaves
only through its own destination exit (:attr:`Scenario.destination`) and one pushed into the other
group's exit is stopped by the end wall behind it. Pedestrians 0..n-1 start in the western spawn
block and walk east; n..2n-1 start in the eastern block and walk west. Measurement line ``"middle"``
across the corridor at x = length/2, crossed both ways: it counts the eastbound group (direction +x).
"""
from __future__ import annotations

import numpy as np
from shapely.geometry import box
from shapely.ops import unary_union

from ..core.geometry import Geometry
from .checks import check_clearance, check_count, check_positive
from .placement import place_pedestrians
from .registry import register_scenario
from .scenario import Measurement, Scenario, ScenarioError

__all__ = ["corridor_bidirectional", "EXIT_INSET_M"]

EXIT_INSET_M = 0.01  # gap between an exit strip and the walls around it (keeps the corridor closed)


@register_scenario("corridor_bidirectional", aliases=("corridor",))
def corridor_bidirectional(length_m: float = 10.0, width_m: float = 3.0, n_per_direction: int = 10,
                           seed: int | None = 0, radius_m: float = 0.23, spawn_depth_m: float = 3.0,
                           exit_depth_m: float = 0.5, density_per_m2: float | None = None,
                           navigation_clearance_m: float | None = None,
                           navigation_resolution_m: float = 0.05) -> Scenario:
    """A ``length_m`` x ``width_m`` corridor with ``n_per_direction`` pedestrians walking each way.

    Each group starts in a ``spawn_depth_m`` deep block next to its origin end (at ``density_per_m2``
    when given, else spread over the block) and has the opposite end's exit as destination.
    ``navigation_clearance_m``: default the radius (eikonal field of the disk centres). Raises
    :class:`ScenarioError` naming the problem (non-positive sizes, spawn blocks overlapping, more
    pedestrians than fit).
    """
    check_positive(length_m=length_m, width_m=width_m, radius_m=radius_m, spawn_depth_m=spawn_depth_m,
                   exit_depth_m=exit_depth_m)
    n = check_count("n_per_direction", n_per_direction)
    if density_per_m2 is not None:
        check_positive(density_per_m2=density_per_m2)
    if width_m <= 2.0 * (radius_m + EXIT_INSET_M):
        raise ScenarioError(f"corridor width {width_m} m leaves no room for a pedestrian of radius {radius_m} m")
    if 2.0 * (exit_depth_m + spawn_depth_m) > length_m:
        raise ScenarioError(f"the two spawn blocks ({spawn_depth_m} m deep) and exits ({exit_depth_m} m deep) do "
                            f"not fit in a {length_m} m corridor: they would overlap")
    hw, inset = 0.5 * width_m, EXIT_INSET_M
    west = box(inset, -hw + inset, exit_depth_m, hw - inset)
    east = box(length_m - exit_depth_m, -hw + inset, length_m - inset, hw - inset)
    geometry = Geometry(box(0.0, -hw, length_m, hw), exits=[west, east],
                        measurement_lines={"middle": {"ends": [(0.5 * length_m, -hw), (0.5 * length_m, hw)],
                                                      "direction": (1.0, 0.0)}},
                        name=f"corridor_{length_m:g}x{width_m:g}")
    rng = np.random.default_rng(seed)
    blocks = {"east": box(exit_depth_m, -hw, exit_depth_m + spawn_depth_m, hw),
              "west": box(length_m - exit_depth_m - spawn_depth_m, -hw, length_m - exit_depth_m, hw)}
    positions = []
    for heading_to, block in blocks.items():
        try:
            positions.append(place_pedestrians(block, n, radius_m, rng, density_per_m2=density_per_m2))
        except ScenarioError as exc:
            raise ScenarioError(f"spawn block of the group walking {heading_to}: {exc}") from exc
    destination = np.repeat(["east", "west"], n)
    metadata = {"length_m": float(length_m), "corridor_width_m": float(width_m), "n_per_direction": n,
                "seed": seed, "groups": {"eastbound": [0, n], "westbound": [n, 2 * n]},
                "spawn_blocks": {k: b.bounds for k, b in blocks.items()}}
    return Scenario(geometry=geometry, position_m=np.vstack(positions), pedestrian_params={"radius_m": float(radius_m)},
                    spawn_area=unary_union(list(blocks.values())), name="corridor_bidirectional", metadata=metadata,
                    seed=seed, navigation_resolution_m=navigation_resolution_m,
                    navigation_clearance_m=check_clearance(navigation_clearance_m, radius_m),
                    destination=destination, exit_names=("west", "east"), measurement=Measurement("middle"))
