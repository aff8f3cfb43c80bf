"""RiMEA test 10: allocation of escape routes."""
from __future__ import annotations

import numpy as np

from ....scenarios import make_scenario
from .base import RimeaTest, Verdict, exits_used, register_test


@register_test
class EscapeRoutes(RimeaTest):
    number = "10"
    title = "Allocation of escape routes"
    checks = "23 persons in 12 rooms leave by their assigned exit (rooms 1-4, 7-10: main; 5, 6, 11, 12: second)"
    criterion = "everybody leaves, each through its assigned exit"
    source = "RiMEA 4.1.1 A4 test 10; rooms and doors from JuPedSim v0.8 (Utest/rimea_tests/test_10)"

    def scenarios(self, quick: bool, seed: int) -> dict:
        self._scenario = make_scenario("rimea_10_escape_routes", seed=seed)
        return {"rooms": self._scenario}

    def max_time_s(self, quick: bool) -> float:
        return 180.0

    def evaluate(self, runs: dict) -> Verdict:
        run = runs["rooms"]
        used = exits_used(run, self._scenario.geometry)
        assigned = np.asarray(self._scenario.destination)
        right = int(np.sum(used == assigned))
        return Verdict(f"{right}/{assigned.size} by their exit, {run.n_left} left", right / assigned.size,
                       bool(run.complete and right == assigned.size), {"assigned": assigned, "used": used})

    def plot(self, ax, runs_by_backend: dict) -> None:
        geom = self._scenario.geometry
        x, y = geom.walkable_area.exterior.xy
        ax.plot(x, y, "k-", lw=0.6)
        for e in geom.exits:
            ax.fill(*e.exterior.xy, color="tab:green", alpha=0.4)
        assigned = np.asarray(self._scenario.destination)
        run = next(iter(runs_by_backend.values()))["rooms"]
        for i in range(run.n_pedestrians):
            _, xy = run.positions(i)
            ax.plot(xy[:, 0], xy[:, 1], "-", lw=0.8, color="tab:blue" if assigned[i] == 0 else "tab:orange")
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)  [blue: main exit, orange: second exit; first backend]")
        ax.set_ylabel("y (m)")
