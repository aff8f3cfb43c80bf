"""RiMEA test 11: choice of escape route."""
from __future__ import annotations

import numpy as np

from ....scenarios import make_scenario
from .base import RimeaTest, Verdict, exits_used, register_test

QUICK_N = 300


@register_test
class RouteChoice(RimeaTest):
    number = "11"
    title = "Choice of escape route"
    checks = "1000 persons packed on the left of a 30 m x 20 m room choose between a near and a far door"
    criterion = ("everybody leaves; more by the near door than by the far one; at least one by the far door "
                 "(RiMEA: prefer the near exit and queue there, some use the other; reading ours)")
    source = "RiMEA 4.1.1 A4 test 11 (qualitative); geometry from JuPedSim v0.8 (Utest/rimea_tests/test_11)"

    def scenarios(self, quick: bool, seed: int) -> dict:
        self._scenario = make_scenario("rimea_11_route_choice", seed=seed, n_pedestrians=QUICK_N if quick else 1000)
        return {"room": self._scenario}

    def max_time_s(self, quick: bool) -> float:
        return 400.0 if quick else 1200.0

    def evaluate(self, runs: dict) -> Verdict:
        run = runs["room"]
        used = exits_used(run, self._scenario.geometry)
        near, far = int(np.sum(used == 0)), int(np.sum(used == 1))
        ok = bool(run.complete and near > far and far >= 1)
        return Verdict(f"near {near}, far {far}" + ("" if run.complete else f", {run.n_pedestrians - run.n_left} left "
                                                                         "inside"), far / max(1, near + far), ok,
                       {"near": near, "far": far, "evacuation_time_s": run.evacuation_time_s})

    def plot(self, ax, runs_by_backend: dict) -> None:
        geom = self._scenario.geometry
        ax.plot(*geom.walkable_area.exterior.xy, "k-", lw=0.6)
        run = next(iter(runs_by_backend.values()))["room"]
        used = exits_used(run, geom)
        for i in range(0, run.n_pedestrians, max(1, run.n_pedestrians // 150)):
            _, xy = run.positions(i)
            ax.plot(xy[:, 0], xy[:, 1], "-", lw=0.5, color={0: "tab:blue", 1: "tab:orange"}.get(int(used[i]), "0.5"))
        for backend, runs in runs_by_backend.items():
            u = exits_used(runs["room"], geom)
            ax.plot([], [], " ", label=f"{backend}: near {int(np.sum(u == 0))}, far {int(np.sum(u == 1))}")
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)  [paths of the first backend: blue near door, orange far door]")
        ax.set_ylabel("y (m)")
        ax.legend(fontsize=8, loc="lower right")
