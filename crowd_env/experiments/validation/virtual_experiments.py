"""Virtual experiments: every shipped experiment run as it was run, for one model, side by side with its data.

Three experiments (:data:`EXPERIMENTS`), each in its own geometry, population and measurement:

- ``bottleneck``: Seyfried et al. (2009), N = 20, 40, 60 in front of a 2.8 m channel of width b = 0.8-1.2 m
  (:mod:`crowd_env.experiments.validation.bottleneck`): J_s (Eq. 22, first to last passage of the channel's middle),
  the density and speed inside the channel over the stationary phase; the experiment's J_s for N = 60, the range
  [1.77, 2.31] for N = 20 and 40, and the ranges of density (1.42-1.73 /m²) and speed (0.94-1.22 m/s) inside;
- ``corridor``: the nine Jülich corridor runs with their entrance and exit
  (:mod:`crowd_env.experiments.validation.corridor_runs`): the Voronoi density and speed in y in [−2, 0] and the exit
  flow over the steady state, each run against its row;
- ``single_file``: the single-file ring (Seyfried et al. 2005), a periodic strip 0.7 m wide at each bin's 1D
  density (:mod:`crowd_env.experiments.validation.fundamental_diagram`): mean speed against the bin's.

:func:`virtual_tasks` makes the runs of a :class:`VirtualPlan` for one model, or for a learned policy driving every
pedestrian (the configuration's ``policy``, :func:`virtual_config`) (the same seeds in every experiment:
common random numbers between models); :func:`run_virtual_experiments` runs those not yet stored on the project's
executor (a :class:`~crowd_env.experiments.running.store.RunStore` per output folder, keyed by task: a stopped run
resumes); :func:`virtual_rows` puts each measured quantity beside the experiment with its tolerance, over the complete
runs only, and counts the runs that stalled or stayed incomplete; :func:`virtual_figure` draws each run's model point
and experiment point in the density-speed plane, joined.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from crowd_env.errors import InputError, SweepError

from ...analysis.experiment import (INSIDE_DENSITY_RANGE_PER_M2, INSIDE_SPEED_RANGE_M_S,
                                    SPECIFIC_FLOW_RANGE_N20_N40_PER_M_S, seyfried_2009)
from ...analysis.corridor_runs import lapse_summary, uo_run
from ...analysis.fd_reference import single_file
from ...analysis.figures import pyplot, save_figure
from ...core.body import body_circles, circle_count
from ...walking.model import ModelParams
from ...walking.navigation import NavigationField
from ..running.backends import execute
from ..running.crowd_policy import crowd_policy, policy_entry
from ..running.store import RunStore
from .bottleneck import GEOMETRY_OPTIONS, bottleneck_scenario, params_dict, run_one
from .calibration.tasks import with_body
from .corridor_runs import (CORRIDOR_RUN_NAMES, CORRIDOR_TOLERANCES, corridor_scenario, corridor_tasks,
                            run_corridor_one, summarise_corridor)
from .fundamental_diagram import SINGLE_FILE_DENSITIES, fd_tasks, run_fd_one
from crowd_env.files import write_atomic, write_csv_atomic

__all__ = ["EXPERIMENTS", "VirtualPlan", "QUICK_PLAN", "virtual_config", "virtual_tasks", "run_virtual_task",
           "run_virtual_experiments", "virtual_rows", "ROW_COLUMNS", "format_rows", "write_virtual_outputs",
           "virtual_figure", "snapshot_case", "run_snapshot", "snapshot_figure", "BOTTLENECK_TOLERANCE",
           "SINGLE_FILE_TOLERANCE_M_S",
           "PASSAGE_QUANTITIES", "passage_rows", "format_passage_rows", "approach_figure", "entry_figure",
           "spacing_rows",
           "format_spacing_rows", "spacing_figure", "LAPSE_QUANTITIES", "lapse_rows", "format_lapse_rows",
           "lapse_figure", "corridor_miss", "selection_rank", "format_selection"]

EXPERIMENTS = ("bottleneck", "corridor", "single_file")
BOTTLENECK_TOLERANCE = 0.05  # J_s of N = 60 within ±5 % of Seyfried's
SINGLE_FILE_TOLERANCE_M_S = 0.10  # single-file speed within ±0.10 m/s of each bin
BOTTLENECK_WIDTHS_M = (0.8, 0.9, 1.0, 1.1, 1.2)
BOTTLENECK_SIZES = (20, 40, 60)


@dataclass(frozen=True)
class VirtualPlan:
    """Which runs: the experiments, the seeds (the same in each), the bottleneck's widths and N, the corridor runs by
    name, the single file's 1D densities (shipped bins), and the time limit of a bottleneck or corridor run."""

    experiments: tuple = EXPERIMENTS
    seeds: tuple = (0, 1, 2, 3, 4)
    widths_m: tuple = BOTTLENECK_WIDTHS_M
    sizes: tuple = BOTTLENECK_SIZES
    corridor_runs: tuple = CORRIDOR_RUN_NAMES
    single_file_densities: tuple = SINGLE_FILE_DENSITIES
    max_time_s: float = 300.0

    def __post_init__(self) -> None:
        unknown = sorted(set(self.experiments) - set(EXPERIMENTS))
        if unknown or not self.experiments:
            raise InputError(f"unknown experiment(s) {unknown}; choose among {list(EXPERIMENTS)}")
        seeds = tuple(int(s) for s in self.seeds)
        if not seeds or min(seeds) < 0 or len(set(seeds)) != len(seeds):
            raise InputError(f"seeds must be distinct integers >= 0, at least one, got {list(self.seeds)}")
        object.__setattr__(self, "seeds", seeds)
        unknown_runs = sorted(set(self.corridor_runs) - set(CORRIDOR_RUN_NAMES))
        if unknown_runs:
            raise InputError(f"unknown corridor run(s) {unknown_runs}; the runs are {list(CORRIDOR_RUN_NAMES)}")
        off = [d for d in self.single_file_densities if not np.any(np.isclose(SINGLE_FILE_DENSITIES, d))]
        if off:
            raise InputError(f"single-file densities {off} are no shipped bins; choose among {list(SINGLE_FILE_DENSITIES)}")
        if not (math.isfinite(self.max_time_s) and self.max_time_s > 0):
            raise InputError(f"max_time_s must be finite and > 0, got {self.max_time_s!r}")


# the default suite's reduced plan: two corridor runs (a narrow entrance, a narrowed exit), one door, one bin
QUICK_PLAN = VirtualPlan(seeds=(0, 1), widths_m=(1.0,), sizes=(60,), corridor_runs=("uo-070-180-180", "uo-180-180-095"),
                         single_file_densities=(SINGLE_FILE_DENSITIES[2],))


def virtual_config(params: ModelParams, *, navigation_clearance_m: float, pedestrian: dict | None = None,
                   radius_m: float | None = None, corridor_geometry: dict | None = None, policy: str | None = None,
                   navigation_wall_slowdown=None, policy_social_force: bool = False,
                   policy_social_force_below_m_s: float | None = None) -> dict:
    """The configuration of a folder of virtual experiments: the model, the navigation clearance of the bottleneck
    (the corridor uses the disk centres' field, as every other scenario), per-pedestrian overrides and the body's
    radius (None: Kabalan's Table 2, 0.23 m; else every scenario's, the bottleneck's clearance following it where
    it is the disk centres' field, the single file's strip scaled with it:
    :func:`~crowd_env.experiments.validation.calibration.tasks.with_body`); ``corridor_geometry``: options of the
    scenario ``juelich_corridor`` for every corridor run (its undocumented dimensions: barrier and end-wall
    thickness, floor and outflow width, the waiting area), checked by building every run's scenario once.
    ``policy``: who drives every pedestrian of every run (a shipped trained policy's name, a policy file, an import
    path: :func:`~crowd_env.experiments.running.crowd_policy.policy_entry`, which checks that it loads); None or
    ``"calibrated"``: the calibrated agent of ``params``; ``policy_social_force``: the social force of ``params``
    added to the policy's intents (``policy_social_force_below_m_s``: only to those nearly standing).
    ``navigation_wall_slowdown`` ``(distance_m, speed_factor)``: a slower eikonal wavefront near walls (Eq. 11's V < 1)
    in the bottleneck's field; give the corridor's in ``corridor_geometry`` (the command gives both)."""
    config = {"kind": "virtual_experiments", "params": params_dict(params),
              "navigation_clearance_m": float(navigation_clearance_m), "pedestrian": dict(pedestrian or {})}
    if navigation_wall_slowdown is not None:
        config["navigation_wall_slowdown"] = list(NavigationField.check_wall_slowdown(navigation_wall_slowdown))
    if (policy_social_force or policy_social_force_below_m_s is not None) and policy is None:
        raise InputError("policy_social_force adds the model's social force to a learned policy: name the policy")
    entry = policy_entry(policy, social_force=policy_social_force,
                         social_force_below_m_s=policy_social_force_below_m_s) if policy is not None else None
    if entry is not None:
        config["policy"] = entry
    if radius_m is not None:
        config["radius_m"] = float(radius_m)
    if corridor_geometry:
        from ...scenarios import make_scenario

        for name in CORRIDOR_RUN_NAMES:
            run = uo_run(name)
            make_scenario("juelich_corridor", entrance_width_m=run.entrance_width_m, exit_width_m=run.exit_width_m,
                          n_pedestrians=run.n_pedestrians, **dict(corridor_geometry))
        config["corridor_geometry"] = dict(corridor_geometry)
    return config


def virtual_tasks(config: dict, plan: VirtualPlan) -> list:
    """Every run of ``plan`` for the model of ``config`` (tasks of :func:`run_virtual_task`, each with its
    ``experiment``)."""
    params = ModelParams.from_dict(config["params"])
    pedestrian = config.get("pedestrian") or {}
    radius = config.get("radius_m")
    tasks = []
    if "bottleneck" in plan.experiments:
        geometry = {opt: float(default) for opt, default in GEOMETRY_OPTIONS.values()}
        geometry["navigation_clearance_m"] = config["navigation_clearance_m"]
        if config.get("navigation_wall_slowdown") is not None:
            geometry["navigation_wall_slowdown"] = list(config["navigation_wall_slowdown"])
        for b in plan.widths_m:
            for n in plan.sizes:
                for s in plan.seeds:
                    tasks.append(with_body({"experiment": "bottleneck", "width_m": float(b), "n_pedestrians": int(n),
                                            "seed": s, "geometry": geometry, "params": params_dict(params),
                                            "max_time_s": plan.max_time_s, "pedestrian": dict(pedestrian)}, radius))
    if "corridor" in plan.experiments:
        geometry = dict(config.get("corridor_geometry") or {}, **({} if radius is None else {"radius_m": radius}))
        tasks += corridor_tasks(params, runs=plan.corridor_runs, seeds=plan.seeds, pedestrian=pedestrian or None,
                                max_time_s=plan.max_time_s, geometry=geometry)
    if "single_file" in plan.experiments:
        for t in fd_tasks(["single_file"], {"single_file": plan.single_file_densities}, plan.seeds, params,
                          radius_m=radius):
            tasks.append(dict(t, experiment="single_file", pedestrian=dict(pedestrian)))
    if config.get("policy"):
        tasks = [dict(t, policy=dict(config["policy"])) for t in tasks]
    return tasks


def run_virtual_task(task: dict) -> dict:
    """One run of any experiment (its ``experiment`` picks the runner); the record carries ``experiment``."""
    kind = task["experiment"]
    if kind == "bottleneck":
        record = run_one({k: v for k, v in task.items() if k != "experiment"})
    elif kind == "corridor":
        record = run_corridor_one(task)
    elif kind == "single_file":
        record = run_fd_one(task)
    else:
        raise InputError(f"unknown experiment {kind!r}; choose among {list(EXPERIMENTS)}")
    record["experiment"] = kind
    return record


def run_virtual_experiments(out, config: dict, plan: VirtualPlan, backend, *, desc: str = "virtual experiments") -> list:
    """Run the tasks of ``plan`` not stored in ``out`` on ``backend``; all records, in the order of the tasks. A
    failed run raises :class:`~crowd_env.errors.SweepError` with its reason once the others are stored."""
    store = RunStore(out, config, keyed_by="task")
    tasks = virtual_tasks(config, plan)
    failed = execute(tasks, store, backend, run_virtual_task, desc=desc)
    if failed:
        raise SweepError(f"{failed} run(s) failed: {_first_error(Path(out))} (all in {Path(out) / 'errors.jsonl'})")
    return [store.load(t) for t in tasks]


def _first_error(out: Path) -> str:
    import json

    path = out / "errors.jsonl"
    lines = path.read_text().splitlines() if path.exists() else []
    return json.loads(lines[-1])["error"] if lines else "no reason recorded"


ROW_COLUMNS = ["experiment", "case", "quantity", "model", "model_sd", "experiment_value", "tolerance", "within",
               "runs", "complete", "stalled", "incomplete"]


def _stats(values) -> tuple:
    v = np.asarray([x for x in values if x is not None and np.isfinite(x)], dtype=np.float64)
    if not v.size:
        return math.nan, math.nan
    return float(v.mean()), float(v.std(ddof=1)) if v.size > 1 else math.nan


def _row(experiment, case, quantity, values, exp_value, tolerance, within, counts) -> dict:
    mean, sd = _stats(values)
    return {"experiment": experiment, "case": case, "quantity": quantity, "model": mean, "model_sd": sd,
            "experiment_value": exp_value, "tolerance": tolerance, "within": bool(within(mean)) if np.isfinite(mean)
            else False, **counts}


def _counts(records) -> dict:
    return {"runs": len(records), "complete": sum(bool(r["complete"]) for r in records),
            "stalled": sum(bool(r.get("stalled")) for r in records),
            "incomplete": sum(not r["complete"] and not r.get("stalled") for r in records)}


def _bottleneck_rows(records: list) -> list:
    exp = seyfried_2009()
    rows = []
    lo, hi = SPECIFIC_FLOW_RANGE_N20_N40_PER_M_S
    for (b, n) in sorted({(r["width_m"], r["n_pedestrians"]) for r in records}):
        rs = [r for r in records if r["width_m"] == b and r["n_pedestrians"] == n]
        done = [r for r in rs if r["complete"]]
        counts = _counts(rs)
        case = f"b = {b:.1f} m, N = {n}"
        js = [r["specific_flow_per_m_s"] for r in done]
        if n == 60:
            ref = float(exp.specific_flow_per_m_s[exp.lookup(b, 60)[0]])
            rows.append(_row("bottleneck", case, "J_s (1/(m s))", js, ref, f"±{BOTTLENECK_TOLERANCE:.0%}",
                             lambda m, ref=ref: abs(m / ref - 1.0) <= BOTTLENECK_TOLERANCE, counts))
        else:
            rows.append(_row("bottleneck", case, "J_s (1/(m s))", js, math.nan, f"[{lo}, {hi}]",
                             lambda m: lo <= m <= hi, counts))
        for quantity, key, (qlo, qhi) in (("density inside (1/m²)", "density_inside_per_m2", INSIDE_DENSITY_RANGE_PER_M2),
                                          ("speed inside (m/s)", "speed_inside_m_s", INSIDE_SPEED_RANGE_M_S)):
            if n == 60:
                rows.append(_row("bottleneck", case, quantity, [r[key] for r in done], math.nan, f"[{qlo}, {qhi}]",
                                 lambda m, qlo=qlo, qhi=qhi: qlo <= m <= qhi, counts))
    return rows


def _corridor_rows(records: list) -> list:
    rows = []
    tol = CORRIDOR_TOLERANCES
    for s in summarise_corridor(records):
        rs = [r for r in records if r["run"] == s["run"]]
        done = [r for r in rs if r["complete"]]
        counts = _counts(rs)
        case = f"{s['run']} (entrance {s['entrance_width_m']:.2f} m, exit {s['exit_width_m']:.2f} m, N = {s['n_pedestrians']})"
        for quantity, key, exp_key, tolerance, within in (
                ("density (1/m²)", "density_per_m2", "density_exp", f"±{tol['density_relative']:.0%}",
                 lambda m, e: abs(m / e - 1.0) <= tol["density_relative"]),
                ("speed (m/s)", "speed_m_s", "speed_exp", f"±{tol['speed_m_s']:g} m/s",
                 lambda m, e: abs(m - e) <= tol["speed_m_s"]),
                ("exit flow (1/s)", "flow_exit_per_s", "flow_exit_exp", f"±{tol['flow_exit_relative']:.0%}",
                 lambda m, e: abs(m / e - 1.0) <= tol["flow_exit_relative"])):
            e = s[exp_key]
            rows.append(_row("corridor", case, quantity, [r[key] for r in done], e, tolerance,
                             lambda m, e=e, within=within: within(m, e), counts))
    return rows


def _single_file_rows(records: list) -> list:
    table = single_file()
    rows = []
    for d in sorted({r["density"] for r in records}):
        rs = [r for r in records if r["density"] == d]
        ref = float(table.speed_at(d))
        rows.append(_row("single_file", f"ρ = {d:g} /m", "speed (m/s)", [r["speed_m_s"] for r in rs], ref,
                         f"±{SINGLE_FILE_TOLERANCE_M_S:g} m/s",
                         lambda m, ref=ref: abs(m - ref) <= SINGLE_FILE_TOLERANCE_M_S, _counts(rs)))
    return rows


def virtual_rows(records: list) -> list:
    """One row per experiment case and quantity (:data:`ROW_COLUMNS`): the model's mean and spread over the
    complete runs, the experiment's value (nan where it is a range), the tolerance, whether the mean lies within
    it (never for a case without a complete run), and the runs that were complete, stalled or otherwise
    incomplete."""
    by_kind = {k: [r for r in records if r.get("experiment") == k] for k in EXPERIMENTS}
    rows = []
    if by_kind["bottleneck"]:
        rows += _bottleneck_rows(by_kind["bottleneck"])
    if by_kind["corridor"]:
        rows += _corridor_rows(by_kind["corridor"])
    if by_kind["single_file"]:
        rows += _single_file_rows(by_kind["single_file"])
    return rows


def corridor_miss(records: list) -> dict:
    """How far the corridor runs of ``records`` are from their experiments, as the human policy's candidates are
    ranked (docs/validation/human_policy.md): ``miss``, the mean over the runs and their density, speed and exit flow
    of the miss in units of the tolerance (:func:`~crowd_env.experiments.validation.corridor_runs.summarise_corridor`,
    seed means of the complete runs; a run with no complete seed counts no quantity); ``failed``, the runs that
    stalled or stayed incomplete (a candidate with any ranks after every candidate without); ``unmeasured``, the
    quantities no complete seed measured (the miss leaves them out); ``runs``, the summary's rows. Raises
    :class:`InputError` without corridor records."""
    rows = summarise_corridor(records)
    if not rows:
        raise InputError("no corridor runs among the records: nothing to score")
    values = [row[k] for row in rows for k in ("density_miss", "speed_miss", "flow_exit_miss")]
    misses = [v for v in values if np.isfinite(v)]
    failed = sum(row["stalled"] + row["incomplete"] for row in rows)
    return {"miss": float(np.mean(misses)) if misses else math.inf, "failed": int(failed),
            "unmeasured": len(values) - len(misses), "runs": rows}


def selection_rank(score: dict) -> tuple:
    """The order of candidates scored by :func:`corridor_miss` (smallest first): those with no stalled or incomplete
    run first; then those whose miss covers every quantity (a mean over fewer quantities is not comparable: a run
    that never completed has none); then the miss."""
    return score["failed"] > 0, score["unmeasured"], score["miss"]


def format_selection(names: list, scores: list, best: int) -> str:
    """Candidates scored by :func:`corridor_miss` as a Markdown table: each run's density / speed / exit flow (seed
    means of the complete runs, the experiment's in the header), the miss, the quantities it could not count (no
    complete seed), the stalled or incomplete runs; the candidate ``best`` in bold."""
    head = ["candidate", *(f"{r['run']} ρ / v / J (exp. {r['density_exp']:.2f} / {r['speed_exp']:.2f} / "
                           f"{r['flow_exit_exp']:.2f})" for r in scores[0]["runs"]), "miss", "unmeasured",
            "stalled or incomplete"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for k, (name, score) in enumerate(zip(names, scores)):
        cells = [f"{k}: {name}", *(" / ".join(_cell(r[q]) for q in ("density_per_m2", "speed_m_s", "flow_exit_per_s"))
                                   for r in score["runs"]), _cell(score["miss"]), str(score["unmeasured"]),
                 str(score["failed"])]
        lines.append("| " + " | ".join(f"**{c}**" if k == best else c for c in cells) + " |")
    return "\n".join(lines)


def _cell(value, sd=math.nan) -> str:
    if not np.isfinite(value):
        return "–"
    return f"{value:.2f}" + (f" ± {sd:.2f}" if np.isfinite(sd) else "")


def format_rows(rows: list, *, markdown: bool = False) -> str:
    """The rows as a table (plain text for the console, or Markdown), and a closing line counting the quantities
    within tolerance and the runs that did not complete."""
    head = ["experiment", "case", "quantity", "model", "experiment", "tolerance", "within", "runs (stalled/incomplete)"]
    body = [[r["experiment"], r["case"], r["quantity"], _cell(r["model"], r["model_sd"]), _cell(r["experiment_value"]),
             r["tolerance"], "yes" if r["within"] else "NO",
             f"{r['complete']}/{r['runs']}" + (f" ({r['stalled']}/{r['incomplete']})" if r["stalled"] or r["incomplete"]
                                               else "")] for r in rows]
    if markdown:
        lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)] + ["| " + " | ".join(b) + " |" for b in body]
    else:
        widths = [max(len(str(x)) for x in col) for col in zip(head, *body)]
        lines = ["  ".join(str(x).ljust(w) for x, w in zip(line, widths)) for line in [head, *body]]
    n_in = sum(r["within"] for r in rows)
    cases = {(r["experiment"], r["case"]): r for r in rows}
    stalled = sum(r["stalled"] for r in cases.values())
    incomplete = sum(r["incomplete"] for r in cases.values())
    lines.append(f"{n_in} of {len(rows)} quantities within tolerance; {stalled} run(s) stalled, {incomplete} otherwise "
                 f"incomplete (means are over complete runs only)")
    return "\n".join(lines)


def _corridor_points(records: list) -> list:
    return [(s["run"], s["density_per_m2"], s["speed_m_s"], s["density_exp"], s["speed_exp"], s["complete"] < s["runs"])
            for s in summarise_corridor([r for r in records if r.get("experiment") == "corridor"])]


def _flow_points(records: list) -> tuple:
    """(model, experiment) flows (1/s) against the width of the opening that limits each corridor run (the narrower of
    its entrance and exit), and the bottleneck's J = J_s b at N = 60: lists of (width, flow, label)."""
    model, exp = [], []
    for s in summarise_corridor([r for r in records if r.get("experiment") == "corridor"]):
        b = min(s["entrance_width_m"], s["exit_width_m"])
        label = "exit" if s["exit_width_m"] < s["entrance_width_m"] else "entrance"
        model.append((b, s["flow_exit_per_s"], label))
        exp.append((b, s["flow_exit_exp"], label))
    neck = [r for r in records if r.get("experiment") == "bottleneck" and r["n_pedestrians"] == 60 and r["complete"]]
    ref = seyfried_2009()
    for b in sorted({r["width_m"] for r in neck}):
        js = np.mean([r["specific_flow_per_m_s"] for r in neck if r["width_m"] == b])
        model.append((b, float(js * b), "channel"))
        exp.append((b, float(ref.specific_flow_per_m_s[ref.lookup(b, 60)[0]] * b), "channel"))
    return model, exp


def virtual_figure(records: list, path) -> Path:
    """Three panels: the density-speed plane of the corridor runs (each model point joined to its experiment point)
    and of the bottleneck channel at N = 60 beside the experiment's ranges; the flow against the width of the
    opening that limits it (the corridor runs' entrance or exit, Seyfried's 2.8 m channel); the single file against
    its bins."""
    plt = pyplot()
    fig, (ax, ax2, ax1) = plt.subplots(1, 3, figsize=(16, 5.2), gridspec_kw={"width_ratios": [1.5, 1.1, 1]})
    for name, rho, v, rho_e, v_e, failed in _corridor_points(records):
        ax.plot([rho_e, rho], [v_e, v], color="0.6", lw=1, zorder=1)
        ax.scatter([rho_e], [v_e], marker="o", facecolor="white", edgecolor="k", zorder=2)
        if np.isfinite(rho):
            ax.scatter([rho], [v], marker="x" if failed else "o", color="C3", zorder=3)
        label = name.removeprefix("uo-") + ("" if np.isfinite(rho) else " (model: no complete run)")
        ax.annotate(label, (rho_e, v_e), fontsize=7, xytext=(3, 3), textcoords="offset points")
    neck = [r for r in records if r.get("experiment") == "bottleneck" and r["n_pedestrians"] == 60 and r["complete"]]
    if neck:
        (dlo, dhi), (vlo, vhi) = INSIDE_DENSITY_RANGE_PER_M2, INSIDE_SPEED_RANGE_M_S
        ax.add_patch(plt.Rectangle((dlo, vlo), dhi - dlo, vhi - vlo, fill=False, ls="--", ec="C0",
                                   label="Seyfried channel, N = 60 (experiment's ranges)"))
        for b in sorted({r["width_m"] for r in neck}):
            rs = [r for r in neck if r["width_m"] == b]
            ax.scatter([np.mean([r["density_inside_per_m2"] for r in rs])], [np.mean([r["speed_inside_m_s"] for r in rs])],
                       marker="s", color="C0", s=20)
    ax.scatter([], [], marker="o", facecolor="white", edgecolor="k", label="Jülich corridor run (experiment)")
    ax.scatter([], [], marker="o", color="C3", label="model (mean of complete runs; x: some incomplete)")
    ax.scatter([], [], marker="s", color="C0", label="model, Seyfried channel per width")
    ax.set_xlabel("density (1/m²)")
    ax.set_ylabel("speed (m/s)")
    ax.set_xlim(0, None)
    ax.set_ylim(0, 1.6)
    ax.legend(fontsize=7, loc="upper right")
    ax.set_title("corridor runs as run (Voronoi, y in [−2, 0]) and the bottleneck channel", fontsize=9)
    model, exp = _flow_points(records)
    styles = {"entrance": ("^", "corridor run, narrowed entrance"), "exit": ("v", "corridor run, narrowed exit"),
              "channel": ("s", "Seyfried channel, N = 60")}
    for kind, (marker, label) in styles.items():
        m = [(b, j) for b, j, k in model if k == kind]
        e = [(b, j) for b, j, k in exp if k == kind]
        if e:
            ax2.scatter(*zip(*e), marker=marker, facecolor="white", edgecolor="k", label=f"{label}: experiment")
        if m:
            ax2.scatter(*zip(*m), marker=marker, color="C3", label=f"{label}: model")
        for (b, jm), (_, je) in zip(m, e):
            if np.isfinite(jm):
                ax2.plot([b, b], [je, jm], color="0.6", lw=1)
            else:  # no complete run: no flow, a clog marked at zero
                ax2.scatter([b], [0.0], marker="x", color="C3", s=60)
    ax2.scatter([], [], marker="x", color="C3", s=60, label="model: no complete run (stalled)")
    ax2.set_xlabel("width of the limiting opening (m)")
    ax2.set_ylabel("flow (1/s)")
    ax2.set_ylim(0, None)
    ax2.legend(fontsize=6)
    ax2.set_title("flow against the opening that limits it", fontsize=9)
    sf = [r for r in records if r.get("experiment") == "single_file"]
    table = single_file()
    ax1.plot(table.density, table.speed_m_s, "o-", mfc="white", color="k", label="Seyfried 2005 (bins)")
    for d in sorted({r["density"] for r in sf}):
        v = float(np.mean([r["speed_m_s"] for r in sf if r["density"] == d]))
        ax1.plot([d, d], [float(table.speed_at(d)), v], color="0.6", lw=1)
        ax1.scatter([d], [v], color="C3")
    ax1.scatter([], [], color="C3", label="model")
    ax1.set_xlabel("1D density (1/m)")
    ax1.set_ylabel("speed (m/s)")
    ax1.set_ylim(0, 1.6)
    ax1.legend(fontsize=7)
    ax1.set_title("single file on a ring", fontsize=9)
    return save_figure(fig, Path(path))


PASSAGE_QUANTITIES = (("headway_median_s", "time between passages, median (s)"),
                      ("speed_median_m_s", "speed at the opening, median (m/s)"),
                      ("lateral_sd_m", "spread of the crossing point, sd (m)"),
                      ("share_off_axis", "share crossing farther off the axis than a 0.46 m disk's centre can"),
                      ("following_median_m", "distance behind the passer before, median (m)"),
                      ("lateral_step_median_m", "distance beside the passer before, median (m)"),
                      ("side_alternation", "share passing on the other side of the axis than the passer before"),
                      # where the next one stood as the one before left the opening (the recordings' entrances: "–")
                      ("entry_wait_median_s", "next one enters the opening after the one before left it, median (s)"),
                      ("entry_before_median_m", "next one's distance before the opening then, median (m)"),
                      ("entry_offset_median_m", "next one's distance off the axis then, median (m)"),
                      ("entry_share_beside", "share of next ones standing beside the opening's span then"),
                      ("entry_speed_median_m_s", "next one's speed then, median (m/s)"))


def _corridor_runs_with(records: list, key: str, *, narrowed_exit: bool = False) -> list:
    """The complete corridor records carrying the figure ``key``, by run name; with ``narrowed_exit`` only the runs
    whose exit is narrower than the corridor (a door seen by the camera)."""
    runs = {}
    for r in records:
        if r.get("experiment") == "corridor" and r["complete"] and key in r \
                and (not narrowed_exit or r["width_m"] < 1.8 - 1e-9):
            runs.setdefault(r["run"], []).append(r)
    return sorted(runs.items())


def _narrowed_opening_runs(records: list, key: str) -> list:
    """``(run name, its narrower opening's label, that opening's record prefix, its complete records)`` of every
    corridor run with a narrowed entrance or exit whose records carry the figure ``key`` (:func:`_limiting_opening`)."""
    found = []
    for name, rs in _corridor_runs_with(records, key):
        run = uo_run(name)
        if min(run.entrance_width_m, run.exit_width_m) < run.corridor_width_m:
            found.append((name, *_limiting_opening(name), rs))
    return found


def _narrowed_exit_runs(records: list) -> list:
    """The complete corridor records of the runs with a narrowed exit that carry the passage figures, by run name."""
    return _corridor_runs_with(records, "exit_headway_median_s", narrowed_exit=True)


def passage_rows(records: list) -> list:
    """How the model passes each run's narrowed opening (a narrowed exit at its line, a narrowed entrance at the
    line 0.4 m past it) beside how people did (the recordings measured by the same function,
    :func:`~crowd_env.experiments.validation.corridor_runs.passage_figures`): one row per run and quantity of
    :data:`PASSAGE_QUANTITIES`, the model's seed mean and the recording's value; the open 1.8 / 1.8 m run has none."""
    from .corridor_runs import recorded_passage_figures

    rows = []
    for name, opening, prefix, rs in _narrowed_opening_runs(records, "entrance_headway_median_s"):
        recorded = recorded_passage_figures(name)
        for suffix, label in PASSAGE_QUANTITIES:
            key = f"{prefix}_{suffix}"
            carrying = [r[key] for r in rs if key in r]  # runs stored before a figure existed lack it
            mean, sd = _stats(carrying)
            rows.append({"run": name, "opening": opening, "quantity": label, "model": mean, "model_sd": sd,
                         "recorded": recorded[key], "runs": len(carrying)})
    return rows


def approach_figure(records: list, path) -> Path | None:
    """Density and speed in 0.5 m bands before each narrowed exit, the recording beside the model's seed mean: how
    people thin out and speed up into a door (None without such runs)."""
    from .corridor_runs import recorded_passage_figures

    runs = _narrowed_exit_runs(records)
    if not runs:
        return None
    plt = pyplot()
    fig, axes = plt.subplots(2, len(runs), figsize=(4.2 * len(runs), 6.5), squeeze=False)
    for k, (name, rs) in enumerate(runs):
        recorded = recorded_passage_figures(name)
        for row, (key, unit) in enumerate((("approach_density_per_m2", "density (1/m²)"),
                                            ("approach_speed_m_s", "speed (m/s)"))):
            ax = axes[row, k]
            ax.plot(recorded["approach_y_m"], recorded[key], "o-", mfc="white", color="k", label="recorded")
            model = np.nanmean(np.array([r[key] for r in rs], dtype=np.float64), axis=0)
            ax.plot(rs[0]["approach_y_m"], model, "o-", color="C3", label=f"model ({len(rs)} runs)")
            ax.set_xlabel("y (m): the exit wall at −4")
            ax.set_ylabel(unit)
            ax.set_ylim(0, None)
            if row == 0:
                ax.set_title(name, fontsize=9)
            ax.legend(fontsize=7)
    return save_figure(fig, Path(path))


def passing_figure(records: list, path) -> Path | None:
    """How successive walkers pass each run's narrowed opening: the median distance behind the passer before against
    the median distance beside it (:func:`~crowd_env.analysis.corridor_runs.door_passage`), the recording and the
    model's seed mean of each run joined, the share passing on the other side of the axis than the one before in the
    legend; the circle of one body width (0.46 m) between successive centres. One file lies high on the vertical
    axis, two staggered files (a zipper) near the circle. None without such runs or figures."""
    from .corridor_runs import recorded_passage_figures

    found = _narrowed_opening_runs(records, "entrance_following_median_m")
    if not found:
        return None
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(11, 6.5))
    angle = np.linspace(0.0, 0.5 * np.pi, 50)
    ax.plot(0.46 * np.cos(angle), 0.46 * np.sin(angle), ":", color="0.5", label="0.46 m between centres")
    for k, (name, opening, prefix, rs) in enumerate(found):
        recorded = recorded_passage_figures(name)
        beside = np.nanmean([r[f"{prefix}_lateral_step_median_m"] for r in rs])
        behind = np.nanmean([r[f"{prefix}_following_median_m"] for r in rs])
        alternation = np.nanmean([r[f"{prefix}_side_alternation"] for r in rs])
        colour = f"C{k % 10}"
        ax.plot([recorded[f"{prefix}_lateral_step_median_m"], beside],
                [recorded[f"{prefix}_following_median_m"], behind], "-", color=colour, lw=0.8)
        ax.plot(recorded[f"{prefix}_lateral_step_median_m"], recorded[f"{prefix}_following_median_m"], "o",
                mfc="white", color=colour)
        ax.plot(beside, behind, "s", color=colour,
                label=f"{opening}: {recorded[f'{prefix}_side_alternation']:.2f} / {alternation:.2f}")
    ax.set_xlabel("distance beside the passer before, median (m)")
    ax.set_ylabel("distance behind the passer before, median (m)")
    top = max(0.5, *(max(line.get_xdata().max(), line.get_ydata().max()) for line in ax.get_lines())) + 0.1
    ax.set_xlim(0, top)
    ax.set_ylim(0, top)
    ax.set_aspect("equal")
    ax.set_title("open circles: recorded; squares: model (seed mean)", fontsize=9)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0), title="the share on the other side\nthan the passer before,\nrecorded / model",
              title_fontsize=7)
    return save_figure(fig, Path(path))


def entry_figure(records: list, path) -> Path | None:
    """Where the next walker stood when the one before left each run's narrowed opening
    (:func:`~crowd_env.analysis.corridor_runs.opening_entries`): one panel per run, its position across the axis and
    before the wall's face, the model's seeds pooled beside the recording (the exits; the camera does not see before
    the entrances), the wall and its opening drawn. A crowd queued in line stands above the gap; one pressed against
    the barrier stands beside it. None without such runs or figures."""
    from .corridor_runs import recorded_passage_figures

    found = _narrowed_opening_runs(records, "entrance_entry_positions_m")
    if not found:
        return None
    plt = pyplot()
    fig, axes = plt.subplots(1, len(found), figsize=(3.4 * len(found), 2.7), squeeze=False)
    reach_m = 1.3  # each panel's half-width and height
    for ax, (name, opening, prefix, rs) in zip(axes[0], found):
        run = uo_run(name)
        half = 0.5 * (run.exit_width_m if prefix == "exit" else run.entrance_width_m)
        wall = 0.5 * run.corridor_width_m if prefix == "exit" else reach_m  # the corridor's walls; the barrier on
        for side in (-1.0, 1.0):
            ax.plot([side * half, side * wall], [0.0, 0.0], "-", color="0.3", lw=3)
        model = np.array([p for r in rs for p in r[f"{prefix}_entry_positions_m"]], dtype=np.float64).reshape(-1, 2)
        ax.plot(model[:, 0], model[:, 1], ".", color="C3", ms=3, alpha=0.5, label=f"model ({len(rs)} runs)")
        recorded = np.array(recorded_passage_figures(name)[f"{prefix}_entry_positions_m"],
                            dtype=np.float64).reshape(-1, 2)
        if recorded.size:
            ax.plot(recorded[:, 0], recorded[:, 1], "o", mfc="none", color="k", ms=3.5, label="recorded")
        ax.set_xlim(-reach_m, reach_m)
        ax.set_ylim(-0.3, reach_m)
        ax.set_aspect("equal")
        ax.set_xlabel("across the axis (m)")
        ax.set_title(f"{name}: {opening}", fontsize=8)
        ax.legend(fontsize=7, loc="upper right")
    axes[0, 0].set_ylabel("before the wall's face (m)")
    return save_figure(fig, Path(path))


def _beside_recording(rows: list, leading: tuple, trailing: dict | None = None) -> str:
    """A Markdown table of rows that set the model beside a recording: the ``leading`` fields, the model's mean ±
    sd, the recorded value, then the ``trailing`` columns (title: a function of the row)."""
    trailing = trailing or {}
    head = [*leading, "model", "recorded", *trailing]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join([*(str(r[k]) for k in leading), _cell(r["model"], r["model_sd"]), _cell(r["recorded"]),
                                 *(cell(r) for cell in trailing.values())]) + " |" for r in rows]
    return "\n".join(lines)


def format_passage_rows(rows: list) -> str:
    """The rows of :func:`passage_rows` as a Markdown table."""
    return _beside_recording(rows, ("run", "opening", "quantity"))


def spacing_rows(records: list) -> list:
    """How close walkers come to each other ahead or behind (the first bearing bin, 0-15°) and beside (the last,
    75-90°) in the measurement area of each corridor run, the model's seed mean beside the recording measured by the
    same function (:func:`~crowd_env.experiments.validation.corridor_runs.passage_figures`, ``spacing_*``): the 5 %
    quantile of the distance and the share of pairs closer than 0.46 m."""
    from .corridor_runs import recorded_passage_figures

    rows = []
    for name, rs in _corridor_runs_with(records, "spacing_q05_m"):
        recorded = recorded_passage_figures(name)
        edges = recorded["spacing_bearing_edges_deg"]
        for k, where in ((0, "ahead or behind"), (len(edges) - 2, "beside")):
            label = f"{where} ({edges[k]:g}-{edges[k + 1]:g}°)"
            for key, quantity in (("spacing_q05_m", "distance, 5 % quantile (m)"),
                                  ("spacing_share_closer", "share closer than 0.46 m")):
                mean, sd = _stats([r[key][k] for r in rs])
                rows.append({"run": name, "bearing": label, "quantity": quantity, "model": mean, "model_sd": sd,
                             "recorded": recorded[key][k], "runs": len(rs)})
    return rows


def format_spacing_rows(rows: list) -> str:
    """The rows of :func:`spacing_rows` as a Markdown table."""
    return _beside_recording(rows, ("run", "bearing", "quantity"))


def _run_grid(n: int) -> tuple:
    """``(figure, the first n axes)``: one panel per corridor run, three to a row, the unused ones hidden."""
    plt = pyplot()
    cols = min(3, n)
    rows_n = -(-n // cols)
    fig, axes = plt.subplots(rows_n, cols, figsize=(4.0 * cols, 3.2 * rows_n), squeeze=False)
    for ax in axes.ravel()[n:]:
        ax.set_visible(False)
    return fig, axes.ravel()[:n]


def spacing_figure(records: list, path) -> Path | None:
    """The 5 % quantile of the distance between walkers against the bearing, per corridor run, the recording beside
    the model's seed mean, with two radii of Kabalan's body (0.46 m) drawn (None without such runs)."""
    from .corridor_runs import recorded_passage_figures

    runs = _corridor_runs_with(records, "spacing_q05_m")
    if not runs:
        return None
    fig, axes = _run_grid(len(runs))
    for ax, (name, rs) in zip(axes, runs):
        recorded = recorded_passage_figures(name)
        edges = np.asarray(recorded["spacing_bearing_edges_deg"])
        centres = 0.5 * (edges[:-1] + edges[1:])
        ax.plot(centres, recorded["spacing_q05_m"], "o-", mfc="white", color="k", label="recorded")
        model = np.nanmean(np.array([r["spacing_q05_m"] for r in rs], dtype=np.float64), axis=0)
        ax.plot(centres, model, "o-", color="C3", label=f"model ({len(rs)} runs)")
        ax.axhline(0.46, color="0.5", ls="--", lw=1)
        ax.set_title(name, fontsize=9)
        ax.set_xlabel("bearing (°): 0 ahead or behind, 90 beside", fontsize=8)
        ax.set_ylabel("distance, 5 % quantile (m)", fontsize=8)
        ax.set_ylim(0.2, 1.0)
        ax.legend(fontsize=7)
    return save_figure(fig, Path(path))


LAPSE_QUANTITIES = (("median_s", "lapse, median (s)"), ("mean_s", "lapse, mean (s): 1 / flow"),
                    ("q95_s", "lapse, 95 % quantile (s)"), ("longest_s", "longest lapse (s)"),
                    ("share_of_time_in_long", "share of the time in lapses > 2 s"),
                    ("flow_without_long_per_s", "flow without the lapses > 2 s (1/s)"))


def _limiting_opening(name: str) -> tuple:
    """``(label, prefix of its record fields)`` of the narrower opening of run ``name`` (the entrance when both are
    as wide): the one whose passages set its flow."""
    run = uo_run(name)
    if run.exit_width_m < run.entrance_width_m:
        return f"exit {run.exit_width_m:g} m", "exit"
    return f"entrance {run.entrance_width_m:g} m", "entrance"


def _lapse_runs(records: list) -> list:
    """``(run name, its complete records carrying the lapses, all its records)`` for every corridor run of
    ``records`` that has either: a run whose every seed stalled is listed with no complete record."""
    lapsed = dict(_corridor_runs_with(records, "entrance_lapses_s"))
    runs = {}
    for r in records:
        if r.get("experiment") == "corridor":
            runs.setdefault(r["run"], []).append(r)
    return [(name, lapsed.get(name, []), every) for name, every in sorted(runs.items())
            if name in lapsed or not any(r["complete"] for r in every)]


def lapse_rows(records: list) -> list:
    """How each corridor run passes its narrower opening, beside how people did: the time lapses between successive
    passages (:func:`~crowd_env.analysis.corridor_runs.passage_lapses`, measured alike on the recordings by
    :func:`~crowd_env.experiments.validation.corridor_runs.passage_figures`) summarised by
    :func:`~crowd_env.analysis.corridor_runs.lapse_summary` per run, the model's mean ± sd over its complete runs
    (``runs``: complete of all, the stalled ones counted in ``stalled``; a stalled run's last lapse never ends)."""
    from .corridor_runs import recorded_passage_figures

    rows = []
    for name, rs, every in _lapse_runs(records):
        opening, prefix = _limiting_opening(name)
        key = f"{prefix}_lapses_s"
        recorded = lapse_summary(recorded_passage_figures(name)[key])
        summaries = [lapse_summary(r[key]) for r in rs]
        for field, label in LAPSE_QUANTITIES:
            mean, sd = _stats([getattr(x, field) for x in summaries])
            rows.append({"run": name, "opening": opening, "quantity": label, "model": mean, "model_sd": sd,
                         "recorded": getattr(recorded, field), "runs": f"{len(rs)}/{len(every)}",
                         "stalled": sum(bool(r.get("stalled")) for r in every)})
    return rows


def format_lapse_rows(rows: list) -> str:
    """The rows of :func:`lapse_rows` as a Markdown table."""
    return _beside_recording(rows, ("run", "opening", "quantity"),
                             {"complete runs (stalled)": lambda r: f"{r['runs']} ({r['stalled']})"})


def lapse_figure(records: list, path) -> Path | None:
    """The survival function of the lapses between passages of each run's narrower opening, P(lapse ≥ t) on a log
    scale: the recording beside the model's lapses pooled over its complete runs (a run whose every seed stalled
    says so; None without corridor runs). A tail that reaches far beyond the recording's is an opening that clogs
    for a while."""
    from .corridor_runs import recorded_passage_figures

    runs = _lapse_runs(records)
    if not runs:
        return None
    fig, axes = _run_grid(len(runs))
    for ax, (name, rs, every) in zip(axes, runs):
        opening, prefix = _limiting_opening(name)
        key = f"{prefix}_lapses_s"
        curves = [(recorded_passage_figures(name)[key], "k", "recorded")]
        stalled = sum(bool(r.get("stalled")) for r in every)
        if rs:
            curves.append((np.concatenate([r[key] for r in rs]), "C3", f"model ({len(rs)} runs"
                           + (f"; {stalled} stalled)" if stalled else ")")))
        else:
            ax.text(0.5, 0.5, f"model: {stalled} of {len(every)} runs stalled", transform=ax.transAxes,
                    ha="center", color="C3", fontsize=8)
        for lapses, color, label in curves:
            t = np.sort(np.asarray(lapses, dtype=np.float64))
            ax.step(t, 1.0 - np.arange(t.size) / t.size, where="post", color=color, label=label)
        ax.axvline(2.0, color="0.5", ls="--", lw=1)
        ax.set_yscale("log")
        ax.set_title(f"{name}: {opening}", fontsize=9)
        ax.set_xlabel("lapse between passages t (s)", fontsize=8)
        ax.set_ylabel("P(lapse ≥ t)", fontsize=8)
        ax.legend(fontsize=7)
    return save_figure(fig, Path(path))


def write_virtual_outputs(out, records: list, rows: list, *, figure: bool = True) -> list:
    """``OUT/virtual_experiments.csv`` (the rows), ``.md`` (the table in Markdown) and, with ``figure``,
    ``.png``; with runs of a narrowed opening also ``OUT/door_passage.md`` (:func:`passage_rows`) and, with
    ``figure`` and a narrowed exit, ``OUT/approach.png`` (:func:`approach_figure`), with ``figure`` and the runs'
    passing figures ``OUT/passing.png`` (:func:`passing_figure`) and ``OUT/entries.png`` (:func:`entry_figure`);
    with corridor runs ``OUT/spacing.md`` (:func:`spacing_rows`) and, with ``figure``, ``OUT/spacing.png``
    (:func:`spacing_figure`), and ``OUT/passage_lapses.md`` (:func:`lapse_rows`) and, with ``figure``,
    ``OUT/passage_lapses.png`` (:func:`lapse_figure`); returns the paths."""
    out = Path(out)
    paths = [out / "virtual_experiments.csv", out / "virtual_experiments.md"]
    write_csv_atomic(paths[0], ROW_COLUMNS, rows)
    write_atomic(paths[1], format_rows(rows, markdown=True) + "\n")
    if figure:
        paths.append(virtual_figure(records, out / "virtual_experiments.png"))
    for table, make_rows, format_table, plots in (
            ("door_passage.md", passage_rows, format_passage_rows,
             ((approach_figure, "approach.png"), (passing_figure, "passing.png"), (entry_figure, "entries.png"))),
            ("spacing.md", spacing_rows, format_spacing_rows, ((spacing_figure, "spacing.png"),)),
            ("passage_lapses.md", lapse_rows, format_lapse_rows, ((lapse_figure, "passage_lapses.png"),))):
        found = make_rows(records)
        if found:
            paths.append(out / table)
            write_atomic(paths[-1], format_table(found) + "\n")
            for plot, picture in plots if figure else ():
                drawn = plot(records, out / picture)
                if drawn is not None:  # approach.png needs a narrowed exit; door_passage.md a narrowed opening
                    paths.append(drawn)
    return paths


def snapshot_case(case: str) -> tuple:
    """``(plan keywords, label)`` of a snapshot's case: a corridor run's name, or ``bottleneck-B-N`` (Seyfried's
    bottleneck of width B m with N walkers, e.g. ``bottleneck-0.8-60``). Raises :class:`InputError` naming what is
    wrong."""
    if case in CORRIDOR_RUN_NAMES:
        return {"experiments": ("corridor",), "corridor_runs": (case,)}, case
    parts = case.split("-")
    try:
        if len(parts) != 3 or parts[0] != "bottleneck":
            raise ValueError
        width, n = float(parts[1]), int(parts[2])
    except ValueError:
        raise InputError(f"snapshot case {case!r}: give a corridor run ({', '.join(CORRIDOR_RUN_NAMES)}) or "
                         "bottleneck-B-N (the bottleneck's width B in m and its N walkers, e.g. bottleneck-0.8-60)") \
            from None
    if not (math.isfinite(width) and width > 0.0) or n < 1:
        raise InputError(f"snapshot case {case!r}: the width must be > 0 m and N at least 1")
    return {"experiments": ("bottleneck",), "widths_m": (width,), "sizes": (n,)}, case


def run_snapshot(task: dict, *, at_s: float, every_s: float = 0.25) -> dict:
    """A bottleneck or corridor run of the task format (:func:`virtual_tasks`) followed step by step: the crowd at
    ``at_s`` (positions, radii, headings and the body depth, velocities, the agent's intents, who is left), the times
    its measurement line was passed (``crossing_times_s``: the corridor's exit, the bottleneck's line), and every
    ``every_s`` how many have left the floor so far, the mean speed ‖u‖ of those left and their mean net
    displacement over the stall rule's window (from their positions
    :data:`~crowd_env.experiments.running.runner.STALL_WINDOW_S` earlier): a crowd that shakes in place keeps a speed
    while its net displacement falls to nothing. The run stops at ``at_s`` (or at its end)."""
    from ..running.runner import STALL_WINDOW_S, run_scenario

    kind = task["experiment"]
    if kind not in ("bottleneck", "corridor"):
        raise InputError(f"a snapshot follows a bottleneck or corridor run, not a {kind!r} one")
    params = ModelParams.from_dict(task["params"])
    scenario = bottleneck_scenario(task) if kind == "bottleneck" else corridor_scenario(task)
    policy = crowd_policy(task, scenario, params)
    series = {"time_s": [], "left": [], "mean_speed_m_s": [], "net_displacement_m": []}
    kept = []  # (time, positions) every every_s, for the net displacement
    snap = {}

    def capture(sim):
        st = sim.state
        if not series["time_s"] or sim.time_s >= series["time_s"][-1] + every_s - 1e-9:
            inside = st.active
            kept.append((sim.time_s, st.position_m.copy()))
            old = next((p for t, p in reversed(kept) if t <= sim.time_s - STALL_WINDOW_S + 1e-9), None)
            series["time_s"].append(sim.time_s)
            series["left"].append(int(st.n - inside.sum()))
            speed = np.hypot(*st.velocity_m_s[inside].T) if inside.any() else np.zeros(0)
            series["mean_speed_m_s"].append(float(speed.mean()) if speed.size else math.nan)
            series["net_displacement_m"].append(float(np.hypot(*(st.position_m[inside] - old[inside]).T).mean())
                                                if old is not None and inside.any() else math.nan)
        if not snap and sim.time_s >= at_s - 1e-9:
            intents, _ = policy(sim)
            snap.update(position_m=st.position_m.copy(), radius_m=st.radius_m.copy(),
                        velocity_m_s=st.velocity_m_s.copy(), intent_m_s=intents.copy(), active=st.active.copy(),
                        time_s=sim.time_s, heading_rad=st.heading_rad.copy(), body_depth_m=sim.physics.body_depth_m)

    result = run_scenario(scenario, policy, params, max_time_s=min(task["max_time_s"], at_s + 1e-6),
                          line="exit" if kind == "corridor" else "bottleneck", density_areas=(), lane_area=None,
                          progress=capture, compiled=False, stall_window_s=None)
    case = task["run"] if kind == "corridor" else f"bottleneck-{task['width_m']:g}-{task['n_pedestrians']}"
    return {"snapshot": snap, "series": {k: np.asarray(v) for k, v in series.items()}, "complete": result.complete,
            "outline_m": np.asarray(scenario.geometry.walkable_area.exterior.coords), "run": case,
            "seed": int(task["seed"]), "crossing_times_s": np.sort(result.crossing_times_s)}


def snapshot_window_m(name: str) -> tuple:
    """``(x range, y range)`` (m) of a snapshot: for a corridor run, around its narrower opening
    (:func:`_limiting_opening`), the exit (the last 5 m of the corridor) or the entrance (the barrier, the waiting
    crowd before it and the floor behind it); for Seyfried's bottleneck (``bottleneck-B-N``), the crowd before the
    channel and the channel."""
    if name.startswith("bottleneck"):
        return (-3.0, 3.3), (-2.0, 2.0)
    _, prefix = _limiting_opening(name)
    if prefix == "exit":
        return (-1.0, 2.8), (-5.0, 0.0)
    return (-1.7, 3.5), (6.0, 10.0)


def snapshot_figure(study: dict, path, *, window_y_m: tuple | None = None, window_x_m: tuple | None = None) -> Path:
    """A run followed step by step (:func:`run_snapshot`): left, the crowd in the window
    (``window_x_m``, ``window_y_m``; None: :func:`snapshot_window_m`, around the run's narrower opening) at the
    snapshot (bodies, velocities in red, the agent's intents in blue); right, over time, how many have left, the mean
    speed of those left and their mean net speed over the stall rule's window (net displacement / 20 s) beside the
    rule's threshold."""
    default_x, default_y = snapshot_window_m(study["run"])
    window_x_m = default_x if window_x_m is None else window_x_m
    window_y_m = default_y if window_y_m is None else window_y_m
    from ..running.runner import STALL_SPEED_M_S, STALL_WINDOW_S

    plt = pyplot()
    fig, (ax, ax1) = plt.subplots(1, 2, figsize=(12, 5.5), gridspec_kw={"width_ratios": [1, 1.3]})
    snap = study["snapshot"]
    ax.plot(*study["outline_m"].T, color="k", lw=1)
    if snap:
        x, y = snap["position_m"].T
        shown = np.flatnonzero(snap["active"] & (x >= window_x_m[0] - 0.5) & (x <= window_x_m[1] + 0.5)
                               & (y >= window_y_m[0] - 0.5) & (y <= window_y_m[1] + 0.5))
        k = circle_count(snap["body_depth_m"])  # the bodies' circles (one, the disk, at depth 0)
        centre, rad, _ = body_circles(snap["position_m"], snap["heading_rad"], snap["radius_m"], shown,
                                      snap["body_depth_m"])
        for n, i in enumerate(shown):
            p = snap["position_m"][i]
            for c, rc in zip(centre[n * k:(n + 1) * k], rad[n * k:(n + 1) * k]):
                ax.add_patch(plt.Circle(c, rc, fill=False, lw=0.8))
            ax.arrow(*p, *(0.3 * snap["velocity_m_s"][i]), color="C3", width=0.006, length_includes_head=True)
            ax.arrow(*p, *(0.15 * snap["intent_m_s"][i]), color="C0", width=0.003, alpha=0.6, length_includes_head=True)
        ax.set_title(f"{study['run']} (seed {study.get('seed', 0)}) at t = {snap['time_s']:.1f} s: "
                     "velocity × 0.3 s (red), intent × 0.15 s (blue)", fontsize=9)
    ax.set_xlim(*window_x_m)
    ax.set_ylim(*window_y_m)
    ax.set_aspect("equal")
    s = study["series"]
    ax1.plot(s["time_s"], s["left"], color="k", label="left through the exit")
    ax1.set_xlabel("time (s)")
    ax1.set_ylabel("pedestrians out")
    ax2 = ax1.twinx()
    ax2.plot(s["time_s"], s["mean_speed_m_s"], color="C3", label="mean speed of those left")
    ax2.plot(s["time_s"], s["net_displacement_m"] / STALL_WINDOW_S, color="C0",
             label=f"their mean net speed over {STALL_WINDOW_S:g} s")
    ax2.axhline(STALL_SPEED_M_S, color="C0", ls=":", label="stall threshold (net)")
    ax2.set_ylabel("m/s")
    ax2.set_ylim(0, None)
    lines = ax1.get_legend_handles_labels()
    lines2 = ax2.get_legend_handles_labels()
    ax2.legend(lines[0] + lines2[0], lines[1] + lines2[1], fontsize=7, loc="center right")
    return save_figure(fig, Path(path))
