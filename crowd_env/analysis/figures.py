"""Figures of Kabalan et al. (2016) Section 4 from bottleneck run records (matplotlib, Agg)."""
from __future__ import annotations

from crowd_env.errors import InputError
from crowd_env.files import save_figure_atomic

from pathlib import Path

import numpy as np

from .experiment import (FRONT_DENSITY_RANGE_PER_M2, INSIDE_DENSITY_RANGE_PER_M2, INSIDE_SPEED_RANGE_M_S,
                         SPECIFIC_FLOW_RANGE_N20_N40_PER_M_S, seyfried_2009)
from .flow import linear_fit
from .lanes import pooled_lanes


def pyplot():
    """matplotlib.pyplot on the non-interactive Agg backend (imported on first use)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, path):
    """Lay out, write (120 dpi, atomically: :func:`crowd_env.files.save_figure_atomic`) and close ``fig``;
    returns ``path``. The analysis layer's figures go through here."""
    fig.tight_layout()
    save_figure_atomic(fig, path, dpi=120)
    pyplot().close(fig)
    return path


def bottleneck_figures(records: list, rows: list, out: Path) -> list:
    """Write Figs. 11-14 analogues into ``out``; returns the paths written.

    ``rows``: :func:`crowd_env.experiments.validation.bottleneck.summarise`, whose means are over complete runs
    only; a width with stalled or otherwise incomplete runs is labelled with their count in Fig. 11, and
    the discharge diagnostic uses complete runs only.
    """
    out = Path(out)
    sizes = sorted({r["n_pedestrians"] for r in rows})
    n_d = 60 if 60 in sizes else sizes[-1]
    paths = [_specific_flow_figure(rows, sizes, out / "fig11_specific_flow.png"),
             _density_figure(rows, n_d, out / "fig12_density.png"),
             _flow_figure(rows, sizes, out / "fig13_flow_linear.png"),
             _lanes_figure(records, n_d, out / "fig14_lanes.png")]
    # Diagnostic: discharge rate vs the number of pedestrians not yet passed (records with crossing times).
    path = discharge_figure(records, out / "fig15_discharge.png")
    if path is not None:
        paths.append(path)
    return paths


def _specific_flow_figure(rows: list, sizes: list, path: Path) -> Path:
    """Fig. 11: J_s vs b per N against the experiment, incomplete runs counted."""
    plt, exp = pyplot(), seyfried_2009()
    fig, axes = plt.subplots(1, len(sizes), figsize=(4.2 * len(sizes), 3.6), squeeze=False)
    for ax, n in zip(axes[0], sizes):
        sub = [r for r in rows if r["n_pedestrians"] == n]
        b = [r["width_m"] for r in sub]
        ax.errorbar(b, [r["specific_flow_mean"] for r in sub], yerr=[r["specific_flow_std"] for r in sub],
                    fmt="o-", capsize=3, label="crowd_env (complete runs)")
        for r in sub:
            bad = r["runs"] - r.get("complete", r["runs"])
            if bad:
                ax.annotate(f"{r.get('stalled', 0)} stalled, {r.get('incomplete', 0)} inc. of {r['runs']}",
                            (r["width_m"], 1.05), fontsize=6, rotation=90, ha="center", va="bottom", color="C3")
        stationary = [r.get("stationary_specific_flow", np.nan) for r in sub]
        if np.isfinite(stationary).any():
            ax.plot(b, stationary, "v:", color="C0", alpha=0.6, label="crowd_env, stationary (middle 60 %)")
        if n == 60:
            ax.plot(exp.width_m[exp.n_pedestrians == 60], exp.specific_flow_per_m_s[exp.n_pedestrians == 60],
                    "ks--", label="Seyfried 2009")
        else:
            lo, hi = SPECIFIC_FLOW_RANGE_N20_N40_PER_M_S
            ax.axhspan(lo, hi, color="0.85", label="experimental range")
        ax.set(title=f"N = {n}", xlabel="b (m)", ylabel="J_s (1/(m s))", ylim=(1.0, 3.4))
        ax.legend(fontsize=8)
    return save_figure(fig, path)


def _density_figure(rows: list, n_d: int, path: Path) -> Path:
    """Fig. 12: densities in front of and inside the bottleneck, and the speed inside (N = ``n_d``). In a
    stationary channel J_s = ρ_inside · v_inside: the last two panels split the flow."""
    plt = pyplot()
    sub = [r for r in rows if r["n_pedestrians"] == n_d]
    fig, axes = plt.subplots(1, 3, figsize=(12.6, 3.6))
    for ax, key, band, title, unit, top in (
            (axes[0], "density_front", FRONT_DENSITY_RANGE_PER_M2, "density 1 m in front", "ρ (1/m²)", 7),
            (axes[1], "density_inside", INSIDE_DENSITY_RANGE_PER_M2, "density inside", "ρ (1/m²)", 7),
            (axes[2], "speed_inside", INSIDE_SPEED_RANGE_M_S, "speed inside", "v (m/s)", 2)):
        ax.plot([r["width_m"] for r in sub], [r.get(key, np.nan) for r in sub], "o-", label="crowd_env")
        ax.axhspan(*band, color="0.85", label="experiment")
        ax.set(title=f"{title}, N = {n_d}", xlabel="b (m)", ylabel=unit, ylim=(0, top))
        ax.legend(fontsize=8)
    return save_figure(fig, path)


def _flow_figure(rows: list, sizes: list, path: Path) -> Path:
    """Fig. 13: J vs b with linear fits and their residual norms."""
    plt, exp = pyplot(), seyfried_2009()
    fig, axes = plt.subplots(1, len(sizes), figsize=(4.2 * len(sizes), 3.6), squeeze=False)
    for ax, n in zip(axes[0], sizes):
        sub = [r for r in rows if r["n_pedestrians"] == n]
        b = np.array([r["width_m"] for r in sub])
        j = np.array([r["flow_mean"] for r in sub], dtype=float)
        b, j = b[np.isfinite(j)], j[np.isfinite(j)]  # widths without a complete run have no flow
        ax.plot(b, j, "o", label="crowd_env")
        if b.size >= 2:
            fit = linear_fit(b, j)
            ax.plot(b, fit.slope * b + fit.intercept, "-", label=f"fit, residual norm {fit.residual_norm:.3f}")
        if n == 60:
            sel = exp.n_pedestrians == 60
            ax.plot(exp.width_m[sel], exp.flow_per_s[sel], "ks", label="Seyfried 2009")
        ax.set(title=f"N = {n}", xlabel="b (m)", ylabel="J (1/s)")
        ax.legend(fontsize=8)
    return save_figure(fig, path)


def _lanes_figure(records: list, n_d: int, path: Path) -> Path:
    """Fig. 14: lateral-position histograms (N = ``n_d``) at each simulated width."""
    plt = pyplot()
    widths = sorted({r["width_m"] for r in records if r["n_pedestrians"] == n_d})
    fig, axes = plt.subplots(1, len(widths), figsize=(3.2 * len(widths), 3.2), squeeze=False, sharey=True)
    for ax, b in zip(axes[0], widths):
        recs = [r for r in records if r["n_pedestrians"] == n_d and r["width_m"] == b]
        lanes = pooled_lanes(recs)
        start, step, n_edges = recs[0]["lane_bin_edges_m"]
        centers = start + step * (np.arange(n_edges - 1) + 0.5)
        counts = np.sum([r["lane_counts"] for r in recs], axis=0).astype(float)
        ax.bar(centers, counts / max(counts.sum(), 1.0), width=step)
        ax.set(title=f"b = {b:.1f} m: {lanes.n_lanes} lane(s)", xlabel="y (m)", xlim=(-b / 2 - 0.05, b / 2 + 0.05))
    axes[0][0].set_ylabel("probability")
    return save_figure(fig, path)


def discharge_rate(crossing_times_s, window: int = 5):
    """Flow (1/s) over ``window`` consecutive passages and the number of pedestrians not yet passed at
    the middle of each window (those still upstream of the line). Empty arrays for too few passages.

    In the experiment the flow of a bottleneck is a capacity, independent of how many people still
    wait (Seyfried 2009: J_s of N = 20 and 40 as high as of N = 60); a flow that grows with the
    crowd left behind is a pressure-driven discharge.
    """
    t = np.sort(np.asarray(crossing_times_s, dtype=float))
    n = t.size
    if n <= window:
        return np.zeros(0), np.zeros(0)
    k = np.arange(n)
    dt = t[window:] - t[:-window]
    rate = np.where(dt > 0, window / np.where(dt > 0, dt, 1.0), np.inf)
    remaining = n - 0.5 * (k[:-window] + k[window:])
    return remaining, rate


def discharge_figure(records: list, path: Path, window: int = 5):
    """Specific discharge rate vs crowd left behind: left, pooled over runs, one colour per N; right, for
    the largest N, the median over runs per width (how the tail depends on b). Complete runs only (the
    number not yet passed is counted from N). None without data."""
    recs = [r for r in records if len(r.get("crossing_times_s") or []) > window
            and len(r["crossing_times_s"]) == r["n_pedestrians"]]
    if not recs:
        return None
    plt = pyplot()
    exp = seyfried_2009()
    fig, (ax, ax_b) = plt.subplots(1, 2, figsize=(11.2, 3.8), sharey=True)
    n_max = max(r["n_pedestrians"] for r in recs)
    widths = sorted({r["width_m"] for r in recs if r["n_pedestrians"] == n_max})
    for k, b in enumerate(widths):
        pooled = [discharge_rate(r["crossing_times_s"], window) for r in recs
                  if r["n_pedestrians"] == n_max and r["width_m"] == b]
        remaining = np.concatenate([p[0] for p in pooled])
        rate = np.concatenate([p[1] for p in pooled]) / b
        levels = np.unique(remaining)
        ax_b.plot(levels, [np.median(rate[remaining == x]) for x in levels], "-",
                  color=plt.cm.viridis(k / max(1, len(widths) - 1)), label=f"b = {b:g} m")
    ax_b.set(xlabel="pedestrians not yet passed", title=f"N = {n_max}: median over runs per width")
    ax_b.legend(fontsize=7)
    for k, n in enumerate(sorted({r["n_pedestrians"] for r in recs})):
        first = True
        for r in recs:
            if r["n_pedestrians"] != n:
                continue
            remaining, rate = discharge_rate(r["crossing_times_s"], window)
            ax.plot(remaining, rate / r["width_m"], ".", ms=2.5, color=f"C{k}", label=f"N = {n}" if first else None)
            first = False
    lo, hi = SPECIFIC_FLOW_RANGE_N20_N40_PER_M_S
    ax.axhspan(lo, hi, color="0.88", label="experiment, N = 20/40 range")
    sel = exp.n_pedestrians == 60
    ax.axhspan(exp.specific_flow_per_m_s[sel].min(), exp.specific_flow_per_m_s[sel].max(), color="0.7", alpha=0.6,
               label="experiment, N = 60 (all b)")
    ax.set(xlabel="pedestrians not yet passed", ylabel=f"J_s over {window} passages (1/(m s))",
           title="discharge rate vs crowd left behind")
    ax.legend(fontsize=7)
    save_figure(fig, path)
    return Path(path)


def fundamental_diagram_figure(data_by_area: dict, path: Path, title: str | None = None, bin_width_per_m2: float = 0.25):
    """Speed and specific flow ρ·v vs classic density, one colour per measurement area, with binned means.

    ``data_by_area``: area name -> arrays of :func:`crowd_env.analysis.trajectories.fundamental_diagram_data`
    (``density_per_m2``, ``speed_m_s``, ``specific_flow_per_m_s``). Returns the path written.
    """
    if not data_by_area:
        raise InputError("fundamental_diagram_figure needs at least one measurement area's data")
    if not (np.isfinite(bin_width_per_m2) and bin_width_per_m2 > 0):
        raise InputError(f"bin_width_per_m2 must be > 0, got {bin_width_per_m2!r}")
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(9.0, 3.8))
    for k, (name, d) in enumerate(data_by_area.items()):
        rho = np.asarray(d["density_per_m2"], dtype=float)
        for ax, key in zip(axes, ("speed_m_s", "specific_flow_per_m_s")):
            val = np.asarray(d[key], dtype=float)
            ax.plot(rho, val, ".", ms=2, alpha=0.35, color=f"C{k}")
            if rho.size:
                bins = np.floor(rho / bin_width_per_m2).astype(int)
                idx, inv = np.unique(bins, return_inverse=True)
                counts = np.bincount(inv)
                centre = np.bincount(inv, weights=rho) / counts
                mean = np.bincount(inv, weights=val) / counts
                ax.plot(centre, mean, "o-", color=f"C{k}", ms=4, label=f"{name} (binned mean)")
    axes[0].set(xlabel="ρ (1/m²)", ylabel="v (m/s)", title="speed vs density")
    axes[1].set(xlabel="ρ (1/m²)", ylabel="J_s = ρ v (1/(m s))", title="specific flow vs density")
    return _save_diagram(fig, axes, path, title, legend_size=8)


def _save_diagram(fig, axes, path, title, legend_size):
    """Axes of a fundamental diagram from 0, legends, the title; saved to ``path``, which is returned."""
    for ax in axes:
        ax.set_xlim(left=0)
        ax.set_ylim(bottom=0)
        ax.legend(fontsize=legend_size)
    if title:
        fig.suptitle(title, fontsize=10)
    save_figure(fig, path)
    return Path(path)


def fd_sweep_figure(summary: dict, path: Path, title: str | None = None):
    """The swept fundamental diagram beside the experiments: corridor speed and specific flow against ρ (1/m²)
    with the Jülich bins and Weidmann's curve, single-file speed against ρ (1/m) with Seyfried's bins and their
    headway fit. ``summary``: :func:`~crowd_env.experiments.validation.fundamental_diagram.summarise_fd`. Returns the path."""
    from .fd_reference import SINGLE_FILE_HEADWAY_FIT, juelich_corridor, single_file, weidmann_speed_m_s
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(13.0, 3.8))
    jc, sf = juelich_corridor(), single_file()
    rho = np.linspace(0.2, 5.0, 200)
    axes[0].errorbar(jc.density, jc.speed_m_s, yerr=jc.spread_m_s, fmt="s", color="k", ms=4, label="Jülich 1.8 m (data)")
    axes[0].plot(rho, weidmann_speed_m_s(rho), "k--", lw=1, label="Weidmann (1993)")
    axes[1].plot(jc.density, jc.density * jc.speed_m_s, "s", color="k", ms=4, label="Jülich 1.8 m (data)")
    axes[1].plot(rho, rho * weidmann_speed_m_s(rho), "k--", lw=1, label="Weidmann (1993)")
    axes[2].plot(sf.density, sf.speed_m_s, "s", color="k", ms=4, label="Seyfried 2005 (data)")
    a, b = SINGLE_FILE_HEADWAY_FIT
    r1 = np.linspace(0.55, 2.0, 100)
    axes[2].plot(r1, np.clip((1.0 / r1 - a) / b, 0, None), "k--", lw=1, label=f"data fit d = {a} + {b} v")
    rows = summary.get("corridor", [])
    if rows:
        d = np.array([r["density"] for r in rows])
        v = np.array([r["speed_m_s"] for r in rows])
        e = np.array([r["speed_sd_m_s"] for r in rows])
        axes[0].errorbar(d, v, yerr=np.nan_to_num(e), fmt="o-", color="C0", ms=4, label="model (periodic corridor)")
        axes[1].plot(d, d * v, "o-", color="C0", ms=4, label="model (periodic corridor)")
    rows = summary.get("single_file", [])
    if rows:
        d = np.array([r["density"] for r in rows])
        v = np.array([r["speed_m_s"] for r in rows])
        axes[2].plot(d, v, "o-", color="C0", ms=4, label="model (ring)")
        fa, fb, _ = summary.get("single_file_fit", (np.nan, np.nan, 0))
        if np.isfinite(fa):
            axes[2].plot(r1, np.clip((1.0 / r1 - fa) / fb, 0, None), "--", color="C0", lw=1,
                         label=f"model fit d = {fa:.2f} + {fb:.2f} v")
    axes[0].set(xlabel="ρ (1/m²)", ylabel="v (m/s)", title="corridor: speed")
    axes[1].set(xlabel="ρ (1/m²)", ylabel="J_s (1/(m s))", title="corridor: specific flow")
    axes[2].set(xlabel="ρ (1/m)", ylabel="v (m/s)", title="single file: speed")
    return _save_diagram(fig, axes, path, title, legend_size=7)


def candidate_family(changes: dict) -> str:
    """The family of a candidate point by what it changes: ``vision``, ``social force``, ``both``, ``time to
    collision`` (with nothing else), or ``preset`` (nothing)."""
    vision = any(k.startswith("vision_") for k in changes)
    social = any(k.startswith("social_") for k in changes)
    if any(k.startswith("ttc_") for k in changes):
        return "time to collision" if not (vision or social) else "time to collision and more"
    return "both" if vision and social else "vision" if vision else "social force" if social else "preset"


def candidates_figure(rows: list, path: Path):
    """The door against the corridor for candidate parameter points (rows of ``crowd-fundamental-diagram
    --candidates``): J_s at b = 1.0 m against the corridor's speed at 2.62 /m², and against the largest corridor
    miss, one colour per family (:func:`candidate_family`), the experiment as a star. Points with a stalled door
    run at 1.0 m are left out (counted in the legend). Returns the path."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(10.0, 4.0))
    families = {}
    for r in rows:
        door = r["door"].get("1.0", r["door"].get(1.0))
        corr = r["corridor"].get("2.616", r["corridor"].get(2.616))
        fam = families.setdefault(candidate_family(r["changes"]) if r.get("preset") == "calibrated"
                                  else f"{r.get('preset')} preset and changes", {"x": [], "m": [], "y": [], "stalled": 0})
        if door is None or corr is None or not np.isfinite(door["specific_flow_per_m_s"]):
            fam["stalled"] += 1
            continue
        fam["x"].append(corr["speed_m_s"])
        fam["m"].append(r["corridor_max_miss_m_s"])
        fam["y"].append(door["specific_flow_per_m_s"])
    for k, (name, f) in enumerate(sorted(families.items())):
        label = name + (f" ({f['stalled']} stalled at 1 m, not shown)" if f["stalled"] else "")
        axes[0].plot(f["x"], f["y"], "o", color=f"C{k}", ms=5, label=label)
        axes[1].plot(f["m"], f["y"], "o", color=f"C{k}", ms=5, label=label)
    axes[0].plot([0.422], [1.901], "k*", ms=14, label="experiments (Jülich corridor, Seyfried door)")
    axes[1].plot([0.0], [1.901], "k*", ms=14, label="experiments")
    axes[1].axvline(0.10, color="k", lw=0.8, ls=":")
    axes[0].set(xlabel="corridor speed at 2.62 /m² (m/s)", ylabel="door J_s at b = 1.0 m, N = 60 (1/(m s))",
                title="door against corridor")
    axes[1].set(xlabel="largest corridor speed miss, 0.63-3.10 /m² (m/s)", ylabel="door J_s at b = 1.0 m (1/(m s))",
                title="door against the whole corridor")
    for ax in axes:
        ax.legend(fontsize=7, loc="lower right")
    save_figure(fig, path)
    return Path(path)
