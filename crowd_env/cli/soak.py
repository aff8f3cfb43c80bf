"""Soak test: many agent-steps over every registered scenario with random and adversarial actions.

Every registered scenario (aliases once; :func:`crowd_env.experiments.validation.soak.distinct_scenarios`) runs through
the PettingZoo parallel environment with every pedestrian controlled (even episodes) or half of them
(odd episodes; the others follow the calibrated baseline), under each action mode:

- ``random``: uniform intents in the action Box;
- ``toward_neighbour``: every learner pushes at maximum intent toward its nearest neighbour;
- ``toward_wall``: every learner pushes at maximum intent toward the nearest wall.

Scenarios whose factory requires options (the user polygon) get them from ``--scenario-options`` or
``crowd_env.experiments.validation.soak.EXAMPLE_OPTIONS``; any still missing is skipped and listed.

Then the high-pressure phase (:func:`crowd_env.experiments.validation.soak.pressure_soak`, ``--pressure-agent-steps``,
by default as many as ``--agent-steps``; 0 skips it): hundreds of pedestrians on the calibrated baseline
agent pressing into a door, :data:`crowd_env.experiments.validation.soak.PRESSURE_CASES`: a widened Seyfried bottleneck
(corridor 7 m, channel 4 m; N = 220 at b = 1.0 m with the ``paper`` preset, N = 250 at b = 0.9 m with
desired speeds doubled) and a room packed at 3 /m² (N = 300, 1.0 m door, ``paper``; N = 400, 0.8 m door,
doubled speeds), episodes of 20 s with seeds ``--seed``, ``--seed`` + 1, ... It prints the largest
impact cluster and the largest group of pedestrians joined by contacts that carried a percussion.

After every simulator step :class:`crowd_env.experiments.validation.soak.InvariantChecker` checks overlaps (pairs and
walls, tolerance 1e-3 m), centres inside the walkable area, kinetic energy across the impact and the
projection stages, and finite state. Memory (RSS, and tracemalloc with ``--tracemalloc``) is sampled
at every episode end; the growth after the first quarter of the run, fitted by least squares, must stay
below ``--memory-tolerance-mib`` over the fitted window. The budget of agent-steps (live agents summed
over environment steps) is split evenly over (scenario, mode) pairs.

Exit status: 0 when nothing was violated, 1 otherwise. Example (about 10⁶ agent-steps in each phase)::

    nice -n 5 crowd-soak --agent-steps 1000000

or the high-pressure phase alone: ``--agent-steps 0 --pressure-agent-steps 8000000``.
"""
from __future__ import annotations

import argparse
import json
import sys

from crowd_env.files import write_json_atomic
from ..experiments.validation.soak import DEFAULT_AGENT_STEPS, PRESSURE_CASES, SoakError, soak


def format_summary(r: dict) -> str:
    m = r["memory"]
    lines = [
        f"environment phase: agent-steps {r['agent_steps']}, environment steps {r['env_steps']}; "
        f"simulator steps checked {r['sim_steps']}, "
        f"episodes {r['episodes']}; wall time {r['wall_s']:.0f} s in all",
        f"scenarios {r['scenarios']}" + (f", skipped {r['skipped_scenarios']}" if r["skipped_scenarios"] else "")
        + f"; modes {r['modes']}",
        f"violations: {r['violations'] or 'none'}",
        f"max overlap {r['max_overlap_m']:.3g} m (walls {r['max_wall_overlap_m']:.3g} m; tolerance "
        f"{r['overlap_tolerance_m']:g} m)",
        f"simulator steps with impacts {r['impact_steps']} (largest impact cluster {r['max_cluster_size']} "
        f"pedestrians, {r['environment_max_cluster_size']} in the environment phase; largest group joined by "
        f"contacts carrying a percussion {r['max_contact_group']}, {r['environment_max_contact_group']} in the "
        f"environment phase)",
        f"max KE change across impacts {r['max_impact_energy_increase_j']:+.3g} J "
        f"(relative {r['max_impact_energy_increase_rel']:+.3g}); across the projection "
        f"{r['max_projection_energy_increase_j']:+.3g} J",
        f"memory: RSS {m['rss_start_mib']:.1f} -> {m['rss_end_mib']:.1f} MiB, slope "
        f"{m['rss_slope_kib_per_1000_agent_steps']:.3g} KiB / 1000 agent-steps"
        + (f"; traced {m['traced_start_mib']:.1f} -> {m['traced_end_mib']:.1f} MiB, slope "
           f"{m['traced_slope_kib_per_1000_agent_steps']:.3g} KiB / 1000 agent-steps" if m["traced_end_mib"] is not None
           else "")
        + f"; growth over the last {m['fit_window_agent_steps']:.0f} agent-steps "
        f"{m['growth_over_window_mib'][m['judged_on']]:.3g} MiB ({m['judged_on']}, tolerance {m['tolerance_mib']} MiB)",
    ]
    p = r.get("pressure")
    if p:
        lines.append(f"pressure phase ({', '.join(p['cases'])}): {p['agent_steps']} agent-steps, {p['sim_steps']} "
                     f"simulator steps, largest impact cluster {p['max_cluster_size']}, largest contact group "
                     f"{p['max_contact_group']}, max overlap {p['max_overlap_m']:.3g} m, violations "
                     f"{p['violations'] or 'none'} ({p['wall_s']:.0f} s)")
    lines += [f"  {e}" for e in r["examples"]]
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="crowd-soak", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--agent-steps", type=int, default=DEFAULT_AGENT_STEPS,
                    help="total agent-steps of the environment phase (all scenarios; 0: skip it)")
    ap.add_argument("--pressure-agent-steps", type=int, default=None,
                    help="agent-steps of the high-pressure phase (default: as many as --agent-steps; 0: skip it)")
    ap.add_argument("--pressure-cases", nargs="+", default=None,
                    help="bottleneck_paper, bottleneck_push, room_paper, room_push (default: all)")
    ap.add_argument("--scenarios", nargs="+", default=None, help="default: every registered scenario")
    ap.add_argument("--modes", nargs="+", default=None, help="random, toward_neighbour, toward_wall (default: all)")
    ap.add_argument("--scenario-options", type=json.loads, default=None, metavar="JSON",
                    help='per-scenario options, e.g. \'{"seyfried_bottleneck": {"n_pedestrians": 40}}\'')
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--max-steps", type=int, default=200, help="environment steps per episode")
    ap.add_argument("--frame-skip", type=int, default=1, help="simulator steps per environment step")
    ap.add_argument("--fixed-start", action="store_true",
                    help="pin the scenarios' seed option (same start positions, no scenario rebuilt per reset)")
    ap.add_argument("--tracemalloc", action="store_true", help="also trace Python/numpy allocations (slower)")
    ap.add_argument("--memory-tolerance-mib", type=float, default=16.0,
                    help="largest memory growth accepted over the fitted window (after the first quarter)")
    ap.add_argument("--overlap-tolerance-m", type=float, default=1e-3,
                    help="largest overlap accepted (a negative value flags every step: checks the checker)")
    ap.add_argument("--json", default=None, help="write the summary here as JSON")
    args = ap.parse_args(argv)
    pressure = args.agent_steps if args.pressure_agent_steps is None else args.pressure_agent_steps
    if args.agent_steps < 0 or pressure < 0 or args.agent_steps + pressure < 1:
        raise SystemExit("error: --agent-steps and --pressure-agent-steps must be >= 0, one of them >= 1")
    known = [c.name for c in PRESSURE_CASES]
    unknown = sorted(set(args.pressure_cases or ()) - set(known))
    if unknown:
        raise SystemExit(f"error: unknown pressure case(s) {unknown}; known: {known}")
    try:
        r = soak(args.agent_steps, scenarios=args.scenarios, modes=args.modes, seed=args.seed,
                 max_steps=args.max_steps, frame_skip=args.frame_skip, fixed_start=args.fixed_start,
                 trace_memory=args.tracemalloc, memory_tolerance_mib=args.memory_tolerance_mib,
                 overlap_tolerance_m=args.overlap_tolerance_m, scenario_options=args.scenario_options,
                 pressure_agent_steps=pressure, pressure_cases=args.pressure_cases,
                 progress=lambda s: print(s, flush=True))
    except SoakError as exc:
        raise SystemExit(f"error: {exc}") from None
    print(format_summary(r))
    if args.json:
        write_json_atomic(args.json, r, indent=2, default=float)
    return 0 if r["n_violations"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
