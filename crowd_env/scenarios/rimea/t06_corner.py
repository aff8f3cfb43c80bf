"""RiMEA test 6: twenty pedestrians walk round a left turn of a 2 m wide corridor.

RiMEA 4.1.1 (A2, Fig. 6): a corridor 2 m wide turning left, arms of 10 m plus the 2 m of the turn, twenty
persons spread uniformly over the first 6 m. Coordinates are JuPedSim's transcription (the notebook
``corner.ipynb`` and jpscore v0.8's ``test_6``): the walkable area is the L
``(0,0) (12,0) (12,12) (10,12) (10,2) (0,2)``: the first arm x 0-12 / y 0-2, the second x 10-12 / y 2-12,
the exit the door (10,12)-(12,12) at the end of the second arm. The square x 0-10 / y 2-12 inside the
turn is the region jpscore v0.8 forbids (:data:`FORBIDDEN_SQUARE`).
"""
from __future__ import annotations
from ..checks import check_count, check_positive
from ..registry import register_scenario
from ..scenario import Scenario
from .base import rimea_scenario

__all__ = ["rimea_6_corner", "FORBIDDEN_SQUARE", "CORNER_ARM_M", "CORNER_WIDTH_M"]

CORNER_ARM_M = 10.0  # each arm's length before/after the 2 m of the turn
CORNER_WIDTH_M = 2.0
# x0, y0, x1, y1: the inner-corner region no trajectory point may enter (jpscore v0.8 test_6)
FORBIDDEN_SQUARE = (0.0, CORNER_WIDTH_M, CORNER_ARM_M, CORNER_ARM_M + CORNER_WIDTH_M)


def rimea_6_corner(seed: int = 0, n_pedestrians: int = 20, spawn_length_m: float = 6.0,
                   desired_speed_m_s: float | None = None) -> Scenario:
    """Test 6: ``n_pedestrians`` (20) placed at random without overlap in the first ``spawn_length_m`` (6 m)
    of the 2 m wide first arm, walking round the left turn to the door at the end of the second arm.
    ``desired_speed_m_s`` None: the preset's desired-speed distribution (RiMEA asks for no particular
    speed in this test)."""
    n = check_count("n_pedestrians", n_pedestrians)
    check_positive(spawn_length_m=spawn_length_m)
    w, arm = CORNER_WIDTH_M, CORNER_ARM_M
    end = arm + w
    walk = [(0.0, 0.0), (end, 0.0), (end, end), (arm, end), (arm, w), (0.0, w)]
    spawn = [(0.0, 0.0), (spawn_length_m, 0.0), (spawn_length_m, w), (0.0, w)]
    lines = {"turn_in": [(arm, 0.0), (arm, w)], "turn_out": [(end, w), (arm, w)], "exit": [(end, end), (arm, end)]}
    return rimea_scenario("rimea_6_corner", walk, [[(arm, end), (end, end)]], spawn, n, seed=seed,
                          desired_speed_m_s=desired_speed_m_s, measurement_lines=lines,
                          metadata={"rimea_test": "6", "arm_m": arm, "width_m": w,
                                    "spawn_length_m": float(spawn_length_m),
                                    "forbidden_square": list(FORBIDDEN_SQUARE)})


register_scenario("rimea_6_corner", rimea_6_corner)
