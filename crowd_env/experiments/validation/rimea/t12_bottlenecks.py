"""RiMEA test 12a-12d: the effect of bottlenecks (RiMEA 4.1.1 A4; one test in older editions).

RiMEA's own text asks only for documentation ("a jam may occur only in room 1 and not in room 2 ... should
not be treated as an exclusion criterion"); 4.1.1 splits the test in four and states expected trends. The
quantitative readings are JuPedSim's verification suite's (``jupedsim-web-community:tests/vv/test_rimea.py``),
measured here on the trajectories (line crossings, :func:`crowd_env.analysis.flow.trajectory_crossings`):

* 12a: the time room 1 is cleared (the last crossing of the bottleneck's entrance line x = 10, RiMEA's
  "time for the persons to leave room 1") for goal distances a; T1(a=0) <= T1(a=8), on the mean of the
  replicates. (JuPedSim asserts the same on the total evacuation time, which also contains the walk of a
  metres and so holds trivially; it is reported beside it.)
* 12b: total evacuation time, short (0.2 m) vs long (5 m) bottleneck; T_long > T_short on the mean of the
  replicates (JuPedSim's assertion). The room-1 clearance times are reported beside it.
* 12c: one run; all cross both lines; the peak and the mean of the 10 largest per-frame counts in the
  2 m x 3 m queue area before opening 1 exceed those before opening 2; the first crossing of line 1 comes
  before that of line 2.
* 12d: flow J = N / Δt (first to last crossing, Kabalan Eq. 22's convention) at the entrance of a 5 m long
  bottleneck of width 0.8, 1.0, 1.2 m; J(0.8) < J(1.0) < J(1.2) on the mean of the replicates, plotted
  against J = 1.9·w (the line JuPedSim's notebook draws; whether RiMEA or JuPedSim chose it is unclear).

Replicates: 12a, 12b and 12d compare a few seconds' difference between runs whose own scatter is of the
same order, so each variant is run ``REPLICATES`` times (the suite's seed + k for the placement and, drawn
from the preset's distribution, the desired speeds: variants share their replicates' crowds, common random
numbers). Populations: 150 (RiMEA's "150 adults") in the full versions, 50 in the quick ones, in the left
half of room 1, desired speeds from the preset's distribution (RiMEA's adults; no constant speed asked),
reaction time 0.
"""
from __future__ import annotations

import numpy as np

from ....analysis.flow import MeasurementLine, trajectory_crossings
from ....scenarios import make_scenario
from ....scenarios.rimea.t12_bottlenecks import LINES_12C, QUEUE_AREAS_12C, preset_desired_speeds
from .base import BackendRun, RimeaTest, Verdict, register_test

__all__ = ["GoalDistance12a", "BottleneckLength12b", "Congestion12c", "BottleneckWidth12d", "crossing_times_s",
           "area_counts", "clearance_time_s", "REPLICATES", "N_FULL", "N_QUICK",
           "REFERENCE_FLOW_PER_M_S"]

REPLICATES = 3
N_FULL = 150
N_QUICK = 50
REFERENCE_FLOW_PER_M_S = 1.9  # JuPedSim notebook's line J = 1.9 w (provenance unclear)
ENTRANCE_1M = ((10.0, 4.5), (10.0, 5.5))
_COLOURS = ["tab:blue", "tab:orange", "tab:green"]


def crossing_times_s(run: BackendRun, segment, first_only: bool = True) -> tuple:
    """``(ids, times)`` of the crossings of ``segment`` ((x0, y0), (x1, y1), counted along its clockwise normal,
    see :class:`~crowd_env.analysis.flow.MeasurementLine`) in the run's trajectories, sorted by time."""
    t = run.trajectories
    if len(t) == 0:
        return np.zeros(0, np.int64), np.zeros(0)
    return trajectory_crossings(t.frame, t.id, t.x_m, t.y_m, t.frame_time_s, MeasurementLine(*segment),
                                first_only=first_only)


def clearance_time_s(run: BackendRun, segment=ENTRANCE_1M) -> tuple:
    """``(time, n)``: when the last crossing of ``segment`` happened and how many distinct pedestrians crossed
    it (the time is nan unless every pedestrian crossed).

    The goal of every test 12 variant lies behind the segment, so a pedestrian that left crossed it: one
    that left without a crossing in the frames (it went from before the segment into the goal between two
    frames, which JuPedSim's social force model does at up to 2.5 m/s in test 12a with the goal right
    behind the opening) counts as crossing when it left, its exit time (it crossed no later)."""
    ids, times = crossing_times_s(run, segment, first_only=False)
    crossed = np.unique(ids).astype(np.int64)
    left = np.flatnonzero(np.isfinite(run.exit_time_s))
    unseen = np.setdiff1d(left, crossed)
    times = np.concatenate([np.asarray(times, float), run.exit_time_s[unseen]])
    n = int(crossed.size + unseen.size)
    return (float(times.max()) if n == run.n_pedestrians and n else float("nan")), n


def area_counts(run: BackendRun, box) -> tuple:
    """``(frames, counts)``: the number of centres inside the closed rectangle ``box`` (x0, y0, x1, y1) in each
    recorded frame."""
    t = run.trajectories
    x0, y0, x1, y1 = box
    frames = np.arange(int(t.frame.max()) + 1) if len(t) else np.zeros(0, np.int64)
    inside = (t.x_m >= x0) & (t.x_m <= x1) & (t.y_m >= y0) & (t.y_m <= y1)
    counts = np.bincount(t.frame[inside], minlength=frames.size) if len(t) else np.zeros(0, np.int64)
    return frames, counts


def _incomplete(runs: dict):
    bad = sorted(k for k, r in runs.items() if not r.complete)
    if bad:
        return Verdict(f"incomplete: {', '.join(bad)} did not finish", float("nan"), False,
                       {"incomplete": bad, "n_left": {k: runs[k].n_left for k in bad}})
    return None


class _Bottleneck12(RimeaTest):
    """What 12a, 12b and 12d share: variants x replicates, named ``<variant>/r<k>``."""

    def max_time_s(self, quick: bool) -> float:
        return 400.0

    @staticmethod
    def _n(quick: bool) -> int:
        return N_QUICK if quick else N_FULL

    def _replicates(self, scenario: str, variants: dict, quick: bool, seed: int) -> dict:
        n = self._n(quick)
        out = {}
        for k in range(REPLICATES):
            speeds = preset_desired_speeds(n, seed + k)
            for label, options in variants.items():
                out[f"{label}/r{k}"] = make_scenario(scenario, seed=seed + k, n_pedestrians=n,
                                                     desired_speed_m_s=speeds, **options)
        return out

    def _times(self, runs: dict) -> tuple:
        """``(room1, total)``: variant -> the room-1 clearance times and the total evacuation times per replicate."""
        return (self._by_variant(runs, lambda r: clearance_time_s(r)[0]),
                self._by_variant(runs, lambda r: r.evacuation_time_s))

    @staticmethod
    def _by_variant(runs: dict, value) -> dict:
        """variant label -> [value(run) per replicate]."""
        out: dict = {}
        for name, run in runs.items():
            label = name.split("/")[0]
            out.setdefault(label, []).append(value(run))
        return out


@register_test
class GoalDistance12a(_Bottleneck12):
    number = "12a"
    title = "Bottlenecks: position of the goal"
    checks = "time to clear room 1 through a 1 m opening for goal distances a behind it"
    criterion = ("mean over 3 replicates of the room-1 clearance time (last crossing of the opening) "
                 "T1(a=0) <= T1(a=8) (JuPedSim's check, which it applies to the total time)")
    source = ("RiMEA 4.1.1 A4 test 12a (expected: time decreases as the goal nears the bottleneck; a 0-10 m); set-up "
              "and a <= 8 from JuPedSim tests/vv/test_rimea.py; room-1 time as in JuPedSim's notebook")

    def _distances(self, quick: bool) -> tuple:
        return (0.0, 8.0) if quick else (0.0, 2.0, 4.0, 6.0, 8.0)

    def scenarios(self, quick: bool, seed: int) -> dict:
        return self._replicates("rimea_12a_goal_distance",
                                {f"a={a:g}": {"goal_distance_m": a} for a in self._distances(quick)}, quick, seed)

    def evaluate(self, runs: dict) -> Verdict:
        bad = _incomplete(runs)
        if bad:
            return bad
        room1, total = self._times(runs)
        mean1 = {k: float(np.mean(v)) for k, v in room1.items()}
        t0, t8 = mean1["a=0"], mean1["a=8"]
        passed = bool(np.isfinite(t0) and np.isfinite(t8) and t0 <= t8)
        diff = np.asarray(room1["a=8"]) - np.asarray(room1["a=0"])  # paired: replicate k shares its crowd
        se = float(np.std(diff, ddof=1) / np.sqrt(diff.size)) if diff.size > 1 else float("nan")
        details = {"room1_difference_a8_minus_a0_s": diff.tolist(), "room1_difference_se_s": se,
                   "room1_clearance_s": room1, "room1_clearance_mean_s": mean1, "total_evacuation_s": total,
                   "total_evacuation_mean_s": {k: float(np.mean(v)) for k, v in total.items()},
                   "room1_sd_s": {k: float(np.std(v, ddof=1)) if len(v) > 1 else 0.0 for k, v in room1.items()}}
        return Verdict(f"T1(a=0) = {t0:.1f} s, T1(a=8) = {t8:.1f} s, difference {t8 - t0:+.1f} ± {se:.1f} s (SE); "
                       f"total {np.mean(total['a=0']):.1f} / {np.mean(total['a=8']):.1f} s", t8 - t0, passed, details)

    def plot(self, ax, runs_by_backend: dict) -> None:
        for c, (backend, runs) in zip(_COLOURS, runs_by_backend.items()):
            room1, total = self._times(runs)
            a = np.array([float(k.split("=")[1]) for k in room1])
            for x, vals in zip(a, room1.values()):
                ax.plot([x] * len(vals), vals, "o", color=c, alpha=0.35, ms=4)
            ax.plot(a, [np.mean(v) for v in room1.values()], "-o", color=c, label=f"{backend}: room 1 cleared")
            ax.plot(a, [np.mean(v) for v in total.values()], "--s", color=c, ms=4,
                    label=f"{backend}: all at the goal")
        ax.set_xlabel("goal distance a (m)")
        ax.set_ylabel("time (s)")
        ax.legend(fontsize=7)


@register_test
class BottleneckLength12b(_Bottleneck12):
    number = "12b"
    title = "Bottlenecks: length"
    checks = "evacuation through a 1 m wide bottleneck 0.2 m vs 5 m long"
    criterion = "mean over 3 replicates of the total evacuation time T_long > T_short (JuPedSim's check)"
    source = ("RiMEA 4.1.1 A4 test 12b (expected: a longer bottleneck increases the evacuation time); 0.2 m / 5 m and "
              "the check from JuPedSim tests/vv/test_rimea.py")

    LENGTHS = {"short": 0.2, "long": 5.0}

    def scenarios(self, quick: bool, seed: int) -> dict:
        return self._replicates("rimea_12b_bottleneck_length",
                                {k: {"bottleneck_length_m": v} for k, v in self.LENGTHS.items()}, quick, seed)

    def evaluate(self, runs: dict) -> Verdict:
        bad = _incomplete(runs)
        if bad:
            return bad
        room1, total = self._times(runs)
        ts, tl = float(np.mean(total["short"])), float(np.mean(total["long"]))
        details = {"total_evacuation_s": total, "room1_clearance_s": room1,
                   "room1_clearance_mean_s": {k: float(np.mean(v)) for k, v in room1.items()},
                   "extra_walk_at_1.34_m_s_s": (self.LENGTHS["long"] - self.LENGTHS["short"]) / 1.34}
        return Verdict(f"T_short = {ts:.1f} s, T_long = {tl:.1f} s (room 1 cleared {np.mean(room1['short']):.1f} / "
                       f"{np.mean(room1['long']):.1f} s)", tl - ts, bool(tl > ts), details)

    def plot(self, ax, runs_by_backend: dict) -> None:
        width = 0.8 / max(1, 2 * len(runs_by_backend))
        for j, (backend, runs) in enumerate(runs_by_backend.items()):
            room1, total = self._times(runs)
            x = np.arange(len(total))
            off = (2 * j) * width
            ax.bar(x + off, [np.mean(v) for v in total.values()], width,
                   yerr=[np.std(v, ddof=1) for v in total.values()], color=_COLOURS[j % 3], label=f"{backend}: total")
            ax.bar(x + off + width, [np.mean(v) for v in room1.values()], width,
                   yerr=[np.std(v, ddof=1) for v in room1.values()], color=_COLOURS[j % 3], alpha=0.45,
                   label=f"{backend}: room 1 cleared")
            ax.set_xticks(x + width / 2 * (2 * len(runs_by_backend) - 1))
            ax.set_xticklabels([f"{k} ({self.LENGTHS[k]:g} m)" for k in total])
        ax.set_ylabel("time (s), mean ± sd of 3 replicates")
        ax.legend(fontsize=7)


@register_test
class Congestion12c(RimeaTest):
    number = "12c"
    title = "Bottlenecks: influence of congestion"
    checks = "three rooms, two identical 1 m openings in series: the queue forms before the first only"
    criterion = ("all cross both lines; queue area before opening 1 has the larger peak count and the larger mean "
                 "of its 10 largest counts; first crossing of line 1 before line 2 (JuPedSim's checks)")
    source = ("RiMEA 4.1.1 A4 test 12c (expected: no congestion at bottleneck 2); geometry, 2 m x 3 m queue areas and "
              "checks from JuPedSim tests/vv/test_rimea.py")

    def scenarios(self, quick: bool, seed: int) -> dict:
        n = N_QUICK if quick else N_FULL
        return {"three_rooms": make_scenario("rimea_12c_two_bottlenecks", seed=seed, n_pedestrians=n)}

    def max_time_s(self, quick: bool) -> float:
        return 400.0

    @staticmethod
    def measure(run: BackendRun) -> dict:
        out = {}
        for k, (line, area) in enumerate(zip(LINES_12C.values(), QUEUE_AREAS_12C.values()), start=1):
            ids, times = crossing_times_s(run, line)
            _, counts = area_counts(run, area)
            top = np.sort(counts)[::-1][:10]
            span = float(times.max() - times.min()) if times.size > 1 else 0.0
            out[k] = {"n_crossed": int(np.unique(ids).size), "first_crossing_s": float(times.min()) if times.size
                      else float("nan"), "last_crossing_s": float(times.max()) if times.size else float("nan"),
                      "flow_per_s": times.size / span if span > 0 else float("nan"),
                      "peak_queue": int(counts.max()) if counts.size else 0,
                      "top10_mean_queue": float(top.mean()) if top.size else 0.0}
        return out

    def evaluate(self, runs: dict) -> Verdict:
        run = runs["three_rooms"]
        m = self.measure(run)
        q1, q2 = m[1], m[2]
        n = run.n_pedestrians
        checks = {"all_cross_both": q1["n_crossed"] == n and q2["n_crossed"] == n,
                  "peak_1_gt_2": q1["peak_queue"] > q2["peak_queue"],
                  "top10_1_gt_2": q1["top10_mean_queue"] > q2["top10_mean_queue"],
                  "first_1_before_2": q1["first_crossing_s"] < q2["first_crossing_s"]}
        passed = bool(run.complete and all(checks.values()))
        measured = (f"queue peak {q1['peak_queue']} vs {q2['peak_queue']}, top-10 mean {q1['top10_mean_queue']:.1f} vs "
                    f"{q2['top10_mean_queue']:.1f}; crossed {q1['n_crossed']}/{q2['n_crossed']} of {n}; first "
                    f"{q1['first_crossing_s']:.1f} s / {q2['first_crossing_s']:.1f} s; J {q1['flow_per_s']:.2f} / "
                    f"{q2['flow_per_s']:.2f} 1/s")
        return Verdict(measured, q1["top10_mean_queue"] - q2["top10_mean_queue"], passed,
                       {"line_1": q1, "line_2": q2, "checks": checks, "complete": run.complete})

    def plot(self, ax, runs_by_backend: dict) -> None:
        ax2 = ax.twinx()
        for c, (backend, runs) in zip(_COLOURS, runs_by_backend.items()):
            run = runs["three_rooms"]
            for k, (line, area, ls) in enumerate(zip(LINES_12C.values(), QUEUE_AREAS_12C.values(), ("-", "--")), 1):
                _, times = crossing_times_s(run, line)
                ax.step(np.concatenate(([0.0], times)), np.arange(times.size + 1), ls, color=c, where="post",
                        label=f"{backend}: N(t) at line {k}")
                frames, counts = area_counts(run, area)
                ax2.plot(frames / run.trajectories.frame_rate_per_s, counts, ls, color=c, alpha=0.35, lw=0.8,
                         label=f"{backend}: in queue area {k}")
        ax.set_xlabel("time (s)")
        ax.set_ylabel("pedestrians crossed (bold)")
        ax2.set_ylabel("pedestrians in the 2 m x 3 m queue area (faint)")
        ax.legend(fontsize=7, loc="upper left")
        ax2.legend(fontsize=7, loc="lower right")


@register_test
class BottleneckWidth12d(_Bottleneck12):
    number = "12d"
    title = "Bottlenecks: width and flow"
    checks = "flow into a 5 m long bottleneck of width 0.8, 1.0, 1.2 m"
    criterion = ("mean over 3 replicates of J = N/Δt at the bottleneck entrance increases with width: "
                 "J(0.8) < J(1.0) < J(1.2) (JuPedSim's check); plotted against J = 1.9·w, a line of unclear "
                 "provenance (JuPedSim's notebook; not found in RiMEA's text)")
    source = ("RiMEA 4.1.1 A4 test 12d (expected: flow increases with width); widths, 5 m length and check from "
              "JuPedSim tests/vv/test_rimea.py; J = 1.9 w from JuPedSim's notebook")

    WIDTHS = (0.8, 1.0, 1.2)

    def scenarios(self, quick: bool, seed: int) -> dict:
        return self._replicates("rimea_12d_bottleneck_width", {f"w={w:g}": {"width_m": w} for w in self.WIDTHS},
                                quick, seed)

    @staticmethod
    def flow_per_s(run: BackendRun, width_m: float) -> float:
        """J = N / Δt over the crossings of the bottleneck entrance (x = 10, across the width)."""
        lo, hi = 5.0 - width_m / 2, 5.0 + width_m / 2
        _, times = crossing_times_s(run, ((10.0, lo), (10.0, hi)))
        if times.size < 2 or times.max() <= times.min():
            return float("nan")
        return float(times.size / (times.max() - times.min()))

    def _flows(self, runs: dict) -> dict:
        out: dict = {}
        for name, run in runs.items():
            label = name.split("/")[0]
            out.setdefault(label, []).append(self.flow_per_s(run, float(label.split("=")[1])))
        return out

    def evaluate(self, runs: dict) -> Verdict:
        bad = _incomplete(runs)
        if bad:
            return bad
        flows = self._flows(runs)
        mean = {k: float(np.mean(v)) for k, v in flows.items()}
        j = [mean[f"w={w:g}"] for w in self.WIDTHS]
        passed = bool(np.all(np.isfinite(j)) and j[0] < j[1] < j[2])
        details = {"flow_per_s": flows, "flow_mean_per_s": mean,
                   "flow_sd_per_s": {k: float(np.std(v, ddof=1)) for k, v in flows.items()},
                   "specific_flow_mean_per_m_s": {f"w={w:g}": mean[f"w={w:g}"] / w for w in self.WIDTHS},
                   "reference_1.9w_per_s": {f"w={w:g}": REFERENCE_FLOW_PER_M_S * w for w in self.WIDTHS}}
        measured = "J = " + " / ".join(f"{x:.2f}" for x in j) + " 1/s at w = 0.8 / 1.0 / 1.2 m"
        return Verdict(measured, j[2] - j[0], passed, details)

    def plot(self, ax, runs_by_backend: dict) -> None:
        w = np.array(self.WIDTHS)
        ax.plot([0.7, 1.3], [REFERENCE_FLOW_PER_M_S * 0.7, REFERENCE_FLOW_PER_M_S * 1.3], "k--", lw=0.8,
                label="J = 1.9·w (JuPedSim notebook; provenance unclear)")
        for c, (backend, runs) in zip(_COLOURS, runs_by_backend.items()):
            flows = self._flows(runs)
            for x, vals in zip(w, flows.values()):
                ax.plot([x] * len(vals), vals, "o", color=c, alpha=0.35, ms=4)
            ax.plot(w, [np.mean(v) for v in flows.values()], "-o", color=c, label=f"{backend} (mean of replicates)")
        ax.set_xlabel("bottleneck width w (m)")
        ax.set_ylabel("flow J (1/s)")
        ax.legend(fontsize=7)
