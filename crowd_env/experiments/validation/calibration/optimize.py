"""Minimise ε_T (Eq. 25) over (A, B) and optionally λ, τ, the desired-speed mean/std and the vision rule's
parameters, or every target of the experiment (``objective="targets"``), or those and the fundamental diagram
(``objective="targets+fd"``: the bottleneck's runs plus the density sweep's, scored by the one objective
:func:`crowd_env.experiments.validation.calibration.objective.target_error`).

Method: scipy's derivative-free Nelder–Mead (default) or Powell, on log-parameters (A, B, τ, speeds;
λ ∈ [0, 1] stays linear) with bounds. Why not Bayesian optimisation: with common random numbers (the
same seeds, hence the same initial positions and standard-normal speed draws, for every candidate)
the objective is a deterministic function of the parameters, a few parameters only, and each
evaluation is itself 15 × seeds parallel runs, so a sequential simplex keeps the cluster busy; scipy
is already a dependency, and a deterministic optimiser on a deterministic objective replays its
path exactly from the cache after a crash. The objective stays rough at the scale of single
pedestrians' decisions, so use ``xatol`` of a few percent and start from the grid's best point.

Resumable at two levels: every run is stored (:class:`~crowd_env.experiments.running.store.RunStore`) and every
evaluated point is appended (fsync) to ``OUT/optimise/evaluations.jsonl``, keyed by its parameter
values and the evaluation set-up (widths, sizes, seeds, reference, range weight; with the target objective
its weights, and with the fundamental diagram its :class:`~crowd_env.experiments.validation.calibration.tasks.FDPlan`).
"""
from __future__ import annotations

import hashlib
import json
import math
import sys
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np

from crowd_env.files import append_json_line, read_json_lines, write_csv_atomic, write_json_atomic
from .errors import CalibrationError
from ....analysis.experiment import ExperimentTable, seyfried_2009
from .objective import TargetWeights, required_cases, target_error, virtual_error
from ..corridor_runs import CORRIDOR_RUN_NAMES, run_corridor_one
from ..fundamental_diagram import SINGLE_FILE_DENSITIES
from ....core.checks import check_integer
from ...running.backends import execute
from ..bottleneck import run_one
from ..fundamental_diagram import run_fd_one
from ...running.store import RunStore
from .grid import INCOMPLETE_RULES, check_run_plan, n_stalled_runs, point_error_of, point_tasks
from .tasks import FDPlan, canonical, make_fd_tasks, make_task, make_virtual_tasks, run_calibration_task

FAILED_OBJECTIVE = 1.0e6  # objective of a point whose runs failed (not cached: retried next time)


@dataclass(frozen=True)
class FreeParameter:
    """A calibratable parameter: its field in ModelParams (``model``) or PedestrianDefaults (``pedestrian``), the
    body's radius (``body``) or a constant of the navigation field's wall slowdown (``navigation``)."""

    field: str
    target: str
    log: bool
    bounds: tuple
    default: float
    step: float  # initial simplex step in the optimiser's coordinate (ln x or x)


FREE_PARAMETERS = {
    "A": FreeParameter("social_strength_n", "model", True, (1.0, 5000.0), 790.0, 0.4),
    "B": FreeParameter("social_range_m", "model", True, (0.005, 0.5), 0.08, 0.3),
    "lambda": FreeParameter("social_anisotropy", "model", False, (0.0, 1.0), 1.0, 0.2),
    # the range beside a walker, s B (crowd_env.walking.social_force; 1: Eq. 16's one range)
    "social_lateral_range_scale": FreeParameter("social_lateral_range_scale", "model", False, (0.05, 1.0), 0.5, 0.1),
    "tau": FreeParameter("tau_s", "pedestrian", True, (0.05, 3.0), 0.5, 0.2),
    "speed_mean": FreeParameter("desired_speed_mean_m_s", "pedestrian", True, (0.3, 3.0), 1.34, 0.1),
    "speed_std": FreeParameter("desired_speed_std_m_s", "pedestrian", True, (0.01, 1.0), 0.26, 0.3),
    # the vision rule (crowd_env.walking.vision, an addition to the paper; defaults: the ``vision`` preset's).
    # vision_rays is an integer: fix it with --param vision_rays=N.
    "vision_time_gap_s": FreeParameter("vision_time_gap_s", "model", True, (0.05, 5.0), 1.0, 0.3),
    "vision_jam_gap_m": FreeParameter("vision_jam_gap_m", "model", False, (0.0, 1.0), 0.2, 0.1),
    "vision_half_angle_rad": FreeParameter("vision_half_angle_rad", "model", False, (0.1, math.pi), 1.309, 0.2),
    "vision_body_scale": FreeParameter("vision_body_scale", "model", False, (0.1, 1.0), 0.5, 0.1),
    "vision_leader_time_s": FreeParameter("vision_leader_time_s", "model", False, (0.0, 5.0), 0.0, 0.3),
    # the time gap through a door and the width called a door (start: half the corridor's, three shoulder widths)
    "vision_door_time_gap_s": FreeParameter("vision_door_time_gap_s", "model", True, (0.05, 5.0), 0.5, 0.3),
    "vision_door_ratio": FreeParameter("vision_door_ratio", "model", False, (0.0, 5.0), 3.0, 0.5),
    # the time-to-collision interaction (crowd_env.walking.time_to_collision; defaults: the paper's fit)
    "ttc_strength_m2_s2": FreeParameter("ttc_strength_m2_s2", "model", False, (0.0, 10.0), 1.5, 0.5),
    "ttc_horizon_s": FreeParameter("ttc_horizon_s", "model", True, (0.3, 10.0), 3.0, 0.3),
    # giving way at contact (crowd_env.walking.give_way; defaults: the whole push taken out within 5 cm)
    "give_way_share": FreeParameter("give_way_share", "model", False, (0.0, 1.0), 1.0, 0.3),
    "give_way_gap_m": FreeParameter("give_way_gap_m", "model", False, (0.0, 0.5), 0.05, 0.05),
    # the body: every pedestrian's radius (Kabalan's Table 2: 0.23 m), in every scenario of the point's runs
    # (tasks.with_body; the navigation's clearance follows it where it is the disk centres' field)
    "radius": FreeParameter("radius_m", "body", False, (0.12, 0.26), 0.23, 0.02),
    # the navigation field's wall slowdown (Eq. 11's V = factor within distance of a wall;
    # crowd_env.walking.navigation), in the bottleneck's field and every corridor run's; the one not freed is the
    # configuration's (--navigation-wall-slowdown). Start: the pair measured on calibrated and joint (docs: virtual
    # experiments).
    "wall_slowdown_m": FreeParameter("distance_m", "navigation", False, (0.02, 1.0), 0.35, 0.1),
    "wall_speed_factor": FreeParameter("speed_factor", "navigation", False, (0.05, 1.0), 0.5, 0.15),
}
METHODS = ("Nelder-Mead", "Powell")
# "epsilon": Eq. 24-25 (+ the optional N = 20/40 range penalty), the paper's objective; "targets": every
# figure the experiment measured (crowd_env.experiments.validation.calibration.objective), on the runs of its required_cases;
# "targets+fd": those runs plus the fundamental diagram's (an FDPlan), the same objective with its FD terms.
# "virtual": every shipped experiment as it was run (the bottleneck's required cases, the nine Jülich corridor runs
# with their entrance and exit, the single file), objective.virtual_error.
OBJECTIVES = ("epsilon", "targets", "targets+fd", "virtual")
TARGET_OBJECTIVES = ("targets", "targets+fd", "virtual")


@dataclass
class OptimResult:
    best: dict  # name -> value
    objective: float
    epsilon_total: float
    n_evaluations: int  # evaluations requested by the optimiser (cached ones included)
    n_computed: int  # evaluations that needed runs in this call
    history: list
    message: str


def _setup_hash(widths, sizes, seeds, reference: ExperimentTable | None, range_weight: float, incomplete: str,
                objective: str = "epsilon", weights: TargetWeights | None = None, fd_plan: FDPlan | None = None) -> str:
    ref = seyfried_2009() if reference is None else reference
    setup = {"widths": widths, "sizes": sizes, "seeds": seeds, "range_weight": float(range_weight),
             "incomplete": incomplete,
             "ref": [ref.width_m.tolist(), ref.n_pedestrians.tolist(), ref.specific_flow_per_m_s.tolist()]}
    w = weights or TargetWeights()
    if objective == "targets":  # the ε_T and bottleneck-target set-ups keep the hash they always had
        setup.update(objective=objective, weights=w.bottleneck_dict())
    elif objective == "targets+fd":
        setup.update(objective=objective, weights=w.as_dict(), fd=(fd_plan or FDPlan()).as_dict())
    elif objective == "virtual":
        setup.update(objective=objective, weights=w.virtual_dict(), corridor_runs=list(CORRIDOR_RUN_NAMES),
                     single_file=list(SINGLE_FILE_DENSITIES))
    blob = json.dumps(setup, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def _check_free(free, x0: dict | None, bounds: dict | None) -> tuple:
    names = list(dict.fromkeys(free))
    if not names:
        raise CalibrationError(f"no free parameter given; choose from {list(FREE_PARAMETERS)}")
    for group, label in ((names, "free"), (x0 or {}, "x0"), (bounds or {}, "bounds")):
        unknown = sorted(set(group) - set(FREE_PARAMETERS))
        if unknown:
            raise CalibrationError(f"unknown {label} parameter(s) {unknown}; choose from {list(FREE_PARAMETERS)}")
    extra = sorted(set(x0 or {}) - set(names))
    if extra:
        raise CalibrationError(f"x0 given for parameter(s) {extra} that are not free {names}")
    lo, hi, start = [], [], []
    for name in names:
        p = FREE_PARAMETERS[name]
        b = tuple(float(v) for v in (bounds or {}).get(name, p.bounds))
        v = float((x0 or {}).get(name, p.default))
        if len(b) != 2 or not all(math.isfinite(t) for t in b) or not b[0] < b[1] or (p.log and b[0] <= 0):
            raise CalibrationError(f"bounds of {name} must be finite with low < high{' and low > 0' if p.log else ''}, "
                                   f"got {b}")
        if not math.isfinite(v) or (p.log and v <= 0):
            raise CalibrationError(f"start value of {name} must be finite{' and > 0' if p.log else ''}, got {v!r}")
        if not b[0] <= v <= b[1]:
            raise CalibrationError(f"start value {name} = {v} lies outside its bounds {b}")
        f = math.log if p.log else float
        lo.append(f(b[0]))
        hi.append(f(b[1]))
        start.append(f(v))
    return names, np.array(lo), np.array(hi), np.array(start)


class EvaluationCache:
    """Append-only, fsync'ed JSON lines of evaluated points, keyed by set-up hash and parameter values."""

    def __init__(self, path: Path, setup: str):
        self.path, self.setup = Path(path), setup
        self.entries = {}
        for e in read_json_lines(self.path):  # a line cut by a kill is skipped: that point is evaluated again
            if e.get("setup") == setup:
                self.entries[self.key(e["values"])] = e

    @staticmethod
    def key(values: dict) -> str:
        return json.dumps({k: canonical(v) for k, v in sorted(values.items())})

    def get(self, values: dict):
        return self.entries.get(self.key(values))

    def add(self, entry: dict) -> None:
        entry = {"setup": self.setup, **entry}
        append_json_line(self.path, entry)
        self.entries[self.key(entry["values"])] = entry


class PointEvaluator:
    """The objective at one parameter point, from stored runs or new ones: one implementation for the
    optimiser and the landscape (:mod:`crowd_env.experiments.validation.calibration.landscape`).

    ``values``: names of :data:`FREE_PARAMETERS` → natural values, set on top of ``config``'s model. The
    entry (objective, ε_T, terms or ε_j, stall counts) is cached in ``OUT/optimise/evaluations.jsonl``
    under the set-up hash; a point whose runs raised is not cached (retried next time).

    ``objective="targets+fd"``: each point also runs the fundamental diagram of ``fd_plan`` (default: every
    shipped bin, the bottleneck's ``seeds``) with ``fd_run_fn``; all its runs go to the one executor and store.
    """

    def __init__(self, out, config: dict, widths_m, sizes, seeds, backend, *, reference: ExperimentTable | None = None,
                 range_weight: float = 0.0, run_fn=run_one, incomplete: str = "bound", objective: str = "epsilon",
                 weights: TargetWeights | None = None, fd_plan: FDPlan | None = None, fd_run_fn=run_fd_one,
                 corridor_run_fn=run_corridor_one):
        if incomplete not in INCOMPLETE_RULES:
            raise CalibrationError(f"incomplete must be one of {INCOMPLETE_RULES}, got {incomplete!r}")
        if objective not in OBJECTIVES:
            raise CalibrationError(f"unknown objective {objective!r}; choose one of {OBJECTIVES}")
        self.widths_m, sizes, self.seeds = check_run_plan(widths_m, sizes, seeds)
        if objective in TARGET_OBJECTIVES:
            sizes = sorted({n for _, n in required_cases(self.widths_m)})
        self.fd_plan = None
        if objective == "targets+fd":
            self.fd_plan = FDPlan(seeds=tuple(self.seeds)) if fd_plan is None else fd_plan
            make_fd_tasks(config, {}, {}, self.fd_plan)  # a configuration the sweep cannot run fails before any run
            run_fn = partial(run_calibration_task, run_fn=run_fn, fd_run_fn=fd_run_fn)
        elif objective == "virtual":
            run_fn = partial(run_calibration_task, run_fn=run_fn, fd_run_fn=fd_run_fn, corridor_run_fn=corridor_run_fn)
        self.sizes, self.config, self.backend, self.run_fn = sizes, config, backend, run_fn
        self.reference, self.range_weight, self.incomplete = reference, range_weight, incomplete
        self.objective, self.weights = objective, weights
        self.store = RunStore(out, config, keyed_by="task")
        self.cache = EvaluationCache(Path(out) / "optimise" / "evaluations.jsonl",
                                     _setup_hash(self.widths_m, sizes, self.seeds, reference, range_weight, incomplete,
                                                 objective, weights, self.fd_plan))
        self.n_computed = 0  # points that needed runs in this object's life

    def tasks(self, values: dict) -> list:
        model = {FREE_PARAMETERS[n].field: v for n, v in values.items() if FREE_PARAMETERS[n].target == "model"}
        ped = {FREE_PARAMETERS[n].field: v for n, v in values.items() if FREE_PARAMETERS[n].target == "pedestrian"}
        radius = values.get("radius")
        slowdown = self.wall_slowdown(values)
        if self.objective == "virtual":
            return make_virtual_tasks(self.config, model, ped, self.widths_m, self.seeds, radius_m=radius,
                                      navigation_wall_slowdown=slowdown)
        if radius is not None or slowdown is not None:
            raise CalibrationError(f"the {'radius' if radius is not None else 'wall slowdown'} is calibrated with "
                                   "--objective virtual (it changes every scenario, the corridor runs' too)")
        if self.objective == "targets+fd":
            return (target_tasks(self.config, model, ped, self.widths_m, self.seeds)
                    + make_fd_tasks(self.config, model, ped, self.fd_plan))
        if self.objective == "targets":
            return target_tasks(self.config, model, ped, self.widths_m, self.seeds)
        return point_tasks(self.config, model, ped, self.widths_m, self.sizes, self.seeds)

    def wall_slowdown(self, values: dict):
        """The navigation field's ``(distance_m, speed_factor)`` of a point with ``wall_slowdown_m`` and/or
        ``wall_speed_factor`` free (the other from the configuration's ``navigation_wall_slowdown``); None when
        neither is free."""
        free = {FREE_PARAMETERS[n].field: float(v) for n, v in values.items()
                if FREE_PARAMETERS[n].target == "navigation"}
        if not free:
            return None
        own = self.config["geometry"].get("navigation_wall_slowdown")
        if len(free) < 2 and own is None:
            missing = "wall_speed_factor" if "distance_m" in free else "wall_slowdown_m"
            raise CalibrationError(f"free {missing} too, or give the other constant of the wall slowdown with "
                                   "--navigation-wall-slowdown DIST FACTOR")
        dist_m, factor = (float(v) for v in own) if own is not None else (None, None)
        return free.get("distance_m", dist_m), free.get("speed_factor", factor)

    def __call__(self, values: dict, desc: str = "evaluation") -> dict:
        unknown = sorted(set(values) - set(FREE_PARAMETERS))
        if unknown:
            raise CalibrationError(f"unknown parameter(s) {unknown}; choose from {list(FREE_PARAMETERS)}")
        values = {n: canonical(v) for n, v in values.items()}
        entry = self.cache.get(values)
        if entry is not None:
            return entry
        tasks = self.tasks(values)
        failed = execute(tasks, self.store, self.backend, self.run_fn, desc=desc, leave=False)
        self.n_computed += 1
        if failed:
            return {"values": values, "objective": FAILED_OBJECTIVE, "epsilon_total": float("nan"), "failed_runs": failed}
        records = [self.store.load(t) for t in tasks]
        if self.objective == "virtual":
            entry = target_entry(values, virtual_error(records, weights=self.weights, reference=self.reference))
        elif self.objective in TARGET_OBJECTIVES:
            entry = target_entry(values, target_error(records, weights=self.weights, reference=self.reference,
                                                      fd=self.objective == "targets+fd"))
        else:
            e = point_error_of(tasks, records, self.reference, self.range_weight, self.incomplete)
            entry = {"values": values, "objective": e.objective, "epsilon_total": e.epsilon_total,
                     "epsilon_by_group": {str(k): v for k, v in e.epsilon_by_group.items()},
                     "range_penalty": e.range_penalty, "n_undefined": e.n_undefined,
                     "n_stalled": n_stalled_runs(records)}  # > 0: a failed point (grid.STALLED_OBJECTIVE)
        self.cache.add(entry)
        return self.cache.get(values)  # the stored form, as a later call reads it


def optimise(out, config: dict, free, widths_m, sizes, seeds, backend, *, x0: dict | None = None,
             bounds: dict | None = None, method: str = "Nelder-Mead", max_evaluations: int = 60,
             xatol: float = 0.02, fatol: float = 1e-4, reference: ExperimentTable | None = None,
             range_weight: float = 0.0, run_fn=run_one, verbose: bool = True, incomplete: str = "bound",
             objective: str = "epsilon", weights: TargetWeights | None = None, fd_plan: FDPlan | None = None,
             fd_run_fn=run_fd_one) -> OptimResult:
    """argmin ε_T (+ range_weight × N = 20/40 range penalty) over the ``free`` parameters (Eq. 25), or, with
    ``objective="targets"``, argmin of :func:`crowd_env.experiments.validation.calibration.objective.target_error` (``weights``) on the
    runs of :func:`~crowd_env.experiments.validation.calibration.objective.required_cases` at ``widths_m`` (``sizes`` is then unused), or,
    with ``objective="targets+fd"``, the same objective on those runs plus the fundamental diagram's of
    ``fd_plan`` (:class:`PointEvaluator`).

    ``free``: names in :data:`FREE_PARAMETERS`; ``x0``/``bounds``: per-name start values and bounds in
    natural units. All candidates use the same ``seeds`` (common random numbers).
    """
    from scipy.optimize import minimize

    if method not in METHODS:
        raise CalibrationError(f"unknown method {method!r}; choose one of {METHODS}")
    check_integer("max_evaluations", max_evaluations, error=CalibrationError, minimum=1, whole_floats=True)
    names, lo, hi, z0 = _check_free(free, x0, bounds)
    evaluator = PointEvaluator(out, config, widths_m, sizes, seeds, backend, reference=reference,
                               range_weight=range_weight, run_fn=run_fn, incomplete=incomplete, objective=objective,
                               weights=weights, fd_plan=fd_plan, fd_run_fn=fd_run_fn)
    history = []

    def values_of(z) -> dict:
        z = np.clip(z, lo, hi)
        return {n: canonical(math.exp(v) if FREE_PARAMETERS[n].log else v) for n, v in zip(names, z)}

    def evaluate(z) -> float:
        values = values_of(z)
        entry = evaluator(values, desc=f"evaluation {len(history) + 1}")
        history.append(entry)
        if verbose:
            best = min(h["objective"] for h in history)
            shown = ", ".join(f"{n}={v:.4g}" for n, v in values.items())
            print(f"[{len(history)}] {shown}: objective {entry['objective']:.5g} (best {best:.5g})", file=sys.stderr)
        return float(entry["objective"])

    # Keep the start point inside the bounds for the simplex: step away from the nearer bound.
    options = {"maxfev": int(max_evaluations)}
    if method == "Nelder-Mead":
        steps = np.array([FREE_PARAMETERS[n].step for n in names])
        simplex = np.repeat(z0[None, :], len(names) + 1, axis=0)
        for k in range(len(names)):
            up = z0[k] + steps[k] <= hi[k]
            simplex[k + 1, k] = z0[k] + steps[k] if up else z0[k] - steps[k]
        options.update(initial_simplex=np.clip(simplex, lo, hi), xatol=xatol, fatol=fatol)
    else:
        options.update(xtol=xatol, ftol=fatol)
    res = minimize(evaluate, z0, method=method, bounds=list(zip(lo, hi)), options=options)
    k = int(np.argmin([h["objective"] for h in history]))
    result = OptimResult(history[k]["values"], float(history[k]["objective"]), float(history[k]["epsilon_total"]),
                         len(history), evaluator.n_computed, history, str(res.message))
    write_optimum(result, Path(out) / "optimise", names, method)
    return result


def target_tasks(config: dict, model: dict, pedestrian: dict, widths_m, seeds) -> list:
    """The runs :func:`~crowd_env.experiments.validation.calibration.objective.target_error` needs at one parameter point."""
    return [make_task(config, model, pedestrian, b, n, s) for b, n in required_cases(widths_m) for s in seeds]


def target_entry(values: dict, e) -> dict:
    """An evaluation record of the target objective (``e``: a :class:`~crowd_env.experiments.validation.calibration.objective.TargetScore`);
    its ``terms`` are the scored ones (without the fundamental diagram's when its runs were not part of it)."""
    return {"values": values, "objective": e.objective, "epsilon_total": e.terms.get("epsilon_60", float("nan")),
            "terms": {k: v for k, v in e.terms.items() if k not in e.unscored}, "n_incomplete": e.n_incomplete,
            "n_stalled": e.n_stalled, "failed_point": e.failed,
            "capacity_ratio": {f"{b:g}": v for b, v in e.capacity_ratio.items()}, "figures": e.figures}


def write_optimum(result: OptimResult, folder: Path, names: list, method: str) -> list:
    """``optimum.json`` (best point; with the target objective its terms too) and ``history.csv`` (every
    evaluation in order, a column per target term when there are any)."""
    folder.mkdir(parents=True, exist_ok=True)
    fields = {n: FREE_PARAMETERS[n].field for n in names}
    best = min(result.history, key=lambda h: h["objective"])
    term_names = list(best.get("terms") or {})
    write_json_atomic(folder / "optimum.json", {
        "best": {fields[n]: v for n, v in result.best.items()}, "objective": result.objective,
        "epsilon_total": result.epsilon_total, "terms": best.get("terms"), "n_evaluations": result.n_evaluations,
        "n_computed": result.n_computed, "method": method, "message": result.message}, indent=2)
    write_csv_atomic(folder / "history.csv",
                     ["evaluation"] + [fields[n] for n in names] + ["objective", "epsilon_total"] + term_names,
                     ([i] + [h["values"][n] for n in names] + [h["objective"], h["epsilon_total"]]
                      + [(h.get("terms") or {}).get(t, "") for t in term_names] for i, h in enumerate(result.history, 1)))
    return [folder / "optimum.json", folder / "history.csv"]
