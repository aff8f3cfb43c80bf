"""The human-likeness scorecard: any policy through the experiments the calibration measures the model against.

A policy (the calibrated agent, a shipped trained policy, a policy file, a behaviour clone, a user's observation
policy by import path; :mod:`crowd_env.experiments.running.crowd_policy`) drives every pedestrian, or a fraction of
them among calibrated walkers (the mixed case), through the calibration's own runs: the Seyfried et al. (2009)
bottleneck at its widths (N = 20, 40, 60, and N = 120 at 1.0 and 1.2 m;
:func:`~crowd_env.experiments.validation.calibration.optimize.target_tasks`) and the fundamental-diagram sweep
(the periodic 1.8 m corridor at the Jülich bins and the single-file ring at Seyfried et al.'s 2005 bins;
:func:`~crowd_env.experiments.validation.calibration.tasks.make_fd_tasks`), seeds shared by every policy.

One distance per experiment, the calibration's own terms (:mod:`crowd_env.experiments.validation.calibration.
objective`, each a mean squared relative miss, 0 inside the experiment's band), summed:

- ``bottleneck``: epsilon_60 + small_groups + ordering + speed_inside + density_inside + density_front + capacity
  (J_s of N = 60 against Table 2, N = 20/40 in their band and not below N = 60, the stationary speed and
  densities in the channel and in front, the N = 120 / N = 60 rate ratio);
- ``corridor``: corridor_fd + corridor_monotone (speeds at the Jülich bins within 0.10 m/s, never rising);
- ``single_file``: single_file + headway_fit (speeds at the bins, the headway-speed fit d = a + b v).

A run that stalls or leaves people inside at the time limit makes the bottleneck's distance *failed* (counted,
never a number, as the calibration's failed points). The interval of each distance is the percentile bootstrap
over seeds: the seeds are drawn with replacement, every run of a drawn seed kept, the distance recomputed,
:data:`BOOTSTRAP_DRAWS` times (a fixed generator seed, so tables are reproducible). The calibrated agent's row is
the calibration's own (the same tasks, seeds, store format and code path as ``crowd-calibrate targets --fd``;
``tests/experiments/validation/test_scorecard.py`` checks that its tasks are the calibration's target and
fundamental-diagram tasks and its distances sums of ``target_error``'s and ``fd_terms``' terms of the same
records). Command: ``crowd-scorecard``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

import numpy as np

from crowd_env.errors import InputError
from crowd_env.files import save_figure_atomic, write_atomic, write_csv_atomic, write_json_atomic

from ..output.tables import format_table
from ..running.backends import execute, failure_report
from ...envs.background import CALIBRATED_NAMES
from ..running.crowd_policy import policy_entry
from ..running.store import RunStore
from .bottleneck import run_one
from .calibration.errors import CalibrationError
from .calibration.objective import CAPACITY_WIDTHS_M, TargetWeights, fd_terms, required_cases, target_error
from .calibration.tasks import FDPlan, make_fd_tasks, make_task, run_calibration_task
from .fundamental_diagram import run_fd_one

__all__ = ["EXPERIMENTS", "EXPERIMENT_TERMS", "BOOTSTRAP_DRAWS", "ScorecardPlan", "QUICK_PLAN", "describe_plan",
           "plan_limits", "parse_policy",
           "scorecard_tasks", "distances", "bootstrap_intervals", "score_records", "run_scorecard",
           "format_scorecard", "write_scorecard"]

EXPERIMENTS = ("bottleneck", "corridor", "single_file")
EXPERIMENT_TERMS = {"bottleneck": tuple(TargetWeights().bottleneck_dict()),  # the calibration's bottleneck terms
                    "corridor": ("corridor_fd", "corridor_monotone"),
                    "single_file": ("single_file", "headway_fit")}
BOOTSTRAP_DRAWS = 1000


@dataclass(frozen=True)
class ScorecardPlan:
    """The runs of one scorecard: bottleneck widths (N = 20, 40, 60 each; N = 120 at those of 1.0 and 1.2 m),
    seeds (the same for the bottleneck and the fundamental diagram), and the fundamental diagram's densities and
    run lengths (:class:`~crowd_env.experiments.validation.calibration.tasks.FDPlan`, its seeds replaced)."""

    widths_m: tuple = (0.8, 0.9, 1.0, 1.1, 1.2)
    seeds: tuple = (0, 1, 2)
    fd: FDPlan = field(default_factory=FDPlan)

    def __post_init__(self):
        seeds = tuple(int(s) for s in self.seeds)
        if not seeds or len(set(seeds)) != len(seeds) or min(seeds) < 0:
            raise InputError(f"the scorecard's seeds must be distinct integers >= 0, at least one, got {self.seeds}")
        object.__setattr__(self, "seeds", seeds)
        object.__setattr__(self, "widths_m", tuple(float(b) for b in self.widths_m))
        object.__setattr__(self, "fd", FDPlan(**{**self.fd.as_dict(), "seeds": seeds}))

    def as_dict(self) -> dict:
        return {"widths_m": list(self.widths_m), "seeds": list(self.seeds), "fd": self.fd.as_dict()}


# A small plan for tests and a first look (the default tests run it): one width without the capacity runs, one
# corridor and two single-file bins, short fundamental-diagram runs. Its distances are not the full plan's.
QUICK_PLAN = ScorecardPlan(widths_m=(0.9,), seeds=(0, 1),
                           fd=FDPlan(corridor_densities=(1.147,), single_file_densities=(0.87, 1.651),
                                     length_m=12.0, max_time_s=12.0, transient_s=4.0))


def _values(values, unit: str, fmt: str = "g") -> str:
    return ", ".join(format(v, fmt) for v in values) + f" {unit}"


def describe_plan(plan: ScorecardPlan) -> str:
    """The runs of ``plan`` in words: widths, seeds, how many corridor and single-file bins, the runs' length."""
    fd = plan.fd
    return (f"b = {_values(plan.widths_m, 'm', '.1f')}, {len(plan.seeds)} seeds, {len(fd.corridor_densities)} corridor and "
            f"{len(fd.single_file_densities)} single-file bins, fundamental-diagram runs of {fd.max_time_s:g} s on "
            f"{fd.length_m:g} m")


def plan_limits(plan: ScorecardPlan, full: ScorecardPlan | None = None) -> list:
    """What ``plan`` does not measure that the ``full`` plan (default :class:`ScorecardPlan`'s) does, one phrase
    each: widths, capacity runs, corridor and single-file bins, seeds, shorter runs ([] when nothing is left out).
    A distance of 0 on a plan with limits says only that the runs it has meet their bands."""
    full = full or ScorecardPlan()
    out = []
    missing = [b for b in full.widths_m if b not in plan.widths_m]
    if missing:
        out.append(f"the bottleneck at b = {_values(missing, 'm', '.1f')}")
    capacity = [b for b in CAPACITY_WIDTHS_M if b in full.widths_m and b not in plan.widths_m]
    if capacity:
        out.append(f"the door's capacity (N = 120 at b = {_values(capacity, 'm', '.1f')})")
    for name, unit, what in (("corridor_densities", "/m²", "corridor"), ("single_file_densities", "/m", "single-file")):
        have, every = getattr(plan.fd, name), getattr(full.fd, name)
        left = [d for d in every if not any(abs(d - x) < 1e-9 for x in have)]
        if left:
            out.append(f"{len(left)} of the {len(every)} {what} bins ({what} measured at {_values(have, unit)} only, "
                       f"the full plan {min(every):.2f}-{max(every):.2f} {unit})")
    if len(plan.seeds) < len(full.seeds):
        out.append(f"{len(full.seeds) - len(plan.seeds)} of the full plan's {len(full.seeds)} seeds")
    if plan.fd.max_time_s < full.fd.max_time_s or plan.fd.length_m < full.fd.length_m:
        out.append(f"fundamental-diagram runs as long as the full plan's ({full.fd.max_time_s:g} s on "
                   f"{full.fd.length_m:g} m; these {plan.fd.max_time_s:g} s on {plan.fd.length_m:g} m)")
    return out


def parse_policy(spec: str) -> tuple:
    """``"name"`` or ``"name@fraction"`` -> (label, name, learned fraction): the fraction of the crowd the policy
    drives among calibrated walkers (default 1, everybody)."""
    name, sep, fraction = str(spec).partition("@")
    try:
        f = float(fraction) if sep else 1.0
    except ValueError:
        raise InputError(f"policy {spec!r}: the part after '@' must be a fraction in (0, 1], got {fraction!r}") from None
    return (spec if sep else name), name, f


def scorecard_tasks(config: dict, entry: dict | None, plan: ScorecardPlan) -> list:
    """The calibration's target and fundamental-diagram runs of ``config`` (:func:`~.calibration.tasks.base_config`),
    each with the ``policy`` entry (none for the calibrated agent: the calibration's own tasks; with the capacity
    widths among ``plan.widths_m`` the tasks of :func:`~.calibration.optimize.target_tasks`, else without the
    N = 120 runs)."""
    capacity = [b for b in CAPACITY_WIDTHS_M if any(abs(b - w) < 1e-9 for w in plan.widths_m)]
    tasks = [make_task(config, {}, {}, b, n, s) for b, n in required_cases(plan.widths_m, capacity)
             for s in plan.seeds] + make_fd_tasks(config, {}, {}, plan.fd)
    return tasks if entry is None else [dict(t, policy=entry) for t in tasks]


def _scores(records: list) -> tuple:
    """(the bottleneck's :class:`~.calibration.objective.TargetScore`, the fundamental diagram's terms and figures)
    of ``records``, each scored once."""
    score = target_error([r for r in records if "setup" not in r], fd=False)
    terms, figures = fd_terms([r for r in records if "setup" in r])
    return score, terms, figures


def _distances_of(score, terms: dict) -> dict:
    out = {"failed_runs": int(score.n_incomplete)}
    out["bottleneck"] = None if score.failed else float(sum(score.terms[k] for k in EXPERIMENT_TERMS["bottleneck"]))
    for name in ("corridor", "single_file"):
        out[name] = float(sum(terms[k] for k in EXPERIMENT_TERMS[name]))
    return out


def distances(records: list) -> dict:
    """Per experiment (:data:`EXPERIMENTS`) its distance, or None for a bottleneck with incomplete runs; and
    ``"failed_runs"``: how many bottleneck runs did not complete (stalled or out of time)."""
    score, terms, _ = _scores(records)
    return _distances_of(score, terms)


def bootstrap_intervals(records: list, seeds, *, draws: int = BOOTSTRAP_DRAWS, seed: int = 0,
                        confidence: float = 0.95) -> dict:
    """Per experiment the percentile interval (low, high) of its distance over ``draws`` resamplings of the seeds
    (with replacement, all runs of a drawn seed kept); (nan, nan) for a bottleneck that fails in any draw."""
    by_seed = {s: [r for r in records if int(r["seed"]) == s] for s in seeds}
    rng = np.random.default_rng(seed)
    values = {name: [] for name in EXPERIMENTS}
    seeds = list(seeds)
    for _ in range(int(draws)):
        drawn = rng.choice(seeds, size=len(seeds), replace=True)
        d = distances([r for s in drawn for r in by_seed[int(s)]])
        for name in EXPERIMENTS:
            values[name].append(np.nan if d[name] is None else d[name])
    alpha = (1.0 - confidence) / 2.0
    out = {}
    for name, v in values.items():
        v = np.asarray(v)
        out[name] = (float("nan"), float("nan")) if np.isnan(v).any() else \
            tuple(float(x) for x in np.quantile(v, [alpha, 1.0 - alpha]))
    return out


def score_records(label: str, records: list, plan: ScorecardPlan, *, draws: int = BOOTSTRAP_DRAWS) -> dict:
    """One row of the scorecard: the distances, their intervals and the key figures of ``records``."""
    score, terms, fd_figures = _scores(records)
    d = _distances_of(score, terms)
    ci = bootstrap_intervals(records, plan.seeds, draws=draws)
    js60, n_complete, n_runs = _js60_of_complete_runs(records, plan)
    row = {"policy": label, "runs": len(records), "failed_runs": d["failed_runs"],
           "stalled_runs": int(score.n_stalled),
           "js60_per_m_s": js60, "js60_complete_runs": n_complete, "js60_runs": n_runs,
           "corridor_speeds_m_s": {k.split("rho")[1]: v for k, v in fd_figures.items() if k.startswith("fd_speed_m_s corridor")},
           "single_file_speeds_m_s": {k.split("rho")[1]: v for k, v in fd_figures.items()
                                      if k.startswith("fd_speed_m_s single_file")},
           "headway_a_m": fd_figures["headway_a_m"], "headway_b_s": fd_figures["headway_b_s"]}
    for name in EXPERIMENTS:
        row[name] = d[name]
        row[f"{name}_ci"] = list(ci[name])
    return row


def _js60_of_complete_runs(records: list, plan: ScorecardPlan) -> tuple:
    """Per width of ``plan``: the mean J_s of the N = 60 runs that got everybody out (NaN without one), how many
    those were and how many runs there were; a failed run gives no flow figure, and the table says over how
    many runs a mean is."""
    means, counts, runs = [], [], []
    for b in plan.widths_m:
        at_b = [r for r in records if "setup" not in r and r["n_pedestrians"] == 60 and abs(r["width_m"] - b) < 1e-9]
        flows = [r["specific_flow_per_m_s"] for r in at_b if r.get("complete") and not r.get("stalled")]
        means.append(float(np.mean(flows)) if flows else float("nan"))
        counts.append(len(flows))
        runs.append(len(at_b))
    return means, counts, runs


def run_scorecard(out, config: dict, policies, plan: ScorecardPlan, backend, *, draws: int = BOOTSTRAP_DRAWS,
                  progress=print) -> list:
    """Score ``policies`` (``"name"`` or ``"name@fraction"``; the calibrated agent first, added when missing) on
    ``config``'s set-up: runs missing from ``out/<label>/`` are run on ``backend`` and stored (resumable); returns
    the rows, the calibrated agent's first. A failed run raises :class:`CalibrationError` saying why
    (:func:`~crowd_env.experiments.running.backends.failure_report`)."""
    specs = [parse_policy(p) for p in policies]
    if not any(name in CALIBRATED_NAMES and f == 1.0 for _, name, f in specs):
        specs.insert(0, ("calibrated", "calibrated", 1.0))
    labels = [label for label, _, _ in specs]
    if len(set(labels)) != len(labels):
        raise InputError(f"policies named twice: {labels}")
    entries = {label: policy_entry(name, f) for label, name, f in specs}  # every policy loads before any run
    run_fn = partial(run_calibration_task, run_fn=run_one, fd_run_fn=run_fd_one)
    rows = []
    for label in labels:
        store = RunStore(Path(out) / _folder(label), config, keyed_by="task")
        tasks = scorecard_tasks(config, entries[label], plan)
        failed = execute(tasks, store, backend, run_fn, desc=f"scorecard: {label}")
        if failed:
            raise CalibrationError(f"policy {label}: {failure_report(tasks, store)}")
        rows.append(score_records(label, [store.load(t) for t in tasks], plan, draws=draws))
        if progress:
            progress(format_scorecard(rows[-1:]).splitlines()[-1])
    return rows


def _folder(label: str) -> str:
    return label.replace("/", "_").replace("@", "_at_")


def _cell(value, ci) -> str:
    if value is None:
        return "failed"
    lo, hi = ci
    return f"{value:.4f} [{lo:.4f}, {hi:.4f}]" if np.isfinite(lo) else f"{value:.4f}"


def format_scorecard(rows: list, *, markdown: bool = False) -> str:
    """The scorecard as a table: per policy each experiment's distance [95 % interval] (lower is more human;
    "failed" when runs stalled or ran out of time) and the key figures (J_s of N = 60 per width over the runs
    that got everybody out, "(k of n)" where some did not)."""
    head = ["policy", *[f"{e} distance" for e in EXPERIMENTS], "failed runs", "J_s N=60 (1/(m s))", "headway a, b"]
    lines = []
    for r in rows:
        js = ", ".join("nan" if not np.isfinite(x) else f"{x:.2f}" + (f" ({k} of {n})" if k < n else "")
                       for x, k, n in zip(r["js60_per_m_s"], r["js60_complete_runs"], r["js60_runs"]))
        fit = (f"{r['headway_a_m']:.2f} m, {r['headway_b_s']:.2f} s" if np.isfinite(r["headway_a_m"])
               and np.isfinite(r["headway_b_s"]) else "undefined")
        lines.append([r["policy"], *[_cell(r[e], r[f"{e}_ci"]) for e in EXPERIMENTS],
                      f"{r['failed_runs']}/{r['runs']}", js, fit])
    return format_table(head, lines, markdown=markdown)


def write_scorecard(out, rows: list, plan: ScorecardPlan, *, figure: bool = True) -> list:
    """``scorecard.json`` (plan and rows), ``scorecard.csv``, ``scorecard.md`` and ``scorecard.png`` (each
    experiment's distance with its interval, per policy) in ``out``; returns the paths."""
    out = Path(out)
    paths = [out / "scorecard.json", out / "scorecard.csv", out / "scorecard.md"]
    write_json_atomic(paths[0], {"plan": plan.as_dict(), "experiments": EXPERIMENT_TERMS, "rows": rows})
    columns = ["policy", "runs", "failed_runs", "stalled_runs"] + [c for e in EXPERIMENTS for c in (e, f"{e}_ci_low",
                                                                                                  f"{e}_ci_high")]
    write_csv_atomic(paths[1], columns, [{**{k: r[k] for k in columns[:4]},
                                          **{c: v for e in EXPERIMENTS for c, v in
                                             ((e, r[e]), (f"{e}_ci_low", r[f"{e}_ci"][0]),
                                              (f"{e}_ci_high", r[f"{e}_ci"][1]))}} for r in rows])
    write_atomic(out / "scorecard.md", format_scorecard(rows, markdown=True) + "\n")
    if figure:
        paths.append(_figure(rows, out / "scorecard.png"))
    return paths


def _figure(rows: list, path: Path) -> Path:
    """One panel per experiment, the policies on one shared row axis: each policy's distance with its 95 %
    interval on a log scale (the distances span orders of magnitude; one inside every band, 0, and a failed
    one are written instead of drawn)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(4.0 * len(EXPERIMENTS), 0.45 * len(rows) + 1.6))
    FigureCanvasAgg(fig)
    y = np.arange(len(rows))
    axes = fig.subplots(1, len(EXPERIMENTS), sharey=True, squeeze=False)[0]
    for ax, name in zip(axes, EXPERIMENTS):
        drawn = [r[name] for r in rows if r[name] is not None and r[name] > 0]
        floor = min(drawn) / 3.0 if drawn else 1e-3  # where the words sit and the bars start
        for i, r in enumerate(rows):
            if r[name] is None or r[name] <= 0:
                # at the panel's left edge (axes coordinates) and clipped: a word outside the panel would make
                # tight_layout give up ("Tight layout not applied") on a narrow figure
                ax.text(0.02, i, "failed" if r[name] is None else "0 (in every band)", va="center",
                        color="C3" if r[name] is None else "C2", fontsize=8, transform=ax.get_yaxis_transform(),
                        clip_on=True)
                continue
            lo, hi = r[f"{name}_ci"]
            err = [[r[name] - max(lo, floor)], [hi - r[name]]] if np.isfinite(lo) else None
            ax.barh(i, r[name] - floor, left=floor, xerr=err, color="C0" if i else "0.5", capsize=2)
        ax.set_xscale("log")
        ax.set_title(f"{name} (lower is more human)", fontsize=9)
        ax.set_xlabel("distance (sum of squared relative misses, log scale)", fontsize=8)
    axes[0].set_yticks(y)
    axes[0].set_yticklabels([r["policy"] for r in rows], fontsize=8)
    axes[0].set_ylim(len(rows) - 0.5, -0.5)  # the first row on top, every panel the same rows
    fig.tight_layout()
    return save_figure_atomic(fig, path, dpi=110)
