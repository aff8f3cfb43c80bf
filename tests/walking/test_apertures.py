"""The widths across a walker's path (crowd_env.walking.apertures): the walls' widths line by line by hand, and the
aperture without neighbours equal to the narrowest of them (the two functions the shoulder turn and vision's door
read)."""
import numpy as np
import pytest

from crowd_env.walking.apertures import LINE_STEP_M, apertures_along, line_count, wall_sides_m

from .scenes import random_scene

NO_PAIRS = np.zeros((0, 2), np.int64)


def test_wall_sides_through_a_door_by_hand():
    """Walking along +x in a 1.8 m corridor towards a 0.95 m door in a wall 0.1 m thick at x = 1.02: the lines (every
    LINE_STEP_M at most, from the centre to 1.5 m ahead) read 1.8 m before the door, 0.95 m within it, 1.8 m past it,
    0.8 + 1.0 m (the walker 0.1 m left of the axis) and 0.375 + 0.575 m in the door on its left and right."""
    walls = np.array([[-5.0, -0.9, 5.0, -0.9], [-5.0, 0.9, 5.0, 0.9],
                      [1.02, -0.9, 1.02, -0.475], [1.02, 0.475, 1.02, 0.9],
                      [1.02, -0.475, 1.12, -0.475], [1.02, 0.475, 1.12, 0.475]])
    reach = np.array([1.5])
    sides = wall_sides_m(np.array([[0.0, 0.1]]), np.arange(1), np.array([[1.0, 0.0]]), np.zeros(1), walls, 0.0, reach)
    n_lines = line_count(reach)
    assert n_lines == int(np.ceil(1.5 / LINE_STEP_M)) + 1 and sides.shape == (1, n_lines, 2)
    s = np.linspace(0.0, 1.5, n_lines)
    door = (s > 1.02) & (s < 1.12)  # the lines at s = 1.05 and 1.1
    np.testing.assert_allclose(sides[0, :, 0], np.where(door, 0.375, 0.8), atol=1e-12)
    np.testing.assert_allclose(sides[0, :, 1], np.where(door, 0.575, 1.0), atol=1e-12)


def test_aperture_without_neighbours_is_the_narrowest_wall_width():
    """Random walls and walkers: apertures_along with no pairs equals the narrowest of wall_sides_m's lines."""
    rng = np.random.default_rng(7)
    for _ in range(10):
        n = 5
        pos, ang, walk, walls = random_scene(rng, n, 4)
        reach = rng.uniform(0.2, 1.8, n)
        aperture, left, right = apertures_along(pos, np.full(n, 0.23), np.arange(n), walk, ang, NO_PAIRS, walls, 0.0,
                                                reach)
        sides = wall_sides_m(pos, np.arange(n), walk, ang, walls, 0.0, reach)
        np.testing.assert_allclose(aperture, sides.sum(axis=2).min(axis=1), atol=1e-12)
        np.testing.assert_allclose(left + right, aperture, atol=1e-12)
        assert np.all(aperture > 0.0)


def test_a_periodic_strip_has_walls_across_its_seam():
    """In a strip periodic along x (cell [0, 10), walls along y = ±0.35 over the cell), a walker 0.5 m before the seam
    sees the walls on every line of its 1.5 m stretch, those beyond the seam too: 0.7 m wide all along (without the
    periodic cell the lines past x = 10 would see no wall)."""
    walls = np.array([[0.0, -0.35, 10.0, -0.35], [0.0, 0.35, 10.0, 0.35]])
    args = (np.array([[9.5, 0.0]]), np.arange(1), np.array([[1.0, 0.0]]), np.zeros(1), walls)
    sides = wall_sides_m(*args, 10.0, np.array([1.5]))
    np.testing.assert_allclose(sides[0].sum(axis=1), 0.7, atol=1e-12)
    open_ended = wall_sides_m(*args, 0.0, np.array([1.5]))
    assert open_ended[0, -1].sum() > 5.0
    aperture, _, _ = apertures_along(args[0], np.full(1, 0.23), *args[1:4], NO_PAIRS, walls, 10.0, np.array([1.5]))
    assert aperture[0] == pytest.approx(0.7, abs=1e-12)
