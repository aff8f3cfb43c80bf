"""Why the ``paper`` preset clogs for good under pressure and ``calibrated`` does not (Kabalan et al. 2016, Eq. 11-16).

The Seyfried bottleneck with a large crowd under each preset and the runner's stall rule
(:class:`~crowd_env.experiments.running.runner.StallDetector`): :func:`stall_run` runs one (optionally with a
snapshot of the crowd, its desired directions e_d, Eq. 13, and social forces, Eq. 16), :func:`run_jobs`
runs many in worker processes, :func:`figure` draws a `paper` snapshot beside the `calibrated` one.
The mechanism it shows is told in ``crowd-stall-study --help``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from crowd_env.files import save_figure_atomic
from ...walking.presets import get_preset
from ...scenarios import make_scenario
from ...walking.agent import SocialForceAgent
from ..running.backends import make_backend, run_all
from ..running.runner import run_scenario

__all__ = ["stall_run", "stall_jobs", "run_jobs", "figure"]


def stall_run(job: dict) -> dict:
    """One run of ``job`` (``preset``, ``width_m``, ``n``, ``seed``, ``corridor_width_m``, ``max_time_s``, and
    optionally ``changes``: ModelParams fields on top of the preset); with
    ``snapshot_s`` also the state at that simulated time (or at the end, if earlier): positions, e_d
    (Eq. 13), the social force (Eq. 16), the agent's intent u_int (with vision: v e(α*)) and the speeds of the
    pedestrians left."""
    preset = get_preset(job["preset"])
    scenario = make_scenario("seyfried_bottleneck", width_m=job["width_m"], n_pedestrians=job["n"], seed=job["seed"],
                             corridor_width_m=job["corridor_width_m"],
                             navigation_clearance_m=preset.navigation_clearance_m, radius_m=preset.radius_m)
    agent = SocialForceAgent(scenario.navigation())
    snap = {}
    t_snap = job.get("snapshot_s")

    def capture(sim):
        if t_snap is not None and "position_m" not in snap and sim.time_s >= t_snap - 1e-9:
            snap.update(_snapshot(agent, sim))
        snap["last"] = sim

    # The snapshot reads the state after every step: the run goes step by step then (compiled chunks
    # would pass the snapshot time).
    r = run_scenario(scenario, agent, preset.params(**job.get("changes", {})), max_time_s=job["max_time_s"],
                     progress=capture, compiled=t_snap is None)
    if t_snap is not None and "position_m" not in snap:  # the run ended first: its last state
        snap.update(_snapshot(agent, snap["last"]))
    snap.pop("last", None)
    return {**job, "complete": r.complete, "stalled": r.stalled, "stall_time_s": r.stall_time_s,
            "n_passed": r.n_passed, "specific_flow_per_m_s": r.specific_flow_per_m_s, "min_gap_m": r.min_gap_m,
            "time_s": r.simulated_time_s, "snapshot": snap or None,
            "outline_m": np.asarray(scenario.geometry.walkable_area.exterior.coords)}


def _snapshot(agent, sim) -> dict:
    """The state of the pedestrians left in ``sim``: positions, e_d (Eq. 13), the social force on them (Eq. 16),
    their speeds and ``agent``'s intents (empty arrays when nobody is left)."""
    idx = sim.active_index
    if idx.size == 0:
        return {"time_s": sim.time_s, "position_m": np.zeros((0, 2)), "e_d": np.zeros((0, 2)),
                "force_n": np.zeros((0, 2)), "speed_m_s": np.zeros(0), "intent_m_s": np.zeros((0, 2))}
    e_d = agent.desired_direction(sim, idx)
    return {"time_s": sim.time_s, "position_m": sim.state.position_m[idx].copy(), "e_d": e_d,
            "force_n": agent.social_force(sim, e_d), "speed_m_s": np.linalg.norm(sim.state.velocity_m_s[idx], axis=1),
            "intent_m_s": agent(sim)[0][idx]}


def stall_jobs(presets, width_m: float, n: int, corridor_width_m: float, seeds: int, max_time_s: float,
               changes: dict | None = None) -> list:
    """One job per preset and seed 0..seeds-1 (the job dicts of :func:`stall_run`); ``changes``: ModelParams
    fields on top of every preset."""
    base = {"width_m": width_m, "n": n, "corridor_width_m": corridor_width_m, "max_time_s": max_time_s,
            "changes": dict(changes or {})}
    return [dict(base, preset=p, seed=s) for p in presets for s in range(seeds)]


def run_jobs(jobs: list, workers: int) -> list:
    """:func:`stall_run` of every job on ``workers`` processes (the project's one executor,
    :mod:`crowd_env.experiments.running.backends`; serial for one worker); the rows in the order of ``jobs``."""
    with make_backend("process" if workers > 1 else "serial", jobs=workers) as backend:
        return run_all(jobs, backend, stall_run)


def figure(stalled: dict, reference: dict, path: Path, title: str | None = None) -> Path:
    """The crowd in front of the entrance in two snapshots (:func:`stall_run` with ``snapshot_s``), side by
    side: each pedestrian with e_d, the social force on it and its intent u_int, those at < 5 cm/s in red.
    ``stalled`` is the stalled run (any preset), ``reference`` the comparison (`calibrated`'s, same seed and
    time); ``title`` the figure's (default: the point-field reading of the `paper` preset's stall)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 5.4), sharey=True)
    for ax, run in zip(axes, (stalled, reference)):
        snap = run["snapshot"]
        ax.plot(run["outline_m"][:, 0], run["outline_m"][:, 1], "k-", lw=1.5)
        p, e, f, v = snap["position_m"], snap["e_d"], snap["force_n"], snap["speed_m_s"]
        still = v < 0.05
        for k in range(p.shape[0]):
            ax.add_patch(plt.Circle(p[k], 0.23, fc="tab:red" if still[k] else "tab:blue", ec="k", lw=0.4, alpha=0.55))
        ax.quiver(p[:, 0], p[:, 1], e[:, 0], e[:, 1], color="k", scale=18, width=0.004, label="e_d (Eq. 13)")
        ax.quiver(p[:, 0], p[:, 1], f[:, 0], f[:, 1], color="tab:orange", scale=4000, width=0.004,
                  label="social force (Eq. 16)")
        u = snap.get("intent_m_s")
        if u is not None:
            ax.quiver(p[:, 0], p[:, 1], u[:, 0], u[:, 1], color="tab:green", scale=18, width=0.004,
                      label="intent u_int (m/s)")
        ax.set_xlim(-4.5, 1.5)
        ax.set_ylim(-2.2, 2.2)
        ax.set_aspect("equal")
        state = "stalled" if run["stalled"] else ("complete" if run["complete"] else "incomplete")
        ax.set_title(f"preset {run['preset']}, seed {run['seed']}: t = {snap['time_s']:.1f} s ({state}; "
                     f"{int(still.sum())} of {p.shape[0]} at < 5 cm/s, red)", fontsize=9)
        ax.set_xlabel("x (m)")
    axes[0].set_ylabel("y (m)")
    axes[0].legend(loc="lower left", fontsize=8)
    fig.suptitle(title or f"b = {stalled['width_m']:g} m, N = {stalled['n']}: the point field aims everyone beside the "
                 f"opening at its corners (left); the configuration-space field aims past them (right)", fontsize=10)
    fig.tight_layout()
    save_figure_atomic(fig, path, dpi=130)
    plt.close(fig)
    return path
