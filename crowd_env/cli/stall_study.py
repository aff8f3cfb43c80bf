"""Why the `paper` preset clogs for good under pressure, and the `calibrated` preset does not.

Runs the Seyfried bottleneck with a large crowd (default b = 1.0 m, N = 180, seeds 0-5) under each
preset with the runner's stall rule (:class:`crowd_env.experiments.running.runner.StallDetector`), prints one row per run
(complete / stalled, when, passages, J_s of complete runs only, smallest gap) and draws
``OUT/stall_mechanism.png``: the crowd in front of the entrance at the moment the first `paper` run
stalls (or the first run of the first other preset of ``--presets`` that stalls), beside the `calibrated` run
of the same seed at the same time, each pedestrian with its
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

Examples::

    crowd-stall-study --out out/stalls
    crowd-stall-study --presets vision calibrated --width 0.8 --n 20 --seeds 20 --set vision_right_of_way=false
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..walking.presets import get_preset
from ..experiments.validation.stall_study import figure, run_jobs, stall_jobs
from .options import add_key_values, key_values


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="crowd-stall-study", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--presets", nargs="+", default=["paper", "calibrated"])
    ap.add_argument("--width", type=float, default=1.0, help="bottleneck width b (m)")
    ap.add_argument("--n", type=int, default=180, help="crowd size N")
    ap.add_argument("--corridor-width", type=float, default=4.0)
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--max-time", type=float, default=300.0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path("out/stalls"))
    add_key_values(ap, "--set",
                   "ModelParams fields on top of every preset (values as JSON: numbers, true, false, null)")
    return ap


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    changes = key_values(args.set, "--set expects NAME=VALUE")
    for name in args.presets:
        get_preset(name).params(**changes)  # unknown presets or parameters fail here, naming them
    rows = run_jobs(stall_jobs(args.presets, args.width, args.n, args.corridor_width, args.seeds, args.max_time,
                               changes), args.jobs)
    print(f"b = {args.width:g} m, N = {args.n}, corridor {args.corridor_width:g} m; stall rule: no passage for "
          f"20 s while those left get nowhere (mean net displacement < 0.05 m/s x 20 s)")
    print(f"{'preset':>12} {'seed':>4} {'result':>10} {'at (s)':>7} {'passed':>7} {'J_s':>6} {'min gap (m)':>12}")
    for r in rows:
        result = "stalled" if r["stalled"] else ("complete" if r["complete"] else "time limit")
        js = f"{r['specific_flow_per_m_s']:.3f}" if r["complete"] else "-"
        at = f"{r['stall_time_s']:.1f}" if r["stalled"] else f"{r['time_s']:.1f}"
        print(f"{r['preset']:>12} {r['seed']:>4} {result:>10} {at:>7} {r['n_passed']:>7} {js:>6} {r['min_gap_m']:>12.2e}")
    for p in args.presets:
        sub = [r for r in rows if r["preset"] == p]
        print(f"{p}: {sum(r['stalled'] for r in sub)} of {len(sub)} stalled, {sum(r['complete'] for r in sub)} complete")
    stalled = [r for p in args.presets if p != "calibrated" for r in rows if r["stalled"] and r["preset"] == p]
    if stalled and "calibrated" in args.presets:
        first = stalled[0]  # the first stall of the first preset (in --presets order) that stalls
        t = first["stall_time_s"]
        pair = run_jobs([dict(job, seed=first["seed"], snapshot_s=t)
                         for job in stall_jobs((first["preset"], "calibrated"), args.width, args.n,
                                               args.corridor_width, 1, args.max_time, changes)], min(2, args.jobs))
        args.out.mkdir(parents=True, exist_ok=True)
        title = None if first["preset"] == "paper" else (
            f"b = {args.width:g} m, N = {args.n}: preset {first['preset']} stalled (left), calibrated at the same "
            f"time of the same seed (right)")
        print(f"figure: {figure(pair[0], pair[1], args.out / 'stall_mechanism.png', title)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
