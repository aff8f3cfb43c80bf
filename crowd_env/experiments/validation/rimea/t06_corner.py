"""RiMEA test 6: movement around a corner.

RiMEA's criterion ("they will go round the corner without passing through walls") is qualitative. The
reading here is jpscore v0.8's stricter one (``Utest/rimea_tests/test_6``): no trajectory point lies in the
square x 0-10 / y 2-12 inside the turn (:data:`~crowd_env.scenarios.rimea.t06_corner.FORBIDDEN_SQUARE`,
closed), and, as JuPedSim's current suite also asks, everybody arrives. The smallest distance of a centre
to that square is reported beside it: a body of radius r that never touches the inner walls keeps it >= r.
"""
from __future__ import annotations

import numpy as np

from ....scenarios import make_scenario
from ....scenarios.rimea.t06_corner import CORNER_ARM_M, CORNER_WIDTH_M, FORBIDDEN_SQUARE
from .base import RimeaTest, Verdict, register_test

__all__ = ["CornerTest", "forbidden_points", "distance_to_square_m"]


def forbidden_points(x, y, square=FORBIDDEN_SQUARE) -> np.ndarray:
    """Indices of the points (x, y) that lie in the closed ``square`` (x0, y0, x1, y1)."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    x0, y0, x1, y1 = square
    return np.flatnonzero((x >= x0) & (x <= x1) & (y >= y0) & (y <= y1))


def distance_to_square_m(x, y, square=FORBIDDEN_SQUARE) -> np.ndarray:
    """Distance of each point to the closed ``square`` (0 inside it)."""
    x0, y0, x1, y1 = square
    dx = np.maximum(np.maximum(x0 - np.asarray(x, dtype=np.float64), 0.0), np.asarray(x, dtype=np.float64) - x1)
    dy = np.maximum(np.maximum(y0 - np.asarray(y, dtype=np.float64), 0.0), np.asarray(y, dtype=np.float64) - y1)
    return np.hypot(dx, dy)


@register_test
class CornerTest(RimeaTest):
    number = "6"
    title = "Movement around a corner"
    checks = "20 persons in a 2 m wide corridor turn left round a corner (10 m arms + 2 m turn)"
    criterion = ("all 20 arrive and no trajectory point lies in the inner-corner square x 0-10, y 2-12 "
                 "(jpscore v0.8's reading of 'without passing through walls')")
    source = ("RiMEA 4.1.1 A2 test 6 (qualitative); forbidden square from jpscore v0.8 Utest/rimea_tests/test_6; "
              "L-shape and 6 m spawn stretch from JuPedSim's corner.ipynb; preset desired speeds")

    def scenarios(self, quick: bool, seed: int) -> dict:
        return {"corner": make_scenario("rimea_6_corner", seed=seed)}  # 20 persons: seconds either way

    def max_time_s(self, quick: bool) -> float:
        return 120.0

    def evaluate(self, runs: dict) -> Verdict:
        run = runs["corner"]
        t = run.trajectories
        inside = forbidden_points(t.x_m, t.y_m)
        clearance = float(distance_to_square_m(t.x_m, t.y_m).min()) if len(t) else float("nan")
        details = {"n_arrived": run.n_left, "n_pedestrians": run.n_pedestrians,
                   "points_in_forbidden_square": int(inside.size), "trajectory_points": len(t),
                   "min_distance_to_forbidden_square_m": clearance, "forbidden_square": list(FORBIDDEN_SQUARE)}
        if inside.size:
            k = int(inside[0])
            details["first_violation"] = {"id": int(t.id[k]), "time_s": float(t.time_s[k]),
                                          "x_m": float(t.x_m[k]), "y_m": float(t.y_m[k])}
        passed = bool(run.complete and inside.size == 0)
        measured = (f"{run.n_left}/{run.n_pedestrians} arrived, {inside.size} points in the square "
                    f"(closest centre {clearance:.2f} m from it)")
        return Verdict(measured, float(inside.size), passed, details)

    def plot(self, ax, runs_by_backend: dict) -> None:
        from matplotlib.patches import Rectangle

        x0, y0, x1, y1 = FORBIDDEN_SQUARE
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, color="tab:red", alpha=0.15,
                               label="forbidden square (jpscore v0.8)"))
        end = CORNER_ARM_M + CORNER_WIDTH_M
        ax.plot([0, end, end, CORNER_ARM_M, CORNER_ARM_M, 0], [0, 0, end, end, CORNER_WIDTH_M, CORNER_WIDTH_M],
                "k-", lw=1.0)
        colours = ["tab:blue", "tab:orange", "tab:green"]
        for c, (backend, runs) in zip(colours, runs_by_backend.items()):
            run = runs["corner"]
            for i in range(run.n_pedestrians):
                _, xy = run.positions(i)
                ax.plot(xy[:, 0], xy[:, 1], "-", color=c, lw=0.6, alpha=0.7, label=backend if i == 0 else None)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.legend(fontsize=7, loc="upper left")
