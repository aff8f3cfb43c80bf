"""RiMEA test 9: a crowd leaves a large public room through four exits, then two."""
from __future__ import annotations

from ....scenarios import make_scenario
from .base import RimeaTest, Verdict, evacuation_curve, register_test

RATIO_RANGE = (1.6, 2.4)  # JuPedSim v0.8's reading of "approximately doubles"
QUICK_N = 200


@register_test
class LargeRoom(RimeaTest):
    number = "9"
    title = "Crowd leaving a large public room"
    checks = "1000 persons leave a 30 m x 20 m room by 4 doors, then by 2 (two closed)"
    criterion = (f"T(2 doors) / T(4 doors) in {RATIO_RANGE[0]:g}-{RATIO_RANGE[1]:g} (RiMEA: \"approximately "
                 "doubles\", documentation; range from JuPedSim v0.8)")
    source = "RiMEA 4.1.1 A4 test 9; geometry and 1.6-2.4 from JuPedSim v0.8 (Utest/rimea_tests/test_9)"

    def scenarios(self, quick: bool, seed: int) -> dict:
        n = QUICK_N if quick else 1000
        return {f"{k} doors": make_scenario("rimea_9_large_room", seed=seed, n_pedestrians=n, open_exits=k)
                for k in (4, 2)}

    def max_time_s(self, quick: bool) -> float:
        return 300.0 if quick else 900.0

    def evaluate(self, runs: dict) -> Verdict:
        four, two = runs["4 doors"], runs["2 doors"]
        if not (four.complete and two.complete):
            left = {k: f"{r.n_left}/{r.n_pedestrians}" for k, r in runs.items()}
            return Verdict(f"incomplete: left {left}", float("nan"), False, {"left": left})
        ratio = two.evacuation_time_s / four.evacuation_time_s
        return Verdict(f"{four.evacuation_time_s:.0f} s -> {two.evacuation_time_s:.0f} s, ratio {ratio:.2f}", ratio,
                       RATIO_RANGE[0] <= ratio <= RATIO_RANGE[1],
                       {"t4_s": four.evacuation_time_s, "t2_s": two.evacuation_time_s})

    def plot(self, ax, runs_by_backend: dict) -> None:
        for backend, runs in runs_by_backend.items():
            for (name, run), ls in zip(runs.items(), ("-", "--")):
                t, n = evacuation_curve(run)
                ax.step(t, n, ls, where="post", label=f"{backend}, {name}")
        ax.set_xlabel("time (s)")
        ax.set_ylabel("persons out")
        ax.legend(fontsize=8)
