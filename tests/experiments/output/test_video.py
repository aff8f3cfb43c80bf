"""Videos (crowd_env.experiments.output.video, crowd-video, crowd-evaluate --video): frame counts and rates follow
simulated time, learned and background pedestrians and contact percussions are visible where they are,
trajectory files of the project's exporter become videos, and bad input raises the named error."""
from __future__ import annotations

import math
import sys

import numpy as np
import pytest

iio = pytest.importorskip("imageio.v3")

from baselines.reference_policies import as_policy  # noqa: E402
from crowd_env.analysis.trajectories import Trajectories, export_run  # noqa: E402
from crowd_env.envs.crowd_v0 import CrowdParallelEnv  # noqa: E402
from crowd_env.envs.rendering import (BACKGROUND_COLOR, CONTROLLED_COLOR, ContactPercussions,  # noqa: E402
                                      CrowdRenderer)
from crowd_env.errors import (InputError, MissingDependencyError, MissingFileError, NotFoundError,  # noqa: E402
                              PolicyError, ScenarioError, TrajectoryFormatError)
from crowd_env.experiments.running.evaluation import evaluate  # noqa: E402
from crowd_env.experiments.output.video import (frame_stride, per_policy, record_rollout,  # noqa: E402
                                         record_trajectory_file)
from crowd_env.scenarios import make_scenario  # noqa: E402

RESOLVER = "baselines.reference_policies:as_policy"
SCENARIO = "seyfried_bottleneck"
OPTIONS = {"n_pedestrians": 10}
LEARNED = [0, 3, 7]


def _n_frames(path) -> int:
    if str(path).endswith(".gif"):
        return iio.imread(path, index=None).shape[0]
    import imageio.v2 as iio2

    with iio2.get_reader(path, format="FFMPEG") as reader:
        return reader.count_frames()


def _size(path) -> tuple:
    if str(path).endswith(".gif"):
        frame = iio.imread(path, index=0)
    else:  # through imageio-ffmpeg, the writer's own plugin (the video extra), not PyAV
        import imageio.v2 as iio2

        with iio2.get_reader(path, format="FFMPEG") as reader:
            frame = reader.get_data(0)
    return frame.shape[1], frame.shape[0]


def _rgb(color):
    return np.round(255 * np.asarray(color)).astype(int)


@pytest.mark.parametrize("ext, fps, every, expected_fps, expected_every", [
    (".gif", None, None, 25.0, 4),   # default: real time, at most 25 fps (h = 0.01 s)
    (".mp4", 10.0, None, 10.0, 10),  # fps alone: a frame every 1/10 s simulated
    (".gif", None, 5, 20.0, 5),      # every alone: fps = 1 / (5 h)
])
def test_rollout_video_frames_follow_simulated_time(tmp_path, ext, fps, every, expected_fps, expected_every):
    path = tmp_path / f"rollout{ext}"
    metrics, info = record_rollout("baseline", path, SCENARIO, 0, scenario_options=OPTIONS,
                                   env_options={"controlled": LEARNED}, max_time_s=1.0, fps=fps, every=every,
                                   resolver=RESOLVER)
    assert metrics.n_evacuated == 0 and metrics.simulated_time_s == pytest.approx(1.0)  # nobody leaves in 1 s
    assert (info.fps, info.every, info.speed) == (pytest.approx(expected_fps), expected_every, pytest.approx(1.0))
    expected = math.floor(metrics.simulated_time_s * expected_fps + 1e-6) + 1  # t = 0 and every 1/fps s after
    assert info.n_frames == expected
    assert path.exists() and _n_frames(path) == expected
    assert _size(path) == info.size and info.size[0] % 16 == 0 and info.size[1] % 16 == 0
    if ext == ".gif":
        assert iio.immeta(path, index=1)["duration"] == pytest.approx(1000.0 / expected_fps)
    else:
        import imageio.v2 as iio2

        with iio2.get_reader(path, format="FFMPEG") as reader:
            assert reader.get_meta_data()["fps"] == pytest.approx(expected_fps)
    assert not list(tmp_path.glob(".*partial*"))  # the temporary file was renamed


def test_first_frame_shows_learned_and_background_colours_where_the_pedestrians_are(tmp_path):
    path = tmp_path / "colours.gif"
    record_rollout("zero", path, SCENARIO, 3, scenario_options=OPTIONS, env_options={"controlled": LEARNED},
                   max_time_s=0.1, resolver=RESOLVER)
    frame = iio.imread(path, index=0)[..., :3].astype(int)
    env = CrowdParallelEnv(scenario=SCENARIO, scenario_options=OPTIONS, controlled=LEARNED)
    env.reset(seed=3)  # the same episode start
    st = env.sim.state
    renderer = CrowdRenderer(env.geometry, env.controlled_mask, "rgb_array", pixel_multiple=16)
    assert (renderer.fig.canvas.get_width_height()) == (frame.shape[1], frame.shape[0])
    back = -np.column_stack([np.cos(st.heading_rad), np.sin(st.heading_rad)])  # away from the heading line
    px = np.round(renderer.pixel_of(st.position_m + 0.5 * st.radius_m[:, None] * back)).astype(int)
    renderer.close()
    for k in range(st.n):
        colour = frame[px[k, 1], px[k, 0]]
        want = _rgb(CONTROLLED_COLOR if k in LEARNED else BACKGROUND_COLOR)
        assert np.abs(colour - want).max() <= 12, (k, colour, want)
    # between two pedestrians nothing of theirs is drawn: the floor, not a pedestrian colour
    floor = frame[px[0, 1] - 40, 10]
    assert np.abs(floor - _rgb(CONTROLLED_COLOR)).max() > 40 and np.abs(floor - _rgb(BACKGROUND_COLOR)).max() > 40


def test_percussion_lines_are_drawn_between_touching_pedestrians_and_to_walls():
    geom = make_scenario("corridor", length_m=10.0, width_m=4.0, n_per_direction=1).geometry
    x0, y0, x1, y1 = geom.bounds
    pos = np.array([[x0 + 2.0, y0 + 2.0], [x0 + 6.0, y0 + 2.0]])
    renderer = CrowdRenderer(geom, np.array([True, False]), "rgb_array", pixel_multiple=16)
    heading = np.zeros(2)
    active = np.ones(2, dtype=bool)
    hook = ContactPercussions()
    hook.add([0], [1], [0], [12.0])  # a pair, in two sub-steps of one frame
    hook.add([0, 1], [1, -1], [0, 0], [-8.0, 30.0])  # the same pair again, and pedestrian 1 on wall segment 0
    i, j, wall, p = hook.take()
    contacts = dict(zip(zip(i.tolist(), j.tolist(), wall.tolist()), p.tolist()))
    assert contacts == {(0, 1, -1): pytest.approx(20.0), (1, -1, 0): pytest.approx(30.0)}
    assert hook.take()[3].size == 0  # a new sum per frame
    plain = renderer.draw_frame(pos, 0.23, heading, active).astype(int)
    drawn = renderer.draw_frame(pos, 0.23, heading, active, contacts=(i, j, wall, p)).astype(int)
    seg = geom.walls[0]
    a, b = seg[:2], seg[2:]
    t = np.clip(np.dot(pos[1] - a, b - a) / np.dot(b - a, b - a), 0, 1)
    to_wall = a + t * (b - a)
    mids = renderer.pixel_of([(pos[0] + pos[1]) / 2, (pos[1] + to_wall) / 2 + 0.1 * (to_wall - pos[1])])
    renderer.close()
    for col, row in np.round(mids).astype(int):
        assert np.abs(plain[row, col] - drawn[row, col]).max() > 60  # a line where there was floor
        r, g, bl = drawn[row, col]
        assert r > g + 40 and r > bl + 40  # reddish: the percussion colour map


def test_bodies_of_three_circles_are_drawn_as_their_circles():
    """With a body depth (crowd_env.core.body) each pedestrian is drawn as its three circles: a point 0.2 m out along
    the shoulders is body, a point ahead of the chest inside the paper's disk (0.19 m from the centre) is floor,
    where the disk of depth 0 covers it."""
    geom = make_scenario("corridor", length_m=10.0, width_m=4.0, n_per_direction=1).geometry
    x0, y0, _, _ = geom.bounds
    pos = np.array([[x0 + 2.0, y0 + 2.0]])
    heading = np.array([0.4])
    e = np.array([np.cos(0.4), np.sin(0.4)])
    side = np.array([-e[1], e[0]])
    points = [pos[0] + 0.2 * side, pos[0] + 0.18 * e + 0.06 * side]
    colours = {}
    for depth in (0.0, 0.25):
        renderer = CrowdRenderer(geom, np.array([True]), "rgb_array", pixel_multiple=16, body_depth_m=depth)
        frame = renderer.draw_frame(pos, 0.23, heading, np.ones(1, bool)).astype(int)
        colours[depth] = [frame[row, col] for col, row in np.round(renderer.pixel_of(points)).astype(int)]
        renderer.close()
    body = _rgb(CONTROLLED_COLOR)
    assert np.abs(colours[0.0][0] - body).max() <= 12 and np.abs(colours[0.0][1] - body).max() <= 12
    assert np.abs(colours[0.25][0] - body).max() <= 12  # a shoulder
    assert np.abs(colours[0.25][1] - body).max() > 40  # floor before the chest
    with pytest.raises(InputError, match="body_depth_m"):
        CrowdRenderer(geom, np.array([True]), "rgb_array", body_depth_m=-0.1)


def test_trajectory_file_of_the_exporter_becomes_a_video(tmp_path):
    from crowd_env.experiments.running.recording import record_run
    from crowd_env.walking.agent import SocialForceAgent

    scenario = make_scenario(SCENARIO, n_pedestrians=6, seed=0)
    _, traj = record_run(scenario, SocialForceAgent(scenario.navigation()), max_time_s=1.0)
    export_run(tmp_path / "run", traj, scenario.geometry)
    assert traj.frame_rate_per_s == 25.0 and int(traj.frame.max()) == 25
    info = record_trajectory_file(tmp_path / "run.txt", tmp_path / "run.mp4", every=2)
    assert info.n_frames == _n_frames(tmp_path / "run.mp4") == 25 // 2 + 1 and info.fps == pytest.approx(12.5)
    info = record_trajectory_file(tmp_path / "run.txt", tmp_path / "run.gif", max_time_s=0.4, learned_ids=[2])
    assert info.n_frames == _n_frames(tmp_path / "run.gif") == 11 and info.fps == pytest.approx(25.0)
    frame = iio.imread(tmp_path / "run.gif", index=0)[..., :3].astype(int)
    renderer = CrowdRenderer(scenario.geometry, np.zeros(6, bool), "rgb_array", pixel_multiple=16)
    at0 = traj.frame == 0
    back = -np.column_stack([np.cos(traj.heading_rad[at0]), np.sin(traj.heading_rad[at0])])
    px = np.round(renderer.pixel_of(np.column_stack([traj.x_m[at0], traj.y_m[at0]]) + 0.1 * back)).astype(int)
    renderer.close()
    for pid, (col, row) in zip(traj.id[at0].tolist(), px):
        want = _rgb(CONTROLLED_COLOR if pid == 2 else BACKGROUND_COLOR)
        assert np.abs(frame[row, col] - want).max() <= 12, pid


def test_evaluate_records_the_first_episode_of_each_policy_without_changing_metrics(tmp_path):
    recorders = []
    scen = [(SCENARIO, {"n_pedestrians": 6})]
    with_video = evaluate(["baseline", "zero"], scen, seeds=[0, 1], max_time_s=0.5, progress=None, resolve=as_policy,
                          video=per_policy(tmp_path / "ep.gif", written=recorders))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ep-baseline.gif", "ep-zero.gif"]
    assert [r.info.n_frames for r in recorders] == [13, 13]  # 0.5 s at 25 fps, one episode each
    assert _n_frames(tmp_path / "ep-zero.gif") == 13
    without = evaluate(["baseline", "zero"], scen, seeds=[0, 1], max_time_s=0.5, progress=None, resolve=as_policy)
    assert len(with_video) == len(without) == 4
    for a, b in zip(with_video, without):  # the recorder only reads the environment
        np.testing.assert_equal({**a.__dict__, "wall_time_s": 0.0}, {**b.__dict__, "wall_time_s": 0.0})


def test_commands_write_videos(tmp_path, capsys):
    from crowd_env.cli import evaluate as evaluate_cli
    from crowd_env.cli import video as video_cli

    assert video_cli.main(["rollout", "--policy", "zero", "--scenario", "corridor_bidirectional", "--scenario-option",
                           "n_per_direction=2", "--max-time", "0.2", "--fps", "10", "--out",
                           str(tmp_path / "sub" / "c.gif")]) == 0
    assert _n_frames(tmp_path / "sub" / "c.gif") == 3
    assert evaluate_cli.main(["--policies", "zero", "--seeds", "0", "--max-time", "0.2", "--scenario-option",
                              "n_pedestrians=4", "--out", str(tmp_path / "eval"), "--video",
                              str(tmp_path / "eval" / "v.gif")]) == 0
    assert _n_frames(tmp_path / "eval" / "v-zero.gif") == 6
    assert "v-zero.gif: 6 frames at 25 fps" in capsys.readouterr().out
    with pytest.raises(SystemExit, match=r"\.mp4 or \.gif"):
        video_cli.main(["trajectory", "x.txt", "--out", str(tmp_path / "x.avi")])


# -- bad input -------------------------------------------------------------------------------------
def _rollout(path, **kw):
    args = {"scenario_options": {"n_pedestrians": 4}, "max_time_s": 0.1, "resolver": RESOLVER, **kw}
    policy = args.pop("policy", "zero")
    scenario = args.pop("scenario", SCENARIO)
    return record_rollout(policy, path, scenario, 0, **args)


@pytest.mark.parametrize("kwargs, name, error, match", [
    ({"policy": "no_such_policy"}, "v.gif", PolicyError, "no_such_policy"),
    ({"policy": "no_such_module:Policy"}, "v.gif", PolicyError, "no_such_module"),
    ({"scenario": "no_such_scenario"}, "v.gif", ScenarioError, "no_such_scenario"),
    ({"scenario_options": {"bogus": 1}}, "v.gif", ScenarioError, "bogus"),
    ({}, "v.avi", InputError, r"'\.avi'.*\.mp4 or \.gif"),
    ({}, "v", InputError, r"\(none\).*\.mp4 or \.gif"),
    ({"fps": 0}, "v.gif", InputError, "fps must be a positive"),
    ({"fps": -5.0}, "v.mp4", InputError, "fps must be a positive"),
    ({"fps": float("nan")}, "v.mp4", InputError, "fps"),
    ({"every": 0}, "v.gif", InputError, "every"),
    ({"fps": 30}, "v.mp4", InputError, "does not follow simulated time"),
    ({"fps": 30, "every": 2}, "v.gif", InputError, "hundredths"),
    ({"max_time_s": 0.0}, "v.gif", InputError, "max_time_s"),
])
def test_bad_rollout_input_raises_the_named_error(tmp_path, kwargs, name, error, match):
    with pytest.raises(error, match=match):
        _rollout(tmp_path / name, **kwargs)
    assert not list(tmp_path.iterdir())  # nothing written


def test_missing_folder_and_missing_ffmpeg_are_named(tmp_path, monkeypatch):
    with pytest.raises(MissingFileError, match="does not exist"):
        _rollout(tmp_path / "no_such_folder" / "v.gif")
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # import imageio_ffmpeg now fails
    with pytest.raises(MissingDependencyError, match=r"crowd_env\[video\]"):
        _rollout(tmp_path / "v.mp4")
    _, info = _rollout(tmp_path / "v.gif")  # GIF needs only pillow
    assert info.n_frames == 3


def test_frame_stride_rules():
    assert frame_stride(0.01) == (4, pytest.approx(25.0))
    assert frame_stride(0.1) == (1, pytest.approx(10.0))
    assert frame_stride(0.04, gif=True) == (1, pytest.approx(25.0))
    assert frame_stride(1 / 30, gif=True)[0] == 3  # 10 fps: the first whole number of hundredths
    assert frame_stride(0.01, fps=50, every=4) == (4, pytest.approx(50.0))  # twice real time
    with pytest.raises(InputError, match="every"):
        frame_stride(0.01, every=1.5)
    for bad in (0, -25.0, float("inf"), "25", True):  # not coerced: "25" was read as 25 before
        with pytest.raises(InputError, match="fps must be a positive finite number"):
            frame_stride(0.01, fps=bad)
    for bad in (0.0, float("nan"), "0.01"):
        with pytest.raises(InputError, match="step_s must be a positive finite number"):
            frame_stride(bad)


@pytest.fixture
def exported(tmp_path):
    geom = make_scenario(SCENARIO, n_pedestrians=2).geometry
    traj = Trajectories(np.array([0, 1, 0, 1]), np.array([0, 0, 1, 1]), np.array([1.0, 1.1, 2.0, 2.1]),
                        np.array([1.0, 1.0, 1.5, 1.5]), np.zeros(4), 25.0)
    export_run(tmp_path / "run", traj, geom)
    return tmp_path


def test_bad_trajectory_input_raises_the_named_error(exported):
    d = exported
    assert record_trajectory_file(d / "run.txt", d / "ok.gif").n_frames == 2
    with pytest.raises(MissingFileError, match="no_such.txt"):
        record_trajectory_file(d / "no_such.txt", d / "v.gif")
    (d / "bad.txt").write_text("# framerate: 25\n1 2 oops 4 5\n")
    with pytest.raises(TrajectoryFormatError, match="non-numeric"):
        record_trajectory_file(d / "bad.txt", d / "v.gif", geometry=d / "run.geometry.json")
    (d / "short.txt").write_text("# framerate: 25\n1 2\n")
    with pytest.raises(TrajectoryFormatError, match="column"):
        record_trajectory_file(d / "short.txt", d / "v.gif", geometry=d / "run.geometry.json")
    (d / "alone.txt").write_text((d / "run.txt").read_text())
    with pytest.raises(MissingFileError, match=r"alone\.geometry\.json"):
        record_trajectory_file(d / "alone.txt", d / "v.gif")
    (d / "broken.json").write_text("{not json")
    with pytest.raises(TrajectoryFormatError, match="geometry"):
        record_trajectory_file(d / "run.txt", d / "v.gif", geometry=d / "broken.json")
    with pytest.raises(NotFoundError, match=r"\[5\]"):
        record_trajectory_file(d / "run.txt", d / "v.gif", learned_ids=[5])
    with pytest.raises(InputError, match="radius_m"):
        record_trajectory_file(d / "run.txt", d / "v.gif", radius_m=0.0)
    with pytest.raises(InputError, match=r"\.webm"):
        record_trajectory_file(d / "run.txt", d / "v.webm")
    with pytest.raises(InputError, match="fps"):
        record_trajectory_file(d / "run.txt", d / "v.gif", fps=-1)
    assert not list(d.glob("v.*"))


def test_mp4_quality_trades_file_size_and_is_checked(tmp_path):
    from crowd_env.experiments.output.video import RolloutVideo, VideoWriter

    rng = np.random.default_rng(0)
    frames = [(rng.random((64, 96, 3)) * 255).astype(np.uint8) for _ in range(20)]  # noise: hard to compress
    sizes = {}
    for q in (2, 9):
        path = tmp_path / f"q{q}.mp4"
        w = VideoWriter(path, 10.0, quality=q)
        for f in frames:
            w.append(f)
        w.close()
        sizes[q] = path.stat().st_size
    assert sizes[2] < 0.5 * sizes[9]
    for bad in (-1, 11, "high", True):
        with pytest.raises(InputError, match="quality must be a number from 0"):
            RolloutVideo(tmp_path / "x.mp4", quality=bad)
