"""ε_T on an (A, B) grid (Kabalan Section 4.1.2, Eq. 23-25, Fig. 10) from single runs.

Every grid point is the bottleneck reproduction's (b, N) runs × seeds with A and B set; the same seeds
at every point (common random numbers). :func:`evaluate_grid` runs what is missing, then
:func:`write_grid_outputs` writes the surface table, the valley of minima with its exponential fit
A(B) = a exp(c B) beside the paper's A = 1501 exp(-7.98 B), the best point and the figure.

Incomplete and stalled runs. A run in which not everybody passed reports no J_s (``complete`` False);
``--incomplete`` says how it enters ε_T: ``bound`` (default) with the largest J_s consistent with the
time limit, ``partial`` with the flow of the passages that happened. A *stalled* run (the runner's stall
rule: nobody passed for 20 s while those left stood still; the run stopped there) is a failure of the
parameter point, whatever ε_T says: the point's objective becomes :data:`STALLED_OBJECTIVE` ×
(1 + fraction of its runs that stalled) + its objective, above any stall-free point (whose objectives
are far below 1000) and ordered by how many runs stalled, so that an optimiser walks out of a clogging
region. ε_T itself stays the measured one. ``surface.csv`` counts ``n_stalled`` beside ``n_clogged``
(all incomplete runs, stalled included); the best point and the valley of minima skip points with a
stall, and the figure marks them.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from crowd_env.files import write_csv_atomic, write_json_atomic
from .errors import (PAPER_VALLEY_FIT, CalibrationError, ExponentialFit, PointScore, Valley,
                                    best_grid_point, censored_specific_flow, check_grid_values, fit_exponential_valley, point_error,
                                    valley_of_minima)
from ....analysis.experiment import ExperimentTable
from ...running.backends import execute, failure_report
from ..bottleneck import run_one
from ...running.store import RunStore
from .tasks import canonical, make_task


def check_run_plan(widths_m, sizes, seeds) -> tuple:
    """Validated (widths, group sizes, seeds): non-empty, widths > 0, N >= 2, seeds distinct integers >= 0."""
    b = [float(x) for x in widths_m]
    n = [int(x) for x in sizes]
    s = [int(x) for x in seeds]
    if not b or not n or not s:
        raise CalibrationError(f"need at least one width, group size and seed, got {len(b)}, {len(n)}, {len(s)}")
    if any(not np.isfinite(x) or x <= 0 for x in b) or len(set(b)) != len(b):
        raise CalibrationError(f"widths must be distinct, finite and > 0, got {b}")
    if any(x < 2 for x in n) or len(set(n)) != len(n):
        raise CalibrationError(f"group sizes must be distinct and >= 2 (J = N/Δt needs two passages), got {n}")
    if any(x < 0 for x in s) or len(set(s)) != len(s):
        raise CalibrationError(f"seeds must be distinct and >= 0, got {s}")
    return b, n, s


def point_tasks(config: dict, model: dict, pedestrian: dict, widths_m, sizes, seeds) -> list:
    """The (b, N, seed) tasks of one parameter point."""
    return [make_task(config, model, pedestrian, b, n, s) for n in sizes for b in widths_m for s in seeds]


INCOMPLETE_RULES = ("bound", "partial")
STALLED_OBJECTIVE = 1000.0  # a point with stalled runs: objective 1000 × (1 + stalled fraction) + objective


def n_stalled_runs(records: list) -> int:
    """Runs the stall rule stopped (``stalled``; records from before the rule count as not stalled)."""
    return sum(bool(r.get("stalled", False)) for r in records)


def point_error_of(tasks: list, records: list, reference: ExperimentTable | None, range_weight: float,
                   incomplete: str = "bound") -> PointScore:
    """Eq. 23-24 of one point from its tasks and run records.

    ``incomplete``: how a run in which not all N passed (stalled, or people left at the time limit)
    counts: ``bound`` (default) with the bound of :func:`censored_specific_flow` (a stuck pedestrian makes
    the flow small, as Δt = first to last of N passages demands; T is the task's time limit also for a
    run stopped early by a stall), ``partial`` with the flow of the passages that happened
    (``partial_specific_flow_per_m_s``). A point with stalled runs gets the objective of the module
    docstring (:data:`STALLED_OBJECTIVE`); its ε_T is unchanged.
    """
    if incomplete not in INCOMPLETE_RULES:
        raise CalibrationError(f"incomplete must be one of {INCOMPLETE_RULES}, got {incomplete!r}")
    col = {k: np.array([r[k] for r in records], dtype=np.float64)
           for k in ("width_m", "n_pedestrians", "specific_flow_per_m_s", "n_passages", "first_passage_s")}
    js = col["specific_flow_per_m_s"]
    if incomplete == "bound":
        js = censored_specific_flow(js, col["n_pedestrians"], col["n_passages"], col["first_passage_s"],
                                    [t["max_time_s"] for t in tasks], col["width_m"])
    else:
        partial = np.array([r.get("partial_specific_flow_per_m_s", r["specific_flow_per_m_s"]) for r in records],
                           dtype=np.float64)
        js = np.where(col["n_passages"] < col["n_pedestrians"], partial, js)
    e = point_error(col["width_m"], col["n_pedestrians"].astype(np.int64), js, reference, range_weight)
    stalled = n_stalled_runs(records)
    if stalled:
        e = replace(e, objective=STALLED_OBJECTIVE * (1.0 + stalled / len(records)) + e.objective)
    return e


@dataclass
class GridResult:
    """ε_T (and the objective with the range penalty) on the grid, shape (n_A, n_B); nan where runs failed."""

    social_strength_n: np.ndarray
    social_range_m: np.ndarray
    epsilon_total: np.ndarray
    objective: np.ndarray
    errors: dict = field(default_factory=dict)  # (i, j) -> PointScore
    n_failed_runs: int = 0
    failure_report: str = ""  # why runs failed (crowd_env.experiments.running.backends.failure_report), "" if none
    n_clogged: np.ndarray | None = None  # (n_A, n_B) runs where not all N passed (stalled ones included)
    n_stalled: np.ndarray | None = None  # (n_A, n_B) runs stopped by the stall rule


def evaluate_grid(out, config: dict, social_strength_n, social_range_m, widths_m, sizes, seeds, backend, *,
                  reference: ExperimentTable | None = None, range_weight: float = 0.0, run_fn=run_one,
                  pedestrian: dict | None = None, model: dict | None = None, incomplete: str = "bound") -> GridResult:
    """Run (or reuse) every (A, B, b, N, seed) run of the grid under ``out`` and compute ε_T per point.

    ``model`` / ``pedestrian``: fixed overrides applied at every point (e.g. λ). Tasks are single runs,
    submitted together so the backend balances load; each is saved as it finishes (resumable).
    """
    a = np.array([canonical(x) for x in check_grid_values(social_strength_n, "A")])
    bb = np.array([canonical(x) for x in check_grid_values(social_range_m, "B")])
    if np.unique(a).size != a.size or np.unique(bb).size != bb.size:
        raise CalibrationError("grid values coincide after rounding to 6 significant digits")
    widths_m, sizes, seeds = check_run_plan(widths_m, sizes, seeds)
    store = RunStore(out, config, keyed_by="task")
    fixed = dict(model or {})
    clash = sorted({"social_strength_n", "social_range_m"} & set(fixed))
    if clash:
        raise CalibrationError(f"{clash} are the grid axes; they cannot also be fixed")
    tasks = {(i, j): point_tasks(config, {**fixed, "social_strength_n": ai, "social_range_m": bj}, pedestrian or {},
                                 widths_m, sizes, seeds)
             for i, ai in enumerate(a) for j, bj in enumerate(bb)}
    # Check the error definition applies (experimental counterparts exist) before running anything.
    first = next(iter(tasks.values()))
    point_error_of(first, [{**t, "specific_flow_per_m_s": 1.0, "n_passages": t["n_pedestrians"], "first_passage_s": 0.0}
                           for t in first], reference, range_weight, incomplete)
    failed = execute([t for ts in tasks.values() for t in ts], store, backend, run_fn,
                     desc=f"ε_T grid {a.size}×{bb.size}")
    eps = np.full((a.size, bb.size), np.nan)
    obj = np.full_like(eps, np.nan)
    clogged = np.zeros(eps.shape, dtype=np.int64)
    stalled = np.zeros(eps.shape, dtype=np.int64)
    errors = {}
    for (i, j), ts in tasks.items():
        records = [store.load(t) for t in ts]
        if any(r is None for r in records):
            continue
        e = point_error_of(ts, records, reference, range_weight, incomplete)
        errors[(i, j)] = e
        clogged[i, j] = sum(r["n_passages"] < r["n_pedestrians"] for r in records)
        stalled[i, j] = n_stalled_runs(records)
        eps[i, j], obj[i, j] = e.epsilon_total, e.objective
    report = failure_report([t for ts in tasks.values() for t in ts], store) if failed else ""
    return GridResult(a, bb, eps, obj, errors, failed, report, clogged, stalled)


def analyse_surface(result: GridResult, use_objective: bool = False, exclude_edges: bool = True) -> dict:
    """Best point, valley of minima and its exponential fit (with the paper's for comparison); points with
    a stalled run are left out (failed points, module docstring)."""
    surface = result.objective if use_objective else result.epsilon_total
    if result.n_stalled is not None and result.n_stalled.any():
        surface = np.where(result.n_stalled > 0, np.nan, surface)
    a_best, b_best, e_best = best_grid_point(result.social_strength_n, result.social_range_m, surface)
    valley = valley_of_minima(result.social_strength_n, result.social_range_m, surface)
    use = ~valley.at_edge if exclude_edges and np.count_nonzero(~valley.at_edge) >= 2 else np.ones_like(valley.at_edge)
    fit = None
    if np.unique(valley.social_range_m[use]).size >= 2:
        fit = fit_exponential_valley(valley.social_range_m[use], valley.social_strength_n[use])
    return {"best": {"social_strength_n": a_best, "social_range_m": b_best, "epsilon": e_best},
            "valley": valley, "fit_mask": use, "fit": fit}


def _fit_json(fit: ExponentialFit | None) -> dict | None:
    if fit is None:
        return None
    return {"coefficient_n": fit.coefficient_n, "rate_per_m": fit.rate_per_m,
            "residual_norm_log": fit.residual_norm_log if np.isfinite(fit.residual_norm_log) else None,
            "n_points": fit.n_points,
            "formula": f"A = {fit.coefficient_n:.4g} * exp({fit.rate_per_m:.4g} * B)"}


def write_grid_outputs(result: GridResult, out, analysis: dict, meta: dict | None = None, figure: bool = True) -> list:
    """``surface.csv`` (one row per grid point), ``valley.csv``, ``calibration.json`` and
    ``fig10_epsilon_surface.png`` under ``out``; returns the paths written."""
    out = Path(out)
    paths = []
    keys = sorted({(float(b), int(n)) for e in result.errors.values() for b, n in zip(e.width_m, e.n_pedestrians)},
                  key=lambda k: (k[1], k[0]))
    js_cols = [f"js_mean_b{b:.2f}_n{n}" for b, n in keys]
    groups = sorted({g for e in result.errors.values() for g in e.epsilon_by_group})
    header = (["social_strength_n", "social_range_m", "epsilon_total", "objective"]
              + [f"epsilon_n{g}" for g in groups] + ["range_penalty", "range_all_inside", "n_runs", "n_clogged",
                                                       "n_stalled"]
              + js_cols)
    path = out / "surface.csv"
    rows = []
    for i, a in enumerate(result.social_strength_n):
        for j, b in enumerate(result.social_range_m):
            e = result.errors.get((i, j))
            if e is None:
                rows.append([a, b] + [""] * (len(header) - 2))
                continue
            js = {(float(bb), int(nn)): v for bb, nn, v in zip(e.width_m, e.n_pedestrians, e.mean_specific_flow_per_m_s)}
            rows.append([a, b, e.epsilon_total, e.objective] + [e.epsilon_by_group.get(g, "") for g in groups]
                        + [e.range_penalty, e.range_all_inside, e.n_runs,
                           int(result.n_clogged[i, j]) if result.n_clogged is not None else "",
                           int(result.n_stalled[i, j]) if result.n_stalled is not None else ""]
                        + [js.get(k, "") for k in keys])
    write_csv_atomic(path, header, rows)
    paths.append(path)
    valley: Valley = analysis["valley"]
    path = out / "valley.csv"
    write_csv_atomic(path, ["social_range_m", "social_strength_n_at_min", "epsilon_min", "at_grid_edge", "used_in_fit"],
                     ([float(row[0]), float(row[1]), float(row[2]), bool(row[3]), bool(row[4])] for row in
                      zip(valley.social_range_m, valley.social_strength_n, valley.epsilon, valley.at_edge,
                          analysis["fit_mask"])))
    paths.append(path)
    fit = analysis["fit"]
    summary = {
        "best_point": analysis["best"], "valley_fit": _fit_json(fit), "paper_valley_fit": _fit_json(PAPER_VALLEY_FIT),
        "grid": {"social_strength_n": result.social_strength_n.tolist(), "social_range_m": result.social_range_m.tolist()},
        "n_points_complete": int(np.isfinite(result.epsilon_total).sum()), "n_points": int(result.epsilon_total.size),
        "n_failed_runs": result.n_failed_runs,
        "n_points_with_stalls": int((result.n_stalled > 0).sum()) if result.n_stalled is not None else 0,
        **(meta or {}),
    }
    path = out / "calibration.json"
    write_json_atomic(path, summary, indent=2, default=float)
    paths.append(path)
    if figure:
        paths.append(surface_figure(result, analysis, out / "fig10_epsilon_surface.png"))
    return paths


def surface_figure(result: GridResult, analysis: dict, path) -> Path:
    """Fig. 10 analogue: ε_T over (B, A) (log colour scale), valley minima, fitted and paper curves."""
    from matplotlib.colors import LogNorm

    from ....analysis.figures import pyplot, save_figure

    plt = pyplot()

    a, b, eps = result.social_strength_n, result.social_range_m, result.epsilon_total
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    finite = eps[np.isfinite(eps) & (eps > 0)]
    if finite.size and a.size > 1 and b.size > 1:
        norm = LogNorm(vmin=finite.min(), vmax=finite.max()) if finite.max() > finite.min() else None
        mesh = ax.pcolormesh(b, a, np.ma.masked_invalid(eps), shading="nearest", norm=norm, cmap="viridis")
        fig.colorbar(mesh, ax=ax, label="ε_T (Eq. 24)")
    else:
        sc = ax.scatter(np.repeat(b[None, :], a.size, 0).ravel(), np.repeat(a[:, None], b.size, 1).ravel(),
                        c=eps.ravel(), cmap="viridis")
        fig.colorbar(sc, ax=ax, label="ε_T (Eq. 24)")
    v = analysis["valley"]
    ax.plot(v.social_range_m, v.social_strength_n, "o", mfc="none", mec="red", ms=8, label="min over A per B")
    bs = np.linspace(b.min(), b.max(), 200)
    if analysis["fit"] is not None:
        f = analysis["fit"]
        ax.plot(bs, f(bs), "r-", label=f"fit A = {f.coefficient_n:.0f} exp({f.rate_per_m:.2f} B)")
    ax.plot(bs, PAPER_VALLEY_FIT(bs), "w--", label="paper A = 1501 exp(-7.98 B)")
    if result.n_stalled is not None and result.n_stalled.any():
        ia, ib = np.nonzero(result.n_stalled > 0)
        ax.plot(b[ib], a[ia], "x", color="red", ms=9, mew=2, label="stalled run(s): failed point")
    best = analysis["best"]
    ax.plot(best["social_range_m"], best["social_strength_n"], "*", color="orange", ms=14,
            label=f"best ε_T = {best['epsilon']:.3g}")
    ax.set_ylim(a.min() - 0.05 * (a.max() - a.min() or a.min()), a.max() + 0.05 * (a.max() - a.min() or a.max()))
    ax.set_xlabel("B (m)")
    ax.set_ylabel("A (N)")
    ax.set_title("ε_T(A, B), Kabalan et al. (2016) Fig. 10")
    ax.legend(fontsize=7, loc="upper right")
    save_figure(fig, path)
    return Path(path)
