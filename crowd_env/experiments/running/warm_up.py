"""A cold start on two cores: the compiled rollout's kernels compiled in two processes at once.

On a machine where numba has not cached crowd_env's kernels yet, the first run of the compiled rollout
(:func:`~crowd_env.experiments.running.rollout.rollout_steps`) compiles about 136 functions, one after the
other, in one process (``benchmarks/compile_profile.py``): the core's step
(:func:`~crowd_env.core.step.advance`, its impact and projection solvers) is about 70 % of it, the walking model
and the measurements most of the rest. Numba keeps every compiled kernel in its on-disk cache, and a kernel
compiled in one process is loaded, not compiled again, by another that needs it with the same argument
types: :func:`compile_in_parallel` starts a helper process that compiles the core's step (one fused
:meth:`~crowd_env.core.simulator.Simulator.step` of a small bottleneck, which types ``advance`` exactly as the
rollout does), compiles the walking model meanwhile in this process (one decision of the calibrated agent), and
waits for the helper; the rollout then compiles only its own body. Nothing is run twice and the results do not
change (the cache holds the same machine code a serial compilation makes); when the rollout is cached already,
it returns at once. ``python benchmarks/compile_profile.py`` shows the compilation a cold run needs.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import asdict

import numpy as np

from ...core.params import ModelParams
from ...walking.agent import SocialForceAgent
from .rollout import rollout_steps

__all__ = ["rollout_cached", "compile_in_parallel"]


def rollout_cached() -> bool:
    """Whether numba's on-disk cache holds a compiled rollout for the current source (False when it cannot
    tell)."""
    try:
        return bool(rollout_steps._cache._cache_file._load_index())
    except Exception:  # numba's cache layout is not public API: when it changes, compile as if cold
        return False


def _small_simulator(params: ModelParams):
    from ...scenarios import make_scenario

    scenario = make_scenario("seyfried_bottleneck", n_pedestrians=20, width_m=1.0, seed=0)
    return scenario, scenario.make_simulator(params=params)


def compile_core(params: ModelParams) -> None:
    """Compile (or load) the core's one fused step: a step of a small bottleneck."""
    _, sim = _small_simulator(params)
    sim.step(np.zeros((sim.state.n, 2)))


def compile_walking(params: ModelParams) -> None:
    """Compile (or load) the calibrated agent's decision: one decision on a small bottleneck."""
    scenario, sim = _small_simulator(params)
    SocialForceAgent(scenario.navigation())(sim)


def compile_in_parallel(params: ModelParams | None = None) -> bool:
    """On a cold cache and a machine with two cores or more, compile the core's step in a helper process and the
    walking model here at the same time (module docstring); returns whether it did. A helper that fails is
    ignored: the run then compiles what is missing itself, as it would have without this."""
    params = params or ModelParams()
    if rollout_cached() or (os.cpu_count() or 1) < 2:
        return False
    code = ("import json, sys; from crowd_env.core.params import ModelParams; "
            "from crowd_env.experiments.running.warm_up import compile_core; "
            "compile_core(ModelParams.from_dict(json.loads(sys.argv[1])))")
    env = {**os.environ, "CROWD_ENV_QUIET": "1"}
    try:
        helper = subprocess.Popen([sys.executable, "-c", code, json.dumps(asdict(params))], env=env,
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    except OSError:
        return False
    try:
        compile_walking(params)
    finally:
        helper.wait()
    return True
