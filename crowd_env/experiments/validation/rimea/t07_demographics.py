"""RiMEA test 7: allocation of demographic parameters (walking speeds by age)."""
from __future__ import annotations

import numpy as np

from ....scenarios import make_scenario
from ....scenarios.demographics import WEIDMANN_SPEEDS_BY_AGE_M_S
from .base import RimeaTest, Verdict, register_test, walking_speeds_m_s

TOLERANCE_M_S = 0.03  # JuPedSim's suite: observed speeds within the band +- 0.03 m/s


@register_test
class Demographics(RimeaTest):
    number = "7"
    title = "Allocation of demographic parameters"
    checks = "50 adults aged 20-70, abreast in a wide hall, walk at their age's speed (Weidmann's bands)"
    criterion = (f"each walking speed within its age band +- {TOLERANCE_M_S:g} m/s and the age groups' mean "
                 "speeds non-increasing with age")
    source = ("RiMEA 4.1.1 A2 test 7 (\"consistent with the distribution\"); bands and reading from JuPedSim's "
              "suite (rimea07_demographic.py, tests/vv/test_rimea.py)")

    def scenarios(self, quick: bool, seed: int) -> dict:
        self._scenario = make_scenario("rimea_7_demographics", seed=seed)  # 50 free walkers: seconds
        return {"corridor": self._scenario}

    def max_time_s(self, quick: bool) -> float:
        return 120.0

    def evaluate(self, runs: dict) -> Verdict:
        run = runs["corridor"]
        ages = np.asarray(self._scenario.metadata["ages_years"])
        speed = walking_speeds_m_s(run)
        lo = np.array([WEIDMANN_SPEEDS_BY_AGE_M_S[int(a)][0] for a in ages]) - TOLERANCE_M_S
        hi = np.array([WEIDMANN_SPEEDS_BY_AGE_M_S[int(a)][1] for a in ages]) + TOLERANCE_M_S
        inside = np.isfinite(speed) & (speed >= lo) & (speed <= hi)
        groups = sorted(set(ages.tolist()))
        means = np.array([np.nanmean(speed[ages == a]) for a in groups])
        monotone = bool(np.all(np.diff(means) <= 0.0))
        ok = bool(inside.all() and monotone and run.complete)
        return Verdict(f"{int(inside.sum())}/{ages.size} in band; means {', '.join(f'{m:.2f}' for m in means)} m/s",
                       float(inside.mean()), ok, {"ages": ages, "speed_m_s": speed, "group_ages": groups,
                                                  "group_mean_m_s": means})

    def plot(self, ax, runs_by_backend: dict) -> None:
        ages = np.asarray(self._scenario.metadata["ages_years"])
        for a, (lo, hi) in WEIDMANN_SPEEDS_BY_AGE_M_S.items():
            ax.fill_between([a - 3, a + 3], lo - TOLERANCE_M_S, hi + TOLERANCE_M_S, color="0.85")
        for k, (backend, runs) in enumerate(runs_by_backend.items()):
            ax.plot(ages + 1.2 * (k - 1), walking_speeds_m_s(runs["corridor"]), "o", ms=4, alpha=0.7, label=backend)
        ax.set_xlabel("age (years)")
        ax.set_ylabel("walking speed (m/s)")
        ax.legend(fontsize=8, title="grey: band +- 0.03 m/s", title_fontsize=8)
