"""Reliability: a reduced soak, the invariant checker, memory, determinism across processes, resumable
sweeps and training, and the bad-input catalogue (issue 8).

The full soak (≥ 10⁶ agent-steps) is ``crowd-soak``; here a reduced one runs over every
registered scenario (``crowd_env.experiments.validation.soak.distinct_scenarios``), so new scenarios are covered
without editing this file.
"""
import dataclasses
import json
import os
import signal
import subprocess
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context

import numpy as np
import pytest
from shapely.geometry import MultiPolygon, box

from crowd_env.core import CrowdState, Simulator
from crowd_env.walking import ModelParams
from crowd_env.core.geometry import Geometry
from crowd_env.envs import crowd_v0
from crowd_env.experiments.validation.soak import (ACTION_MODES, InvariantChecker, MemoryProbe, distinct_scenarios,
                                        max_intent_toward, trajectory_hashes)
from crowd_env.experiments.validation.soak import soak as run_soak
from crowd_env.scenarios import Scenario, make_scenario
from tests.conftest import ROOT, load_script, room_geometry

PYTHON = sys.executable


def room_scenario(positions=((1.0, 2.0),), **kw):
    """A 6 m x 4 m room with an exit strip x in [5.5, 6]."""
    geom = room_geometry()
    return Scenario(geometry=geom, position_m=np.array(positions, dtype=float), name="room", **kw)


# ---------------------------------------------------------------------------------------------- soak
def test_reduced_soak_over_every_registered_scenario():
    """60k agent-steps (a few thousand per scenario and mode) with random and adversarial actions: no overlap,
    no energy created at impacts, everybody inside the walkable area; every registered scenario is covered."""
    r = run_soak(60_000, max_steps=150, memory_tolerance_mib=float("inf"), progress=lambda s: None)
    assert r["agent_steps"] >= 60_000
    assert r["skipped_scenarios"] == {}, "add example values for these options to experiments.validation.soak.EXAMPLE_OPTIONS"
    assert sorted(r["scenarios"]) == distinct_scenarios() and "seyfried_bottleneck" in r["scenarios"]
    assert set(r["modes"]) == set(ACTION_MODES)
    assert r["violations"] == {}, "\n".join(r["examples"])
    # the energy check had impacts to judge: in the crowd scenarios, as before the RiMEA set-ups were
    # registered (those are sparse by design: test 1 is one walker), and in the RiMEA ones too
    crowd = [v for k, v in r["per_pair"].items() if not k.startswith("rimea_")]
    assert sum(v["impact_steps"] for v in crowd) > 0.3 * sum(v["sim_steps"] for v in crowd)
    assert sum(v["impact_steps"] for k, v in r["per_pair"].items() if k.startswith("rimea_")) > 0
    assert r["max_overlap_m"] < 1e-3 and r["max_impact_energy_increase_j"] <= 1e-9


def test_soak_reports_violations_and_exit_status(monkeypatch):
    """A negative overlap tolerance flags every step: the soak counts it and the command exits 1."""
    soak = load_script("soak")
    r = run_soak(300, scenarios=["seyfried_bottleneck"], modes=["random"], max_steps=5, overlap_tolerance_m=-1.0,
                  memory_tolerance_mib=float("inf"), progress=lambda s: None)
    assert r["violations"]["pedestrian_overlap"] == r["sim_steps"] > 0 and r["n_violations"] > 0
    assert any("pedestrian_overlap" in e for e in r["examples"])
    # the exit status (every scenario's soak is test_reduced_soak_over_every_registered_scenario's job)
    assert soak.main(["--agent-steps", "300", "--modes", "random", "--max-steps", "5", "--scenarios",
                      "seyfried_bottleneck", "room_pillar", "--overlap-tolerance-m", "-1"]) == 1
    assert soak.main(["--agent-steps", "300", "--modes", "toward_wall", "--max-steps", "5", "--scenarios",
                      "seyfried_bottleneck", "room_pillar", "--memory-tolerance-mib", "inf"]) == 0


def _stepped_env(n=6):
    env = crowd_v0.parallel_env(scenario_options={"n_pedestrians": n, "seed": 0}, max_steps=50)
    env.reset(seed=0)
    results = []
    env.substep_hooks.append(lambda e, res, *_: results.append(res))
    env.step({a: np.zeros(2) for a in env.agents})
    return env, results[-1]


@pytest.mark.parametrize("kind", ["pedestrian_overlap", "wall_overlap", "outside_walkable", "non_finite",
                                  "impact_energy_increase", "projection_energy_increase", "energy_report_mismatch"])
def test_checker_detects_each_violation(kind):
    """Each check can fail: corrupt a real post-step state or StepResult and the checker names it."""
    env, res = _stepped_env()
    st = env.sim.state
    clean = InvariantChecker()
    clean.check(env.sim, env.geometry, res)
    assert clean.n_violations == 0
    if kind == "pedestrian_overlap":
        st.position_m[1] = st.position_m[0] + [0.3, 0.0]
    elif kind == "wall_overlap":
        st.position_m[0] = [-0.1, 1.9]  # 0.1 m from the corridor's side wall y = 2
    elif kind == "outside_walkable":
        st.position_m[0] = [-3.0, 2.5]
    elif kind == "non_finite":
        st.velocity_m_s[2] = [np.nan, 0.0]
    elif kind == "impact_energy_increase":
        res = dataclasses.replace(res, kinetic_energy_after_impact_j=res.kinetic_energy_before_impact_j + 1e-3)
    elif kind == "projection_energy_increase":
        res = dataclasses.replace(res, kinetic_energy_after_impact_j=res.kinetic_energy_after_projection_j - 1e-3)
    elif kind == "energy_report_mismatch":
        st.velocity_m_s[0] += 0.5
    checker = InvariantChecker()
    checker.check(env.sim, env.geometry, res)
    assert dict(checker.counts) == {kind: 1}, checker.examples
    assert kind in checker.examples[0]


def test_adversarial_actions_are_maximal_and_aimed():
    env, _ = _stepped_env()
    st = env.sim.state
    acts = ACTION_MODES["toward_neighbour"](env)
    for a, v in acts.items():
        i = int(a[4:])
        assert np.abs(v).max() == env.action_max_m_s and env.action_space(a).contains(v.astype(np.float32))
        d = np.linalg.norm(st.position_m - st.position_m[i], axis=1)
        d[i] = np.inf
        to = st.position_m[np.argmin(d)] - st.position_m[i]
        assert np.dot(v, to) / (np.linalg.norm(v) * np.linalg.norm(to)) == pytest.approx(1.0)
    dist, normal = env.geometry.distance_to_walls(st.position_m, return_normal=True)
    for a, v in ACTION_MODES["toward_wall"](env).items():
        assert np.dot(v / np.linalg.norm(v), -normal[int(a[4:])]) == pytest.approx(1.0)
    assert np.array_equal(max_intent_toward([[0.0, 0.0], [1.0, -3.0]], 2.0), [[0.0, 0.0], [2.0 / 3.0, -2.0]])


# ---------------------------------------------------------------------------------------------- memory
def _traced_growth_mib(run, warmup, repeats):
    """tracemalloc growth (MiB) over ``repeats`` calls of ``run`` after ``warmup`` calls."""
    for _ in range(warmup):
        run()
    probe = MemoryProbe(trace=True)
    probe.start()
    try:
        probe.sample(0)
        for k in range(repeats):
            run()
            probe.sample(k + 1)
    finally:
        probe.stop()
    return (probe.samples[-1][2] - probe.samples[0][2]) / 2**20


def test_memory_flat_over_steps_within_an_episode():
    env = crowd_v0.parallel_env(scenario_options={"n_pedestrians": 20, "seed": 0}, max_steps=100_000)
    env.reset(seed=0)
    rng = np.random.default_rng(0)

    def run():
        for _ in range(50):
            env.step(ACTION_MODES["toward_neighbour" if rng.random() < 0.5 else "random"](env, rng))

    assert _traced_growth_mib(run, warmup=2, repeats=8) < 0.5  # measured: ~0.01 MiB


def test_memory_flat_across_resets_with_pinned_scenario_seed():
    env = crowd_v0.parallel_env(scenario_options={"n_pedestrians": 10, "seed": 1}, max_steps=5)
    seeds = iter(range(10_000))
    assert _traced_growth_mib(lambda: env.reset(seed=next(seeds)), warmup=3, repeats=15) < 1.0  # measured: ~0.01


def test_memory_flat_across_resets():
    """Resetting an environment whose scenario is rebuilt per seed (the default) must not grow memory
    (regression: the navigation cache once kept the field of every rebuilt scenario)."""
    env = crowd_v0.parallel_env(scenario_options={"n_pedestrians": 10}, max_steps=5)
    seeds = iter(range(10_000))
    assert _traced_growth_mib(lambda: env.reset(seed=next(seeds)), warmup=3, repeats=15) < 1.0  # measured: 7.8


# ---------------------------------------------------------------------------------------------- determinism
def test_same_seed_bitwise_identical_serially_and_in_spawned_workers():
    """1000 steps with contacts: per-step position hashes equal serially and in 2 spawned worker processes;
    another seed differs."""
    serial = trajectory_hashes(3, 1000)
    assert len(serial) == 1000
    with ProcessPoolExecutor(max_workers=2, mp_context=get_context("spawn")) as pool:
        parallel = list(pool.map(trajectory_hashes, [3, 3, 4], [1000, 1000, 1000]))
    assert parallel[0] == serial and parallel[1] == serial
    assert parallel[2][0] != serial[0] and sum(a != b for a, b in zip(parallel[2], serial)) > 900


# ---------------------------------------------------------------------------------------------- resumable runs
def _wait_for(predicate, proc, timeout_s=60.0):
    t0 = time.perf_counter()
    while not predicate():
        if proc.poll() is not None:
            raise AssertionError(f"process ended (rc {proc.returncode}) before the condition: "
                                 f"{proc.stderr.read().decode()[-2000:] if proc.stderr else ''}")
        if time.perf_counter() - t0 > timeout_s:
            proc.kill()
            raise AssertionError("timed out waiting for the process")
        time.sleep(0.02)


def _kill(proc):
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL


def _records(out):
    """Run records by file name, without the wall-clock time (NaN-safe: compared as JSON text)."""
    recs = {}
    for p in sorted((out / "runs").glob("*.json")):
        r = json.loads(p.read_text())
        r.pop("wall_time_s")
        recs[p.name] = json.dumps(r, sort_keys=True)
    return recs


def test_bottleneck_sweep_killed_midway_resumes_without_loss(tmp_path):
    """SIGKILL the sweep after its first run file; the rerun computes only the missing runs and the
    results equal those of an uninterrupted sweep."""
    from crowd_env.cli import reproduce_bottleneck as cli

    args = ["--widths", "1.0", "--sizes", "4", "--seeds", "4", "--max-time", "4", "--jobs", "1", "--no-figures"]
    killed = tmp_path / "killed"
    proc = subprocess.Popen([PYTHON, "-m", "crowd_env.cli.reproduce_bottleneck", *args, "--out", str(killed)],
                            cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _wait_for(lambda: any((killed / "runs").glob("*.json")), proc)
    _kill(proc)
    done = {p.name: (p.stat().st_mtime_ns, p.read_bytes()) for p in (killed / "runs").glob("*.json")}
    assert 1 <= len(done) < 4, "the sweep must be killed midway for this test to mean anything"
    assert not (killed / "results.csv").exists()
    assert cli.main([*args, "--out", str(killed)]) == 0
    runs = sorted(p.name for p in (killed / "runs").glob("*.json"))
    assert runs == [f"b1.000_n4_s{s}.json" for s in range(4)]
    for name, (mtime, data) in done.items():  # finished runs were not recomputed
        p = killed / "runs" / name
        assert p.stat().st_mtime_ns == mtime and p.read_bytes() == data
    fresh = tmp_path / "fresh"
    assert cli.main([*args, "--out", str(fresh)]) == 0
    assert _records(killed) == _records(fresh)
    rows = [(killed / "results.csv").read_text().splitlines(), (fresh / "results.csv").read_text().splitlines()]
    col = rows[0][0].split(",").index("wall_time_s")
    strip = [[",".join(v for k, v in enumerate(line.split(",")) if k != col) for line in r] for r in rows]
    assert strip[0] == strip[1] and len(strip[0]) == 5


TRAIN_ARGS = ["--scenario-option", "n_pedestrians=6", "--max-steps", "30", "--copies", "1", "--n-steps", "64",
              "--batch-size", "64", "--n-epochs", "2", "--eval-seeds", "5", "--checkpoint-every", "384"]


def test_training_killed_midway_resumes_to_the_target(tmp_path):
    """SIGKILL train_ppo.py after its first checkpoint; --resume continues from the latest checkpoint to the
    requested total, the checkpoint step counter only grows, and the learning curve keeps the early part."""
    pytest.importorskip("stable_baselines3")
    out = tmp_path / "ppo"
    index = out / "checkpoints" / "index.json"
    target = 2500
    cmd = [PYTHON, os.path.join(ROOT, "scripts", "train_ppo.py"), "--timesteps", str(target), "--out", str(out),
           *TRAIN_ARGS]
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _wait_for(index.exists, proc, timeout_s=120)
    _kill(proc)
    before = [e["timesteps"] for e in json.loads(index.read_text())["checkpoints"]]
    assert before and before[-1] < target, "the training must be killed midway for this test to mean anything"
    assert not (out / "summary.json").exists()
    train = load_script("train_ppo")
    with pytest.raises(SystemExit, match="--resume"):  # a folder with checkpoints is not silently restarted
        train.main(["--timesteps", str(target), "--out", str(out), *TRAIN_ARGS])
    assert train.main(["--timesteps", str(target), "--out", str(out), *TRAIN_ARGS, "--resume"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    after = [e["timesteps"] for e in json.loads(index.read_text())["checkpoints"]]
    assert summary["resumed_from_timesteps"] == before[-1]
    assert target <= summary["timesteps"] < target + 384 and after[-1] == summary["timesteps"]
    assert after[:len(before)] == before and all(b > a for a, b in zip(after, after[1:]))
    curve = np.loadtxt(out / "learning_curve.csv", delimiter=",", skiprows=1, ndmin=2)
    assert (curve[:, 0] <= before[-1]).any() and (curve[:, 0] > before[-1]).any()
    assert np.all(np.diff(curve[:, 0]) >= 0)
    # resuming a finished run trains no further
    assert train.main(["--timesteps", str(target), "--out", str(out), *TRAIN_ARGS, "--resume"]) == 0
    assert json.loads((out / "summary.json").read_text())["timesteps"] == summary["timesteps"]
    with pytest.raises(SystemExit, match="other environment options"):
        train.main(["--timesteps", str(target), "--out", str(out), *TRAIN_ARGS, "--n-rays", "4", "--resume"])


# ---------------------------------------------------------------------------------------------- bad inputs
def _live_env(**kw):
    """A reset 6-pedestrian bottleneck environment (all controlled)."""
    env = crowd_v0.parallel_env(**{"scenario_options": {"n_pedestrians": 6, "seed": 0}, "max_steps": 50, **kw})
    env.reset(seed=0)
    return env


def _step_with(action=None, extra=None, drop=None):
    """Step a live environment with zero actions, one of them (``ped_2``) replaced by ``action``."""
    env = _live_env()
    acts = {a: np.zeros(2) for a in env.agents}
    if action is not None:
        acts["ped_2"] = action
    acts.update(extra or {})
    for a in drop or ():
        acts.pop(a)
    env.step(acts)


def _step_after_exit():
    """Give an action to an agent that already left through the exit."""
    env = crowd_v0.parallel_env(scenario=room_scenario([(5.2, 2.0), (1.0, 2.0)]), frame_skip=10, max_steps=50)
    env.reset(seed=0)
    while "ped_0" in env.agents:
        env.step({a: np.array([2.5, 0.0]) for a in env.agents})
    env.step({"ped_0": np.zeros(2), "ped_1": np.zeros(2)})


def _sim_step(**kw):
    sim = Simulator(CrowdState.create([[0.0, 0.0], [1.0, 0.0]]))
    sim.step(kw.pop("intents", np.zeros((2, 2))), **kw)


def _env_with(**pedestrian_params):
    """An environment on the room scenario with pedestrian parameters, reset (the state is built there)."""
    env = crowd_v0.parallel_env(scenario=room_scenario([(1.0, 2.0), (2.0, 2.0)], pedestrian_params=pedestrian_params))
    env.reset(seed=0)


ROOM = [(0, 0), (6, 0), (6, 4), (0, 4)]
BOWTIE = [(0, 0), (6, 4), (6, 0), (0, 4)]
EXIT = box(5.5, 0, 6, 4)
TWO_ROOMS = MultiPolygon([box(0, 0, 3, 4), box(4, 0, 7, 4)])
# two rooms joined by a 0.3 m slit, narrower than a pedestrian (0.46 m): the door at x = 8 is out of reach
TWO_ROOMS_SLIT = [(0, 0), (4, 0), (4, 2.85), (5, 2.85), (5, 0), (8, 0), (8, 6), (5, 6), (5, 3.15), (4, 3.15), (4, 6),
                  (0, 6)]
POLY = {"walkable_area": [(0, 0), (8, 0), (8, 6), (0, 6)], "exits": [[(8, 2.5), (8, 3.5)]],
        "spawn_area": [(0, 0), (3, 0), (3, 6), (0, 6)], "n_pedestrians": 5}
CATALOGUE_SCENARIO_OPTION = "no_such_option_m"


def _warnings_as_errors(call):
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return call()


def _bad_cases():
    """(id, callable, exception type, regex on the message): every one must raise that error naming the problem."""
    cases = [
        # actions and agent ids (PettingZoo parallel env)
        ("action NaN", lambda: _step_with(np.array([np.nan, 0.0])), ValueError, r"non-finite action.*ped_2"),
        ("action +inf", lambda: _step_with(np.array([np.inf, 0.0])), ValueError, r"non-finite action.*ped_2"),
        ("action -inf", lambda: _step_with(np.array([0.0, -np.inf])), ValueError, r"non-finite action.*ped_2"),
        ("action shape (3,)", lambda: _step_with(np.zeros(3)), ValueError, r"ped_2 must have shape \(2,\).*\(3,\)"),
        ("action shape (1,)", lambda: _step_with(np.zeros(1)), ValueError, r"ped_2 must have shape \(2,\)"),
        ("action shape (2, 2)", lambda: _step_with(np.zeros((2, 2))), ValueError, r"ped_2 must have shape \(2,\)"),
        ("action scalar", lambda: _step_with(1.0), ValueError, r"ped_2 must have shape \(2,\).*\(\)"),
        ("action string", lambda: _step_with("fast"), ValueError, r"action of ped_2 is not numeric"),
        ("action None", lambda: _step_with(None, extra={"ped_2": None}), ValueError, r"ped_2 .*shape.*None"),
        ("action outside Box", lambda: _step_with(np.array([2.6, 0.0])), ValueError,
         r"ped_2.*outside the action space"),
        ("unknown agent id", lambda: _step_with(extra={"ped_99": np.zeros(2)}), ValueError,
         r"unknown agent id.*ped_99"),
        ("agent id not a string", lambda: _step_with(extra={3: np.zeros(2)}), ValueError, r"unknown agent id.*3"),
        ("missing agent", lambda: _step_with(drop=["ped_4"]), ValueError, r"missing action.*ped_4"),
        ("actions not a dict", lambda: _live_env().step([np.zeros(2)] * 6), ValueError, r"must be a dict"),
        ("agent that left", _step_after_exit, ValueError, r"ped_0.*no longer live"),
        ("step before reset", lambda: crowd_v0.parallel_env(scenario_options={"n_pedestrians": 4}).step(
            {"ped_0": np.zeros(2)}), RuntimeError, r"call reset\(\) before step\(\)"),
        ("observation_space of unknown agent", lambda: _live_env().observation_space("ped_42"), ValueError,
         r"unknown agent 'ped_42'"),
        ("action_space of unknown agent", lambda: _live_env().action_space("bob"), ValueError, r"unknown agent 'bob'"),
        # simulator inputs
        ("intents wrong shape", lambda: _sim_step(intents=np.zeros((3, 2))), ValueError,
         r"intents_m_s must have shape \(2, 2\)"),
        ("intents NaN", lambda: _sim_step(intents=np.array([[0.0, 0.0], [np.nan, 0.0]])), ValueError,
         r"intents_m_s is not finite for pedestrian\(s\) \[1\]"),
        ("desired heading inf", lambda: _sim_step(desired_heading_rad=np.array([0.0, np.inf])), ValueError,
         r"desired_heading_rad is not finite"),
        ("external force wrong shape", lambda: _sim_step(external_force_n=np.zeros(2)), ValueError,
         r"external_force_n must have shape"),
        # starts
        ("overlapping starts (state)", lambda: CrowdState.create([[0.0, 0.0], [0.3, 0.0]]), ValueError,
         r"pedestrians 0 and 1 overlap by 0.16"),
        ("overlapping starts (scenario)", lambda: room_scenario([(1.0, 2.0), (1.2, 2.0)]), ValueError,
         r"pedestrians 0 and 1 overlap"),
        ("start overlapping a wall", lambda: room_scenario([(1.0, 0.1)]), ValueError,
         r"pedestrian 0 .*overlaps a wall"),
        ("start outside the walkable area", lambda: room_scenario([(1.0, 2.0), (7.0, 2.0)]), ValueError,
         r"pedestrian 1 starts at \[7.0, 2.0\], outside the walkable area"),
        ("start inside an obstacle", lambda: Scenario(geometry=Geometry(box(0, 0, 6, 4), [EXIT],
                                                                        obstacles=[box(2, 1, 3, 3)]),
                                                      position_m=[[2.5, 2.0]]), ValueError,
         r"pedestrian 0 .*outside the walkable area"),
        ("start inside an exit", lambda: room_scenario([(5.7, 2.0)]), ValueError, r"pedestrian 0 .*inside an exit"),
        ("start non-finite", lambda: room_scenario([(np.nan, 2.0)]), ValueError,
         r"pedestrian 0 has a non-finite start position"),
        ("starts wrong shape", lambda: CrowdState.create(np.zeros((3, 3))), ValueError,
         r"position_m must have shape \(N, 2\)"),
        ("start on overlapping wall (simulator)", lambda: Simulator(CrowdState.create([[1.0, 1.0]]),
                                                                    walls=[[0, 1.1, 3, 1.1]]), ValueError,
         r"pedestrian 0 .*overlaps wall segment 0"),
        # geometry
        ("geometry with no exit", lambda: Geometry(ROOM, exits=[]), ValueError, r"no exit"),
        ("exit not touching the area", lambda: Geometry(ROOM, exits=[box(8, 0, 9, 1)]), ValueError,
         r"exit 0 does not touch the walkable area"),
        ("exit touching at one point", lambda: Geometry(ROOM, exits=[box(6, 4, 7, 5)]), ValueError,
         r"exit 0 does not touch"),
        ("unreachable exit (disconnected area)", lambda: Scenario(geometry=Geometry(TWO_ROOMS, [box(6.5, 0, 7, 4)]),
                                                                  position_m=[[1.0, 2.0]]), ValueError,
         r"pedestrian 0 at \[1.0, 2.0\] cannot reach any exit"),
        ("unreachable exit (wall across)", lambda: Scenario(
            geometry=Geometry(box(0, 0, 6, 4), [EXIT], obstacles=[box(3, -1, 3.2, 5)]), position_m=[[1.0, 2.0]]),
         ValueError, r"pedestrian 0 .*cannot reach any exit"),
        ("self-intersecting walkable area", lambda: Geometry(BOWTIE, exits=[EXIT]), ValueError,
         r"walkable area is not a valid polygon: Self-intersection"),
        ("self-intersecting exit", lambda: Geometry(ROOM, exits=[[(5, 0), (6, 4), (6, 0), (5, 4)]]), ValueError,
         r"exit 0 is not a valid polygon: Self-intersection"),
        ("self-intersecting obstacle", lambda: Geometry(ROOM, [EXIT], obstacles=[[(1, 1), (2, 2), (2, 1), (1, 2)]]),
         ValueError, r"obstacle 0 is not a valid polygon: Self-intersection"),
        ("polygon with 2 vertices", lambda: Geometry([(0, 0), (1, 1)], exits=[EXIT]), ValueError,
         r"at least 3 vertices"),
        ("zero-area polygon", lambda: Geometry([(0, 0), (1, 0), (2, 0)], exits=[EXIT]), ValueError,
         r"walkable area .*(zero area|not a valid polygon)"),
        ("non-finite polygon", lambda: Geometry([(0, 0), (np.inf, 0), (1, 1)], exits=[EXIT]), ValueError,
         r"non-finite"),
        ("bad WKT", lambda: Geometry("POLYGON ((0 0, 1 0", exits=[EXIT]), ValueError, r"cannot parse WKT"),
        ("obstacles cover the area", lambda: Geometry(ROOM, [EXIT], obstacles=[box(-1, -1, 7, 5)]), ValueError,
         r"empty once the obstacles are removed"),
        ("exit narrower than the navigation grid", lambda: Scenario(
            geometry=Geometry(ROOM, [box(3.01, 2.01, 3.02, 2.02)]), position_m=[[1.0, 2.0]]), ValueError,
         r"no grid node lies inside an exit"),
        ("zero-length wall (simulator)", lambda: Simulator(CrowdState.create([[1.0, 1.0]]), walls=[[0, 0, 0, 0]]),
         ValueError, r"wall segment 0 has zero length"),
        ("user polygon: self-intersecting", lambda: make_scenario("polygon", **{**POLY, "walkable_area": BOWTIE}),
         ValueError, r"not a valid polygon: Self-intersection"),
        ("user polygon: no exit", lambda: make_scenario("polygon", **{**POLY, "exits": []}), ValueError, r"exit"),
        ("user polygon: door off the boundary",
         lambda: make_scenario("polygon", **{**POLY, "exits": [[(4, 2), (4, 3)]]}),
         ValueError, r"does not lie on the boundary"),
        ("user polygon: exit unreachable",
         lambda: make_scenario("polygon", **{**POLY, "walkable_area": TWO_ROOMS_SLIT}),
         ValueError, r"exit 0 .*(unreachable|cannot be reached|not reachable)"),
        ("user polygon: spawn outside", lambda: make_scenario("polygon", **{**POLY, "spawn_area": [(7, 0), (9, 0),
                                                                                                    (9, 6), (7, 6)]}),
         ValueError, r"spawn area must lie inside the walkable area"),
        # non-positive physical values
        ("mass 0", lambda: CrowdState.create([[0.0, 0.0]], mass_kg=0.0), ValueError,
         r"mass_kg must be > 0; pedestrian 0 has .*0\.0"),
        ("mass negative", lambda: CrowdState.create([[0.0, 0.0], [1.0, 0.0]], mass_kg=[80.0, -1.0]), ValueError,
         r"mass_kg must be > 0; pedestrian 1 has .*-1\.0"),
        ("mass NaN", lambda: CrowdState.create([[0.0, 0.0]], mass_kg=np.nan), ValueError, r"mass_kg has non-finite"),
        ("radius 0", lambda: CrowdState.create([[0.0, 0.0]], radius_m=0.0), ValueError, r"radius_m must be > 0"),
        ("radius negative (scenario)", lambda: room_scenario(pedestrian_params={"radius_m": -0.2}), ValueError,
         r"radius_m.*must be > 0"),
        ("tau 0", lambda: CrowdState.create([[0.0, 0.0]], tau_s=0.0), ValueError, r"tau_s must be > 0"),
        ("tau negative (scenario, env)", lambda: _env_with(tau_s=-0.5), ValueError, r"tau_s must be > 0"),
        ("mass 0 (scenario, env)", lambda: _env_with(mass_kg=0.0), ValueError, r"mass_kg must be > 0"),
        ("inertia 0", lambda: CrowdState.create([[0.0, 0.0]], inertia_kg_m2=0.0), ValueError,
         r"inertia_kg_m2 must be > 0"),
        ("heading stiffness negative", lambda: CrowdState.create([[0.0, 0.0]], heading_stiffness=-1.0), ValueError,
         r"heading_stiffness must be >= 0"),
        ("desired speed negative", lambda: CrowdState.create([[0.0, 0.0]], desired_speed_m_s=-1.0), ValueError,
         r"desired_speed_m_s must be >= 0"),
        ("time step 0", lambda: ModelParams(dt_s=0.0), ValueError, r"dt_s must be > 0"),
        ("time step negative", lambda: ModelParams(dt_s=-0.01), ValueError, r"dt_s must be > 0"),
        ("time step NaN", lambda: ModelParams(dt_s=float("nan")), ValueError, r"dt_s must be a finite number"),
        ("time step 0 (env params)", lambda: crowd_v0.parallel_env(params={"dt_s": 0.0}), ValueError,
         r"dt_s must be > 0"),
        ("K_n 0", lambda: ModelParams(normal_dissipation_kg=0.0), ValueError, r"normal_dissipation_kg must be > 0"),
        ("frame_skip 0", lambda: crowd_v0.parallel_env(frame_skip=0), ValueError, r"frame_skip must be"),
        ("max_steps 0", lambda: crowd_v0.parallel_env(max_steps=0), ValueError, r"max_steps must be"),
        ("action_max 0", lambda: crowd_v0.parallel_env(action_max_m_s=0.0), ValueError, r"action_max_m_s must be"),
        # unknown options and names
        ("unknown env option", lambda: crowd_v0.parallel_env(n_agents=3), ValueError,
         r"unknown option\(s\) \['n_agents'\]"),
        ("unknown scenario name", lambda: crowd_v0.parallel_env(scenario="nowhere"), ValueError,
         r"unknown scenario 'nowhere'"),
        ("unknown ModelParams name (from_dict)", lambda: ModelParams.from_dict({"dt": 0.01}), ValueError,
         r"unknown model parameter\(s\): \['dt'\]"),
        ("unknown ModelParams name (replace)", lambda: ModelParams().replace(kn=1.0), ValueError,
         r"unknown model parameter\(s\): \['kn'\]"),
        ("unknown ModelParams name (constructor)", lambda: ModelParams(dt=0.01), TypeError, r"'dt'"),
        ("unknown ModelParams name (env params)", lambda: crowd_v0.parallel_env(params={"kn": 1.0}), ValueError,
         r"unknown model parameter\(s\): \['kn'\]"),
        ("unknown solver", lambda: ModelParams(solver="clarabel"), ValueError, r"unknown solver 'clarabel'"),
        ("unknown pedestrian parameter", lambda: room_scenario(pedestrian_params={"weight": 80.0}), ValueError,
         r"unknown pedestrian parameter\(s\) \['weight'\]"),
        ("scenario options with a Scenario object", lambda: crowd_v0.parallel_env(
            scenario=room_scenario(), scenario_options={"n_pedestrians": 3}), ValueError, r"scenario_options"),
        ("unknown controlled id", lambda: crowd_v0.parallel_env(scenario=room_scenario(), controlled=["ped_7"]),
         ValueError, r"unknown pedestrian id.*ped_7"),
        ("unknown reset option (ignored, as PettingZoo requires, with a warning)",
         lambda: _warnings_as_errors(lambda: _live_env().reset(seed=0, options={"n_pedestrians": 3})),
         crowd_v0.ResetOptionsWarning, r"ignores its options.*n_pedestrians"),
        ("unknown --param in the sweep CLI", lambda: _cli_main(["--param", "kn=1", "--out", "/nonexistent/x"]),
         SystemExit, r"unknown model parameter\(s\): \['kn'\]"),
    ]
    # every registered scenario rejects an unknown option by name (new scenarios are covered automatically)
    for name in distinct_scenarios():
        cases.append((f"unknown option of scenario {name}",
                      lambda name=name: make_scenario(name, **{CATALOGUE_SCENARIO_OPTION: 1.0}),
                      ValueError, rf"unknown option.*{CATALOGUE_SCENARIO_OPTION}"))
    return cases


def _cli_main(argv):
    from crowd_env.cli import reproduce_bottleneck as cli

    return cli.main(argv)


KNOWN_GAPS: dict = {}  # name -> reason, for cases that do not raise (yet); each becomes a strict xfail
BAD_CASES = _bad_cases()


@pytest.mark.parametrize("name, call, error, match", [
    pytest.param(*c, id=c[0], marks=[pytest.mark.xfail(strict=True, reason=KNOWN_GAPS[c[0]])] if c[0] in KNOWN_GAPS
                 else []) for c in BAD_CASES])
def test_bad_input_catalogue(name, call, error, match):
    """Each bad input raises ``error`` whose message matches ``match`` (names the problem); none passes silently."""
    with pytest.raises(error) as info:
        call()
    assert __import__("re").search(match, str(info.value)), f"{name}: vague message {str(info.value)!r}"


def test_bad_input_catalogue_size(capsys):
    assert len(BAD_CASES) >= 80 and len({c[0] for c in BAD_CASES}) == len(BAD_CASES)
    with capsys.disabled():
        print(f"\nbad-input catalogue: {len(BAD_CASES)} cases, {len(KNOWN_GAPS)} known gap(s): {sorted(KNOWN_GAPS)}")


def test_thin_exit_is_rejected_or_cannot_be_stepped_over():
    try:
        geom = Geometry(box(0, 0, 6, 4), exits=[box(5.99, 0, 6, 4)], name="thin exit")
    except ValueError as exc:
        assert "exit" in str(exc)
        return
    env = crowd_v0.parallel_env(scenario=Scenario(geometry=geom, position_m=[[5.0, 2.0]]), action_max_m_s=10.0,
                                max_steps=300)
    checker = InvariantChecker()
    env.substep_hooks.append(checker)
    env.reset(seed=0)
    while env.agents:
        env.step({"ped_0": np.array([10.0, 0.0])})
    assert checker.n_violations == 0 and not env.sim.state.active[0]
