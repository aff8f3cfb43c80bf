"""Evaluation harness: run any policy through the same scenarios and seeds and report the same metrics.

A policy is an object with ``act(env, observations) -> {agent: (2,) intent}`` and optionally
``reset(env, seed)``, ``name`` and ``env_overrides`` (environment options it needs); the harness never
imports one. Specs that are not policy objects are turned into policies by ``resolve(spec, name=...)``
(e.g. ``baselines.reference_policies.as_policy``, which knows ``"baseline"``, ``"random"``, ``"zero"``,
saved SB3 models and callables), or, without ``resolve``, from an import path ``"module:attribute"``
(:func:`import_object`; a class or factory is called without arguments). This is how the shipped
baselines and users' own policies are plugged in.

Each episode runs the parallel environment (every pedestrian controlled by the policy by default)
for at most ``max_time_s`` of simulated time, measuring at every simulator step (through the
environment's ``substep_hooks``) with the runner's own measurement,
:func:`~crowd_env.experiments.running.rollout.measure_step` (passages, densities, the smallest gap, the last
exit, the stall rule), so that an episode is measured as :func:`~crowd_env.experiments.running.runner.run_scenario`
measures a run. When only some pedestrians are agents, the episode goes on after the
last agent has left until the whole crowd has (``CrowdParallelEnv.step_background``), so that the crowd's
measures below cover everybody whatever the agents did:

- ``specific_flow_per_m_s`` J_s = N / (Δt b) at the scenario's measurement line (Kabalan Eq. 22;
  NaN with fewer than two passages or no width in the scenario metadata, and NaN unless the episode is
  ``complete``); the line is ``line``, by default the scenario's
  (:attr:`Scenario.measurement <crowd_env.scenarios.Scenario.measurement>`: "bottleneck" of the Seyfried
  bottleneck, "door" of ``room_pillar``, "middle" of ``corridor_bidirectional``, else the geometry's first line),
  and none (NaN) without one; ``flow_per_s`` likewise;
- ``complete``: nobody remains at the end (each pedestrian crossed the line or left; without a line:
  left) and, with a line, somebody crossed it (``missed_line``: people left but nobody crossed the line, which
  then lies off their path or counts the other way); ``partial_specific_flow_per_m_s`` / ``partial_flow_per_s``: Eq. 22 over the passages that
  happened, for incomplete episodes too;
- ``stalled`` / ``stall_time_s``: the runner's stall rule (:class:`crowd_env.experiments.running.runner.StallDetector`:
  nobody crossed the line or left for 20 s while those remaining, and started, got nowhere, mean net speed below
  0.05 m/s) fired at that time. Unlike ``run_scenario`` the episode is not stopped there, so that every
  policy's return covers the same horizon; ``stall_time_s`` is the first detection;
- ``evacuation_time_s``: time of the last exit if everybody left, else NaN (``n_evacuated`` says
  how many did);
- ``mean_speed_m_s``: mean speed over pedestrians on the floor and simulator steps;
- ``n_percussions`` and ``mean_percussion_kg_m_s``: number and mean size of the non-zero normal
  contact percussions (pedestrian-pedestrian and pedestrian-wall; impacts and the sustained-contact
  projection, each simulator step counted);
- ``density_front_per_m2``: the classic density (pedestrians whose centre lies in the area, over its area)
  in the geometry's measurement area "front" (the Seyfried bottleneck's area before the entrance; NaN
  for geometries without one), averaged over the simulator steps between the first and the last passage
  at the line (the window of J_s; NaN with fewer than two passages);
- ``min_gap_m``: smallest gap between two pedestrians or a pedestrian and a wall (negative = overlap), as the
  runner tracks it: at the start, then among each step's contact candidates (pairs within the contact margin);
- ``mean_return``: mean over agents of the summed environment reward;
- ``lane_order`` and ``lane_order_mixed``: in a counterflow whose scenario says each pedestrian's walking
  direction (metadata ``direction_x``, ±1: the periodic corridor), the lane order parameter Φ
  (:func:`crowd_env.analysis.lanes.lane_order_parameter`: 1 when every lane carries one direction) of the
  pedestrians' lateral positions, sampled every :data:`LANE_SAMPLE_S` of simulated time from
  :data:`LANE_TRANSIENT_S` on and averaged; ``lane_order_mixed`` is the same frames' Φ with the directions
  shuffled (:func:`~crowd_env.analysis.lanes.mixed_lane_order_parameter`), the value of a crowd without lanes
  that Φ is read against. NaN elsewhere (one direction, or no directions in the metadata).
"""
from __future__ import annotations

from crowd_env.errors import PolicyError

import importlib
import json
import os
import time
from dataclasses import dataclass, field

import numpy as np

from ...analysis.flow import specific_flow
from ...analysis.lanes import lane_order_parameter, mixed_lane_order_parameter
from ...walking.model import ModelParams
from ...envs.crowd_v0 import CrowdParallelEnv, decisions_for_time
from .rollout import measure_step
from .runner import StallDetector, _RunMeasures, _run_result, measured

__all__ = ["DEFAULT_POLICY_RESOLVER", "EpisodeMetrics", "ScenarioSpec", "import_object", "resolve_policy", "run_episode",
           "evaluate", "summarize", "METRICS", "ENV_CONFIG_FILE", "recorded_env_config", "episode_setup",
           "describe_setup", "confidence_interval"]

# Names and saved models are turned into policies by the shipped baselines, reached by import path so that
# crowd_env never imports baselines.
DEFAULT_POLICY_RESOLVER = "baselines.reference_policies:as_policy"
METRICS = (
    ("specific_flow_per_m_s", "J_s (1/m/s)"),
    ("evacuation_time_s", "evac. time (s)"),
    ("mean_speed_m_s", "mean speed (m/s)"),
    ("n_percussions", "# percussions"),
    ("mean_percussion_kg_m_s", "mean perc. (kg m/s)"),
    ("density_front_per_m2", "density front (1/m²)"),
    ("min_gap_m", "min gap (m)"),
    ("mean_return", "mean return"),
    ("lane_order", "lane order"),
)
LANE_SAMPLE_S, LANE_TRANSIENT_S = 1.0, 10.0  # the lane order's sampling interval and the transient left out


@dataclass
class EpisodeMetrics:
    policy: str
    scenario: str
    seed: int
    n_pedestrians: int
    n_evacuated: int
    simulated_time_s: float
    evacuation_time_s: float
    specific_flow_per_m_s: float
    flow_per_s: float
    mean_speed_m_s: float
    n_percussions: int
    mean_percussion_kg_m_s: float
    min_gap_m: float
    mean_return: float
    wall_time_s: float
    complete: bool = True
    missed_line: bool = False  # people left but nobody crossed the line: not complete (RunResult.missed_line)
    stalled: bool = False
    stall_time_s: float = field(default=float("nan"), compare=False)  # nan unless stalled (nan != nan)
    partial_specific_flow_per_m_s: float = float("nan")
    partial_flow_per_s: float = float("nan")
    density_front_per_m2: float = float("nan")
    lane_order: float = field(default=float("nan"), compare=False)  # nan unless a counterflow (nan != nan)
    lane_order_mixed: float = field(default=float("nan"), compare=False)


@dataclass
class ScenarioSpec:
    """A scenario to evaluate on: a registered name (+ options) or a Scenario object, and a label."""

    scenario: object = "seyfried_bottleneck"
    scenario_options: dict | None = None
    label: str | None = None

    def __post_init__(self):
        if self.label is None:
            if isinstance(self.scenario, str):
                opts = ",".join(f"{k}={v}" for k, v in sorted((self.scenario_options or {}).items()))
                self.label = f"{self.scenario}({opts})" if opts else self.scenario
            else:
                self.label = getattr(self.scenario, "name", "scenario")

    def env_options(self) -> dict:
        out = {"scenario": self.scenario}
        if self.scenario_options:
            out["scenario_options"] = dict(self.scenario_options)
        return out


ENV_CONFIG_FILE = "env_config.json"  # written by the training commands beside the trained policy


def recorded_env_config(model_path) -> tuple:
    """``(env_config, path)``: the environment options a policy was trained with, from the
    :data:`ENV_CONFIG_FILE` beside the saved model ``model_path`` (a file such as ``runs/ppo/model.zip``, or
    a run folder), or ``(None, None)`` when there is none."""
    folder = os.fspath(model_path)
    if not os.path.isdir(folder):
        folder = os.path.dirname(os.path.abspath(folder))
    path = os.path.join(folder, ENV_CONFIG_FILE)
    if not os.path.exists(path):
        return None, None
    with open(path) as fh:
        return json.load(fh), path


def episode_setup(env_config: dict) -> tuple:
    """``(ScenarioSpec, env_options, max_time_s)`` of the episodes an ``env_config`` (the options of
    :func:`crowd_env.envs.crowd_v0.parallel_env`, as the training commands record them) describes: its
    scenario and options, every other option but ``max_steps``, and ``max_steps`` as simulated time
    (``max_steps × frame_skip × dt``), which :func:`run_episode` takes."""
    params = env_config.get("params")
    dt = ModelParams.from_dict(params).dt_s if isinstance(params, dict) and params else ModelParams().dt_s
    frame_skip = env_config.get("frame_skip") or 1
    steps = env_config.get("max_steps")
    max_time = steps * frame_skip * dt if steps else None
    opts = {k: v for k, v in env_config.items() if k not in ("scenario", "scenario_options", "max_steps")}
    spec = ScenarioSpec(env_config.get("scenario", "seyfried_bottleneck"), env_config.get("scenario_options"))
    return spec, opts, max_time


def describe_setup(scenarios, env_options: dict, max_time_s: float) -> str:
    """One line naming the scenarios, the environment options and the episode length of an evaluation."""
    names = ", ".join(s.label if isinstance(s, ScenarioSpec) else str(s) for s in scenarios)
    return f"scenario {names}; environment options {env_options}; at most {max_time_s:g} s simulated per episode"


def import_object(path: str):
    """The object an import path ``"package.module:attribute"`` names (``importlib``; nested attributes
    with dots after the colon)."""
    module, sep, attr = str(path).partition(":")
    if not sep or not module or not attr:
        raise PolicyError(f"an import path is 'module:attribute', got {path!r}")
    obj = importlib.import_module(module)
    for part in attr.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            raise PolicyError(f"{path!r}: {obj!r} has no attribute {part!r}") from None
    return obj


def resolve_policy(spec, name: str | None = None, resolve=None):
    """A policy object from ``spec``: ``resolve(spec, name=name)`` when ``resolve`` is given; otherwise
    ``spec`` itself when it has ``act``, or the object an import path ``"module:attribute"`` names (called
    without arguments when it is a class or factory without ``act``). ``name`` relabels the policy."""
    if resolve is not None:
        return resolve(spec, name=name)
    policy = spec
    if isinstance(spec, str):
        policy = import_object(spec)
        if not hasattr(policy, "act") or isinstance(policy, type):
            policy = policy()
    if not (hasattr(policy, "act") and callable(policy.act)):
        raise PolicyError(f"not a policy (no act(env, observations)): {spec!r}; pass a policy object, an import path "
                        "'module:attribute', or resolve= (e.g. baselines.reference_policies.as_policy)")
    if name:
        policy.name = name
    return policy


class _Probe:
    """Substep hook collecting the metrics: each simulator step measured by the runner's
    :func:`~crowd_env.experiments.running.rollout.measure_step` (passages of the line, the density in "front", the
    smallest gap, the time of the last exit, the stall rule) as :func:`~crowd_env.experiments.running.runner.run_scenario`
    measures its runs; the mean speed, the percussions and the lane order besides."""

    def __init__(self, env: CrowdParallelEnv, line_name: str | None):
        sim, n = env.sim, env.n_pedestrians
        line_name = measured(env.scenario)[0] if line_name is None else line_name
        self.measures = _RunMeasures(env.scenario, n, 1, line_name,
                                     ("front",) if "front" in env.geometry.measurement_areas else (), None,
                                     sim.min_gap_m(), 0)
        self.stall = StallDetector(sim.params.dt_s, start_s=sim.time_s, n_pedestrians=n)
        self.speed_sum = 0.0
        self.speed_n = 0
        self.n_perc = 0
        self.perc_sum = 0.0
        direction = np.asarray(env.scenario.metadata.get("direction_x", ()), dtype=float)
        two_ways = direction.shape == (n,) and (direction > 0).any() and (direction < 0).any()
        self.eastbound = direction > 0 if two_ways else None
        self.lanes, self.lanes_mixed = [], []
        self.next_lane_s = sim.time_s + LANE_TRANSIENT_S

    def _sample_lanes(self, st, time_s: float) -> None:
        """Φ of this frame and of its shuffled directions, every LANE_SAMPLE_S from the end of the transient."""
        if self.eastbound is None or time_s < self.next_lane_s - 1e-9:
            return
        self.next_lane_s += LANE_SAMPLE_S
        on = st.active
        y, east = st.position_m[on, 1], self.eastbound[on]
        self.lanes.append(lane_order_parameter(y_m=y, eastbound=east))
        self.lanes_mixed.append(mixed_lane_order_parameter(y_m=y, eastbound=east, draws=50, seed=len(self.lanes)))

    def lane_orders(self) -> tuple:
        """(mean Φ, mean Φ of the shuffled directions) over the sampled frames; NaN without any."""
        if not self.lanes or not np.isfinite(self.lanes).any():
            return float("nan"), float("nan")
        return float(np.nanmean(self.lanes)), float(np.nanmean(self.lanes_mixed))

    def result(self, env, wall_s: float):
        """The run's :class:`~crowd_env.experiments.running.runner.RunResult`, as the runner reports its runs."""
        return _run_result(env.scenario, env.sim, self.measures, self.stall, env.scenario.metadata.get("width_m"),
                           wall_s)

    def __call__(self, env, res, prev_pos, prev_t):
        sim = env.sim
        st = sim.state
        idx = np.flatnonzero(st.active)  # those on the floor before the step: these and who left in it
        if res.exited.size:
            idx = np.sort(np.concatenate((idx, res.exited)))
        self.measures.room_for(1)
        measure_step(st.arrays(), idx, prev_pos[idx], res.exited.shape[0], prev_t, sim.time_s, sim.step_count,
                     res.min_gap_m, sim.params.dt_s, sim.period_m, self.measures.bundle(), self.stall.bundle())
        v = st.velocity_m_s[st.active]
        if v.shape[0]:
            self.speed_sum += float(np.hypot(v[:, 0], v[:, 1]).sum())
            self.speed_n += v.shape[0]
        pn = res.percussion_normal
        nz = pn[np.abs(pn) > 0]
        self.n_perc += int(nz.size)
        self.perc_sum += float(np.abs(nz).sum())
        self._sample_lanes(st, sim.time_s)


def run_episode(policy, scenario: ScenarioSpec | str = "seyfried_bottleneck", seed: int = 0, *,
                env_options: dict | None = None, max_time_s: float = 90.0, line: str | None = None,
                resolve=None, video=None) -> EpisodeMetrics:
    """Run one episode of ``policy`` on ``scenario`` with ``seed``; see the module docstring for the metrics.

    ``policy``: a policy object, or a spec :func:`resolve_policy` turns into one (with ``resolve``).

    ``scenario``: a :class:`ScenarioSpec`, or a registered scenario name (any of
    ``crowd_env.scenarios.list_scenarios()``; options through ``ScenarioSpec(name, options)``).

    ``env_options`` go to :class:`~crowd_env.envs.crowd_v0.CrowdParallelEnv` (``controlled`` defaults to
    ``"all"``); the policy's ``env_overrides`` win over them; ``max_steps`` is set from ``max_time_s``.

    ``video``: None, or a recorder (e.g. :class:`crowd_env.experiments.output.video.RolloutVideo`) whose
    ``begin(env)`` is called after the reset, ``after_step(env)`` after every environment step and
    ``end(env, completed)`` at the end (``completed`` False when the episode raised); it only reads the
    environment, so the metrics are the same with or without it.
    """
    policy = resolve_policy(policy, resolve=resolve)
    spec = scenario if isinstance(scenario, ScenarioSpec) else ScenarioSpec(scenario)
    opts = {"controlled": "all", **(env_options or {}), **spec.env_options(), **getattr(policy, "env_overrides", {})}
    opts.pop("max_steps", None)
    env = CrowdParallelEnv(**opts)
    env.max_steps = decisions_for_time(max_time_s, env.dt_s)  # frame_skip and dt resolved
    t0 = time.perf_counter()
    obs, _ = env.reset(seed=seed)
    if hasattr(policy, "reset"):
        policy.reset(env, seed)
    probe = _Probe(env, line)
    env.substep_hooks.append(probe)
    returns = dict.fromkeys(env.possible_agents, 0.0)
    if video is not None:
        video.begin(env)
    completed = False
    try:
        while env.agents:
            actions = policy.act(env, obs)
            obs, rewards, _, _, _ = env.step(actions)
            for a, r in rewards.items():
                returns[a] += r
            if video is not None:
                video.after_step(env)
        while env.step_background():  # learners among a crowd: the crowd goes on after they have left
            if video is not None:
                video.after_step(env)
        completed = True
    finally:
        if video is not None:
            video.end(env, completed)
    env.substep_hooks.remove(probe)
    run = probe.result(env, time.perf_counter() - t0)
    n = env.n_pedestrians
    times = run.crossing_times_s
    width = run.width_m
    j = js = float("nan")
    if times.size >= 2 and times[-1] > times[0]:
        fr = specific_flow(times, width if width else 1.0)
        j = fr.flow_per_s
        js = fr.specific_flow_per_m_s if width else float("nan")
    lanes, lanes_mixed = probe.lane_orders()
    result = EpisodeMetrics(
        policy=getattr(policy, "name", type(policy).__name__), scenario=spec.label, seed=int(seed), n_pedestrians=n,
        n_evacuated=run.n_evacuated, simulated_time_s=env.sim.time_s, evacuation_time_s=run.evacuation_time_s,
        specific_flow_per_m_s=js if run.complete else float("nan"), flow_per_s=j if run.complete else float("nan"),
        mean_speed_m_s=probe.speed_sum / probe.speed_n if probe.speed_n else float("nan"),
        n_percussions=probe.n_perc,
        mean_percussion_kg_m_s=probe.perc_sum / probe.n_perc if probe.n_perc else 0.0,
        min_gap_m=run.min_gap_m, mean_return=float(np.mean(list(returns.values()))),
        wall_time_s=time.perf_counter() - t0, complete=run.complete, missed_line=run.missed_line, stalled=run.stalled,
        stall_time_s=run.stall_time_s, partial_specific_flow_per_m_s=js, partial_flow_per_s=j,
        density_front_per_m2=run.mean_density_per_m2("front", "passages") if "front" in run.density_per_m2
        else float("nan"), lane_order=lanes, lane_order_mixed=lanes_mixed)
    env.close()
    return result


def evaluate(policies, scenarios=("seyfried_bottleneck",), seeds=(0, 1, 2), *, env_options: dict | None = None,
             max_time_s: float = 90.0, line: str | None = None, progress=print, resolve=None, video=None) -> list:
    """Every policy x scenario x seed; ``policies``: a list of policies (or specs) or a dict label -> policy
    (or spec), specs turned into policies by :func:`resolve_policy` (with ``resolve``); ``scenarios``:
    :class:`ScenarioSpec` objects, registered names or ``(name, options)`` pairs.

    ``video``: None, or a callable ``video(policy_label) -> recorder`` (e.g.
    :func:`crowd_env.experiments.output.video.per_policy`) giving the recorder (see :func:`run_episode`) of the
    first episode of each policy: its first scenario with its first seed."""
    items = list(policies.items()) if isinstance(policies, dict) else [(None, p) for p in policies]
    specs = [s if isinstance(s, ScenarioSpec) else ScenarioSpec(*s) if isinstance(s, tuple) else ScenarioSpec(s)
             for s in scenarios]
    results = []
    for label, p in items:
        pol = resolve_policy(p, name=label, resolve=resolve)
        recorder = None if video is None else video(getattr(pol, "name", type(pol).__name__))
        for spec in specs:
            for seed in seeds:
                r = run_episode(pol, spec, seed, env_options=env_options, max_time_s=max_time_s, line=line,
                                video=recorder)
                recorder = None  # only the first episode of each policy
                results.append(r)
                if progress is not None:
                    progress(f"  {r.policy:>12s} | {r.scenario} | seed {seed}: J_s {r.specific_flow_per_m_s:.3f}, "
                             f"evacuated {r.n_evacuated}/{r.n_pedestrians}"
                             + (f", stalled at {r.stall_time_s:.1f} s" if r.stalled else "")
                             + (", nobody crossed the measurement line" if r.missed_line else "")
                             + f" ({r.wall_time_s:.1f} s wall)")
    return results


def summarize(results) -> list:
    """Mean (and std, and the 95 % interval of the mean: ``_ci_low``, ``_ci_high``, :func:`confidence_interval`)
    of every metric per (scenario, policy), in first-seen order."""
    groups: dict = {}
    for r in results:
        groups.setdefault((r.scenario, r.policy), []).append(r)
    rows = []
    for (scen, pol), rs in groups.items():
        row = {"scenario": scen, "policy": pol, "n_episodes": len(rs),
               "evacuated_fraction": float(np.mean([r.n_evacuated / r.n_pedestrians for r in rs])),
               "n_complete": sum(bool(r.complete) for r in rs), "n_stalled": sum(bool(r.stalled) for r in rs)}
        for key, _ in METRICS:
            vals = np.array([getattr(r, key) for r in rs], dtype=float)
            finite = vals[np.isfinite(vals)]
            row[key] = float(finite.mean()) if finite.size else float("nan")
            row[key + "_std"] = float(finite.std()) if finite.size > 1 else float("nan")
            row[key + "_n"] = int(finite.size)
            row[key + "_ci_low"], row[key + "_ci_high"] = confidence_interval(finite)
        rows.append(row)
    return rows


def confidence_interval(values, *, confidence: float = 0.95, n_resamples: int = 2000, seed: int = 0) -> tuple:
    """``(low, high)``: the percentile bootstrap interval of the mean of the finite ``values`` (episodes
    resampled with replacement, ``n_resamples`` times, a fixed ``seed`` so that tables are reproducible);
    ``(mean, mean)`` for one value, NaN for none. With a handful of episodes the interval is rough (and
    narrower than the truth): evaluate more seeds for a firm one."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return float("nan"), float("nan")
    mean = float(v.mean())
    if v.size == 1:
        return mean, mean
    rng = np.random.default_rng(seed)
    means = v[rng.integers(0, v.size, (n_resamples, v.size))].mean(axis=1)
    alpha = (1.0 - confidence) / 2.0
    lo, hi = np.quantile(means, [alpha, 1.0 - alpha])
    return float(min(lo, mean)), float(max(hi, mean))
