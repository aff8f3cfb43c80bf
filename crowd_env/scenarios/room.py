"""Room evacuation with a pillar in front of the door (the classic "obstacle before the exit" layout).

Coordinates (metres): the room spans x in [0, length], y in [-width/2, width/2]; the door is a gap of
``door_width_m`` in the wall x = length, centred on y = 0, and pedestrians leave when their centre
crosses it (the exit is the strip behind the door, :func:`~crowd_env.scenarios.doors.door_exit`). The
pillar (a circle of diameter ``pillar_size_m`` or a square of that side) is a hole in the walkable
area centred ``pillar_distance_m`` in front of the door wall, ``pillar_offset_m`` off the door axis;
its outline is a wall. Pedestrians start in the rear ``spawn_depth_m`` of the room. Measurement line
``"door"`` across the door.
"""
from __future__ import annotations

import numpy as np
from shapely.geometry import Point, box

from ..core.geometry import Geometry
from ..core.segments import GeometryError
from .checks import check_clearance, check_count, check_positive
from .doors import door_exit
from .placement import place_pedestrians
from .registry import register_scenario
from .scenario import Measurement, Scenario, ScenarioError

__all__ = ["room_pillar", "PILLAR_SHAPES"]

PILLAR_SHAPES = ("circle", "square")


@register_scenario("room_pillar")
def room_pillar(length_m: float = 8.0, width_m: float = 6.0, door_width_m: float = 1.0, n_pedestrians: int = 30,
                seed: int | None = 0, pillar_shape: str = "circle", pillar_size_m: float = 0.6,
                pillar_distance_m: float = 1.2, pillar_offset_m: float = 0.0, spawn_depth_m: float = 4.0,
                radius_m: float = 0.23, density_per_m2: float | None = None, exit_depth_m: float = 0.5,
                navigation_clearance_m: float | None = None, navigation_resolution_m: float = 0.05) -> Scenario:
    """Evacuation of ``n_pedestrians`` through a ``door_width_m`` door with a pillar in front of it.

    Raises :class:`ScenarioError` / :class:`GeometryError` naming the problem (door not wider than a
    pedestrian or wider than the wall, pillar outside the room or touching a wall, spawn zone
    reaching the pillar, more pedestrians than fit).
    """
    check_positive(length_m=length_m, width_m=width_m, door_width_m=door_width_m, pillar_size_m=pillar_size_m,
                   pillar_distance_m=pillar_distance_m, spawn_depth_m=spawn_depth_m, radius_m=radius_m,
                   exit_depth_m=exit_depth_m)
    n = check_count("n_pedestrians", n_pedestrians)
    if pillar_shape not in PILLAR_SHAPES:
        raise ScenarioError(f"pillar_shape must be one of {PILLAR_SHAPES}, got {pillar_shape!r}")
    if density_per_m2 is not None:
        check_positive(density_per_m2=density_per_m2)
    if door_width_m <= 2.0 * radius_m:
        raise GeometryError(f"door width {door_width_m} m is not wider than a pedestrian (diameter {2 * radius_m} m)")
    if door_width_m > width_m:
        raise GeometryError(f"door width {door_width_m} m is larger than the room width {width_m} m")
    hw, half = 0.5 * width_m, 0.5 * pillar_size_m
    room = box(0.0, -hw, length_m, hw)
    cx, cy = length_m - pillar_distance_m, float(pillar_offset_m)
    pillar = Point(cx, cy).buffer(half, quad_segs=16) if pillar_shape == "circle" else box(cx - half, cy - half,
                                                                                           cx + half, cy + half)
    if not room.buffer(-1e-6).contains(pillar):
        raise GeometryError(f"the pillar (centre ({cx:.3g}, {cy:.3g}) m, size {pillar_size_m} m) must lie inside the "
                            f"room, clear of its walls (x in [0, {length_m}], y in [{-hw}, {hw}])")
    spawn = box(0.0, -hw, spawn_depth_m, hw)
    if spawn_depth_m > length_m or spawn.intersects(pillar.buffer(radius_m)):
        raise ScenarioError(f"spawn_depth_m {spawn_depth_m} m reaches the pillar (or beyond the room): the "
                            f"pedestrians must start behind it, x < {cx - half - radius_m:.3g} m")
    door = [(length_m, -0.5 * door_width_m), (length_m, 0.5 * door_width_m)]
    geometry = Geometry(room, exits=[door_exit(door, room, exit_depth_m, "door")], obstacles=[pillar],
                        measurement_lines={"door": door}, name=f"room_pillar_{pillar_shape}")
    rng = np.random.default_rng(seed)
    position = place_pedestrians(spawn, n, radius_m, rng, density_per_m2=density_per_m2)
    metadata = {"room_length_m": float(length_m), "room_width_m": float(width_m), "door_width_m": float(door_width_m),
                "pillar_shape": pillar_shape, "pillar_centre_m": (cx, cy), "pillar_size_m": float(pillar_size_m),
                "pillar": pillar.wkt, "n_pedestrians": n, "seed": seed, "width_m": float(door_width_m)}
    return Scenario(geometry=geometry, position_m=position, pedestrian_params={"radius_m": float(radius_m)},
                    spawn_area=spawn, name="room_pillar", metadata=metadata, seed=seed,
                    navigation_resolution_m=navigation_resolution_m,
                    navigation_clearance_m=check_clearance(navigation_clearance_m, radius_m),
                    measurement=Measurement("door"))
