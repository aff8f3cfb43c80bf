#!/usr/bin/env python
"""Where an environment step's time goes, per part, in thread CPU time: a deterministic A/B measure.

One PettingZoo environment (Seyfried bottleneck, b = 1 m, every pedestrian controlled, ``frame_skip=1``, the
calibrated agent's intents as actions) is stepped 30 times, then copied 40 times; each copy runs 100 steps
and the parts are timed with ``time.thread_time`` (the simulator step, the observation pass, the reward, the
action check, and the whole ``env.step``). Each figure is the minimum over the 40 copies of the mean per
step, so another load on the machine changes it little (the copies replay the same 100 steps).

``--against PATH`` runs the same measure on another checkout of crowd_env (``PYTHONPATH=PATH``, e.g. a
``git worktree`` of an older commit) alternately with this one, ``--rounds`` times, and prints both and their
ratio: how issue 38's "no slower than before" was measured. ``--terms`` runs this checkout with
``reward_terms_in_infos=True`` (each agent's reward terms in its info; off by default): the price of that
option. ``--heading desired_direction`` steps the environment with ``heading_target="desired_direction"`` (θ_d
from e_d every sub-step, :func:`crowd_env.walking.agent.facing_headings`) instead of the intent's angle. ``--vector``
adds the vector environment (``workers=1``, 8 copies, vector_speed.py's speed rule) per
copy and step, column ``vec``.

    python benchmarks/env_step_parts.py --n 10 100
    git worktree add /tmp/old 587852c && python benchmarks/env_step_parts.py --against /tmp/old --rounds 3 --vector
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

PARTS = ("step", "sim", "obs", "reward", "actions")


def measure(n: int, copies: int = 40, steps: int = 100, terms_in_infos: bool = False, heading: str = "intent") -> dict:
    """Per-step thread time (µs) of each of :data:`PARTS` for N = ``n``: the minimum over ``copies``;
    ``terms_in_infos`` True: the environment option ``reward_terms_in_infos=True``; ``heading``: its
    ``heading_target``."""
    import copy
    import time

    from crowd_env.envs import crowd_v0
    from crowd_env.walking.agent import SocialForceAgent
    from timing import time_calls

    env = crowd_v0.parallel_env(scenario="seyfried_bottleneck", scenario_options={"n_pedestrians": n, "width_m": 1.0},
                                controlled="all", frame_skip=1, max_steps=10**9, action_max_m_s=50.0,
                                heading_target=heading, **_terms_option(terms_in_infos))
    env.reset(seed=0)

    def act(e, agent):
        intents, _ = agent(e.sim)
        return {a: intents[j] for a, j in zip(e.agents, e._agent_index)}

    agent = SocialForceAgent(env.navigation)
    for _ in range(30):
        env.step(act(env, agent))

    best = {}
    for _ in range(copies):
        e = copy.deepcopy(env)
        a = SocialForceAgent(e.navigation)
        acc = {p: [0.0] for p in PARTS}
        time_calls(e.sim, "step", acc["sim"], time.thread_time)
        time_calls(e._observer, "observe", acc["obs"], time.thread_time)
        time_calls(e, "_rewards", acc["reward"], time.thread_time)
        time_calls(e, "_actions_array", acc["actions"], time.thread_time)
        for _ in range(steps):
            actions = act(e, a)
            t = time.thread_time()
            e.step(actions)
            acc["step"][0] += time.thread_time() - t
        for p in PARTS:
            best[p] = min(best.get(p, float("inf")), acc[p][0] / steps * 1e6)
    return best


def _terms_option(terms_in_infos: bool) -> dict:
    """The option only when asked for (a checkout from before the option does not know it)."""
    return {"reward_terms_in_infos": True} if terms_in_infos else {}


def measure_vector(n: int, copies: int = 8, repeats: int = 12, steps: int = 100, terms_in_infos: bool = False) -> dict:
    """Thread time (µs) per copy and step of the vector environment (``workers=1``, ``copies`` copies of the
    same environment, seeds 0 … copies−1, 30 steps in first), stepped with vector_speed.py's speed rule:
    the minimum over ``repeats`` runs, each a new vector environment replaying the same 100 steps
    (``terms_in_infos``: as in :func:`measure`)."""
    import time

    from crowd_env.envs.vector import vector_env
    from vector_speed import _options, act

    best = float("inf")
    for _ in range(repeats):
        vec = vector_env(copies, workers=1, **_options(n), **_terms_option(terms_in_infos))
        try:
            obs, _ = vec.reset(seed=0)
            layout = vec.envs[0].observation_layout
            total = 0.0
            for s in range(30 + steps):
                actions = act(obs, layout, "speed")
                t = time.thread_time()
                obs, *_ = vec.step(actions)
                if s >= 30:
                    total += time.thread_time() - t
        finally:
            vec.close()
        best = min(best, total / steps / copies * 1e6)
    return {"vec": best}


def _run(path: str | None, n: int, terms: bool = False, vector: bool = False, heading: str = "intent") -> dict:
    env = dict(os.environ)
    if path:
        env["PYTHONPATH"] = path
    cmd = [sys.executable, __file__, "--json", "--n", str(n), "--heading", heading] + (["--terms"] if terms else []) + \
        (["--vector"] if vector else [])
    out = subprocess.run(cmd, env=env, cwd=path or os.getcwd(),
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, nargs="+", default=[10, 100], help="crowd sizes (default 10 100)")
    ap.add_argument("--against", default=None, metavar="PATH", help="another checkout to compare with, alternately")
    ap.add_argument("--rounds", type=int, default=2, help="alternations with --against (default 2)")
    ap.add_argument("--terms", action="store_true", help="this checkout with reward_terms_in_infos=True (each "
                    "agent's reward terms in its info; what that option costs)")
    ap.add_argument("--vector", action="store_true", help="also the vector environment (workers=1, 8 copies): "
                    "thread time per copy and step, column 'vec'")
    ap.add_argument("--heading", choices=["intent", "desired_direction"], default="intent",
                    help="the environment's heading_target (default intent)")
    ap.add_argument("--json", action="store_true", help=argparse.SUPPRESS)  # one measure, as JSON (the child)
    args = ap.parse_args(argv)
    if args.json:
        out = measure(args.n[0], terms_in_infos=args.terms, heading=args.heading)
        print(json.dumps({**out, **(measure_vector(args.n[0], terms_in_infos=args.terms) if args.vector else {})}))
        return 0
    parts = PARTS + (("vec",) if args.vector else ())
    head = " ".join(f"{p:>8}" for p in parts)
    for n in args.n:
        if not args.against:
            m = _run(None, n, args.terms, args.vector, args.heading)
            print(f"N = {n:4d}  µs/step: {head}\n{'':13}{' '.join(f'{m[p]:8.1f}' for p in parts)}")
            continue
        runs = {"this": [], "other": []}
        for _ in range(args.rounds):
            runs["other"].append(_run(os.path.abspath(args.against), n, vector=args.vector, heading=args.heading))
            runs["this"].append(_run(None, n, args.terms, args.vector, args.heading))
        this = {p: min(r[p] for r in runs["this"]) for p in parts}
        other = {p: min(r[p] for r in runs["other"]) for p in parts}
        print(f"N = {n:4d}  µs/step       {head}")
        print(f"{'':8}{args.against:>12.12} {' '.join(f'{other[p]:8.1f}' for p in parts)}")
        print(f"{'':8}{'this, terms' if args.terms else 'this':>12} {' '.join(f'{this[p]:8.1f}' for p in parts)}")
        print(f"{'':8}{'this/other':>12} {' '.join(f'{this[p] / other[p]:8.2f}' for p in parts)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
