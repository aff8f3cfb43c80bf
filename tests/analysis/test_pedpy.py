"""Issue 6: trajectories in PedPy's formats, and PedPy's measures against crowd_env's own (two implementations).

One bottleneck run (b = 1.0 m, N = 30, seed 0, h = 0.01 s) is recorded at 25 frames/s (every 4th step),
exported, read back with ``pedpy.load_trajectory_from_txt`` and measured with PedPy. Tolerances:

- crossing times: crowd_env interpolates the passage inside the 0.01 s step; PedPy reports the first
  frame whose movement from the previous frame crosses the line, so t_PedPy - t_crowd_env lies in
  [0, 1/fps) = [0, 0.04 s) for every pedestrian (one frame of sampling);
- flow J = N/Δt over the passage window: each end moves by less than one frame, so
  |Δt_PedPy - Δt| < 1/fps and |J_PedPy/J - 1| < (1/fps)/Δt (about 0.3 % here); PedPy's compute_flow
  counts one frame more (Δf + 1), hence < 2/fps there;
- density: both count centres strictly inside the area at the same instants, so at every frame they
  are equal (frames with a centre within the file's 1 µm rounding of the area boundary excepted);
  the run's mean over the stationary window uses all 100 steps/s, PedPy's frames only every 4th,
  whose mean differs by at most (k·TV + 4k·max ρ)/n (TV: total variation of the 100 Hz series in the
  window, n its samples; a few per cent of the mean here).
"""
import json
import math
from pathlib import Path

import numpy as np
import pytest
import shapely

pedpy = pytest.importorskip("pedpy")

from baselines import SocialForceAgent  # noqa: E402
from crowd_env.analysis.flow import MeasurementLine, trajectory_crossings  # noqa: E402
from crowd_env.analysis.recorder import TrajectoryRecorder  # noqa: E402
from crowd_env.analysis.trajectories import (Trajectories, TrajectoryFormatError, export_run,  # noqa: E402
                                             fundamental_diagram_data, pedpy_measurement_area, pedpy_measurement_line,
                                             pedpy_walkable_area, read_geometry, steps_per_frame,
                                             trajectory_frame_rate)
from crowd_env.cli.fundamental_diagram import main as fundamental_diagram  # noqa: E402
from crowd_env.cli.reproduce_bottleneck import main as reproduce  # noqa: E402
from crowd_env.walking import ModelParams  # noqa: E402
from crowd_env.errors import InputError  # noqa: E402
from crowd_env.experiments.running.recording import record_run  # noqa: E402
from crowd_env.experiments.running.runner import run_scenario  # noqa: E402
from crowd_env.scenarios import make_scenario  # noqa: E402

FPS = 25.0
N = 30


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """One recorded run, exported; returns (scenario, RunResult, Trajectories, txt path, geometry path)."""
    sc = make_scenario("seyfried_bottleneck", width_m=1.0, n_pedestrians=N, seed=0, navigation_clearance_m=0.0)
    result, traj = record_run(sc, SocialForceAgent(sc.navigation()), ModelParams(), frame_rate_per_s=FPS, max_time_s=120)
    stem = tmp_path_factory.mktemp("traj") / "b1.000_n30_s0"
    txt, geometry_json, wkt = export_run(stem, traj, sc.geometry, comments=["test run"])
    return sc, result, traj, txt, geometry_json, wkt


@pytest.fixture(scope="module")
def loaded(run):
    """The exported trajectory as PedPy reads it, and the geometry read back."""
    _, _, _, txt, geometry_json, _ = run
    return pedpy.load_trajectory_from_txt(trajectory_file=Path(txt)), read_geometry(geometry_json)


def test_recording_does_not_change_the_run(run):
    sc, result, traj, *_ = run
    plain = run_scenario(sc, SocialForceAgent(sc.navigation()), ModelParams(), max_time_s=120)
    np.testing.assert_array_equal(plain.crossing_times_s, result.crossing_times_s)
    assert plain.n_steps == result.n_steps and result.n_evacuated == N
    # every 4th step from t = 0 to the last step with somebody inside, only active pedestrians
    assert traj.frame_rate_per_s == FPS and steps_per_frame(FPS, 0.01) == 4
    assert traj.frame.min() == 0 and traj.frame.max() == (result.n_steps - 1) // 4
    assert traj.n_pedestrians == N
    np.testing.assert_allclose(traj.time_s, traj.frame * 0.04)


def test_round_trip_txt_pedpy_and_geometry(run, loaded):
    sc, _, traj, txt, geometry_json, wkt = run
    traj_data, geometry = loaded
    header = Path(txt).read_text().splitlines()[:3]
    assert header == ["# test run", "# framerate: 25.0", "# id frame x/m y/m z/m heading/rad"]
    assert trajectory_frame_rate(txt) == FPS
    # PedPy's loader: frame rate from the header, metres, the same rows
    assert traj_data.frame_rate == FPS
    d = traj_data.data.sort_values(["id", "frame"])
    np.testing.assert_array_equal(d["id"].to_numpy(), traj.id)
    np.testing.assert_array_equal(d["frame"].to_numpy(), traj.frame)
    np.testing.assert_allclose(d["x"].to_numpy(), traj.x_m, atol=5.1e-7, rtol=0)
    np.testing.assert_allclose(d["y"].to_numpy(), traj.y_m, atol=5.1e-7, rtol=0)
    # our reader keeps the headings too; pedpy.TrajectoryData both ways
    back = Trajectories.read_txt(txt)
    assert back.frame_rate_per_s == FPS
    np.testing.assert_array_equal(back.frame, traj.frame)
    np.testing.assert_allclose(back.heading_rad, traj.heading_rad, atol=5.1e-7, rtol=0)
    again = Trajectories.from_pedpy(traj.to_pedpy())
    np.testing.assert_array_equal(again.x_m, traj.x_m)
    assert again.frame_rate_per_s == FPS and np.isnan(again.heading_rad).all()
    # geometry: walkable area (with the exit), lines and areas survive; PedPy accepts them
    assert geometry.navigable_area.equals(sc.geometry.navigable_area)
    np.testing.assert_array_equal(geometry.measurement_lines["bottleneck"], sc.geometry.measurement_lines["bottleneck"])
    for name in ("front", "inside"):
        assert geometry.measurement_areas[name].equals(sc.geometry.measurement_areas[name])
    assert json.loads(Path(geometry_json).read_text())["measurement_lines"]["bottleneck"] == [[1.4, -0.5], [1.4, 0.5]]
    walkable = pedpy.WalkableArea(Path(wkt).read_text())
    assert walkable.polygon.equals(pedpy_walkable_area(geometry).polygon)
    assert pedpy.is_trajectory_valid(traj_data=traj_data, walkable_area=walkable)


def test_flow_at_the_line_agrees_with_pedpy(run, loaded):
    sc, result, traj, *_ = run
    traj_data, geometry = loaded
    nt, crossing = pedpy.compute_n_t(traj_data=traj_data, measurement_line=pedpy_measurement_line(geometry))
    crossing = crossing.sort_values("frame")
    assert len(crossing) == N and int(nt["cumulative_pedestrians"].iloc[-1]) == N
    pp = dict(zip(crossing["id"].tolist(), (crossing["frame"] / FPS).tolist()))
    # per pedestrian: crowd_env's crossing on the exported frames (interpolated inside the frame) lies
    # within the frame that PedPy reports
    ends = np.asarray(sc.geometry.measurement_lines["bottleneck"])
    ids, t_frames = trajectory_crossings(traj.frame, traj.id, traj.x_m, traj.y_m, traj.frame_time_s,
                                         MeasurementLine(ends[0], ends[1]))
    assert sorted(pp) == sorted(ids.tolist()) == list(range(N))
    lag = np.array([pp[i] for i in ids.tolist()]) - t_frames
    assert lag.min() >= 0 and lag.max() < 1.0 / FPS + 1e-9, (lag.min(), lag.max())
    # the run's own crossing times (interpolated inside the 0.01 s step, no ids): PedPy's frame is the first
    # sampled instant at or after each, a monotone map, so the sorted lists keep the same one-frame lag
    t_run = np.sort(result.crossing_times_s)
    lag = np.sort(np.fromiter(pp.values(), float)) - t_run
    assert lag.min() >= -1e-9 and lag.max() < 1.0 / FPS + 1e-9, (lag.min(), lag.max())
    # J = N / Δt over the passage window (Eq. 22)
    dt_pp = (crossing["frame"].max() - crossing["frame"].min()) / FPS
    j_pp = N / dt_pp
    dt_run = t_run[-1] - t_run[0]
    assert abs(dt_pp - dt_run) < 1.0 / FPS
    assert abs(j_pp / result.flow_per_s - 1.0) < (1.0 / FPS) / dt_run
    # PedPy's compute_flow over one window spanning all passages: N fps / (Δf + 1)
    speed = pedpy.compute_individual_speed(traj_data=traj_data, frame_step=5,
                                           speed_calculation=pedpy.SpeedCalculation.BORDER_SINGLE_SIDED)
    delta = int(crossing["frame"].max() - crossing["frame"].min()) + 1
    flow = pedpy.compute_flow(nt=nt, crossing_frames=crossing, individual_speed=speed, delta_frame=delta,
                              frame_rate=FPS)
    assert len(flow) == 1
    assert abs(float(flow["flow"].iloc[0]) / result.flow_per_s - 1.0) < (2.0 / FPS) / dt_run
    assert 0.5 < float(flow["mean_speed"].iloc[0]) < 2.5


@pytest.mark.parametrize("area", ["inside", "front"])
def test_density_in_the_areas_agrees_with_pedpy(run, loaded, area):
    sc, result, traj, *_ = run
    traj_data, geometry = loaded
    k = 4
    rho = pedpy.compute_classic_density(traj_data=traj_data, measurement_area=pedpy_measurement_area(geometry, area))
    frame = rho["frame"].to_numpy()
    rho_pp = rho["density"].to_numpy()
    series = result.density_per_m2[area]  # value after step j is at time (j + 1) h
    f = frame[frame >= 1]
    ours = series[f * k - 1]
    # frames where a centre lies within the file's rounding of the area boundary may legitimately differ
    poly = sc.geometry.measurement_areas[area]
    near = shapely.distance(poly.boundary, shapely.points(traj.x_m, traj.y_m)) < 1e-6
    ambiguous = np.isin(f, traj.frame[near])
    assert ambiguous.sum() <= 2
    np.testing.assert_allclose(rho_pp[frame >= 1][~ambiguous], ours[~ambiguous], rtol=0, atol=1e-12)
    assert rho_pp[frame >= 1].max() > 0
    # mean over the stationary window: every 4th step (PedPy) vs every step (the run)
    t0, t1 = result.density_window_s()
    sel = (frame / FPS >= t0) & (frame / FPS <= t1)
    mean_pp = float(rho_pp[sel].mean())
    mean_run = result.mean_density_per_m2(area)
    t = (np.arange(series.size) + 1) * 0.01
    win = series[(t >= t0) & (t <= t1)]
    bound = (k * np.abs(np.diff(win)).sum() + 4 * k * win.max()) / win.size
    assert abs(mean_pp - mean_run) <= bound, (mean_pp, mean_run, bound)
    assert bound < 0.15 * mean_run


def test_speed_inside_agrees_with_pedpy(run, loaded):
    """The run's mean speed in the channel (instantaneous ‖u‖ of the pedestrians inside, every step)
    against PedPy's mean speed per frame from positions (centred difference over ±1 frame = 8 steps).
    Positions advance by h·u each step, so PedPy's speed is the length of u averaged over 0.08 s:
    they differ only by how much u turns or changes in that time."""
    sc, result, *_ = run
    traj_data, geometry = loaded
    data = fundamental_diagram_data(traj_data, pedpy_measurement_area(geometry, "inside"), speed_window_s=0.08)
    t0, t1 = result.density_window_s()
    sel = (data["time_s"] >= t0) & (data["time_s"] <= t1)
    assert sel.sum() > 100
    ours = result.speed_m_s["inside"][data["frame"][sel] * 4 - 1]  # step j ends at (j + 1) h
    np.testing.assert_allclose(data["speed_m_s"][sel], ours, rtol=0.01)
    assert float(data["speed_m_s"][sel].mean()) == pytest.approx(result.mean_speed_m_s("inside"), rel=0.005)


def test_fundamental_diagram_data_and_cli(run, loaded, tmp_path):
    sc, result, traj, txt, *_ = run
    traj_data, geometry = loaded
    d = fundamental_diagram_data(traj_data, pedpy_measurement_area(geometry, "inside"))
    assert d["frame"].size > 100 and np.all(d["density_per_m2"] > 0)
    for bad in (0.0, -0.4, float("nan"), "0.4"):
        with pytest.raises(InputError, match="speed_window_s must be a positive finite number"):
            fundamental_diagram_data(traj_data, pedpy_measurement_area(geometry, "inside"), speed_window_s=bad)
    np.testing.assert_allclose(d["specific_flow_per_m_s"], d["density_per_m2"] * d["speed_m_s"])
    # speeds from PedPy (±0.2 s window) vs a numpy central difference on the interior frames
    x = dict(zip(zip(traj.id.tolist(), traj.frame.tolist()), zip(traj.x_m, traj.y_m)))
    inside = sc.geometry.measurement_areas["inside"]
    f0 = int(d["frame"][len(d["frame"]) // 2])
    rows = np.flatnonzero(traj.frame == f0)
    pts = np.column_stack([traj.x_m[rows], traj.y_m[rows]])
    keep = rows[shapely.contains_xy(inside, pts[:, 0], pts[:, 1])]
    v = [math.dist(x[(i, f0 + 5)], x[(i, f0 - 5)]) * FPS / 10 for i in traj.id[keep].tolist()
         if (i, f0 + 5) in x and (i, f0 - 5) in x]
    assert len(v) == keep.size
    np.testing.assert_allclose(d["speed_m_s"][d["frame"] == f0][0], np.mean(v), rtol=1e-5)
    # channel continuity: time-mean of ρ v in the channel is the specific flow at its middle line (±25 %)
    t0, t1 = result.density_window_s()
    sel = (d["time_s"] >= t0) & (d["time_s"] <= t1)
    assert abs(d["specific_flow_per_m_s"][sel].mean() / result.specific_flow_per_m_s - 1) < 0.25
    # the script on the exported file
    out = tmp_path / "fd"
    assert fundamental_diagram(["--trajectory", str(txt), "--out", str(out)]) == 0
    lines = (out / "fundamental_diagram.csv").read_text().splitlines()
    assert lines[0] == "area,frame,time_s,density_per_m2,speed_m_s,specific_flow_per_m_s"
    assert sum(ln.startswith("inside,") for ln in lines) == d["frame"].size
    assert (out / "fundamental_diagram.png").stat().st_size > 10_000


def test_cli_trajectories_resume_and_config(tmp_path):
    out = tmp_path / "run"
    base = ["--widths", "1.0", "--sizes", "20", "--seeds", "1", "--jobs", "1", "--out", str(out), "--no-figures"]
    record = out / "runs" / "b1.000_n20_s0.json"
    txt = out / "trajectories" / "b1.000_n20_s0.txt"
    assert reproduce(base) == 0
    assert not txt.exists()
    config = (out / "config.json").read_text()
    first = json.loads(record.read_text())
    # switching trajectories on is not a configuration change: the run is recomputed once, same results
    assert reproduce(base + ["--trajectories"]) == 0
    assert (out / "config.json").read_text() == config
    second = json.loads(record.read_text())
    first.pop("wall_time_s"), second.pop("wall_time_s")
    assert first == second
    assert trajectory_frame_rate(txt) == 25.0
    td = pedpy.load_trajectory_from_txt(trajectory_file=txt)
    geometry = read_geometry(out / "trajectories" / "b1.000_n20_s0.geometry.json")
    _, crossing = pedpy.compute_n_t(traj_data=td, measurement_line=pedpy_measurement_line(geometry))
    assert len(crossing) == 20
    meta = json.loads((out / "trajectories" / "b1.000_n20_s0.geometry.json").read_text())["metadata"]
    assert meta["frame_rate_per_s"] == 25.0 and meta["n_pedestrians"] == 20
    # resume: nothing recomputed with or without the option
    stamps = record.stat().st_mtime_ns, txt.stat().st_mtime_ns
    assert reproduce(base + ["--trajectories"]) == 0
    assert reproduce(base) == 0
    assert (record.stat().st_mtime_ns, txt.stat().st_mtime_ns) == stamps
    # another frame rate: that run is redone at 10 frames/s
    assert reproduce(base + ["--trajectories", "--trajectory-fps", "10"]) == 0
    assert trajectory_frame_rate(txt) == 10.0
    with pytest.raises(SystemExit, match="trajectory-fps.*integer k"):
        reproduce(base + ["--trajectories", "--trajectory-fps", "30"])
    with pytest.raises(SystemExit, match="different configuration"):
        reproduce(base + ["--trajectories", "--A", "500"])
    assert not list((out / "trajectories").glob("*.tmp")) and not list((out / "runs").glob("*.tmp"))


def _write(path, text):
    path.write_text(text)
    return path


def test_bad_input_gives_clear_errors(tmp_path, run):
    *_, geometry_json, _ = run
    with pytest.raises(FileNotFoundError, match="does not exist"):
        Trajectories.read_txt(tmp_path / "missing.txt")
    with pytest.raises(TrajectoryFormatError, match="not a file"):
        Trajectories.read_txt(tmp_path)
    png = tmp_path / "x.png"
    png.write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00\xff\xfe\x00")
    with pytest.raises(TrajectoryFormatError, match="not a text trajectory"):
        Trajectories.read_txt(png)
    with pytest.raises(TrajectoryFormatError, match="no frame rate"):
        Trajectories.read_txt(_write(tmp_path / "a.txt", "# id frame x/m y/m z/m\n0 0 1.0 2.0 0.0\n"))
    assert len(Trajectories.read_txt(tmp_path / "a.txt", default_frame_rate_per_s=10.0)) == 1
    bad_files = [  # (file text, the error names the problem)
        ("#framerate: 0\n0 0 1.0 2.0 0.0\n", "positive"),
        ("#framerate: fast\n0 0 1.0 2.0 0.0\n", "holds no number"),
        ("#framerate: 25\n", "no trajectory rows"),
        ("#framerate: 25\nwidth_m,n,seed,flow\n1.0,20,0,1.1\n", "not a trajectory file: data row 1 has 1 whitespace"),
        ("#framerate: 25\nid frame x y z\n0 0 1 2 0\n", "not a trajectory file: non-numeric"),
        ("#framerate: 25\n0 0 1 2 0\n0 1 1\n", "row 2 has 3 whitespace"),
        ("#framerate: 25\n7 3 1 2 0\n7 3 1.1 2 0\n", "twice in frame 3"),
        ("#framerate: 25\n0.5 3 1 2 0\n", "integers"),
    ]
    for k, (text, match) in enumerate(bad_files):
        with pytest.raises(TrajectoryFormatError, match=match):
            Trajectories.read_txt(_write(tmp_path / f"bad{k}.txt", text))
    with pytest.raises(TrajectoryFormatError, match="non-finite position"):
        Trajectories([0], [0], [np.nan], [0.0], None, 25.0)
    for bad in (-1, 0.0, float("nan"), "25", True):  # a string or bool is not read as a frame rate
        with pytest.raises(TrajectoryFormatError, match="frame_rate_per_s must be a positive finite number"):
            Trajectories([0], [0], [0.0], [0.0], None, bad)
    # PedPy itself refuses a file without a frame rate: ours always carry one
    with pytest.raises(pedpy.PedPyValueError, match="Frame rate"):
        pedpy.load_trajectory_from_txt(trajectory_file=tmp_path / "a.txt")
    # centimetres (PeTrack style header) are converted like PedPy does
    cm = Trajectories.read_txt(_write(tmp_path / "cm.txt", "#framerate: 16\n# id frame x/cm y/cm z/cm\n1 0 150 -20 0\n"))
    assert cm.x_m[0] == 1.5 and cm.y_m[0] == -0.2 and cm.frame_rate_per_s == 16
    # recording must be evenly spaced; frame rates must be 1/(k h)
    rec = TrajectoryRecorder()
    for t in (0.0, 0.04, 0.1):
        rec.record(t, np.zeros((1, 2)))
    with pytest.raises(TrajectoryFormatError, match="not evenly spaced"):
        Trajectories.from_recorder(rec)
    with pytest.raises(TrajectoryFormatError, match="integer k"):
        steps_per_frame(30.0, 0.01)
    with pytest.raises(TrajectoryFormatError, match="framerate"):
        Trajectories([0], [0], [0.0], [0.0], None, 25.0).write_txt(tmp_path / "w.txt", comments=["framerate 10"])
    # geometry files
    with pytest.raises(TrajectoryFormatError, match="not a geometry JSON"):
        read_geometry(tmp_path / "a.txt")
    with pytest.raises(TrajectoryFormatError, match="walkable_area_wkt"):
        read_geometry(_write(tmp_path / "g.json", json.dumps({"lines": []})))
    broken = json.loads(Path(geometry_json).read_text())
    broken["walkable_area_wkt"] = "POLYGON ((0 0, 1 1, 0 1, 1 0, 0 0))"
    with pytest.raises(TrajectoryFormatError, match="not a valid polygon"):
        read_geometry(_write(tmp_path / "bow.json", json.dumps(broken)))
    with pytest.raises(SystemExit, match="no geometry file"):
        fundamental_diagram(["--trajectory", str(tmp_path / "a.txt"), "--out", str(tmp_path / "o")])
