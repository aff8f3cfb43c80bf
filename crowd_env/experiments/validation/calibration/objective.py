"""Everything the Seyfried et al. (2009) experiment measured, as one calibration objective.

Kabalan et al. (2016) calibrate A, B against one figure, the N = 60 specific flows (ε_T, Eq. 23-24).
A model fitted to that alone can reach it by the wrong mechanism: a discharge driven by the pressure
of the crowd behind (the rate then grows with N, a real bottleneck's does not), pedestrians pushed
through the channel faster than they walk, a jam held apart at half the observed density. The
experiment measured more than the N = 60 flows (``docs/validation/bottleneck.md``, "The experiment"; constants in
:mod:`crowd_env.analysis.experiment`), and :func:`target_error` scores a parameter point against all
of it at once:

Terms (means over seeds per (b, N) first):

- ``epsilon_60``: Eq. 24: mean over b of (J_s / J_s,exp − 1)², N = 60 (known value: Table 2)
- ``small_groups``: N = 20, 40 at every b: J_s inside the band (squared relative miss) (known value: [1.77, 2.31])
- ``ordering``: N = 20, 40 not below N = 60 at the same b: (J_s,60 / J_s,n − 1)² if > 0 (known value: "mostly above")
- ``speed_inside``: N = 60, every b: stationary speed in the channel inside the band (known value: [0.94, 1.22] m/s)
- ``density_inside``: N = 60, every b: stationary density in the channel inside the band (known value: [1.42, 1.73] /m²)
- ``density_front``: N = 60, every b: stationary density 1 m in front, inside the band (known value: [4, 6] /m²)
- ``capacity``: b = 1.0, 1.2 m: stationary rate of N = 120 / N = 60 inside the band (known value: [0.95, 1.10])

Each term is a mean squared *relative* miss (0 inside a band), so a 5 % miss costs 0.0025 wherever it
is; the objective is Σ w_k · term_k with every weight 1 by default (:class:`TargetWeights`): no term
is privileged over the paper's ε_T except by being outside its band. The capacity band is the one
judgement here: experiments through one door at N = 20 ... 60 give rates independent of N within
their scatter (Seyfried's N = 20, 40 flows lie *above* N = 60), so the stationary rate (20 % to 80 %
of the passages, :meth:`crowd_env.experiments.running.runner.RunResult.stationary_specific_flow_per_m_s`) of twice the
crowd may be at most 10 % higher and 5 % lower. A point with any incomplete run (a stall, or people
still inside at the time limit) is a failed point: its objective is :data:`FAILED_POINT_OBJECTIVE`
plus the fraction of incomplete runs, above any objective of a complete point, so that an optimiser
moves away from clogs while still telling a nearly-working point from a hopeless one.

The fundamental diagram (issue 36: one walking model for the door, the corridor and the single file). When
the records hold runs of the fundamental-diagram sweep (:func:`crowd_env.experiments.validation.fundamental_diagram.run_fd_one`,
recognised by their ``setup`` key, ``corridor`` or ``single_file``), four more terms score them, from seed means
per (set-up, density) at the shipped bins (:mod:`crowd_env.analysis.fd_reference`; a run at a density that is no
bin raises):

- ``corridor_fd``: periodic corridor 1.8 m wide, every bin density present from 0.4 to 3.4 /m² (the Jülich
  bins 0.394-3.364 of Zhang et al. 2011, ``data/juelich_uo_corridor_1.8m_fd.csv``):
  ``(max(|v − v_exp| − 0.10, 0) / v_exp)²``, mean over bins (known value: the bin's speed ±0.10 m/s, issue 36)
- ``corridor_monotone``: the same runs, consecutive densities: (max(v_k+1 − v_k − max(v_exp,k+1 − v_exp,k, 0), 0)
  / v_exp,k+1)², mean over pairs (known value: speed never rising with density, issue 36; a rise is allowed only
  as far as the experiment's own bins rise, 0.011 m/s from 0.394 to 0.628 /m², so that the bins score 0)
- ``single_file``: ring 0.7 m wide, the six bins of Seyfried et al. (2005) (``data/single_file_seyfried2005.csv``),
  as ``corridor_fd`` (known value: the bin's speed ±0.10 m/s)
- ``headway_fit``: d = a + b v fitted over the single file's pooled samples with v > 0.05 m/s
  (:func:`crowd_env.analysis.periodic.headway_fit`, the experiment's own fit a = 0.34 m, b = 1.08 s):
  mean of the squared band misses of a and b (known value: a in [0.28, 0.42] m, b in [0.9, 1.25] s, issue 36);
  a fit left undefined (fewer than two samples above 0.05 m/s: the file stands) counts a miss of 1 (100 %)
  for each, :data:`UNDEFINED_FIT_MISS`

The same convention as above (mean squared relative miss, 0 inside the band), weight 1 each by default: a bin
0.2 m/s off a 1 m/s experiment, 0.1 beyond the band, costs 0.01 / number of bins. Without runs of the sweep the
four terms are not scored: they stay 0 and are listed in :attr:`TargetScore.unscored`, and the objective is the
bottleneck's alone, exactly as before (``target_error(records, fd=True)`` demands them instead). A stalled or
incomplete bottleneck run still makes a failed point whatever the fundamental diagram says.

The acceptance table (``crowd-calibrate targets``): :func:`target_table`, one row per target of the bottleneck
with its figure and verdict, and with the sweep's runs :func:`fd_table`, the fundamental diagram's rows (the
corridor's speeds at the bins, its flow peak in [1.45, 1.8] 1/(m s) at 1.4-2.0 /m² and its speed never rising,
the single file's speeds and headway fit: issue 36's targets), from the same seed means and helpers as the terms.
"""
from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from ....core.checks import check_number
from ....analysis import fd_reference
from .errors import CalibrationError, relative_squared_errors
from ....analysis.experiment import (FRONT_DENSITY_RANGE_PER_M2, INSIDE_DENSITY_RANGE_PER_M2, INSIDE_SPEED_RANGE_M_S,
                         SPECIFIC_FLOW_RANGE_N20_N40_PER_M_S, WIDTHS_M, ExperimentTable, seyfried_2009)
from ....analysis.periodic import MIN_FIT_SPEED_M_S, headway_fit
from ..corridor_runs import CORRIDOR_RUN_NAMES, CORRIDOR_TOLERANCES, summarise_corridor

__all__ = ["CAPACITY_RANGE", "CAPACITY_SIZES", "CAPACITY_WIDTHS_M", "FAILED_POINT_OBJECTIVE", "TargetScore",
           "TargetWeights", "band_miss", "required_cases", "target_error", "FD_TERMS", "FD_SETUPS",
           "FD_SPEED_TOLERANCE_M_S", "CORRIDOR_FD_RANGE_PER_M2", "HEADWAY_A_RANGE_M", "HEADWAY_B_RANGE_S",
           "UNDEFINED_FIT_MISS", "DENSITY_MATCH", "corridor_fd_bins", "single_file_bins", "speed_band_miss", "fd_terms",
           "FD_PEAK_FLOW_RANGE_PER_M_S", "FD_PEAK_DENSITY_RANGE_PER_M2", "FD_ROUNDING_M_S", "fd_table",
           "single_file_terms", "corridor_runs_term", "virtual_error", "VIRTUAL_TERMS", "single_file_table",
           "corridor_table"]

# Stationary discharge rate of the larger crowd over the smaller one, at these widths.
CAPACITY_SIZES = (60, 120)
CAPACITY_WIDTHS_M = (1.0, 1.2)
CAPACITY_RANGE = (0.95, 1.10)
SMALL_GROUP_SIZES = (20, 40)
REFERENCE_SIZE = 60
FAILED_POINT_OBJECTIVE = 10.0
# The fundamental diagram (module docstring): its terms, the set-ups of its runs (a record's ``setup``), the
# speed tolerance around a bin, the corridor bins scored, the single-file headway bands.
FD_TERMS = ("corridor_fd", "corridor_monotone", "single_file", "headway_fit")
FD_SETUPS = ("corridor", "single_file")
FD_SPEED_TOLERANCE_M_S = 0.10
CORRIDOR_FD_RANGE_PER_M2 = (0.35, 3.4)  # the Jülich bins "from 0.4 to 3.4 /m²": 0.394 ... 3.364
HEADWAY_A_RANGE_M = (0.28, 0.42)
HEADWAY_B_RANGE_S = (0.9, 1.25)
UNDEFINED_FIT_MISS = 1.0  # relative miss of a and b when the single file gives no fit (nobody moves)
DENSITY_MATCH = 1e-6  # a run's nominal density is a bin's when within this


@dataclass(frozen=True)
class TargetWeights:
    """Weights of the terms of :func:`target_error` (all 1: each a squared relative miss). The last four
    (:data:`FD_TERMS`) weigh the fundamental diagram's terms, scored only from runs of its sweep."""

    epsilon_60: float = 1.0
    small_groups: float = 1.0
    ordering: float = 1.0
    speed_inside: float = 1.0
    density_inside: float = 1.0
    density_front: float = 1.0
    capacity: float = 1.0
    corridor_fd: float = 1.0
    corridor_monotone: float = 1.0
    single_file: float = 1.0
    headway_fit: float = 1.0
    corridor_runs: float = 1.0

    def __post_init__(self) -> None:
        for f in fields(self):
            check_number(f"weight {f.name}", getattr(self, f.name), error=CalibrationError, minimum=0.0)

    def as_dict(self) -> dict:
        """Every weight but ``corridor_runs``, which only the objective of every shipped experiment reads
        (:func:`virtual_error`; its set-up hashes :meth:`virtual_dict`)."""
        return {f.name: float(getattr(self, f.name)) for f in fields(self) if f.name != "corridor_runs"}

    def virtual_dict(self) -> dict:
        """The weights :func:`virtual_error` reads: the bottleneck's, the single file's and the corridor runs'."""
        return {**self.bottleneck_dict(), "single_file": self.single_file, "headway_fit": self.headway_fit,
                "corridor_runs": self.corridor_runs}

    def bottleneck_dict(self) -> dict:
        """The weights of the bottleneck's terms only (what a bottleneck-only set-up hashes, as before)."""
        return {k: v for k, v in self.as_dict().items() if k not in FD_TERMS}


@dataclass(frozen=True)
class TargetScore:
    """Score of one parameter point: ``objective`` = Σ weight · term over :attr:`terms`, or
    :data:`FAILED_POINT_OBJECTIVE` + the incomplete fraction when a run did not complete.

    ``figures`` holds the seed means the terms were computed from, keyed ``"<name> b<b> n<N>"`` (with the
    fundamental diagram also ``"fd_speed_m_s <setup> rho<density>"``, ``"headway_a_m"``, ``"headway_b_s"``,
    ``"headway_samples"``), ``capacity_ratio`` the N = 120 / N = 60 stationary rate ratio per width, and
    ``unscored`` the terms left at 0 because their runs were not given (the fundamental diagram's without
    runs of its sweep).
    """

    objective: float
    terms: dict
    n_runs: int
    n_incomplete: int
    n_stalled: int
    failed: bool
    figures: dict
    capacity_ratio: dict
    unscored: tuple = ()


def band_miss(value, low: float, high: float) -> np.ndarray:
    """Relative distance of ``value`` outside [low, high]: value/low − 1 below, value/high − 1 above, 0 in."""
    v = np.asarray(value, dtype=np.float64)
    return np.where(v < low, v / low - 1.0, np.where(v > high, v / high - 1.0, 0.0))


def required_cases(widths_m=WIDTHS_M, capacity_widths_m=CAPACITY_WIDTHS_M) -> list:
    """The (b, N) runs :func:`target_error` needs: N = 20, 40, 60 at ``widths_m``, N = 120 at
    ``capacity_widths_m`` (which must be among ``widths_m``)."""
    widths = [float(b) for b in widths_m]
    missing = [b for b in capacity_widths_m if not any(abs(b - w) < 1e-9 for w in widths)]
    if missing:
        raise CalibrationError(f"capacity widths {missing} are not among the widths {widths}")
    cases = [(b, n) for n in (*SMALL_GROUP_SIZES, REFERENCE_SIZE) for b in widths]
    return cases + [(float(b), CAPACITY_SIZES[1]) for b in capacity_widths_m]


def _by_case(records) -> dict:
    """Records grouped by (b rounded to 1 µm, N)."""
    groups: dict = {}
    for r in records:
        groups.setdefault((round(float(r["width_m"]), 6), int(r["n_pedestrians"])), []).append(r)
    return groups


def _seed_mean(groups: dict, b: float, n: int, key: str) -> float:
    """Mean of ``key`` over the finite values of case (b, N); nan when there is none. A record with the
    key set to None (a figure never measured) raises naming the case."""
    values = [r.get(key, np.nan) for r in groups.get((b, n), [])]
    if any(v is None for v in values):
        raise CalibrationError(f"a run at b = {b:g} m, N = {n} has no {key!r}")
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    return float(v.mean()) if v.size else float("nan")


def corridor_fd_bins() -> np.ndarray:
    """(density 1/m², speed m/s) rows of the Jülich corridor bins that :func:`target_error` scores."""
    t = fd_reference.juelich_corridor()
    keep = (t.density >= CORRIDOR_FD_RANGE_PER_M2[0]) & (t.density <= CORRIDOR_FD_RANGE_PER_M2[1])
    return np.column_stack([t.density[keep], t.speed_m_s[keep]])


def single_file_bins() -> np.ndarray:
    """(density 1/m, speed m/s) rows of the single-file bins that :func:`target_error` scores (all of them)."""
    t = fd_reference.single_file()
    return np.column_stack([t.density, t.speed_m_s])


def speed_band_miss(speed, reference, tolerance: float = FD_SPEED_TOLERANCE_M_S) -> np.ndarray:
    """How far ``speed`` lies beyond ``reference`` ± ``tolerance``, relative to ``reference`` (0 inside)."""
    v = np.asarray(speed, dtype=np.float64)
    ref = np.asarray(reference, dtype=np.float64)
    return np.clip(np.abs(v - ref) - tolerance, 0.0, None) / ref


def _fd_speeds(records: list, setup: str, bins: np.ndarray) -> tuple:
    """(densities, bin speeds, model seed-mean speeds) of ``setup`` at the bins its runs were at, in density
    order; a run at a density that is no bin of ``bins`` raises naming it."""
    groups: dict = {}
    for r in records:
        if r["setup"] != setup:
            continue
        d = float(r["density"])
        k = np.flatnonzero(np.abs(bins[:, 0] - d) <= DENSITY_MATCH)
        if k.size == 0:
            raise CalibrationError(f"a {setup} run at density {d:g} is at no shipped bin the objective scores "
                                   f"({', '.join(f'{x:g}' for x in bins[:, 0])})")
        if r.get("speed_m_s") is None:
            raise CalibrationError(f"a {setup} run at density {d:g} has no 'speed_m_s'")
        groups.setdefault(int(k[0]), []).append(float(r["speed_m_s"]))
    idx = sorted(groups)
    return (bins[idx, 0], bins[idx, 1], np.array([np.mean(groups[k]) for k in idx], dtype=np.float64))


def _check_fd_setups(records: list) -> None:
    """Raise unless ``records`` (the sweep's runs) hold every set-up of :data:`FD_SETUPS` and no other."""
    missing = [s for s in FD_SETUPS if not any(r["setup"] == s for r in records)]
    if missing:
        raise CalibrationError(f"the fundamental diagram's terms need runs of every set-up {list(FD_SETUPS)}; "
                               f"none of {missing}")
    unknown = sorted({str(r["setup"]) for r in records} - set(FD_SETUPS))
    if unknown:
        raise CalibrationError(f"unknown fundamental-diagram set-up(s) {unknown}; known: {list(FD_SETUPS)}")


def _excess_rises(v, v_exp) -> np.ndarray:
    """Per consecutive pair of bins (density order), how far the speed ``v`` rises (m/s) beyond the bins' own
    rise ``v_exp`` (0 where it falls, or rises no more than the bins do): ``corridor_monotone``'s allowance."""
    return np.clip(np.diff(v) - np.clip(np.diff(v_exp), 0.0, None), 0.0, None)


def _single_file_fit(records: list) -> tuple:
    """``(a m, b s, samples)`` of d = a + b v over the pooled samples of the single-file runs among ``records``
    (:func:`crowd_env.analysis.periodic.headway_fit`; nan, nan when undefined). A run without samples raises."""
    single = [r for r in records if r["setup"] == "single_file"]
    if any("headway_samples_m" not in r or "speed_samples_m_s" not in r for r in single):
        raise CalibrationError("a single_file run has no headway samples ('headway_samples_m', 'speed_samples_m_s')")
    return headway_fit(np.concatenate([np.asarray(r["headway_samples_m"], dtype=np.float64) for r in single]),
                       np.concatenate([np.asarray(r["speed_samples_m_s"], dtype=np.float64) for r in single]))


def single_file_terms(records: list) -> tuple:
    """``(terms, figures)`` of the single file alone (``single_file`` and ``headway_fit``, module docstring) from
    the single-file runs among ``records``."""
    terms, figures = {}, {}
    rho, v_exp, v = _fd_speeds(records, "single_file", single_file_bins())
    figures.update({f"fd_speed_m_s single_file rho{d:g}": float(x) for d, x in zip(rho, v)})
    terms["single_file"] = float(np.mean(speed_band_miss(v, v_exp) ** 2))
    a, b, k = _single_file_fit(records)
    miss = (np.array([band_miss(a, *HEADWAY_A_RANGE_M), band_miss(b, *HEADWAY_B_RANGE_S)])
            if np.isfinite(a) and np.isfinite(b) else np.full(2, UNDEFINED_FIT_MISS))
    terms["headway_fit"] = float(np.mean(miss ** 2))
    figures.update({"headway_a_m": a, "headway_b_s": b, "headway_samples": k})
    return terms, figures


def fd_terms(records: list) -> tuple:
    """``(terms, figures)`` of the fundamental diagram (module docstring) from the sweep's run records (each
    with ``setup``, ``density``, ``speed_m_s``; single-file ones with ``headway_samples_m`` and
    ``speed_samples_m_s``). Both set-ups must be present."""
    _check_fd_setups(records)
    terms, figures = {}, {}
    rho, v_exp, v = _fd_speeds(records, "corridor", corridor_fd_bins())
    figures.update({f"fd_speed_m_s corridor rho{d:g}": float(x) for d, x in zip(rho, v)})
    terms["corridor_fd"] = float(np.mean(speed_band_miss(v, v_exp) ** 2))
    rises = _excess_rises(v, v_exp) / v_exp[1:]
    terms["corridor_monotone"] = float(np.mean(rises ** 2)) if rises.size else 0.0
    more_terms, more_figures = single_file_terms(records)
    return {**terms, **more_terms}, {**figures, **more_figures}


def corridor_runs_term(records: list) -> tuple:
    """``(term, figures)`` of the Jülich corridor runs as run (:mod:`crowd_env.experiments.validation.corridor_runs`):
    per run the seed means of the Voronoi density, speed and exit flow, each's miss beyond its tolerance
    (density and exit flow relative, ±15 % and ±10 %; speed ±0.10 m/s, relative to the experiment's speed: the
    convention of the other terms), squared, the mean over runs and the three quantities. Every run of the
    experiment must be present (:class:`CalibrationError` naming the missing ones)."""
    rows = summarise_corridor(records)
    missing = sorted(set(CORRIDOR_RUN_NAMES) - {r["run"] for r in rows})
    if missing:
        raise CalibrationError(f"the corridor runs' term needs every run of the experiment; none of {missing}")
    tol = CORRIDOR_TOLERANCES
    misses, figures = [], {}
    for r in rows:
        misses += [max(abs(r["density_per_m2"] / r["density_exp"] - 1.0) - tol["density_relative"], 0.0),
                   float(speed_band_miss(r["speed_m_s"], r["speed_exp"], tol["speed_m_s"])),
                   max(abs(r["flow_exit_per_s"] / r["flow_exit_exp"] - 1.0) - tol["flow_exit_relative"], 0.0)]
        for key in ("density_per_m2", "speed_m_s", "flow_exit_per_s"):
            figures[f"{key} {r['run']}"] = r[key]
    return float(np.mean(np.square(misses))), figures


def _complete(record: dict) -> bool:
    if "complete" in record:
        return bool(record["complete"])
    return int(record["n_evacuated"]) == int(record["n_pedestrians"])


def target_error(records: list, *, weights: TargetWeights | None = None,
                 reference: ExperimentTable | None = None, fd: bool | None = None) -> TargetScore:
    """Score the runs of one parameter point against every target of the module table.

    ``records``: the reproduction's run records (``crowd_env.experiments.validation.bottleneck.run_one``) of at
    least the cases of :func:`required_cases` at the widths present for N = 60, any number of seeds
    (the same for every case: common random numbers), and optionally runs of the fundamental-diagram sweep
    (records with a ``setup`` key). ``fd``: score the fundamental diagram's terms (True: its runs are
    required; False: they are left out even when given; None, the default: when any is given). Raises
    :class:`CalibrationError` naming a missing case or a record without the figures a term needs.
    """
    w = TargetWeights() if weights is None else weights
    ref = seyfried_2009() if reference is None else reference
    if not records:
        raise CalibrationError("no run records given")
    fd_records = [r for r in records if "setup" in r]
    records = [r for r in records if "setup" not in r]
    if not records:
        raise CalibrationError("no bottleneck run records given (only runs of the fundamental-diagram sweep)")
    scored_fd = bool(fd_records) if fd is None else bool(fd)
    if scored_fd and not fd_records:
        raise CalibrationError(f"the fundamental diagram's terms need runs of its sweep (set-ups {list(FD_SETUPS)}); "
                               f"none given")
    if not scored_fd:
        fd_records = []
    unscored = () if scored_fd else FD_TERMS
    n_incomplete = sum(not _complete(r) for r in records + fd_records)
    n_stalled = sum(bool(r.get("stalled", False)) for r in records + fd_records)
    n_runs = len(records) + len(fd_records)
    groups = _by_case(records)
    widths = sorted(b for (b, n) in groups if n == REFERENCE_SIZE)
    if not widths:
        raise CalibrationError(f"no N = {REFERENCE_SIZE} runs: the objective needs them at every width")
    cap_widths = [b for b in CAPACITY_WIDTHS_M if round(b, 6) in widths]
    for b, n in required_cases(widths, cap_widths):
        if (round(b, 6), n) not in groups:
            raise CalibrationError(f"the objective needs runs at b = {b:g} m, N = {n}; none given")
    if n_incomplete:
        return TargetScore(FAILED_POINT_OBJECTIVE + n_incomplete / n_runs, {}, n_runs, n_incomplete,
                           n_stalled, True, {}, {}, unscored)

    def mean(b, n, key):
        return _seed_mean(groups, b, n, key)

    figures = {}
    for (b, n) in groups:
        for key in ("specific_flow_per_m_s", "stationary_specific_flow_per_m_s", "speed_inside_m_s",
                    "density_inside_per_m2", "density_front_per_m2"):
            figures[f"{key} b{b:g} n{n}"] = mean(b, n, key)
    js60 = np.array([figures[f"specific_flow_per_m_s b{b:g} n{REFERENCE_SIZE}"] for b in widths])
    terms = {"epsilon_60": float(relative_squared_errors(widths, REFERENCE_SIZE, js60, ref).mean())}
    low, high = SPECIFIC_FLOW_RANGE_N20_N40_PER_M_S
    small = np.array([[figures[f"specific_flow_per_m_s b{b:g} n{n}"] for b in widths] for n in SMALL_GROUP_SIZES])
    terms["small_groups"] = float(np.mean(band_miss(small, low, high) ** 2))
    terms["ordering"] = float(np.mean(np.clip(js60[None, :] / small - 1.0, 0.0, None) ** 2))
    for term, key, (lo, hi) in (("speed_inside", "speed_inside_m_s", INSIDE_SPEED_RANGE_M_S),
                                ("density_inside", "density_inside_per_m2", INSIDE_DENSITY_RANGE_PER_M2),
                                ("density_front", "density_front_per_m2", FRONT_DENSITY_RANGE_PER_M2)):
        values = np.array([figures[f"{key} b{b:g} n{REFERENCE_SIZE}"] for b in widths])
        terms[term] = float(np.mean(band_miss(values, lo, hi) ** 2))
    small_n, large_n = CAPACITY_SIZES
    ratios = {b: figures[f"stationary_specific_flow_per_m_s b{b:g} n{large_n}"]
              / figures[f"stationary_specific_flow_per_m_s b{b:g} n{small_n}"] for b in cap_widths}
    terms["capacity"] = float(np.mean(band_miss(list(ratios.values()), *CAPACITY_RANGE) ** 2)) if ratios else 0.0
    if scored_fd:
        more_terms, more_figures = fd_terms(fd_records)
        terms.update(more_terms)
        figures.update(more_figures)
    else:
        terms.update({k: 0.0 for k in FD_TERMS})
    bad = sorted(k for k, v in terms.items() if not np.isfinite(v))
    if bad:
        raise CalibrationError(f"objective terms {bad} are undefined (a run without passages in its stationary "
                               f"window, an empty measurement area or a fundamental-diagram run without a speed)")
    wd = w.as_dict()
    objective = float(sum(wd[k] * v for k, v in terms.items()))
    return TargetScore(objective, terms, n_runs, 0, n_stalled, False, figures, ratios, unscored)


VIRTUAL_TERMS = ("single_file", "headway_fit", "corridor_runs")


def virtual_error(records: list, *, weights: TargetWeights | None = None,
                  reference: ExperimentTable | None = None) -> TargetScore:
    """Score one parameter point on every shipped experiment as it was run: the bottleneck's terms of
    :func:`target_error` (its runs: records with neither ``setup`` nor ``experiment`` = ``"corridor"``), the single
    file's (``single_file``, ``headway_fit``: runs with ``setup`` = ``"single_file"``) and the corridor runs'
    (:func:`corridor_runs_term`: records with ``experiment`` = ``"corridor"``), Σ weight · term. The periodic
    corridor's terms are not part of it: the corridor runs as run replace them. Any incomplete run of any
    experiment makes a failed point (:data:`FAILED_POINT_OBJECTIVE` + the incomplete fraction)."""
    w = TargetWeights() if weights is None else weights
    corridor = [r for r in records if r.get("experiment") == "corridor"]
    single = [r for r in records if r.get("setup") == "single_file"]
    neck = [r for r in records if r.get("experiment") != "corridor" and "setup" not in r]
    if not corridor or not single:
        raise CalibrationError("the objective of every shipped experiment needs corridor runs and single-file runs "
                               f"(got {len(corridor)} and {len(single)})")
    if len(neck) + len(corridor) + len(single) != len(records):
        raise CalibrationError("records of the periodic corridor's sweep have no place in the objective of every "
                               "shipped experiment")
    bottleneck = target_error(neck, weights=w, reference=reference, fd=False)
    n_incomplete = sum(not _complete(r) for r in corridor + single)
    n_stalled = bottleneck.n_stalled + sum(bool(r.get("stalled", False)) for r in corridor + single)
    n_runs = len(records)
    if bottleneck.failed or n_incomplete:
        bad = bottleneck.n_incomplete + n_incomplete
        return TargetScore(FAILED_POINT_OBJECTIVE + bad / n_runs, {}, n_runs, bad, n_stalled, True, {}, {})
    terms = {k: v for k, v in bottleneck.terms.items() if k not in FD_TERMS}
    figures = dict(bottleneck.figures)
    more, more_figures = single_file_terms(single)
    terms.update(more)
    figures.update(more_figures)
    terms["corridor_runs"], corridor_figures = corridor_runs_term(corridor)
    figures.update(corridor_figures)
    wd = w.virtual_dict()
    return TargetScore(float(sum(wd[k] * v for k, v in terms.items())), terms, n_runs, 0, n_stalled, False, figures,
                       bottleneck.capacity_ratio)


# --- the acceptance table: every target with its figure and verdict ------------------------

RESIDUAL_NORM_MAX = 0.14  # J(b) = a b + c through the N = 60 flows: residual norm at most this
N60_TOLERANCE = 0.05  # J_s of N = 60 within ±5 % of the experiment at every width
EXPECTED_LANES = {0.8: 1, 1.0: 2, 1.1: 2, 1.2: 2}  # Seyfried et al. 2009: one lane at 0.8 m, two (zipper) from 0.9 m


def target_table(records: list, *, reference: ExperimentTable | None = None) -> list:
    """One row per target of the calibration (``target``, ``figure``, ``criterion``, ``passed``) from the
    run records of one model configuration (seed means per (b, N); every required case present).

    Incomplete runs are counted (``stalls`` row) and left out of the means, never averaged in.
    """
    from ....analysis.flow import linear_fit
    from ....analysis.lanes import pooled_lanes

    ref = seyfried_2009() if reference is None else reference
    records = [r for r in records if "setup" not in r]  # the bottleneck's runs (not the fundamental diagram's)
    complete = [r for r in records if _complete(r)]
    rows = []
    n_stalled = sum(bool(r.get("stalled", False)) for r in records)
    rows.append({"target": "stalls / incomplete runs", "figure": f"{n_stalled} / {len(records) - len(complete)} of "
                 f"{len(records)}", "criterion": "0", "passed": len(complete) == len(records)})
    worst_gap = min(float(r["min_gap_m"]) for r in records)
    rows.append({"target": "smallest gap (overlap)", "figure": f"{worst_gap * 1e3:+.2f} mm", "criterion": ">= -1 mm",
                 "passed": worst_gap >= -1e-3})
    groups = _by_case(complete)

    def mean(b, n, key):
        return _seed_mean(groups, b, n, key)

    widths = sorted(b for (b, n) in groups if n == REFERENCE_SIZE)
    errors = []
    for b in widths:
        js_exp = float(ref.specific_flow_per_m_s[ref.lookup(b, REFERENCE_SIZE)[0]])
        errors.append(mean(b, REFERENCE_SIZE, "specific_flow_per_m_s") / js_exp - 1.0)
    rows.append({"target": "J_s N = 60 vs experiment, b = " + "/".join(f"{b:g}" for b in widths),
                 "figure": " / ".join(f"{100 * e:+.1f} %" for e in errors), "criterion": "each within ±5 %",
                 "passed": bool(errors) and all(abs(e) <= N60_TOLERANCE for e in errors)})
    low, high = SPECIFIC_FLOW_RANGE_N20_N40_PER_M_S
    for n in SMALL_GROUP_SIZES:
        js = [mean(b, n, "specific_flow_per_m_s") for b in widths]
        rows.append({"target": f"J_s N = {n}, b = " + "/".join(f"{b:g}" for b in widths),
                     "figure": " / ".join(f"{v:.2f}" for v in js), "criterion": f"each in [{low:g}, {high:g}]",
                     "passed": all(low <= v <= high for v in js)})
    small_n, large_n = CAPACITY_SIZES
    ratios = [mean(b, large_n, "stationary_specific_flow_per_m_s") / mean(b, small_n, "stationary_specific_flow_per_m_s")
              for b in CAPACITY_WIDTHS_M if (round(b, 6), large_n) in groups]
    rows.append({"target": f"capacity: stationary rate N = {large_n} / N = {small_n}, b = "
                 + "/".join(f"{b:g}" for b in CAPACITY_WIDTHS_M),
                 "figure": " / ".join(f"{v:.3f}" for v in ratios),
                 "criterion": f"each in [{CAPACITY_RANGE[0]:g}, {CAPACITY_RANGE[1]:g}]",
                 "passed": bool(ratios) and all(CAPACITY_RANGE[0] <= v <= CAPACITY_RANGE[1] for v in ratios)})
    for label, key, (lo, hi), unit in (("speed inside", "speed_inside_m_s", INSIDE_SPEED_RANGE_M_S, "m/s"),
                                       ("density inside", "density_inside_per_m2", INSIDE_DENSITY_RANGE_PER_M2, "/m²"),
                                       ("density in front", "density_front_per_m2", FRONT_DENSITY_RANGE_PER_M2, "/m²")):
        v = [mean(b, REFERENCE_SIZE, key) for b in widths]
        rows.append({"target": f"{label} (N = 60, stationary), min-max over b", "figure": f"{min(v):.2f}-{max(v):.2f} {unit}",
                     "criterion": f"in [{lo:g}, {hi:g}]", "passed": all(lo <= x <= hi for x in v)})
    if len(widths) >= 3:
        fit = linear_fit(widths, [mean(b, REFERENCE_SIZE, "flow_per_s") for b in widths])
        rows.append({"target": "J(b) linear, N = 60", "figure": f"residual norm {fit.residual_norm:.3f} "
                     f"(J = {fit.slope:.2f} b {fit.intercept:+.2f})", "criterion": f"<= {RESIDUAL_NORM_MAX:g}",
                     "passed": fit.residual_norm <= RESIDUAL_NORM_MAX})
    lanes = {b: pooled_lanes(groups[(b, REFERENCE_SIZE)]).n_lanes for b in widths
             if any("lane_counts" in r for r in groups[(b, REFERENCE_SIZE)])}
    if lanes:
        rows.append({"target": "lanes N = 60, b = " + "/".join(f"{b:g}" for b in lanes),
                     "figure": " / ".join(str(v) for v in lanes.values()),
                     "criterion": "1 at 0.8 m, 2 at >= 1.0 m",
                     "passed": all(lanes[b] == EXPECTED_LANES[b] for b in lanes if b in EXPECTED_LANES)})
    return rows


# --- the fundamental diagram's acceptance rows (issue 36's targets) -----------------------------------------

# The corridor's specific flow ρ·v (bin density × seed-mean speed) peaks inside this band at a density inside
# the next (issue 36; the Jülich bins themselves peak at 1.61 1/(m s) at 1.629 /m²).
FD_PEAK_FLOW_RANGE_PER_M_S = (1.45, 1.8)
FD_PEAK_DENSITY_RANGE_PER_M2 = (1.4, 2.0)
FD_ROUNDING_M_S = 1e-9  # speed comparisons of the table allow this for the rounding of seed means


def _fd_speed_row(label: str, unit: str, rho: np.ndarray, v_exp: np.ndarray, v: np.ndarray) -> dict:
    """The row "speed within the tolerance of every bin run" (:func:`fd_table`) from :func:`_fd_speeds`'s
    densities ``rho`` (in ``unit``), bin speeds ``v_exp`` and model speeds ``v``."""
    within = speed_band_miss(v, v_exp, FD_SPEED_TOLERANCE_M_S + FD_ROUNDING_M_S) == 0.0
    worst = int(np.argmax(np.abs(v - v_exp)))
    return {"target": f"{label}: speed at the bins {rho[0]:g}-{rho[-1]:g} {unit}",
            "figure": f"{int(within.sum())} of {rho.size}, worst {v[worst] - v_exp[worst]:+.2f} m/s at "
                      f"{rho[worst]:g} {unit}",
            "criterion": f"each within ±{FD_SPEED_TOLERANCE_M_S:g} m/s", "passed": bool(within.all())}


def fd_table(records: list) -> list:
    """The fundamental diagram's rows of the acceptance table (keys as :func:`target_table`'s: ``target``,
    ``figure``, ``criterion``, ``passed``) from the sweep's run records among ``records`` (those with a
    ``setup`` key; both set-ups needed), seed means per (set-up, density) at the shipped bins as
    :func:`fd_terms` takes them (:mod:`crowd_env.analysis.fd_reference`: the Jülich 1.8 m corridor,
    ``data/juelich_uo_corridor_1.8m_fd.csv``, and the single file of Seyfried et al. 2005,
    ``data/single_file_seyfried2005.csv``). The targets are issue 36's:

    - corridor: the speed within ±0.10 m/s (:data:`FD_SPEED_TOLERANCE_M_S`) of every bin run (figure: the bins
      within, and the largest difference with its density);
    - corridor: the specific flow ρ·v (bin density × speed) peaking in [1.45, 1.8] 1/(m s)
      (:data:`FD_PEAK_FLOW_RANGE_PER_M_S`) at a density in [1.4, 2.0] /m² (:data:`FD_PEAK_DENSITY_RANGE_PER_M2`)
      (figure: the peak and its density);
    - corridor: the speed never rising with density beyond the bins' own rise, the allowance of
      ``corridor_monotone`` (figure: the rise of the pair that exceeds it most, or else the largest rise);
    - single file: the speed within ±0.10 m/s of every bin run (figure as the corridor's);
    - single file: d = a + b v fitted as for ``headway_fit``, a in [0.28, 0.42] m (:data:`HEADWAY_A_RANGE_M`) and
      b in [0.9, 1.25] s (:data:`HEADWAY_B_RANGE_S`); no fit (fewer than two samples above the fit's speed floor,
      or no spread in speed) fails, and the figure says which.

    Speeds are compared allowing :data:`FD_ROUNDING_M_S` for rounding. Raises :class:`CalibrationError` as
    :func:`fd_terms` does (a set-up missing, a run at no bin, a record without its figures).
    """
    records = [r for r in records if "setup" in r]
    _check_fd_setups(records)
    rho, v_exp, v = _fd_speeds(records, "corridor", corridor_fd_bins())
    rows = [_fd_speed_row("corridor 1.8 m", "/m²", rho, v_exp, v)]
    flow = rho * v
    k = int(np.argmax(flow))
    (f_lo, f_hi), (d_lo, d_hi) = FD_PEAK_FLOW_RANGE_PER_M_S, FD_PEAK_DENSITY_RANGE_PER_M2
    rows.append({"target": "corridor 1.8 m: peak of the specific flow ρ·v",
                 "figure": f"{flow[k]:.2f} 1/(m s) at {rho[k]:g} /m²",
                 "criterion": f"{f_lo:g}-{f_hi:g} at {d_lo:g}-{d_hi:g} /m²",
                 "passed": bool(f_lo <= flow[k] <= f_hi and d_lo <= rho[k] <= d_hi)})
    excess, rise = _excess_rises(v, v_exp), np.diff(v)
    if rise.size:
        j = max(range(rise.size), key=lambda i: (excess[i] > FD_ROUNDING_M_S, excess[i], rise[i]))
        figure = f"{rise[j]:+.3f} m/s at {rho[j]:g}-{rho[j + 1]:g} /m²" if rise[j] > FD_ROUNDING_M_S else "no rise"
    else:
        figure = "one bin: no pair"
    rows.append({"target": "corridor 1.8 m: speed never rising with density", "figure": figure,
                 "criterion": "none beyond the bins'", "passed": bool(np.all(excess <= FD_ROUNDING_M_S))})
    return rows + single_file_table(records)


def single_file_table(records: list) -> list:
    """The single file's rows of :func:`fd_table` (its speeds at the bins, its headway fit) from the single-file
    runs among ``records`` (records with ``setup`` = ``"single_file"``)."""
    records = [r for r in records if r.get("setup") == "single_file"]
    rows = [_fd_speed_row("single file", "/m", *_fd_speeds(records, "single_file", single_file_bins()))]
    a, b, n = _single_file_fit(records)
    fitted = bool(np.isfinite(a) and np.isfinite(b))
    if fitted:
        figure = f"a = {a:.2f} m, b = {b:.2f} s"
    elif n < 2:
        figure = f"no fit: {n} sample(s) above {MIN_FIT_SPEED_M_S:g} m/s"
    else:
        figure = "no fit: every speed equal"
    (a_lo, a_hi), (b_lo, b_hi) = HEADWAY_A_RANGE_M, HEADWAY_B_RANGE_S
    rows.append({"target": "single file: headway d = a + b v", "figure": figure,
                 "criterion": f"a [{a_lo:g}, {a_hi:g}] m, b [{b_lo:g}, {b_hi:g}] s",
                 "passed": fitted and bool(a_lo <= a <= a_hi and b_lo <= b <= b_hi)})
    return rows


def corridor_table(records: list) -> list:
    """One row per Jülich corridor run among ``records`` (keys as :func:`target_table`'s): the seed means of the
    complete runs, density / speed / exit flow beside the experiment's, within every tolerance of
    :data:`~crowd_env.experiments.validation.corridor_runs.CORRIDOR_TOLERANCES` (density ±15 %, speed ±0.10 m/s, exit
    flow ±10 %) or not; a run of which no seed completed fails, named stalled."""
    tol = CORRIDOR_TOLERANCES
    rows = []
    for s in summarise_corridor(records):
        label = (f"corridor {s['run']} (entrance {s['entrance_width_m']:g} m, exit {s['exit_width_m']:g} m, "
                 f"N = {s['n_pedestrians']}): ρ / v / J")
        if not s["complete"]:
            figure = f"stalled {s['stalled']} of {s['runs']}" if s["stalled"] else f"incomplete {s['runs']} of {s['runs']}"
            passed = False
        else:
            figure = f"{s['density_per_m2']:.2f} / {s['speed_m_s']:.2f} / {s['flow_exit_per_s']:.2f}"
            if s["complete"] < s["runs"]:
                figure += f" ({s['runs'] - s['complete']} of {s['runs']} stalled or incomplete)"
            passed = s["complete"] == s["runs"] and max(s["density_miss"], s["speed_miss"], s["flow_exit_miss"]) <= 1.0
        rows.append({"target": label, "figure": figure,
                     "criterion": f"{s['density_exp']:.2f} / {s['speed_exp']:.2f} / {s['flow_exit_exp']:.2f} "
                                  f"±{tol['density_relative']:.0%} / ±{tol['speed_m_s']:g} / ±{tol['flow_exit_relative']:.0%}",
                     "passed": passed})
    return rows
