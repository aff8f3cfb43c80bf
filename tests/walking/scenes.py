"""Scenes the walking tests share: walkers and wall segments drawn in a few square metres; a wall with a narrow gap."""
import numpy as np


def random_scene(rng, n_walkers: int, n_walls: int) -> tuple:
    """``(positions (n, 2) in [−1, 1]², walking angles (n,), unit walking directions (n, 2), walls (n_walls, 4)
    with ends in [−2, 2]²)`` drawn from ``rng``."""
    pos = rng.uniform(-1.0, 1.0, (n_walkers, 2))
    ang = rng.uniform(-np.pi, np.pi, n_walkers)
    walls = np.c_[rng.uniform(-2, 2, (n_walls, 2)), rng.uniform(-2, 2, (n_walls, 2))]
    return pos, ang, np.c_[np.cos(ang), np.sin(ang)], walls


def gap_world(half_m: float = 0.20) -> tuple:
    """``(geometry, navigation)``: a room 9 m × 4 m crossed at x = 1.0-1.1 m by a wall with a gap of 2 ``half_m`` on
    its axis (0.40 m: narrower than a 0.46 m body's shoulders, wider than its 0.25 m depth), the exit at its far
    end."""
    from shapely.geometry import Polygon, box

    from crowd_env.core.geometry import Geometry
    from crowd_env.walking.navigation import NavigationField

    room = Polygon([(-3, -2), (6, -2), (6, 2), (-3, 2)])
    wall = box(1.0, -2.0, 1.1, -half_m).union(box(1.0, half_m, 1.1, 2.0))
    geometry = Geometry(room.difference(wall), exits=[box(5.5, -2, 6, 2)])
    return geometry, NavigationField(geometry)
