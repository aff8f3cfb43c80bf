"""RiMEA test 12 (12a-12d in RiMEA 4.1.1): rooms joined by bottlenecks.

The older RiMEA text: a 10 m x 10 m room joined to a second one by a 1 m wide corridor, 150 adults, reaction
time 0 s. RiMEA 4.1.1 splits the test in four; its figures' dimensions were not available, so the set-ups
are those of JuPedSim's verification suite (``jupedsim-web-community:tests/vv/test_rimea.py``), with the
pedestrians in the left half of room 1 (x 0-5, y 0-10) in every variant:

* 12a: rooms x 0-10 and 10.2-20.2 joined by a 0.2 m long, 1 m wide opening (y 4.5-5.5); the goal is the
  2 m wide strip x 10.2+a .. 12.2+a across room 2 (a = distance between bottleneck and goal, 0-8 m).
* 12b: the same rooms joined by a short (0.2 m) or long (5 m) 1 m wide bottleneck; goal: the last 2 m of
  room 2 (JuPedSim takes the last 2.2 m behind the short one and 2 m behind the long one).
* 12c: three rooms x 0-10, 10.2-20.2, 20.4-25.4 joined by two identical 0.2 m long, 1 m wide openings;
  goal: the last 0.2 m of room 3. Lines at the two openings' entrances (x = 10, x = 20.2) and 2 m x 3 m
  queue areas in front of them (:data:`QUEUE_AREAS_12C`).
* 12d: a 5 m long bottleneck x 10-15 of width w (0.8, 1.0, 1.2 m) centred at y = 5; goal x 23-25.

Each scenario has the measurement line ``"bottleneck"`` across the entrance of the (first) bottleneck,
pointing downstream. ``desired_speed_m_s`` None: the preset's desired-speed distribution (RiMEA's
"adults"); replicates pass speeds drawn with their own seed (:func:`preset_desired_speeds`).
"""
from __future__ import annotations

import numpy as np

from ...core.state import sample_desired_speeds
from ..checks import check_count, check_positive
from ..registry import register_scenario
from ..scenario import Scenario, ScenarioError
from .base import RIMEA_RADIUS_M, rimea_scenario

__all__ = ["rimea_12a_goal_distance", "rimea_12b_bottleneck_length", "rimea_12c_two_bottlenecks",
           "rimea_12d_bottleneck_width", "two_rooms", "preset_desired_speeds", "ROOM_M", "SPAWN_12",
           "QUEUE_AREAS_12C", "LINES_12C"]

ROOM_M = 10.0  # rooms are ROOM_M x ROOM_M
SPAWN_12 = [(0.0, 0.0), (5.0, 0.0), (5.0, ROOM_M), (0.0, ROOM_M)]  # the left half of room 1
LINES_12C = {"bottleneck_1": [(10.0, 4.5), (10.0, 5.5)], "bottleneck_2": [(20.2, 4.5), (20.2, 5.5)]}
QUEUE_AREAS_12C = {"queue_1": (8.0, 3.5, 10.0, 6.5), "queue_2": (18.2, 3.5, 20.2, 6.5)}  # x0, y0, x1, y1


def preset_desired_speeds(n: int, seed: int) -> np.ndarray:
    """(n,) desired speeds from the preset's distribution (N(1.34, 0.26) m/s truncated at ±2σ), drawn with
    ``seed``: what a run would draw itself, fixed in the scenario so that replicates differ."""
    return sample_desired_speeds(int(n), np.random.default_rng(int(seed)))


def two_rooms(length_m: float, width_m: float) -> list:
    """Outer ring of two 10 m x 10 m rooms joined at mid-height by a corridor ``length_m`` long and
    ``width_m`` wide: room 1 x 0-10, corridor x 10-(10+length_m), room 2 beyond it."""
    check_positive(length_m=length_m, width_m=width_m)
    if width_m >= ROOM_M:
        raise ScenarioError(f"the bottleneck width {width_m} m must be narrower than the room ({ROOM_M} m)")
    lo, hi = 0.5 * (ROOM_M - width_m), 0.5 * (ROOM_M + width_m)
    x1 = ROOM_M + length_m
    x2 = x1 + ROOM_M
    return [(0.0, 0.0), (ROOM_M, 0.0), (ROOM_M, lo), (x1, lo), (x1, 0.0), (x2, 0.0), (x2, ROOM_M), (x1, ROOM_M),
            (x1, hi), (ROOM_M, hi), (ROOM_M, ROOM_M), (0.0, ROOM_M)]


def _strip(x0: float, x1: float) -> list:
    return [(x0, 0.0), (x1, 0.0), (x1, ROOM_M), (x0, ROOM_M)]


def _speeds(desired_speed_m_s, n):
    if desired_speed_m_s is None:
        return None
    v = np.asarray(desired_speed_m_s, dtype=np.float64)
    return float(v) if v.ndim == 0 else v


def _entrance_line(width_m: float) -> dict:
    lo, hi = 0.5 * (ROOM_M - width_m), 0.5 * (ROOM_M + width_m)
    return {"bottleneck": [(ROOM_M, lo), (ROOM_M, hi)]}


def _n(n_pedestrians) -> int:
    n = check_count("n_pedestrians", n_pedestrians)
    if n > 150:
        # 150 in the 50 m² half room is 3 /m²; more does not fit at random (see place_pedestrians)
        raise ScenarioError(f"test 12 places its crowd in the left half of room 1 (50 m²): at most 150 "
                            f"pedestrians, got {n}")
    return n


def rimea_12a_goal_distance(seed: int = 0, goal_distance_m: float = 0.0, n_pedestrians: int = 150,
                            desired_speed_m_s=None) -> Scenario:
    """Test 12a: the goal, a 2 m wide strip across room 2, starts ``goal_distance_m`` (a, 0-8 m) behind the
    0.2 m long, 1 m wide opening between the two rooms."""
    n = _n(n_pedestrians)
    a = float(goal_distance_m)
    if not (np.isfinite(a) and 0.0 <= a <= ROOM_M - 2.0):
        raise ScenarioError(f"goal_distance_m must lie in [0, {ROOM_M - 2.0:g}] (the 2 m goal strip inside room 2), "
                            f"got {goal_distance_m!r}")
    x0 = ROOM_M + 0.2 + a
    return rimea_scenario("rimea_12a_goal_distance", two_rooms(0.2, 1.0), [_strip(x0, x0 + 2.0)], SPAWN_12, n,
                          seed=seed, desired_speed_m_s=_speeds(desired_speed_m_s, n),
                          measurement_lines=_entrance_line(1.0),
                          metadata={"rimea_test": "12a", "goal_distance_m": a, "bottleneck_length_m": 0.2,
                                    "bottleneck_width_m": 1.0})


def rimea_12b_bottleneck_length(seed: int = 0, bottleneck_length_m: float = 5.0, n_pedestrians: int = 150,
                                desired_speed_m_s=None) -> Scenario:
    """Test 12b: the two rooms joined by a 1 m wide bottleneck ``bottleneck_length_m`` long (0.2 m short,
    5 m long); the goal is the last 2 m of room 2."""
    n = _n(n_pedestrians)
    check_positive(bottleneck_length_m=bottleneck_length_m)
    x2 = 2.0 * ROOM_M + bottleneck_length_m
    return rimea_scenario("rimea_12b_bottleneck_length", two_rooms(bottleneck_length_m, 1.0),
                          [_strip(x2 - 2.0, x2)], SPAWN_12, n, seed=seed,
                          desired_speed_m_s=_speeds(desired_speed_m_s, n),
                          measurement_lines={**_entrance_line(1.0),
                                             "bottleneck_end": [(ROOM_M + bottleneck_length_m, 4.5),
                                                                (ROOM_M + bottleneck_length_m, 5.5)]},
                          metadata={"rimea_test": "12b", "bottleneck_length_m": float(bottleneck_length_m),
                                    "bottleneck_width_m": 1.0})


def rimea_12c_two_bottlenecks(seed: int = 0, n_pedestrians: int = 150, desired_speed_m_s=None) -> Scenario:
    """Test 12c: three rooms (x 0-10, 10.2-20.2, 20.4-25.4, all 10 m high) joined by two identical 0.2 m
    long, 1 m wide openings; the goal is the last 0.2 m of room 3."""
    n = _n(n_pedestrians)
    walk = [(0.0, 0.0), (10.0, 0.0), (10.0, 4.5), (10.2, 4.5), (10.2, 0.0), (20.2, 0.0), (20.2, 4.5), (20.4, 4.5),
            (20.4, 0.0), (25.4, 0.0), (25.4, 10.0), (20.4, 10.0), (20.4, 5.5), (20.2, 5.5), (20.2, 10.0),
            (10.2, 10.0), (10.2, 5.5), (10.0, 5.5), (10.0, 10.0), (0.0, 10.0)]
    return rimea_scenario("rimea_12c_two_bottlenecks", walk, [_strip(25.2, 25.4)], SPAWN_12, n, seed=seed,
                          desired_speed_m_s=_speeds(desired_speed_m_s, n), measurement_lines=LINES_12C,
                          metadata={"rimea_test": "12c",
                                    "queue_areas": {k: list(v) for k, v in QUEUE_AREAS_12C.items()}})


def rimea_12d_bottleneck_width(seed: int = 0, width_m: float = 1.0, n_pedestrians: int = 150,
                               desired_speed_m_s=None) -> Scenario:
    """Test 12d: a 5 m long bottleneck (x 10-15) of width ``width_m`` (0.8, 1.0, 1.2 m) between the two
    rooms; the goal is x 23-25. The flow is counted at the bottleneck's entrance (line ``"bottleneck"``)."""
    n = _n(n_pedestrians)
    check_positive(width_m=width_m)
    if width_m <= 2.0 * RIMEA_RADIUS_M:
        raise ScenarioError(f"a bottleneck of {width_m} m is not wider than a pedestrian ({2 * RIMEA_RADIUS_M} m)")
    return rimea_scenario("rimea_12d_bottleneck_width", two_rooms(5.0, width_m), [_strip(23.0, 25.0)], SPAWN_12, n,
                          seed=seed, desired_speed_m_s=_speeds(desired_speed_m_s, n),
                          measurement_lines=_entrance_line(width_m),
                          metadata={"rimea_test": "12d", "bottleneck_width_m": float(width_m),
                                    "bottleneck_length_m": 5.0})


register_scenario("rimea_12a_goal_distance", rimea_12a_goal_distance)
register_scenario("rimea_12b_bottleneck_length", rimea_12b_bottleneck_length)
register_scenario("rimea_12c_two_bottlenecks", rimea_12c_two_bottlenecks)
register_scenario("rimea_12d_bottleneck_width", rimea_12d_bottleneck_width)
