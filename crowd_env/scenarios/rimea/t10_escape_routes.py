"""RiMEA test 10: 23 persons in 12 rooms along a corridor, each assigned to one of two exits."""
from __future__ import annotations

import numpy as np
import shapely

from ..placement import place_pedestrians
from ..registry import register_scenario
from ..scenario import Scenario
from .base import RIMEA_RADIUS_M, rimea_scenario

WALL_M = 0.1  # wall thickness between rooms and corridor
DOOR_M = 0.9  # room doors, 1.05-1.95 m from each room's left wall
# top row (rooms 1-6, y 6-11) and bottom row (rooms 7-12, y 0-5): (x_left, x_right, occupants); room 3 is
# 1.8 m wide, the gap x 6-7.2 beside it is the passage to the main exit (JuPedSim's transcription)
TOP = [(0.0, 3.0, 2), (3.0, 6.0, 2), (7.2, 9.0, 1), (9.0, 12.0, 2), (12.0, 15.0, 2), (15.0, 18.0, 2)]
BOTTOM = [(0.0, 3.0, 2), (3.0, 6.0, 2), (6.0, 9.0, 2), (9.0, 12.0, 2), (12.0, 15.0, 2), (15.0, 18.0, 2)]
MAIN_EXIT_ROOMS = (1, 2, 3, 4, 7, 8, 9, 10)  # RiMEA: these rooms go to the main exit, the others to the second


def _rooms():
    """[(room number, box, door box)] for the 12 rooms."""
    out = []
    h = 0.5 * WALL_M
    for k, (x0, x1, _) in enumerate(TOP, start=1):
        box = shapely.box(x0 + h, 6.0 + WALL_M, x1 - h, 11.0)
        d0 = x0 + 1.05 if x1 - x0 >= 2.9 else x0 + 0.45
        out.append((k, box, shapely.box(d0, 6.0 - 1e-9, d0 + DOOR_M, 6.0 + WALL_M + 1e-9)))
    for k, (x0, x1, _) in enumerate(BOTTOM, start=7):
        box = shapely.box(x0 + h, 0.0, x1 - h, 5.0 - WALL_M)
        out.append((k, box, shapely.box(x0 + 1.05, 5.0 - WALL_M - 1e-9, x0 + 1.05 + DOOR_M, 5.0 + 1e-9)))
    return out


def rimea_10_escape_routes(seed: int = 0) -> Scenario:
    """Test 10: 12 rooms of 3 m x 5 m (room 3: 1.8 m) on both sides of a 1 m corridor (y 5-6, x 0-18),
    0.9 m doors, 0.1 m walls; the main exit at the end of a 1.1 m passage beside room 3 (up to y = 11),
    the second at the corridor's right end. 23 persons (rooms 1-6: 2, 2, 1, 2, 2, 2; rooms 7-12: 2 each),
    those of rooms 1-4 and 7-10 assigned to the main exit, those of rooms 5, 6, 11 and 12 to the second
    (``destination``). Both exits lie in 2 m vestibules closed by walls, so each pedestrian can leave
    only through its own (per-pedestrian destinations need closed exits). Rooms in ``metadata["room"]``."""
    rng = np.random.default_rng([seed, 10])
    parts = [shapely.box(0.0, 5.0, 20.0, 6.0),  # corridor and the second exit's vestibule (x 18-20)
             shapely.box(6.0 + 0.5 * WALL_M, 5.0, 7.2 - 0.5 * WALL_M, 13.0)]  # passage and the main exit's vestibule
    positions, rooms, dest = [], [], []
    occupants = {k: n for k, (_, _, n) in enumerate(TOP, start=1)} | {k: n for k, (_, _, n) in enumerate(BOTTOM, start=7)}
    for k, box, door in _rooms():
        parts += [box, door]
        pts = place_pedestrians(box, occupants[k], RIMEA_RADIUS_M, rng, min_gap_m=0.3)
        positions.append(pts)
        rooms += [k] * len(pts)
        dest += [0 if k in MAIN_EXIT_ROOMS else 1] * len(pts)
    walk = shapely.union_all(parts)
    exits = {"main": shapely.box(6.0 + 0.5 * WALL_M + 0.05, 12.0, 7.2 - 0.5 * WALL_M - 0.05, 12.9),
             "second": shapely.box(19.0, 5.05, 19.9, 5.95)}
    pos = np.vstack(positions)
    return rimea_scenario("rimea_10_escape_routes", walk, exits, shapely.box(0.2, 0.2, 2.8, 4.7), len(pos), seed=seed,
                          position_m=pos, destination=np.array(dest), exit_names=("main", "second"),
                          metadata={"rimea_test": "10", "room": rooms})


register_scenario("rimea_10_escape_routes", rimea_10_escape_routes)
