"""The policy imitated from recorded people (crowd_env.experiments.training.human_imitation and .recorded_rollouts):
disks moved apart as little as needed, rollouts from recorded states labelled to bring each pedestrian back to its
recording, the calibrated agent on a recorded state, and the command's quick path: its files, a resume that redoes
nothing, the refusals."""
from __future__ import annotations

import copy
import csv
import json
import time
from pathlib import Path

import numpy as np
import pytest

from crowd_env.analysis.corridor_runs import recorded_uo_trajectories, uo_scenario
from crowd_env.walking.model import ModelParams
from crowd_env.core.segments import as_segments
from crowd_env.core.state import first_overlap
from crowd_env.envs.background import FileObservationPolicy
from crowd_env.envs.observations import to_world_frame
from crowd_env.errors import InputError, RunStoreError, TrainingError
from crowd_env.experiments.training.demonstrations import replay_trajectories
from crowd_env.experiments.training.human_imitation import human_training_config
from crowd_env.experiments.training.recorded_rollouts import (RecordedView, _give_way_m, calibrated_actions,
                                                              dad_rollouts, separated)
from crowd_env.walking.agent import SocialForceAgent

RUN = "uo-050-180-180"


def test_overlapping_disks_move_apart_by_half_their_overlap_each_and_off_the_walls():
    pos = separated(np.array([[0.0, 0.0], [0.36, 0.0], [5.0, 5.0]]), 0.23, np.zeros((0, 4)))
    np.testing.assert_allclose(pos[:, 1], [0.0, 0.0, 5.0])
    np.testing.assert_allclose(pos[0, 0], -0.05, atol=1e-5)  # 0.1 m of overlap: 0.05 m each, along the centres
    np.testing.assert_allclose(pos[1, 0], 0.41, atol=1e-5)
    np.testing.assert_array_equal(pos[2], [5.0, 5.0])  # nobody else moves
    wall = as_segments([(-1.0, 0.1, 1.0, 0.1)])
    crowd = np.random.default_rng(0).uniform([-0.8, -1.0], [0.8, 0.0], size=(12, 2))
    out = separated(crowd, 0.23, wall)
    assert first_overlap(out, np.full(12, 0.23), 1e-9) is None
    assert np.all(out[:, 1] <= 0.1 - 0.23 + 1e-9)  # below the wall at y = 0.1 by a radius at least


@pytest.fixture(scope="module")
def replay():
    traj = recorded_uo_trajectories(RUN)
    keep = traj.frame < 400
    from crowd_env.analysis.trajectories import Trajectories

    cut = Trajectories(traj.frame[keep], traj.id[keep], traj.x_m[keep], traj.y_m[keep], None, 16.0)
    return uo_scenario(RUN), replay_trajectories(cut, uo_scenario(RUN))


class _Still:
    """An observation policy that stands everybody still (intent 0)."""

    env_overrides = {"observation_frame": "egocentric", "heading_target": "desired_direction",
                     "observation_components": ["desired_direction", "neighbors", "wall_rays"], "n_neighbors": 8,
                     "n_rays": 16, "neighbor_radius_m": 4.0, "ray_range_m": 5.0, "frame_skip": 10,
                     "action_max_m_s": 2.5}

    def actions(self, obs):
        return np.zeros((obs.shape[0], 2))


def test_rollouts_label_each_decision_with_the_way_back_to_the_recording(replay):
    scenario, rep = replay
    k0 = int(np.argmax(rep.present.sum(axis=1) >= 8))
    demos = dad_rollouts(rep, scenario, _Still(), starts=[k0], horizon_s=1.0, pull_time_s=1.0, max_pull_m_s=5.0)
    world = to_world_frame(demos.action, np.cos(demos.heading_rad), np.sin(demos.heading_rad))
    col = {int(i): c for c, i in enumerate(rep.ids)}
    first = np.isclose(demos.time_s, rep.time_s[k0])
    last = np.isclose(demos.time_s, demos.time_s.max())
    assert first.any() and last.any() and demos.time_s.max() > rep.time_s[k0] + 0.5
    for r in np.flatnonzero(first | last):
        k = int(np.argmin(np.abs(rep.time_s - demos.time_s[r])))
        c = col[int(demos.pedestrian[r])]
        recorded = (rep.position_m[k + 1, c] - rep.position_m[k, c]) / 0.1
        pull = rep.position_m[k, c] - demos.position_m[r]  # pull_time_s = 1 s
        np.testing.assert_allclose(world[r], recorded + pull, atol=1e-9)
    # the still crowd lags its walking recording: the pull grows over the rollout, forwards (towards −y)
    lag_first = np.mean([rep.position_m[k0, col[int(p)], 1] - y
                         for p, y in zip(demos.pedestrian[first], demos.position_m[first, 1])])
    lag_last = np.mean([rep.position_m[int(np.argmin(np.abs(rep.time_s - t))), col[int(p)], 1] - y
                        for p, y, t in zip(demos.pedestrian[last], demos.position_m[last, 1], demos.time_s[last])])
    assert abs(lag_first) < 0.05 and lag_last < -0.5


def test_rollouts_with_the_push_drive_the_crowd_as_the_virtual_experiments_do():
    """``push_below_m_s``: a crowd held still by its policy gets the model's push in full (every walker is at rest).
    In the queue before the 0.70 m exit (recorded people closer than two disks, moved apart just enough: touching)
    the closest two labelled walkers still touch after 1 s without the push and stand apart with it. Bad gates are
    refused before any rollout."""
    from crowd_env.analysis.trajectories import Trajectories

    run = "uo-180-180-070"
    traj = recorded_uo_trajectories(run)
    keep = (traj.frame >= 800) & (traj.frame < 1100)  # 50-69 s: the queue, about 75 people on the floor
    scenario = uo_scenario(run)
    rep = replay_trajectories(Trajectories(traj.frame[keep], traj.id[keep], traj.x_m[keep], traj.y_m[keep], None,
                                           16.0), scenario)

    def closest_at_end(demos):
        last = np.isclose(demos.time_s, demos.time_s.max())
        p = demos.position_m[last]
        d = np.hypot(*(p[:, None] - p[None]).transpose(2, 0, 1))
        return d[np.triu_indices(len(p), 1)].min()

    plain = dad_rollouts(rep, scenario, _Still(), starts=[20], horizon_s=1.0)
    pushed = dad_rollouts(rep, scenario, _Still(), starts=[20], horizon_s=1.0, push_below_m_s=0.3)
    assert pushed.meta["push_below_m_s"] == 0.3 and plain.meta["push_below_m_s"] is None
    assert closest_at_end(plain) < 0.46 + 1e-3 and closest_at_end(pushed) > 0.46 + 0.02
    for bad in (0.0, -1.0, float("nan"), True):
        with pytest.raises(TrainingError, match="push_below_m_s"):
            dad_rollouts(rep, scenario, _Still(), starts=[20], horizon_s=1.0, push_below_m_s=bad)


def test_newcomers_start_in_the_spawn_area_and_walk_along_e_d_to_arrive_when_they_were_recorded(replay):
    scenario, rep = replay
    first = np.argmax(rep.present, axis=0)
    k0 = int(np.sort(first[first > 30])[0]) - 12  # 1.2 s before somebody appears behind the entrance
    demos = dad_rollouts(rep, scenario, _Still(), starts=[k0], horizon_s=2.0, newcomer_speed_m_s=50.0,
                         spawn_newcomers=True)
    col = {int(i): c for c, i in enumerate(rep.ids)}
    newcomer = np.array([not rep.present[k0, col[int(p)]] for p in demos.pedestrian])
    assert newcomer.any() and np.all(demos.position_m[newcomer, 1] > 8.3)  # in the waiting area, behind the barrier
    world = to_world_frame(demos.action, np.cos(demos.heading_rad), np.sin(demos.heading_rad))
    navigation = scenario.navigation()
    for r in np.flatnonzero(newcomer):
        c = col[int(demos.pedestrian[r])]
        k_app = int(first[c])
        e_d, here = navigation.sample(demos.position_m[r:r + 1])
        _, there = navigation.sample(rep.position_m[k_app, c][None])
        expected = e_d[0] * (here[0] - there[0]) / (rep.time_s[k_app] - demos.time_s[r])  # along e_d, on time
        np.testing.assert_allclose(world[r], expected, atol=1e-9)
    start = newcomer & np.isclose(demos.time_s, rep.time_s[k0])
    arrivals = np.array([first[col[int(p)]] for p in demos.pedestrian[start]])
    entrance = np.array([0.9, 8.3])  # the 0.5 m entrance's middle: the earliest stand nearest it
    gaps = np.hypot(*(demos.position_m[start] - entrance).T)[np.argsort(arrivals, kind="stable")]
    assert start.sum() >= 2 and np.all(np.diff(gaps) > -0.3)
    plain = dad_rollouts(rep, scenario, _Still(), starts=[k0], horizon_s=1.0)
    assert not np.any(plain.position_m[:, 1] > 8.3)  # without them nobody stands there
    pushed = dad_rollouts(rep, scenario, _Still(), starts=[k0], horizon_s=2.0, newcomer_speed_m_s=50.0,
                          spawn_newcomers=True, push_below_m_s=0.3)  # the push leaves the labels' rules alone:
    first = np.isclose(pushed.time_s, rep.time_s[k0])  # before any step, the same decisions and labels
    np.testing.assert_array_equal(pushed.action[first], demos.action[np.isclose(demos.time_s, rep.time_s[k0])])


@pytest.mark.parametrize("to", ["recorded_first", "nearer_exit"])
def test_a_newcomer_too_close_behind_one_who_goes_first_steps_back_to_give_way(replay, to):
    scenario, rep = replay
    first = np.argmax(rep.present, axis=0)
    k0 = int(np.sort(first[first > 30])[0]) - 12
    gap, pull, most = 0.3, 1.0, 1.0
    demos = dad_rollouts(rep, scenario, _Still(), starts=[k0], horizon_s=2.0, newcomer_speed_m_s=50.0,
                         spawn_newcomers=True, give_way_gap_m=gap, give_way_to=to, pull_time_s=pull,
                         max_pull_m_s=most)
    assert demos.meta["give_way_to"] == to and demos.meta["give_way_gap_m"] == gap
    plain = dad_rollouts(rep, scenario, _Still(), starts=[k0], horizon_s=2.0, newcomer_speed_m_s=50.0,
                         spawn_newcomers=True)
    np.testing.assert_array_equal(demos.position_m, plain.position_m)  # standing still: the same states
    col = {int(i): c for c, i in enumerate(rep.ids)}
    arrival = np.array([rep.time_s[first[col[int(p)]]] if not rep.present[k0, col[int(p)]] else -np.inf
                        for p in demos.pedestrian])
    goes_first = arrival if to == "recorded_first" else scenario.navigation().sample(demos.position_m)[1]
    world = to_world_frame(demos.action, np.cos(demos.heading_rad), np.sin(demos.heading_rad))
    plain_world = to_world_frame(plain.action, np.cos(plain.heading_rad), np.sin(plain.heading_rad))
    navigation = scenario.navigation()
    r2 = 2.0 * float(scenario.radius_m()[0])
    stepped_back = 0
    k = np.searchsorted(rep.time_s, demos.time_s - 1e-9)
    walking = np.array([np.isfinite(a) and not rep.present[kk, col[int(p)]]
                        for a, kk, p in zip(arrival, k, demos.pedestrian)])
    for r in np.flatnonzero(walking):  # the labels of the newcomers not yet recorded, one by one
        e_d, _ = navigation.sample(demos.position_m[r:r + 1])
        same_time = np.flatnonzero(np.isclose(demos.time_s, demos.time_s[r]))
        owed = 0.0  # the room owed to those recorded first and ahead along e_d, brute force
        for o in same_time:
            d = demos.position_m[o] - demos.position_m[r]
            if o != r and goes_first[o] < goes_first[r] and d @ e_d[0] > 0.0:
                owed = max(owed, r2 + gap - float(np.hypot(*d)))
        back = -(world[r] @ e_d[0])  # a step back is along -e_d, at most the pull's speed
        if back > 0.0:
            stepped_back += 1
            np.testing.assert_allclose(world[r], -e_d[0] * back, atol=1e-9)
            assert back <= most + 1e-12
        else:  # or the walk of the plain rollout
            np.testing.assert_allclose(world[r], plain_world[r], atol=1e-12)
        # the room owed to those labelled too is given back at least (the unlabelled ones on the floor count too)
        assert max(back, 0.0) >= min(owed / pull, most) - 1e-9
    assert stepped_back > 0
    # only where two bodies cannot pass abreast: the labels give way in a run whose entrance (0.5 m) is narrower
    # than give_way_below_m, and are the plain walk in one whose entrance is not
    for below, same_as in ((0.6, demos), (0.5, plain)):
        only = dad_rollouts(rep, scenario, _Still(), starts=[k0], horizon_s=2.0, newcomer_speed_m_s=50.0,
                            spawn_newcomers=True, give_way_gap_m=gap, give_way_to=to, pull_time_s=pull,
                            max_pull_m_s=most, give_way_below_m=below)
        assert only.meta["give_way_below_m"] == below and only.meta["gives_way"] is (same_as is demos)
        np.testing.assert_array_equal(only.action, same_as.action)
    no_entrance = copy.copy(scenario)
    no_entrance.metadata = {k: v for k, v in scenario.metadata.items() if k != "entrance_width_m"}
    with pytest.raises(TrainingError, match="give_way_below_m needs a scenario with an entrance"):
        dad_rollouts(rep, no_entrance, _Still(), starts=[k0], horizon_s=1.0, give_way_gap_m=gap, give_way_below_m=1.0)
    with pytest.raises(TrainingError, match="give_way_gap_m must be None"):
        dad_rollouts(rep, scenario, _Still(), starts=[k0], horizon_s=1.0, give_way_gap_m=-0.1)
    with pytest.raises(TrainingError, match="give_way_to"):
        dad_rollouts(rep, scenario, _Still(), starts=[k0], horizon_s=1.0, give_way_gap_m=0.1, give_way_to="left")


def test_the_room_owed_is_to_those_ahead_along_e_d_whom_the_recording_shows_first():
    pos = np.array([[0.0, 0.0], [0.0, -0.5], [0.5, 0.0], [0.0, 0.6], [0.0, -0.2]])
    arrival = np.array([5.0, np.nan, 3.0, 4.0, 9.0])
    e_d = np.tile([0.0, -1.0], (5, 1))  # everybody heads towards -y
    owed = _give_way_m(pos, arrival, np.arange(5), e_d, 0.23, 0.1)
    # 0: owes 1 (on the floor from the start, 0.5 m ahead): 0.56 - 0.5; not 2 (beside), not 4 (later)
    # 1: nobody is before it; 2: nobody ahead within 0.56 m; 3: 0 is later; 4: 1 is 0.3 m ahead of it (and 0 behind)
    np.testing.assert_allclose(owed, [0.06, 0.0, 0.0, 0.0, 0.26], atol=1e-12)
    np.testing.assert_allclose(_give_way_m(pos, arrival, np.array([4]), e_d[:1], 0.23, 0.0), [0.16], atol=1e-12)


@pytest.mark.parametrize("to", ["recorded_first", "nearer_exit"])
def test_who_gives_way_is_the_later_one_or_the_one_farther_from_the_exit(to):
    """Two waiting newcomers in line before the 0.5 m entrance: A, behind, is recorded first; B, ahead, is nearer
    the exit. In the recording's order nobody owes room to anyone ahead of it; by travel time A steps back."""
    from types import SimpleNamespace

    from crowd_env.experiments.training.recorded_rollouts import _Setting, _targets

    scenario = uo_scenario(RUN)
    k_max = 40
    rep = SimpleNamespace(present=np.zeros((k_max, 2), bool), time_s=np.arange(k_max) * 0.1, decision_dt_s=0.1,
                          position_m=np.full((k_max, 2, 2), np.nan))
    pos = np.array([[0.9, 9.3], [0.9, 8.8]])  # A behind B, 0.5 m apart, both heading to the opening (-y)
    arrival = np.array([1.0, 2.0])  # A recorded first
    point = np.array([[0.9, 7.9], [0.9, 7.9]])
    gap = 0.3
    setting = _Setting(scenario, None, None, k_max - 1, 1.0, 1.0, 5.0, 0.0, None, True, (gap, to), None)
    target, waiting = _targets(rep, np.arange(2), 0, 0, pos, arrival, point, setting, 0.23)
    assert waiting.all()
    e_d, travel = scenario.navigation().sample(pos)
    assert travel[1] < travel[0] and e_d[0] @ (pos[1] - pos[0]) > 0 > e_d[1] @ (pos[0] - pos[1])
    assert target[1] @ e_d[1] > 0.0  # B walks on either way
    if to == "recorded_first":
        assert target[0] @ e_d[0] > 0.0  # B is later: A owes it nothing
    else:
        np.testing.assert_allclose(target[0], -e_d[0] * (0.46 + gap - 0.5), atol=1e-12)


def test_the_calibrated_agent_acts_on_a_recorded_crowd_as_on_a_simulator(replay):
    scenario, rep = replay
    k = int(np.argmax(rep.present.sum(axis=1) >= 8))
    rows = np.flatnonzero(rep.present[k])
    params = ModelParams()
    mine = calibrated_actions(rep, scenario, params, k, rows)
    from crowd_env.core.state import CrowdState
    from crowd_env.core.simulator import Simulator

    state = CrowdState.create(rep.position_m[k, rows], heading_rad=rep.heading_rad[k, rows],
                              velocity_m_s=rep.velocity_m_s[k, rows], desired_speed_m_s=1.34)
    sim = Simulator(state, geometry=scenario.geometry, params=params)  # this crowd stands apart: a simulator takes it
    theirs, _ = SocialForceAgent(scenario.navigation())(sim)
    np.testing.assert_allclose(mine, theirs, rtol=1e-12, atol=1e-12)
    assert isinstance(RecordedView(state, scenario.geometry.walls, params).neighbor_pairs(1.0), np.ndarray)


def test_training_options_are_checked():
    with pytest.raises(TrainingError, match="disjoint"):
        human_training_config({"validation_runs": ["uo-050-180-180"], "training_runs": ["uo-050-180-180"]})
    with pytest.raises(TrainingError, match="unknown training option"):
        human_training_config({"epochs": 3})
    with pytest.raises(TrainingError, match="dad_rounds must be an integer"):
        human_training_config({"dad_rounds": -1})
    assert human_training_config()["options"]["neighbor_radius_m"] == 3.0
    with pytest.raises(TrainingError, match="dad must be a dict of the rollouts' options"):
        human_training_config({"dad": {"horizon": 8.0}})
    with pytest.raises(TrainingError, match="radius_m must be a body radius"):
        human_training_config({"radius_m": 0.0})
    for bad, match in ((("give_way_to", "left"), "give_way_to must be one of"),
                       (("give_way_gap_m", -0.1), "give_way_gap_m must be None"),
                       (("give_way_below_m", 0.0), "give_way_below_m must be None"),
                       (("horizon_s", 0.0), "horizon_s must be a time"),
                       (("intent_gain", "2"), "intent_gain must be a gain"),
                       (("spawn_newcomers", 1), "spawn_newcomers must be true or false")):
        with pytest.raises(TrainingError, match=match):  # refused at once, not when the first round starts
            human_training_config({"dad": dict([bad])})


def test_a_partial_rollout_option_changes_only_what_it_names():
    cfg = human_training_config({"dad": {"horizon_s": 8.0}})
    assert cfg["dad"]["horizon_s"] == 8.0
    assert cfg["dad"]["spawn_newcomers"] is True  # the human policy's default, not the rollouts' bare one
    assert {k: v for k, v in cfg["dad"].items() if k != "horizon_s"} == \
        {k: v for k, v in human_training_config()["dad"].items() if k != "horizon_s"}


def test_the_training_body_is_the_presets_unless_given():
    from crowd_env.experiments.training.human_imitation import _replay
    from crowd_env.walking.presets import get_preset

    assert human_training_config()["radius_m"] == 0.23  # calibrated: Kabalan's Table 2
    joint = human_training_config(preset="joint")["radius_m"]
    assert joint == get_preset("joint").radius_m != 0.23
    cfg = human_training_config({"radius_m": 0.2, "training_runs": [RUN], "validation_runs": ["uo-060-180-180"]})
    scenario, replay = _replay(RUN, cfg)
    np.testing.assert_array_equal(scenario.radius_m(), 0.2)  # the replay's, the rollouts' and the spawned crowd's


def test_a_training_in_bodies_of_three_circles_reaches_the_replays_and_the_rollouts():
    from crowd_env.experiments.training.human_imitation import rollout_params
    from crowd_env.walking.presets import get_preset

    plain = human_training_config()
    assert "body_depth_m" not in plain["params"] and "body_depth_m" not in plain  # a disk's configuration as before
    assert rollout_params(plain) == get_preset("calibrated").params()
    cfg = human_training_config({"body_depth_m": 0.25}, preset="joint")
    assert cfg["params"]["body_depth_m"] == 0.25
    physics = rollout_params(cfg)  # the rollouts' physics: the preset's, in the body
    assert physics == get_preset("joint").params(body_depth_m=0.25)
    for bad in (-0.1, 0.43, True, "0.25"):  # joint's body is 0.428 m across
        with pytest.raises(TrainingError, match="body_depth_m must be"):
            human_training_config({"body_depth_m": bad}, preset="joint")


def test_a_training_with_the_shoulder_turn_turns_the_replays_headings_in_a_crowd(replay):
    """``shoulder_turn_critical_ratio``: the replays' and rollouts' physics turn the shoulders; a replay's headings
    turn where the recorded crowd narrows the way ahead below 1.3 shoulder widths (the queue before the 0.70 m exit)
    and stay the plain replay's where nothing does (the sparse corridor behind the 0.5 m entrance); bad ratios are
    refused."""
    from crowd_env.analysis.trajectories import Trajectories
    from crowd_env.experiments.training.human_imitation import rollout_params
    from crowd_env.walking.presets import get_preset

    assert "shoulder_turn_critical_ratio" not in human_training_config()["params"]
    cfg = human_training_config({"body_depth_m": 0.25, "shoulder_turn_critical_ratio": 1.3})
    assert rollout_params(cfg) == get_preset("calibrated").params(body_depth_m=0.25, shoulder_turn_critical_ratio=1.3)
    for bad in (-0.1, True, "1.3"):
        with pytest.raises(TrainingError, match="shoulder_turn_critical_ratio must be"):
            human_training_config({"shoulder_turn_critical_ratio": bad})
    params = ModelParams(**cfg["params"])

    def turn(run, plain=None):
        traj = recorded_uo_trajectories(run)
        keep = traj.frame < 400
        cut = Trajectories(traj.frame[keep], traj.id[keep], traj.x_m[keep], traj.y_m[keep], None, 16.0)
        plain = plain or replay_trajectories(cut, uo_scenario(run))
        turned = replay_trajectories(cut, uo_scenario(run), params=params)
        np.testing.assert_array_equal(turned.position_m, plain.position_m)
        return np.where(plain.present, np.abs(np.angle(np.exp(1j * (turned.heading_rad - plain.heading_rad)))), 0.0)

    assert turn(RUN, replay[1]).max() == 0.0  # the sparse corridor: nobody's way narrows below 1.3 × 0.46 m
    queue = turn("uo-180-180-070")
    assert queue.max() > np.radians(45) and np.mean(queue > np.radians(5)) > 0.05  # the queue turns its shoulders


def test_the_quick_training_writes_a_policy_resumes_without_redoing_and_refuses_to_overwrite(tmp_path, capsys):
    from crowd_env.cli.imitate import main

    out = tmp_path / "human"
    t0 = time.perf_counter()
    assert main(["train", "--quick", "--out", str(out)]) == 0
    assert time.perf_counter() - t0 < 60.0
    printed = capsys.readouterr().out
    assert "open-loop speed error on uo-060-180-180" in printed and "calibrated" in printed and "CPU" in printed
    summary = json.loads((out / "summary.json").read_text())
    assert summary["stages"] == ["bc", "dad_1"] and set(summary["timings"]) == {"demonstrations", "bc", "dad_1"}
    with open(out / "progress.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [(r["stage"], r["epoch"]) for r in rows] == [("bc", "1"), ("bc", "2"), ("dad_1", "1")]
    assert int(rows[-1]["samples"]) > int(rows[0]["samples"])  # the round's rollouts were added
    assert (out / "learning_curves.png").stat().st_size > 10_000
    policy = FileObservationPolicy(out / "policy.npz")
    assert policy.env_overrides["observation_frame"] == "egocentric" and policy.file.output == "clip_box"
    assert policy.file.meta["training_runs"] == ["uo-050-180-180"]
    stamp = (out / "policies" / "bc.npz").stat().st_mtime_ns
    assert main(["train", "--quick", "--out", str(out), "--resume"]) == 0
    assert (out / "policies" / "bc.npz").stat().st_mtime_ns == stamp  # nothing redone
    capsys.readouterr()
    assert main(["train", "--quick", "--out", str(out)]) == 2
    assert "pass resume=True (--resume)" in capsys.readouterr().err
    with pytest.raises(RunStoreError, match="different configuration"):
        from crowd_env.experiments.training.human_imitation import QUICK_HUMAN_TRAINING, train_human_policy

        train_human_policy(out, config={**QUICK_HUMAN_TRAINING, "bc_epochs": 3}, resume=True)


def test_corridor_miss_is_the_mean_miss_in_tolerance_units_and_counts_stalls():
    from crowd_env.analysis.corridor_runs import uo_run
    from crowd_env.experiments.validation.virtual_experiments import corridor_miss

    run = uo_run("uo-180-180-095")

    def record(seed, rho, v, flow, complete=True):
        return {"experiment": "corridor", "run": run.name, "seed": seed, "complete": complete, "stalled": not complete,
                "density_per_m2": rho, "speed_m_s": v, "flow_exit_per_s": flow, "flow_y0_per_s": flow,
                "min_gap_m": 0.0}

    exact = corridor_miss([record(0, run.density_per_m2, run.speed_m_s, run.flow_exit_per_s)])
    assert exact["miss"] == pytest.approx(0.0, abs=1e-12) and exact["failed"] == 0
    # +30 % density (2 tolerances), +0.05 m/s (0.5), −10 % flow (1): the mean, 3.5 / 3
    off = corridor_miss([record(0, 1.3 * run.density_per_m2, run.speed_m_s + 0.05, 0.9 * run.flow_exit_per_s),
                         record(1, 0.0, 0.0, 0.0, complete=False)])
    assert off["miss"] == pytest.approx(3.5 / 3) and off["failed"] == 1 and off["unmeasured"] == 0
    with pytest.raises(InputError, match="no corridor runs"):
        corridor_miss([])


def test_selection_rank_puts_stalls_then_unmeasured_quantities_before_the_miss():
    """A candidate whose runs all complete ranks first; among those with a stalled run, one with every quantity
    measured (some seed of each run complete) ranks before one whose miss leaves a run out, however small that
    miss: a mean over fewer quantities is not comparable."""
    from crowd_env.analysis.corridor_runs import uo_run
    from crowd_env.experiments.validation.virtual_experiments import corridor_miss, selection_rank

    runs = [uo_run("uo-180-180-095"), uo_run("uo-180-180-070")]

    def record(run, seed, scale, complete=True):
        return {"experiment": "corridor", "run": run.name, "seed": seed, "complete": complete, "stalled": not complete,
                "density_per_m2": scale * run.density_per_m2, "speed_m_s": run.speed_m_s,
                "flow_exit_per_s": run.flow_exit_per_s, "flow_y0_per_s": run.flow_exit_per_s, "min_gap_m": 0.0}

    clean = corridor_miss([record(r, 0, 1.6) for r in runs])  # every run complete, far off in density
    partial = corridor_miss([record(runs[0], 0, 1.3), record(runs[1], 0, 1.3), record(runs[1], 1, 1.0, False)])
    left_out = corridor_miss([record(runs[0], 0, 1.0), record(runs[1], 0, 1.0, False)])  # exact, but one run never
    assert (clean["failed"], clean["unmeasured"]) == (0, 0) and clean["miss"] == pytest.approx(4.0 / 3)
    assert (partial["failed"], partial["unmeasured"]) == (1, 0) and partial["miss"] == pytest.approx(2.0 / 3)
    assert (left_out["failed"], left_out["unmeasured"]) == (1, 3) and left_out["miss"] == pytest.approx(0.0, abs=1e-12)
    ranked = sorted([left_out, partial, clean], key=selection_rank)
    assert ranked == [clean, partial, left_out]


def test_select_scores_policies_closed_loop_and_keeps_the_best(tmp_path, capsys):
    """Two shipped policies on one validation run (seed 0): the learned-from-people one passes the 0.95 m exit, the
    bottleneck's behaviour clone stalls there and ranks last; the best is copied, the runs stored (a second call runs
    nothing again); a missing file is refused."""
    from crowd_env.cli.imitate import main

    trained = Path(__file__).resolve().parents[3] / "baselines" / "trained"
    argv = ["select", str(trained / "bottleneck_bc.npz"), str(trained / "human_juelich.npz"), "--runs",
            "uo-180-180-095", "--seeds", "1", "--out", str(tmp_path)]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "kept candidate 1" in out
    assert (tmp_path / "policy.npz").read_bytes() == (trained / "human_juelich.npz").read_bytes()
    rows = (tmp_path / "selection.md").read_text().splitlines()
    assert rows[2].endswith("| 1 |") and rows[3].startswith("| **1:")  # bottleneck_bc: its run stalled
    assert sorted(p.name for p in (tmp_path / "runs").iterdir()) == ["candidate_0", "candidate_1"]
    stored = {p: p.stat().st_mtime_ns for p in (tmp_path / "runs").rglob("*.json")}
    assert main(argv) == 0  # resumed from the store: nothing run again, the same choice
    assert {p: p.stat().st_mtime_ns for p in (tmp_path / "runs").rglob("*.json")} == stored
    assert "kept candidate 1" in capsys.readouterr().out
    assert main(["select", str(tmp_path / "nowhere.npz"), "--out", str(tmp_path / "x")]) == 2
    assert "no policy file at" in capsys.readouterr().err


def test_select_scores_each_policy_with_each_push_gate(tmp_path, capsys):
    """``--push-below``: the shipped policy by name, alone and with the model's push for walkers slower than 0.3 m/s,
    on the 0.5 m entrance (seed 0): alone it wedges there (stalled, ranked last), with the push it passes; the
    gated candidate is kept and the command says how to run it. Bad gates are refused by name."""
    from crowd_env.cli.imitate import main

    trained = Path(__file__).resolve().parents[3] / "baselines" / "trained"
    argv = ["select", "human_juelich", "--runs", "uo-050-180-180", "--seeds", "1", "--push-below", "off", "0.3",
            "--out", str(tmp_path)]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "kept candidate 1" in out and "--policy-social-force --policy-social-force-below 0.3" in out
    rows = (tmp_path / "selection.md").read_text().splitlines()
    assert "push" not in rows[2] and rows[2].endswith("| 1 |")  # the policy alone: stalled
    assert rows[3].startswith("| **1:") and "+ push below 0.3 m/s" in rows[3] and rows[3].endswith("| **0** |")
    assert (tmp_path / "policy.npz").read_bytes() == (trained / "human_juelich.npz").read_bytes()
    stored = [json.loads(p.read_text()) for p in (tmp_path / "runs" / "candidate_1").rglob("*.json")
              if "record" in p.read_text()]
    assert [s["task"]["policy"].get("social_force_below_m_s") for s in stored] == [0.3]
    for bad in ("0", "-1", "fast", "nan"):
        assert main(["select", "human_juelich", "--push-below", bad, "--out", str(tmp_path / "x")]) == 2
        assert "--push-below takes" in capsys.readouterr().err
    assert main(["select", "no_such_policy", "--out", str(tmp_path / "x")]) == 2
    assert "no_such_policy" in capsys.readouterr().err
