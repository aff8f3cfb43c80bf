"""RiMEA test 15: a large crowd round a corner.

RiMEA 4.1.1 (A4) compares the time for all persons to reach the destination in three scenarios, a 20 m x
81.4 m straight corridor, the corner, a 20 m x 50 m straight corridor, and says that "ideally" the corner's
lies between the two straight ones: qualitative. jpscore v0.8 (``Utest/rimea_tests/test_15``) made it pass /
fail: T_short <= T_corner <= T_long, the reading used here. 500 persons in the full version (RiMEA's and
jpscore's number), 100 in the quick one on the same geometries; desired speeds from the preset's
distribution (RiMEA asks for no particular speed here; jpscore used 1.0 m/s for all).
"""
from __future__ import annotations

import numpy as np

from ....scenarios import make_scenario
from ....scenarios.rimea.t15_large_corner import SHORT_M
from .base import BackendRun, RimeaTest, Verdict, register_test

__all__ = ["LargeCrowdCorner", "arrival_flow_per_s", "N_FULL", "N_QUICK"]

N_FULL = 500
N_QUICK = 100
_COLOURS = {"long": "tab:blue", "corner": "tab:red", "short": "tab:green"}
_STYLES = ["-", "--", ":"]


def arrival_flow_per_s(run: BackendRun) -> float:
    """The arrival rate at the exit while the middle 60 % of the crowd arrive: 0.6 N / (t_80% - t_20%)."""
    t = np.sort(run.exit_time_s[np.isfinite(run.exit_time_s)])
    if t.size < 5:
        return float("nan")
    lo, hi = t[int(0.2 * (t.size - 1))], t[int(0.8 * (t.size - 1))]
    return float((int(0.8 * (t.size - 1)) - int(0.2 * (t.size - 1))) / (hi - lo)) if hi > lo else float("nan")


@register_test
class LargeCrowdCorner(RimeaTest):
    number = "15"
    title = "Large crowd around a corner"
    checks = "500 persons: 81.4 m straight corridor, the 20 m wide corner, 50 m straight corridor"
    criterion = ("T_short <= T_corner <= T_long (all reach the exit; RiMEA: 'ideally' between, qualitative; "
                 "jpscore v0.8 made it pass/fail)")
    source = ("RiMEA 4.1.1 A4 test 15; geometry, start blocks and the pass/fail reading from jpscore v0.8 "
              "Utest/rimea_tests/test_15; preset desired speeds")

    def scenarios(self, quick: bool, seed: int) -> dict:
        n = N_QUICK if quick else N_FULL
        return {"long": make_scenario("rimea_15_corridor", seed=seed, n_pedestrians=n),
                "corner": make_scenario("rimea_15_corner", seed=seed, n_pedestrians=n),
                "short": make_scenario("rimea_15_corridor", seed=seed, n_pedestrians=n, length_m=SHORT_M)}

    def max_time_s(self, quick: bool) -> float:
        return 600.0

    def evaluate(self, runs: dict) -> Verdict:
        times = {k: r.evacuation_time_s for k, r in runs.items()}
        details = {"evacuation_time_s": times, "n_left": {k: r.n_left for k, r in runs.items()},
                   "n_pedestrians": {k: r.n_pedestrians for k, r in runs.items()},
                   "wall_time_s": {k: r.wall_time_s for k, r in runs.items()},
                   "arrival_flow_20_80_per_s": {k: arrival_flow_per_s(r) for k, r in runs.items()}}
        bad = sorted(k for k, r in runs.items() if not r.complete)
        if bad:
            return Verdict(f"incomplete: {', '.join(bad)} did not finish", float("nan"), False, details)
        ts, tc, tl = times["short"], times["corner"], times["long"]
        passed = bool(ts <= tc <= tl)
        position = (tc - ts) / (tl - ts) if tl != ts else float("nan")
        details["corner_position_between"] = position  # 0: T_short, 1: T_long
        return Verdict(f"T_short = {ts:.1f} s, T_corner = {tc:.1f} s, T_long = {tl:.1f} s", position, passed, details)

    def plot(self, ax, runs_by_backend: dict) -> None:
        for ls, (backend, runs) in zip(_STYLES, runs_by_backend.items()):
            for name, run in runs.items():
                t = np.sort(run.exit_time_s[np.isfinite(run.exit_time_s)])
                t = t[np.isfinite(t)]
                ax.step(np.concatenate(([0.0], t)), np.arange(t.size + 1), ls, where="post", color=_COLOURS.get(name),
                        label=f"{backend}: {name}")
        ax.set_xlabel("time (s)")
        ax.set_ylabel("persons arrived N(t)")
        ax.legend(fontsize=7)
