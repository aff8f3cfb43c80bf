"""RiMEA test 5: premovement times."""
from __future__ import annotations

import numpy as np

from ....scenarios import make_scenario
from .base import RimeaTest, Verdict, register_test, start_times_s

TOLERANCE_S = 0.5  # JuPedSim's suite: each start within 0.5 s of the assigned time


@register_test
class Premovement(RimeaTest):
    number = "5"
    title = "Premovement times"
    checks = "10 persons in an 8 m x 5 m room start at their times, U(10, 100) s"
    criterion = f"every start (moved > 5 cm) within {TOLERANCE_S:g} s after its premovement time; all leave"
    source = "RiMEA 4.1.1 A2 test 5; the 5 cm / 0.5 s reading is JuPedSim's suite (tests/vv/test_rimea.py)"

    def scenarios(self, quick: bool, seed: int) -> dict:
        self._scenario = make_scenario("rimea_5_premovement", seed=seed)  # 10 persons: as fast either way
        return {"room": self._scenario}

    def max_time_s(self, quick: bool) -> float:
        return 180.0

    def evaluate(self, runs: dict) -> Verdict:
        run = runs["room"]
        assigned = np.asarray(self._scenario.pedestrian_params["premovement_s"], dtype=float)
        started = start_times_s(run)
        delay = started - assigned
        ok = bool(np.all(np.isfinite(delay)) and np.all((delay >= 0.0) & (delay <= TOLERANCE_S)) and run.complete)
        worst = float(np.nanmax(np.abs(delay))) if np.isfinite(delay).any() else float("nan")
        return Verdict(f"delays {np.nanmin(delay):.2f}-{np.nanmax(delay):.2f} s", worst, ok,
                       {"premovement_s": assigned, "start_s": started, "delay_s": delay})

    def plot(self, ax, runs_by_backend: dict) -> None:
        assigned = np.asarray(self._scenario.pedestrian_params["premovement_s"], dtype=float)
        for backend, runs in runs_by_backend.items():
            ax.plot(assigned, start_times_s(runs["room"]), "o", label=backend, alpha=0.7)
        x = np.array([0.0, 105.0])
        ax.plot(x, x, "k-", lw=0.8, label="start = premovement time")
        ax.fill_between(x, x, x + TOLERANCE_S, color="tab:green", alpha=0.2, label=f"+{TOLERANCE_S:g} s")
        ax.set_xlabel("assigned premovement time (s)")
        ax.set_ylabel("observed start (moved > 5 cm) (s)")
        ax.legend(fontsize=8)
