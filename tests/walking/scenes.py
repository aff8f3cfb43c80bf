"""Random scenes the walking tests share: walkers and wall segments drawn in a few square metres."""
import numpy as np


def random_scene(rng, n_walkers: int, n_walls: int) -> tuple:
    """``(positions (n, 2) in [−1, 1]², walking angles (n,), unit walking directions (n, 2), walls (n_walls, 4)
    with ends in [−2, 2]²)`` drawn from ``rng``."""
    pos = rng.uniform(-1.0, 1.0, (n_walkers, 2))
    ang = rng.uniform(-np.pi, np.pi, n_walkers)
    walls = np.c_[rng.uniform(-2, 2, (n_walls, 2)), rng.uniform(-2, 2, (n_walls, 2))]
    return pos, ang, np.c_[np.cos(ang), np.sin(ang)], walls
