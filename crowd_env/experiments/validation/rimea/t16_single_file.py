"""RiMEA test 16: the 1D fundamental diagram (single file) on a closed ring.

RiMEA 4.1.1 (A 4, test 16): agents walk in single file in a corridor one agent wide, preferably a ring
without exit, at several densities; the speed against the 1D density (persons per metre) should lie within
the 10 %/90 % percentile envelope of single-file experiments (Fig. 20, ``analysis/data/rimea16_percentiles.csv``).
RiMEA gives no pass fraction.

Set-up (:mod:`crowd_env.scenarios.rimea.t16_single_file`): JuPedSim's oval ring (two 4 m straights, half
circles of 3 m centreline radius, 0.8 m wide, L = 8 + 6π ≈ 26.85 m), N pedestrians evenly spaced on the
centreline, desired speeds from the preset's distribution (N(1.34, 0.26) m/s, truncated at 2σ), walking
round it with :class:`~crowd_env.walking.circulation.CirculationNavigation`. Two disks of 0.46 m in line
along the centreline are at least 0.46 m apart (1D density 2.17 /m); staggered across the 0.8 m corridor
(centres up to ±0.17 m off the centreline) their projections can be 0.31 m apart (3.2 /m), without room to
pass. The envelope goes on to 6.7 /m (real people in single file are about 0.3 m deep).

Measurement (JuPedSim's, ``jupedsim-web-community:scripts/scenario_builders/rimea16_loop.py``): each frame
(10 fps) the centres are projected onto the centreline (arc length s); the 1D Voronoi density of each
pedestrian is 1 / (½ (gap ahead + gap behind)), round the loop; the speed is the change of the unwrapped arc
length over 1 s (±5 frames, centred; JuPedSim: 10 frames ahead). Samples after the transient (JuPedSim
instead keeps samples after 3 laps, which slow dense rings do not complete in reasonable time) from all
densities are pooled, binned by density in 0.2 /m bins, and each bin with >= 50 samples (JuPedSim's notebook)
gives its median speed, compared with the envelope interpolated at the bin's mean density (JuPedSim: at the
bin's lower edge).

**Reading** (JuPedSim's test ``TestRiMEA161DFundamentalDiagram``, baseline run; RiMEA sets no fraction): at
least 75 % of the bins lie within [p10, p90]. JuPedSim's two sensitivity runs (v0 = 0.9 and 1.5 m/s) are not
repeated.

**What the model does here** (measured, not tuned): a platoon forms behind the slowest pedestrian (no
overtaking) and the whole ring walks at that one's desired speed, about 0.9 m/s, at every density up to
disks touching: the calibrated social repulsion (331.5 N at contact, range 0.041 m) acts only within
centimetres, so a follower keeps no speed-dependent distance (in the experiments the headway grows with the
speed, about 0.36 m + 1.06 s × v, Seyfried et al. 2005) and closes up to a few centimetres behind its
leader instead of slowing down. The curve is flat and lies above p90 from about 1 /m on: the test fails for
that reason. (JuPedSim's collision-free speed model, whose agents keep a time gap of 1 s, falls inside the
envelope on the same ring and measurement: ``crowd-rimea 16 --quick --jupedsim``.)

**Full version**: N = 5, 10, ..., 55 (1D density 0.19-2.05 /m), 180 s each, samples after 60 s (every
pedestrian has then walked about 6 laps): 52 s on one core. **Quick version**: N = 10, 30, 50, 50 s each,
samples after 20 s: 4 s. The runs step from Python (the compiled rollout samples grid fields only).
"""
from __future__ import annotations

import math

import numpy as np

from ....analysis.rimea_data import loop_headway_density_per_m, single_file_percentiles
from ....scenarios import make_scenario
from ....scenarios.rimea.t16_single_file import CENTRELINE_SPACING_M
from ....walking.circulation import CirculationNavigation, oval_centreline
from .base import Verdict, WindowedTest, register_test

__all__ = ["SingleFileFundamentalDiagram", "FULL", "QUICK", "loop_samples", "bin_samples"]

FULL = {"n_pedestrians": (5, 10, 15, 20, 25, 30, 35, 40, 45, 50, 55), "transient_s": 60.0, "window_s": 120.0}
QUICK = {"n_pedestrians": (10, 30, 50), "transient_s": 20.0, "window_s": 30.0}
RING = {"straight_m": 4.0, "radius_m": 3.0, "width_m": 0.8}
BIN_WIDTH_PER_M = 0.2
MIN_SAMPLES = 50
INSIDE_FRACTION = 0.75
SPEED_HALF_WINDOW_FRAMES = 5
# Centres may sit up to 0.4 - 0.23 = 0.17 m either side of the centreline: two touching disks staggered across
# the corridor are sqrt(0.46² - 0.34²) = 0.31 m apart along it (1D density up to 3.2 /m, 2.17 /m in line).
STAGGERED_MIN_SPACING_M = math.sqrt((2 * 0.23) ** 2 - (2 * (0.4 - 0.23)) ** 2)


def _variant(n: int) -> str:
    return f"n_{n}"


def ring_navigation() -> CirculationNavigation:
    """The ring's centreline as a navigation (for the measurement: arc lengths)."""
    return CirculationNavigation(oval_centreline(RING["straight_m"], RING["radius_m"], CENTRELINE_SPACING_M),
                                 half_width_m=0.5 * RING["width_m"])


def loop_samples(trajectories, navigation: CirculationNavigation, t0_s: float,
                 half_window_frames: int = SPEED_HALF_WINDOW_FRAMES) -> dict:
    """(density 1/m, speed m/s) samples of one ring run: every pedestrian at every frame with t >= ``t0_s``
    whose frames ± ``half_window_frames`` exist. Density: 1D Voronoi on the centreline
    (:func:`~crowd_env.analysis.rimea_data.loop_headway_density_per_m`); speed: unwrapped arc length over
    the centred window. Frames where somebody is missing (left or not recorded) are skipped. Returns arrays
    ``density_per_m``, ``speed_m_s``, ``time_s``, ``id`` and the per-pedestrian ``laps`` completed."""
    t = trajectories
    ids = np.unique(t.id)
    frames = np.unique(t.frame)
    n, f = ids.size, frames.size
    s = np.full((f, n), np.nan)
    s[np.searchsorted(frames, t.frame), np.searchsorted(ids, t.id)] = navigation.arc_length(
        np.column_stack((t.x_m, t.y_m)))
    full = np.all(np.isfinite(s), axis=1)
    s_full = s[full]
    length = navigation.length_m
    unwrapped = np.unwrap(s_full * (2 * np.pi / length), axis=0) * (length / (2 * np.pi))
    fr = frames[full]
    dens = np.array([loop_headway_density_per_m(row, length) for row in s_full]) if s_full.size else np.zeros((0, n))
    h = int(half_window_frames)
    out = {"density_per_m": [], "speed_m_s": [], "time_s": [], "id": []}
    dt = 2 * h / t.frame_rate_per_s
    for k in range(h, fr.size - h):
        if fr[k + h] - fr[k - h] != 2 * h or fr[k] / t.frame_rate_per_s < t0_s:
            continue
        out["density_per_m"].append(dens[k])
        out["speed_m_s"].append((unwrapped[k + h] - unwrapped[k - h]) / dt)
        out["time_s"].append(np.full(n, fr[k] / t.frame_rate_per_s))
        out["id"].append(ids)
    res = {k: (np.concatenate(v) if v else np.zeros(0)) for k, v in out.items()}
    res["laps"] = (unwrapped[-1] - unwrapped[0]) / length if unwrapped.shape[0] else np.zeros(n)
    return res


def bin_samples(density_per_m, speed_m_s, bin_width: float = BIN_WIDTH_PER_M, min_samples: int = MIN_SAMPLES) -> list:
    """Bins of width ``bin_width`` (lower edges k·width) with at least ``min_samples`` samples: dicts with the
    bin's edges, sample count, mean density, median speed and the envelope at the mean density, and whether
    the median lies below p10, inside [p10, p90] or above p90."""
    ref = single_file_percentiles()
    d = np.asarray(density_per_m, dtype=np.float64)
    v = np.asarray(speed_m_s, dtype=np.float64)
    k = np.floor(d / bin_width + 1e-12).astype(np.int64)
    out = []
    for b in np.unique(k):
        sel = k == b
        if sel.sum() < min_samples:
            continue
        rho = float(d[sel].mean())
        med = float(np.median(v[sel]))
        p10, p50, p90 = (float(x) for x in ref.at(rho))
        out.append({"lower_per_m": b * bin_width, "upper_per_m": (b + 1) * bin_width, "count": int(sel.sum()),
                    "density_per_m": rho, "median_speed_m_s": med, "p10_m_s": p10, "p50_m_s": p50, "p90_m_s": p90,
                    "position": "below" if med < p10 else ("above" if med > p90 else "inside")})
    return out


@register_test
class SingleFileFundamentalDiagram(WindowedTest):
    FULL_DESIGN = FULL
    QUICK_DESIGN = QUICK
    number = "16"
    title = "1D fundamental diagram (single file)"
    checks = "speed against 1D density of disks circulating in single file on a 0.8 m wide oval ring"
    criterion = (f"binned median speed (0.2 /m bins, >= {MIN_SAMPLES} samples) within the 10-90 % envelope of "
                 f"single-file experiments in >= {INSIDE_FRACTION:.0%} of the bins (JuPedSim's reading; RiMEA gives "
                 "no fraction)")
    source = ("RiMEA 4.1.1 A4 test 16 (ring one agent wide, envelope of Fig. 20); ring, measurement and the 75 % "
              "reading from jupedsim-web-community tests/vv/test_rimea.py and scripts/scenario_builders/rimea16_loop.py")

    def scenarios(self, quick: bool, seed: int) -> dict:
        d = self.design(quick)
        self._design = d
        return {_variant(n): make_scenario("rimea_16_ring", seed=seed, n_pedestrians=n, **RING)
                for n in d["n_pedestrians"]}

    def measure(self, runs: dict) -> tuple:
        """``(per-run rows, pooled samples (density, speed), bins)``."""
        d = self.design_for(runs)
        nav = ring_navigation()
        rows, dens, speed = [], [], []
        for name, run in sorted(runs.items(), key=lambda kv: int(kv[0].split("_")[1])):
            smp = loop_samples(run.trajectories, nav, d["transient_s"])
            dens.append(smp["density_per_m"])
            speed.append(smp["speed_m_s"])
            end = float(run.trajectories.time_s.max()) if len(run.trajectories) else 0.0
            rows.append({"variant": name, "n_pedestrians": run.n_pedestrians,
                         "ring_density_per_m": run.n_pedestrians / nav.length_m,
                         "mean_speed_m_s": float(np.mean(smp["speed_m_s"])) if smp["speed_m_s"].size else float("nan"),
                         "n_samples": int(smp["speed_m_s"].size), "min_laps": float(np.min(smp["laps"])),
                         "simulated_s": end, "stalled": run.stalled})
        d_all = np.concatenate(dens) if dens else np.zeros(0)
        v_all = np.concatenate(speed) if speed else np.zeros(0)
        return rows, (d_all, v_all), bin_samples(d_all, v_all)

    def evaluate(self, runs: dict) -> Verdict:
        rows, _, bins = self.measure(runs)
        n_in = sum(b["position"] == "inside" for b in bins)
        n_above = sum(b["position"] == "above" for b in bins)
        n_below = sum(b["position"] == "below" for b in bins)
        frac = n_in / len(bins) if bins else float("nan")
        passed = bool(bins) and frac >= INSIDE_FRACTION
        text = (f"{n_in} of {len(bins)} bins inside [p10, p90] ({frac:.0%}); {n_above} above p90, {n_below} below p10"
                if bins else "no density bin with enough samples")
        stalled = [r["variant"] for r in rows if r["stalled"]]
        if stalled:
            text += f"; stalled: {', '.join(stalled)}"
        return Verdict(text, frac, passed, {"bins": bins, "runs": rows, "inside": n_in, "above": n_above,
                                            "below": n_below, "design": self.design_for(runs)})

    def plot(self, ax, runs_by_backend: dict) -> None:
        ref = single_file_percentiles()
        measured = {backend: self.measure(runs) for backend, runs in runs_by_backend.items()}
        top = max([2.6] + [b["upper_per_m"] for _, _, bins in measured.values() for b in bins])
        keep = ref.density_per_m <= top + 0.2
        ax.fill_between(ref.density_per_m[keep], ref.p10[keep], ref.p90[keep], color="0.85",
                        label="experiments 10-90 %")
        ax.plot(ref.density_per_m[keep], ref.p50[keep], "k--", lw=0.8, label="experiments median")
        colours = ["tab:blue", "tab:orange", "tab:green"]
        for c, (backend, (_, (d, v), bins)) in zip(colours, measured.items()):
            if d.size:
                pick = np.random.default_rng(0).choice(d.size, size=min(d.size, 4000), replace=False)
                ax.plot(d[pick], v[pick], ",", color=c, alpha=0.3)
            if bins:
                x = [b["density_per_m"] for b in bins]
                y = [b["median_speed_m_s"] for b in bins]
                inside = [b["position"] == "inside" for b in bins]
                ax.plot(x, y, "-", color=c, lw=1)
                ax.plot([a for a, i in zip(x, inside) if i], [b for b, i in zip(y, inside) if i], "o", color=c,
                        label=f"{backend}: bin median (inside)")
                ax.plot([a for a, i in zip(x, inside) if not i], [b for b, i in zip(y, inside) if not i], "o",
                        mfc="none", color=c, label=f"{backend}: bin median (outside)")
        for rho, what in ((1.0 / 0.46, "in line"), (1.0 / STAGGERED_MIN_SPACING_M, "staggered")):
            ax.axvline(rho, color="0.6", ls=":", lw=0.8)
            ax.text(rho, 0.02, f"disks touching {what}", rotation=90, fontsize=6, ha="right", va="bottom")
        ax.set_xlim(0, top + 0.1)
        ax.set_ylim(bottom=min(0.0, ax.get_ylim()[0]))
        ax.set_xlabel("1D density (1/m)")
        ax.set_ylabel("speed along the ring (m/s)")
        ax.legend(fontsize=7, loc="upper right")
