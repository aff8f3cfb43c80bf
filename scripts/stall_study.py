"""Why the `paper` preset clogs for good under pressure, and the `calibrated` preset does not.

Runs the Seyfried bottleneck with a large crowd (default b = 1.0 m, N = 180, seeds 0-5) under each
preset with the runner's stall rule (:class:`crowd_env.runner.StallDetector`), prints one row per run
(complete / stalled, when, passages, J_s of complete runs only, smallest gap) and draws
``OUT/stall_mechanism.png``: the crowd in front of the entrance at the moment the first `paper` run
stalls, beside the `calibrated` run of the same seed at the same time, each pedestrian with its
desired direction e_d (Eq. 13) and the social force on it (Eq. 16).

The mechanism it shows: with the point eikonal field (Eq. 11-13 solved for points, preset `paper`),
e_d of everyone beside the opening points at the corner vertex, which a disk centre can never reach,
so the pedestrians on both sides of the entrance drive themselves into the two corners. With the
isotropic social force (λ = 1) each of them is also pushed sideways by the neighbour between them and
forward by the crowd behind (the push is transmitted through the whole jam), and frictionless disks
pressed into two corners by forces whose resultant points into the corner form an arch that nothing in
the model breaks: the driving force of the arch's members has no component that frees them. With the
configuration-space field (walls inflated by the radius, preset `calibrated`) e_d beside the opening
points past the corner into the channel, and with λ < 1 the crowd behind does not push its front rows
into the corners: no arch holds.

Example::

    python scripts/stall_study.py --out out/stalls
"""
from __future__ import annotations

import argparse
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np


def _run(job: dict) -> dict:
    """One run; with ``snapshot_s`` also the state at that simulated time (or at the end, if earlier)."""
    from baselines.social_force import SocialForceAgent
    from crowd_env.core.presets import get_preset
    from crowd_env.runner import run_scenario
    from crowd_env.scenarios import make_scenario

    preset = get_preset(job["preset"])
    scenario = make_scenario("seyfried_bottleneck", width_m=job["width_m"], n_pedestrians=job["n"], seed=job["seed"],
                             corridor_width_m=job["corridor_width_m"],
                             navigation_clearance_m=preset.navigation_clearance_m)
    agent = SocialForceAgent(scenario.navigation())
    snap = {}
    t_snap = job.get("snapshot_s")

    def capture(sim):
        if t_snap is not None and "position_m" not in snap and sim.time_s >= t_snap - 1e-9:
            idx = sim.active_index
            e_d = agent.desired_direction(sim, idx)
            snap.update(time_s=sim.time_s, position_m=sim.state.position_m[idx].copy(), e_d=e_d,
                        force_n=agent.social_force(sim, e_d), speed_m_s=np.linalg.norm(sim.state.velocity_m_s[idx], axis=1))
        snap["last"] = sim

    r = run_scenario(scenario, agent, preset.params(), max_time_s=job["max_time_s"], progress=capture)
    if t_snap is not None and "position_m" not in snap:  # the run ended first: its last state
        sim = snap["last"]
        idx = sim.active_index
        e_d = agent.desired_direction(sim, idx) if idx.size else np.zeros((0, 2))
        snap.update(time_s=sim.time_s, position_m=sim.state.position_m[idx].copy(), e_d=e_d,
                    force_n=agent.social_force(sim, e_d) if idx.size else np.zeros((0, 2)),
                    speed_m_s=np.linalg.norm(sim.state.velocity_m_s[idx], axis=1))
    snap.pop("last", None)
    return {**job, "complete": r.complete, "stalled": r.stalled, "stall_time_s": r.stall_time_s,
            "n_passed": r.n_passed, "specific_flow_per_m_s": r.specific_flow_per_m_s, "min_gap_m": r.min_gap_m,
            "time_s": r.simulated_time_s, "snapshot": snap or None,
            "outline_m": np.asarray(scenario.geometry.walkable_area.exterior.coords)}


def figure(paper: dict, calibrated: dict, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 5.4), sharey=True)
    for ax, run in zip(axes, (paper, calibrated)):
        snap = run["snapshot"]
        ax.plot(run["outline_m"][:, 0], run["outline_m"][:, 1], "k-", lw=1.5)
        p, e, f, v = snap["position_m"], snap["e_d"], snap["force_n"], snap["speed_m_s"]
        still = v < 0.05
        for k in range(p.shape[0]):
            ax.add_patch(plt.Circle(p[k], 0.23, fc="tab:red" if still[k] else "tab:blue", ec="k", lw=0.4, alpha=0.55))
        ax.quiver(p[:, 0], p[:, 1], e[:, 0], e[:, 1], color="k", scale=18, width=0.004, label="e_d (Eq. 13)")
        ax.quiver(p[:, 0], p[:, 1], f[:, 0], f[:, 1], color="tab:orange", scale=4000, width=0.004,
                  label="social force (Eq. 16)")
        ax.set_xlim(-4.5, 1.5)
        ax.set_ylim(-2.2, 2.2)
        ax.set_aspect("equal")
        state = "stalled" if run["stalled"] else ("complete" if run["complete"] else "incomplete")
        ax.set_title(f"preset {run['preset']}, seed {run['seed']}: t = {snap['time_s']:.1f} s ({state}; "
                     f"{int(still.sum())} of {p.shape[0]} at < 5 cm/s, red)", fontsize=9)
        ax.set_xlabel("x (m)")
    axes[0].set_ylabel("y (m)")
    axes[0].legend(loc="lower left", fontsize=8)
    fig.suptitle(f"b = {paper['width_m']:g} m, N = {paper['n']}: the point field aims everyone beside the opening at "
                 f"its corners (left); the configuration-space field aims past them (right)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--presets", nargs="+", default=["paper", "calibrated"])
    ap.add_argument("--width", type=float, default=1.0, help="bottleneck width b (m)")
    ap.add_argument("--n", type=int, default=180, help="crowd size N")
    ap.add_argument("--corridor-width", type=float, default=4.0)
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--max-time", type=float, default=300.0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path("out/stalls"))
    args = ap.parse_args(argv)
    from crowd_env.core.presets import get_preset

    for name in args.presets:
        get_preset(name)  # unknown names fail here, naming the known ones
    base = {"width_m": args.width, "n": args.n, "corridor_width_m": args.corridor_width, "max_time_s": args.max_time}
    jobs = [dict(base, preset=p, seed=s) for p in args.presets for s in range(args.seeds)]
    with ProcessPoolExecutor(args.jobs) as pool:
        rows = list(pool.map(_run, jobs))
    print(f"b = {args.width:g} m, N = {args.n}, corridor {args.corridor_width:g} m; stall rule: no passage for "
          f"20 s while the mean speed of those left is < 0.05 m/s")
    print(f"{'preset':>12} {'seed':>4} {'result':>10} {'at (s)':>7} {'passed':>7} {'J_s':>6} {'min gap (m)':>12}")
    for r in rows:
        result = "stalled" if r["stalled"] else ("complete" if r["complete"] else "time limit")
        js = f"{r['specific_flow_per_m_s']:.3f}" if r["complete"] else "-"
        at = f"{r['stall_time_s']:.1f}" if r["stalled"] else f"{r['time_s']:.1f}"
        print(f"{r['preset']:>12} {r['seed']:>4} {result:>10} {at:>7} {r['n_passed']:>7} {js:>6} {r['min_gap_m']:>12.2e}")
    for p in args.presets:
        sub = [r for r in rows if r["preset"] == p]
        print(f"{p}: {sum(r['stalled'] for r in sub)} of {len(sub)} stalled, {sum(r['complete'] for r in sub)} complete")
    stalled = [r for r in rows if r["stalled"] and r["preset"] == "paper"]
    if stalled and "calibrated" in args.presets:
        first = stalled[0]
        t = first["stall_time_s"]
        with ProcessPoolExecutor(min(2, args.jobs)) as pool:
            pair = list(pool.map(_run, [dict(base, preset=p, seed=first["seed"], snapshot_s=t)
                                        for p in ("paper", "calibrated")]))
        args.out.mkdir(parents=True, exist_ok=True)
        print(f"figure: {figure(pair[0], pair[1], args.out / 'stall_mechanism.png')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
