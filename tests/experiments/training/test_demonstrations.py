"""Demonstrations from recorded trajectories (crowd_env.experiments.training.demonstrations): the actions integrate
back to the recorded positions, the observations are the environment's on the same state, the camera's edges are
handled, the file format round-trips, and the command writes a dataset from any PedPy file and a scenario."""
from __future__ import annotations

import dataclasses
import gzip
from importlib import resources

import numpy as np
import pytest

from crowd_env.analysis.corridor_runs import recorded_uo_trajectories, uo_scenario
from crowd_env.analysis.trajectories import Trajectories
from crowd_env.envs.crowd_v0 import CrowdParallelEnv
from crowd_env.errors import TrainingError, TrajectoryFormatError
from crowd_env.experiments.training.demonstrations import (HUMAN_POLICY_OPTIONS, demonstrations_from_replay,
                                                           demonstrations_from_trajectories, load_demonstrations,
                                                           policy_options, replay_trajectories)

RUN = "uo-050-180-180"  # the sparsest run: many decisions whose recorded crowd a disk crowd can stand in


def _cut(traj: Trajectories, keep) -> Trajectories:
    return Trajectories(traj.frame[keep], traj.id[keep], traj.x_m[keep], traj.y_m[keep], None, traj.frame_rate_per_s)


@pytest.fixture(scope="module")
def recording():
    traj = recorded_uo_trajectories(RUN)
    return _cut(traj, traj.frame < 330)  # the first 18 s: the first 30 people through the corridor


@pytest.fixture(scope="module")
def scenario():
    return uo_scenario(RUN)


def _by_pedestrian(demos):
    for pid in np.unique(demos.pedestrian):
        rows = np.flatnonzero(demos.pedestrian == pid)
        yield rows[np.argsort(demos.time_s[rows])]


@pytest.mark.parametrize("smoothing_s", [0.0, 0.5])
def test_actions_integrated_give_back_the_recorded_positions(recording, scenario, smoothing_s):
    demos = demonstrations_from_trajectories(recording, scenario, smoothing_s=smoothing_s)
    dt = demos.meta["decision_dt_s"]
    assert dt == pytest.approx(0.1) and demos.meta["options"]["observation_frame"] == "egocentric"
    world = demos.world_actions()
    raw = {(int(i), int(f)): (x, y) for i, f, x, y in zip(recording.id, recording.frame, recording.x_m, recording.y_m)}
    on_frames = 0
    for rows in _by_pedestrian(demos):
        assert np.allclose(np.diff(demos.time_s[rows]), dt)  # every pedestrian here is recorded without gaps
        walked = demos.position_m[rows[0]] + dt * np.cumsum(world[rows], axis=0)[:-1]
        np.testing.assert_allclose(walked, demos.position_m[rows[1:]], atol=1e-9)
        if smoothing_s == 0.0:  # without smoothing: the file's own positions where a decision falls on a frame
            for r in rows:
                frame = demos.time_s[r] * recording.frame_rate_per_s
                if abs(frame - round(frame)) < 1e-9:
                    np.testing.assert_allclose(demos.position_m[r], raw[(int(demos.pedestrian[r]), round(frame))],
                                               atol=1e-12)
                    on_frames += 1
    assert smoothing_s or on_frames > 200


def _env_scenario(scenario, replay, k):
    """The juelich_corridor scenario holding exactly the crowd of decision k (positions, velocities, headings)."""
    present = np.flatnonzero(replay.present[k])
    return present, dataclasses.replace(scenario, position_m=replay.position_m[k, present],
                                        heading_rad=replay.heading_rad[k, present],
                                        pedestrian_params={"radius_m": 0.23,
                                                           "velocity_m_s": replay.velocity_m_s[k, present]},
                                        navigation_field=scenario.navigation())


def _valid_decisions(replay, scenario, wanted: int):
    """Decisions whose recorded crowd a scenario accepts (no disks overlapping, none on a wall)."""
    found = []
    for k in range(20, replay.time_s.size - 1, 7):
        if replay.present[k].sum() < 6:
            continue
        try:
            found.append((k, *_env_scenario(scenario, replay, k)))
        except Exception:  # a recorded crowd closer than two radii: not a state of the environment
            continue
        if len(found) == wanted:
            break
    return found


@pytest.mark.parametrize("options", [{}, {"observation_frame": "world", "n_neighbors": 4, "n_rays": 8,
                                          "observation_components": ["velocity", "heading", "desired_direction",
                                                                     "travel_time", "neighbors", "wall_rays"]}])
def test_observations_equal_the_environments_on_the_same_state(recording, scenario, options):
    options = policy_options(options)
    replay = replay_trajectories(recording, scenario, options=options)
    demos = demonstrations_from_replay(replay, scenario, options)
    checked = 0
    for k, present, state_scenario in _valid_decisions(replay, scenario, 3):
        env = CrowdParallelEnv(scenario=state_scenario, controlled="all", **options)
        obs, _ = env.reset(seed=0)
        rows = np.flatnonzero(np.isclose(demos.time_s, replay.time_s[k]))
        for r in rows:
            agent = f"ped_{int(np.flatnonzero(replay.ids[present] == demos.pedestrian[r])[0])}"
            np.testing.assert_array_equal(demos.observation[r], obs[agent])
            checked += 1
    assert checked >= 10


def test_decisions_whose_neighbours_the_camera_may_miss_are_flagged(recording, scenario):
    """A camera that saw only y < 2 m: the decisions the edge rule keeps observe exactly the neighbours the whole
    recording gives them; among those it flags, some do not."""
    options = policy_options({"observation_frame": "world", "observation_components": ["neighbors"], "n_neighbors": 2,
                              "neighbor_radius_m": 2.0})
    full = demonstrations_from_trajectories(recording, scenario, options=options, smoothing_s=0.0)
    cut = demonstrations_from_trajectories(_cut(recording, recording.y_m < 2.0), scenario, options=options,
                                           smoothing_s=0.0)
    k = options["n_neighbors"]
    positions = np.r_[np.arange(0, 4 * k, 4), np.arange(1, 4 * k, 4), np.arange(4 * k, 5 * k)]  # Δx, Δy, mask
    index = {(int(p), round(t * 10)): r for r, (p, t) in enumerate(zip(full.pedestrian, full.time_s))}
    same = np.array([np.array_equal(cut.observation[r, positions], full.observation[index[(int(p), round(t * 10))],
                                                                                    positions])
                     for r, (p, t) in enumerate(zip(cut.pedestrian, cut.time_s))])
    assert cut.seen.sum() > 100 and (~cut.seen).sum() > 100
    assert same[cut.seen].all()
    assert not same[~cut.seen].all()
    assert np.all(cut.edge_distance_m[cut.seen] >= cut.reach_m[cut.seen])


def test_datasets_round_trip_and_other_files_are_refused(recording, scenario, tmp_path):
    demos = demonstrations_from_trajectories(_cut(recording, recording.frame < 150), scenario)
    path = demos.save(tmp_path / "d.npz")
    back = load_demonstrations(path)
    for name in demos.ARRAYS:
        np.testing.assert_array_equal(getattr(back, name), getattr(demos, name))
    assert back.options == policy_options() == {**HUMAN_POLICY_OPTIONS}
    assert back.meta["n_decisions"] == len(demos) and back.observation.dtype == np.float32
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    with pytest.raises(TrainingError, match="not a demonstrations file"):
        load_demonstrations(tmp_path / "other.npz")
    with pytest.raises(TrainingError, match="unknown policy option"):
        policy_options({"n_neighbours": 3})
    with pytest.raises(TrainingError, match="heading_target"):
        replay_trajectories(recording, scenario, options={"heading_target": "intent"})


def test_gzipped_files_in_centimetres_read_as_the_shipped_recording(tmp_path):
    raw = resources.files("crowd_env.analysis").joinpath("data", "juelich_uo", f"{RUN}.txt.gz").read_bytes()
    (tmp_path / "r.txt.gz").write_bytes(raw)
    read = Trajectories.read_txt(tmp_path / "r.txt.gz", default_frame_rate_per_s=16.0, unit="cm")
    shipped = recorded_uo_trajectories(RUN)
    np.testing.assert_allclose(read.x_m, shipped.x_m, rtol=1e-15, atol=1e-12)  # x / 100 against x × 0.01
    np.testing.assert_array_equal(read.frame, shipped.frame)
    (tmp_path / "bad.txt.gz").write_bytes(gzip.compress(b"\xff\xfe\x00garbage")[:10])
    with pytest.raises(TrajectoryFormatError, match="broken .gz"):
        Trajectories.read_txt(tmp_path / "bad.txt.gz", default_frame_rate_per_s=16.0)
    with pytest.raises(TrajectoryFormatError, match="unit must be"):
        Trajectories.read_txt(tmp_path / "r.txt.gz", default_frame_rate_per_s=16.0, unit="mm")


def test_the_command_turns_a_pedpy_file_and_a_scenario_into_a_dataset(recording, tmp_path, capsys):
    from crowd_env.cli.imitate import main

    cut = _cut(recording, recording.frame < 200)
    path = tmp_path / "run.txt"
    path.write_text("\n".join(f"{i} {f} {100 * x:.4f} {100 * y:.4f} 180" for i, f, x, y in
                              zip(cut.id, cut.frame, cut.x_m, cut.y_m)) + "\n")
    out = tmp_path / "demos.npz"
    assert main(["demonstrations", str(path), "--frame-rate", "16", "--unit", "cm", "--scenario", "juelich_corridor",
                 "--scenario-option", "entrance_width_m=0.5", "n_pedestrians=61", "--out", str(out)]) == 0
    assert "decisions of" in capsys.readouterr().out
    demos = load_demonstrations(out)
    expected = demonstrations_from_trajectories(cut, uo_scenario(RUN))
    np.testing.assert_allclose(demos.observation, expected.observation, atol=1e-5)
    assert demos.meta["scenario_options"] == {"entrance_width_m": 0.5, "n_pedestrians": 61}
    assert main(["demonstrations", str(path), "--frame-rate", "16", "--out", str(out)]) == 2
    assert "needs --scenario" in capsys.readouterr().err
    assert main(["demonstrations", "--out", str(out)]) == 2
    assert "one of them" in capsys.readouterr().err
