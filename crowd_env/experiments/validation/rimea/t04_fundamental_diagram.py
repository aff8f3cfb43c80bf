"""RiMEA test 4: measurement of the fundamental diagram in a corridor.

RiMEA 4.1.1 (A 2, test 4): a corridor 1000 m × 10 m filled at 0.5, 1, 2, 3, 4, 5 and 6 P/m²; in three
measuring areas of 2 m × 2 m (a main one and two controls) the mean speed over 60 s after a 10 s transient,
and flow = speed × density. RiMEA's criterion is qualitative: produce and document the diagram; it names no
reference curve and no tolerance.

**How the density is held.** The model has no periodic boundary. The corridor is filled at the density and
the measuring areas sit where neither end's disturbance reaches them within the 70 s (RiMEA's own way: its
1000 m put them 500 m from the ends); no ring, because on a 10 m wide ring a desired direction along the
loop makes the driving force's relaxation (τ = 0.5 s) lag behind the turning direction and carry every
walker outwards by π τ v ≈ 2 m per half turn at free speed, an artefact a straight corridor does not have.
Margins (:mod:`crowd_env.scenarios.rimea.t04_fundamental_diagram`), from what was measured in this model:

- behind the main area ``back_margin_m``: the crowd's tail walks away from the back wall at most at the
  free speed, 1.34 m/s × 70 s = 94 m (at 0.5-2 P/m² the whole crowd moves as one block at 1.34 m/s: all
  desired speeds are equal, as RiMEA asks);
- before it ``front_margin_m``: at the open end the crowd streams out and the released state runs upstream.
  Up to 3 P/m² the block already walks at nearly the free speed and there is little to release; at 4 P/m²
  the released region's edge ran upstream at 3-4 m/s (with 200 m it reached the main area after about 60 s:
  density 4.09 -> 3.66 /m², speed 0.53 -> 0.87 m/s between the window's first and last 10 s), hence 300 m
  at 4 P/m²; at 5 P/m² it is slower (the main area was still jammed at 70 s with 200 m).

The control areas: one 10 m downstream of the main area (ends, along the corridor) and one beside it 1 m from
the wall (walls, across it). At 5 P/m² the homogeneous crowd walks *backwards* at first (about −0.3 m/s): with
gaps of about 2 cm the anisotropic social repulsion of the pedestrians ahead (331.5 N at contact, range
0.041 m, full weight ahead, λ = 0.11 behind) exceeds the driving force m v0 / τ = 83 × 1.34 / 0.5 = 222 N.
The back wall stops that (the compression front ran about 5-7 m/s), and the main area, 100 m from it, then
reads the jam: 0.22 m/s (backwards: net flow −0.18 1/(m s)) in [10, 20] s, 0 in [60, 70] s. In RiMEA's
1000 m corridor the backward walk would last longer in the middle; a back margin that long (the compression
front needs about 70 s for 420 m) costs too much at 5 P/m². At 4 P/m² the uniform crowd breaks into
stop-and-go waves, with backward steps (18 % of the speed samples in the main area had a negative velocity
along the corridor).

**Full version** (``quick=False``): width 10 m, back margin 100 m, front margin 200 m (300 m at 4 P/m²), so a
300 m corridor (400 m at 4 P/m²) of 1500-16 000 pedestrians, densities 0.5, 1, 2, 3, 4, 5 and 6 P/m², 70 s,
window [10, 70] s. 6 P/m² exceeds hexagonal packing of r = 0.23 m disks (5.46 /m²): the placement fails and
is reported with its capacity (15 636 disks in 3000 m², 5.21 /m²). Cost on one core (measured, the run
of ``docs/validation/rimea/full``): 2.5 minutes for 0.5-3 P/m² together, 4 minutes for 4 P/m², and 93 minutes
for 5 P/m² (a jam of 15 000 disks pressed together, the gap projection of about 31 000 candidates every step:
60 s per simulated second while the crowd is loose, 140-190 s while it is pressed, about 50 s once it loosens
again); 1 h 40 min and at least 2.3 GB in all. **Quick version**: the same
10 m width, back margin 30 m, front margin 60 m (90 m), densities 0.5, 2, 4 (and 6, to report the placement
failure), 20 s, window [5, 20] s: 9 s. The measurement is PedPy's (classic density, mean of the individual
speeds, ±0.2 s, in the area; frames with the area empty count as density 0).

**The reading** (this suite's, stated: RiMEA's test is qualitative; JuPedSim's placeholder expects "speed
decreases with density; flow = speed × density"): in the main area (1) the mean speed does not increase with
the measured density (a rise of at most 0.05 m/s from one density to the next is allowed as noise) and (2)
the flow ρ·v agrees with the specific flow counted independently across the main area's centre line (net
crossings / (window × 2 m)) within 15 % or 0.1 1/(m s). (2) fails where pedestrians step backwards: the
speed is a magnitude, the counted flow a net one. Weidmann's curve (v0 = 1.34 m/s, γ = 1.913 /m²,
ρ_max = 5.4 /m²) is drawn and the deviation from it reported, never judged.
"""
from __future__ import annotations

import numpy as np

from ....analysis.rimea_data import weidmann_speed_m_s
from ....analysis.trajectories import Trajectories
from crowd_env.errors import ScenarioError
from ....scenarios import make_scenario
from ....scenarios.rimea.t04_fundamental_diagram import MEASURING_AREA_NAMES, fd_measuring_areas, hexagonal_capacity_per_m2
from .base import Verdict, WindowedTest, register_test

__all__ = ["FundamentalDiagram", "FULL", "QUICK", "measure_areas", "line_flow_per_m_s"]

# front_margin_m per density (the default for densities not listed): see the module docstring
FULL = {"densities": (0.5, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0), "width_m": 10.0, "back_margin_m": 100.0,
        "front_margin_m": {4.0: 300.0, None: 200.0}, "transient_s": 10.0, "window_s": 60.0}
QUICK = {"densities": (0.5, 2.0, 4.0, 6.0), "width_m": 10.0, "back_margin_m": 30.0, "front_margin_m": {None: 60.0},
         "transient_s": 5.0, "window_s": 15.0}
SPEED_RISE_TOLERANCE_M_S = 0.05
FLOW_REL_TOLERANCE = 0.15
FLOW_ABS_TOLERANCE_PER_M_S = 0.1
SPEED_WINDOW_S = 0.4  # PedPy individual speeds: ±0.2 s around each frame
_STATIONARITY_S = 10.0


def front_margin_m(design: dict, rho: float) -> float:
    """The design's front margin at density ``rho``."""
    margins = design["front_margin_m"]
    return float(margins.get(float(rho), margins[None]))


def _variant(rho: float) -> str:
    return f"rho_{rho:g}"


def _subset(traj: Trajectories, x_range, t_range) -> Trajectories:
    keep = (traj.x_m >= x_range[0]) & (traj.x_m <= x_range[1]) & (traj.time_s >= t_range[0]) & \
           (traj.time_s <= t_range[1])
    return Trajectories(traj.frame[keep], traj.id[keep], traj.x_m[keep], traj.y_m[keep], traj.heading_rad[keep],
                        traj.frame_rate_per_s)


def _on_frames(frames, frame_of_value, values, fill) -> np.ndarray:
    """``values`` given at ``frame_of_value`` spread onto ``frames`` (sorted); ``fill`` elsewhere."""
    out = np.full(frames.size, fill, dtype=np.float64)
    idx = np.searchsorted(frames, frame_of_value)
    ok = idx < frames.size
    ok[ok] = frames[idx[ok]] == frame_of_value[ok]
    out[idx[ok]] = values[ok]
    return out


def measure_areas(traj: Trajectories, areas: dict, t0_s: float, t1_s: float,
                  speed_window_s: float = SPEED_WINDOW_S) -> dict:
    """Per measuring area (name -> shapely polygon), PedPy's classic density and mean speed in frames with
    t in [``t0_s``, ``t1_s``]: ``density_per_m2`` (mean over all frames, an empty area counting 0),
    ``speed_m_s`` (mean over the frames with somebody in the area), ``flow_per_m_s`` (mean of ρ·v over all
    frames), ``occupied_fraction``, and for stationarity the density and speed means over the first and
    the last 10 s of the window. The trajectories are cut to the areas' x range ± 3 m first (PedPy's
    individual speeds at the cut use one-sided differences, 3 m away from any area)."""
    import pedpy

    x0 = min(a.bounds[0] for a in areas.values()) - 3.0
    x1 = max(a.bounds[2] for a in areas.values()) + 3.0
    sub = _subset(traj, (x0, x1), (t0_s - 1.0, t1_s + 1.0))
    fps = traj.frame_rate_per_s
    frames = np.arange(int(np.ceil(t0_s * fps - 1e-9)), int(np.floor(t1_s * fps + 1e-9)) + 1)
    out = {}
    if len(sub) == 0:
        for name in areas:
            out[name] = {"density_per_m2": 0.0, "speed_m_s": float("nan"), "flow_per_m_s": 0.0,
                         "occupied_fraction": 0.0, "density_first_per_m2": 0.0, "density_last_per_m2": 0.0,
                         "speed_first_m_s": float("nan"), "speed_last_m_s": float("nan")}
        return out
    data = sub.to_pedpy()
    step = max(1, int(round(0.5 * speed_window_s * fps)))
    speed = pedpy.compute_individual_speed(traj_data=data, frame_step=step,
                                           speed_calculation=pedpy.SpeedCalculation.BORDER_SINGLE_SIDED)
    for name, poly in areas.items():
        area = pedpy.MeasurementArea(poly)
        dens = pedpy.compute_classic_density(traj_data=data, measurement_area=area)
        rho = _on_frames(frames, dens["frame"].to_numpy(), dens["density"].to_numpy(), 0.0)
        vs = pedpy.compute_mean_speed_per_frame(traj_data=data, individual_speed=speed, measurement_area=area)
        v = _on_frames(frames, vs["frame"].to_numpy(), vs["speed"].to_numpy(), np.nan)
        occupied = rho > 0
        v[~occupied] = np.nan
        t = frames / fps
        first = t < t0_s + _STATIONARITY_S
        last = t > t1_s - _STATIONARITY_S
        out[name] = {
            "density_per_m2": float(rho.mean()),
            "speed_m_s": float(np.nanmean(v)) if occupied.any() else float("nan"),
            "flow_per_m_s": float(np.where(occupied, rho * np.nan_to_num(v), 0.0).mean()),
            "occupied_fraction": float(occupied.mean()),
            "density_first_per_m2": float(rho[first].mean()), "density_last_per_m2": float(rho[last].mean()),
            "speed_first_m_s": float(np.nanmean(v[first])) if occupied[first].any() else float("nan"),
            "speed_last_m_s": float(np.nanmean(v[last])) if occupied[last].any() else float("nan"),
        }
    return out


def line_flow_per_m_s(traj: Trajectories, x_line_m: float, y_range, t0_s: float, t1_s: float) -> float:
    """Specific flow (1/(m s)) across the line x = ``x_line_m``, y in ``y_range``: (forward − backward
    crossings between consecutive frames inside [``t0_s``, ``t1_s``]) / ((t1 − t0) × line length)."""
    same = (traj.id[1:] == traj.id[:-1]) & (traj.frame[1:] == traj.frame[:-1] + 1)
    xa, xb = traj.x_m[:-1], traj.x_m[1:]
    fwd = same & (xa < x_line_m) & (xb >= x_line_m)
    bwd = same & (xa >= x_line_m) & (xb < x_line_m)
    cross = fwd | bwd
    with np.errstate(invalid="ignore", divide="ignore"):  # w is used only where the line is crossed (xa != xb)
        w = (x_line_m - xa) / (xb - xa)
        y = traj.y_m[:-1] + w * (traj.y_m[1:] - traj.y_m[:-1])
        t = (traj.frame[:-1] + w) / traj.frame_rate_per_s
    inside = cross & (y >= y_range[0]) & (y <= y_range[1]) & (t >= t0_s) & (t < t1_s)
    net = int(np.count_nonzero(inside & fwd)) - int(np.count_nonzero(inside & bwd))
    return net / ((t1_s - t0_s) * (y_range[1] - y_range[0]))


@register_test
class FundamentalDiagram(WindowedTest):
    FULL_DESIGN = FULL
    QUICK_DESIGN = QUICK
    number = "4"
    title = "Measurement of the fundamental diagram"
    checks = "speed and flow against density in a 10 m wide corridor filled at 0.5-6 P/m²"
    criterion = (f"RiMEA: qualitative (document the diagram). Reading used (this suite's): in the main 2 m x 2 m area "
                 f"the mean speed does not increase with density (rise <= {SPEED_RISE_TOLERANCE_M_S} m/s) and rho*v "
                 f"matches the flow counted across the area's centre line (within {FLOW_REL_TOLERANCE:.0%} or "
                 f"{FLOW_ABS_TOLERANCE_PER_M_S} 1/(m s)); deviation from Weidmann reported, not judged")
    source = ("RiMEA 4.1.1 A2 test 4 (1000 m x 10 m corridor, 2 m x 2 m main + 2 control areas, 0.5-6 P/m², mean "
              "speed over 60 s after 10 s, flow = v rho); Weidmann 1993 via secondary sources (v0 1.34, gamma 1.913, "
              "rho_max 5.4); the monotonicity reading follows JuPedSim's placeholder docstring")

    def __init__(self):
        super().__init__()
        self._unplaceable = {}

    def scenarios(self, quick: bool, seed: int) -> dict:
        d = self.design(quick)
        self._design = d
        self._unplaceable = {}
        out = {}
        for rho in d["densities"]:
            try:
                out[_variant(rho)] = make_scenario("rimea_4_fundamental_diagram", seed=seed, density_per_m2=rho,
                                                   width_m=d["width_m"], back_margin_m=d["back_margin_m"],
                                                   front_margin_m=front_margin_m(d, rho))
            except ScenarioError as exc:  # more disks than fit: reported, not skipped silently
                self._unplaceable[float(rho)] = str(exc)
        return out

    def measure(self, runs: dict) -> list:
        """One row per run: the nominal density and, per measuring area, the figures of :func:`measure_areas`,
        the main area's line flow and Weidmann's speed at its measured density."""
        d = self.design_for(runs)
        areas = fd_measuring_areas(d["back_margin_m"], d["width_m"])
        t0, t1 = d["transient_s"], d["transient_s"] + d["window_s"]
        rows = []
        for name, run in runs.items():
            rho_nominal = float(name.split("_", 1)[1])
            m = measure_areas(run.trajectories, areas, t0, t1)
            yc = 0.5 * d["width_m"]
            j_line = line_flow_per_m_s(run.trajectories, d["back_margin_m"], (yc - 1.0, yc + 1.0), t0, t1)
            main = m["main"]
            rows.append({"variant": name, "nominal_density_per_m2": rho_nominal, "areas": m,
                         "line_flow_per_m_s": j_line,
                         "weidmann_speed_m_s": float(weidmann_speed_m_s(main["density_per_m2"])),
                         "complete": run.complete, "stalled": run.stalled, "n_pedestrians": run.n_pedestrians})
        rows.sort(key=lambda r: r["nominal_density_per_m2"])
        return rows

    def evaluate(self, runs: dict) -> Verdict:
        rows = self.measure(runs)
        unplaceable = {f"{k:g}": v for k, v in self._unplaceable.items()}
        main = [(r["areas"]["main"]["density_per_m2"], r["areas"]["main"]["speed_m_s"], r["areas"]["main"]["flow_per_m_s"],
                 r["line_flow_per_m_s"], r) for r in rows]
        usable = [t for t in main if np.isfinite(t[1])]
        usable.sort(key=lambda t: t[0])
        rises = [b[1] - a[1] for a, b in zip(usable, usable[1:])]
        monotone = all(r <= SPEED_RISE_TOLERANCE_M_S for r in rises)
        flow_ok = [abs(t[2] - t[3]) <= max(FLOW_REL_TOLERANCE * abs(t[3]), FLOW_ABS_TOLERANCE_PER_M_S) for t in usable]
        passed = bool(usable) and monotone and all(flow_ok) and len(usable) == len(rows)
        table = []
        for rho, v, j, j_line, r in main:
            a = r["areas"]
            table.append({"nominal_density_per_m2": r["nominal_density_per_m2"], "n_pedestrians": r["n_pedestrians"],
                          **{f"{k}_{q}": a[k][q] for k in MEASURING_AREA_NAMES
                             for q in ("density_per_m2", "speed_m_s", "flow_per_m_s")},
                          "main_line_flow_per_m_s": j_line,
                          "main_net_speed_m_s": j_line / rho if rho > 0 else float("nan"),
                          "main_density_first_last_per_m2": (a["main"]["density_first_per_m2"], a["main"]["density_last_per_m2"]),
                          "main_speed_first_last_m_s": (a["main"]["speed_first_m_s"], a["main"]["speed_last_m_s"]),
                          "weidmann_speed_m_s": r["weidmann_speed_m_s"],
                          "speed_minus_weidmann_m_s": v - r["weidmann_speed_m_s"]})
        text = ", ".join(f"{rho:.2f}/m²: {v:.2f} m/s" for rho, v, *_ in usable)
        if unplaceable:
            text += f"; not placeable: {', '.join(k + ' P/m²' for k in unplaceable)}"
        if not monotone:
            text += f"; speed rises by up to {max(rises):.2f} m/s"
        if not all(flow_ok):
            bad = [f"{t[0]:.2f}/m² (rho v {t[2]:.2f} vs line {t[3]:.2f})" for t, ok in zip(usable, flow_ok) if not ok]
            text += f"; flow mismatch at {', '.join(bad)}"
        dev = [t["speed_minus_weidmann_m_s"] for t in table if np.isfinite(t["speed_minus_weidmann_m_s"])]
        details = {"table": table, "unplaceable": unplaceable, "speed_rises_m_s": rises, "monotone": monotone,
                   "flow_consistent": flow_ok,
                   "max_abs_deviation_from_weidmann_m_s": float(np.max(np.abs(dev))) if dev else float("nan"),
                   "hexagonal_packing_per_m2": hexagonal_capacity_per_m2(), "design": self.design_for(runs)}
        return Verdict("main area v(rho): " + text, float(np.max(np.abs(dev))) if dev else float("nan"), passed, details)

    def plot(self, ax, runs_by_backend: dict) -> None:
        from mpl_toolkits.axes_grid1 import make_axes_locatable

        ax_flow = make_axes_locatable(ax).append_axes("right", size="100%", pad=0.55)
        rho = np.linspace(0.05, 6.0, 300)
        vw = weidmann_speed_m_s(rho)
        ax.plot(rho, vw, "k-", lw=1, label="Weidmann")
        ax_flow.plot(rho, rho * vw, "k-", lw=1, label="Weidmann")
        markers = {"main": "o", "control_downstream": "s", "control_lateral": "^"}
        colours = ["tab:blue", "tab:orange", "tab:green"]
        for c, (backend, runs) in zip(colours, runs_by_backend.items()):
            rows = self.measure(runs)
            for area, mk in markers.items():
                pts = np.array([(r["areas"][area]["density_per_m2"], r["areas"][area]["speed_m_s"],
                                 r["areas"][area]["flow_per_m_s"]) for r in rows])
                if not pts.size:
                    continue
                label = f"{backend} {area}" if len(runs_by_backend) > 1 else area
                ax.plot(pts[:, 0], pts[:, 1], mk, color=c, mfc="none" if area != "main" else c, label=label, ms=5)
                ax_flow.plot(pts[:, 0], pts[:, 2], mk, color=c, mfc="none" if area != "main" else c, ms=5)
            lines = np.array([(r["areas"]["main"]["density_per_m2"], r["line_flow_per_m_s"]) for r in rows])
            if lines.size:
                ax_flow.plot(lines[:, 0], lines[:, 1], "x", color=c, label="line count (main)")
        for k, why in self._unplaceable.items():
            ax.axvline(k, color="0.6", ls=":", lw=0.8)
            ax.text(k, 0.05, f"{k:g}: not placeable", rotation=90, fontsize=6, va="bottom", ha="right")
        ax.axvline(hexagonal_capacity_per_m2(), color="0.8", lw=0.8)
        ax.set_xlabel("density (1/m²)")
        ax.set_ylabel("speed (m/s)")
        ax_flow.set_xlabel("density (1/m²)")
        ax_flow.set_ylabel("specific flow (1/(m s))")
        ax.set_xlim(0, 6.3)
        ax_flow.set_xlim(0, 6.3)
        ax.legend(fontsize=6, loc="upper right")
        ax_flow.legend(fontsize=6, loc="upper right")
