"""RiMEA test 1: maintaining the walking speed in a corridor."""
from __future__ import annotations

from ....scenarios import make_scenario
from .base import RimeaTest, Verdict, register_test

LOW_S, HIGH_S = 26.0, 34.0


@register_test
class CorridorSpeed(RimeaTest):
    number = "1"
    title = "Maintaining the walking speed in a corridor"
    checks = "one pedestrian at 1.33 m/s walks a 40 m x 2 m corridor"
    criterion = f"travel time {LOW_S:g}-{HIGH_S:g} s"
    source = "RiMEA 4.1.1 A2 test 1 (40 m, 1.33 m/s, 26-34 s)"

    def scenarios(self, quick: bool, seed: int) -> dict:
        return {"corridor": make_scenario("rimea_1_corridor", seed=seed)}  # seconds either way: no reduction

    def max_time_s(self, quick: bool) -> float:
        return 120.0

    def evaluate(self, runs: dict) -> Verdict:
        run = runs["corridor"]
        t = run.evacuation_time_s
        if not run.complete:
            return Verdict("did not arrive", float("nan"), False, {"n_left": run.n_left})
        return Verdict(f"{t:.1f} s", t, LOW_S <= t <= HIGH_S, {"travel_time_s": t})

    def plot(self, ax, runs_by_backend: dict) -> None:
        for backend, runs in runs_by_backend.items():
            t, xy = runs["corridor"].positions(0)
            ax.plot(t, xy[:, 0], label=backend)
        ax.axvspan(LOW_S, HIGH_S, color="tab:green", alpha=0.15, label="RiMEA window 26-34 s")
        ax.axhline(40.0, color="k", lw=0.8)
        ax.set_xlabel("time (s)")
        ax.set_ylabel("x (m)")
        ax.legend(fontsize=8)
