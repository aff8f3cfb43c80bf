"""speed_profile and centred_velocities_m_s: the mean velocity along a direction, binned by where it is measured."""
import numpy as np
import pytest

from crowd_env.analysis.speed import centred_velocities_m_s, speed_profile
from crowd_env.analysis.trajectories import Trajectories
from crowd_env.errors import AnalysisError


def _walk(x_by_frame, *, pid=0, y=0.0, first_frame=0):
    frames = np.arange(first_frame, first_frame + len(x_by_frame))
    return frames, np.full(frames.size, pid), np.asarray(x_by_frame, float), np.full(frames.size, y)


def _trajectories(*walks, fps=10.0):
    cols = [np.concatenate(c) for c in zip(*walks)]
    return Trajectories(cols[0], cols[1], cols[2], cols[3], None, fps)


def test_a_walker_that_speeds_up_at_one_metre_has_both_speeds_in_their_bins():
    """0.5 m/s up to x = 1 m (frames 0-20), then 1.5 m/s (10 frames/s). Centred over ±1 frame, every row before
    1 m reads 0.5, every row after it 1.5, the row at 1 m the mean of both, 1.0; the first and last rows have
    none. Along −x the sign flips and the places mirror; the speed is the same either way."""
    x = np.concatenate([np.arange(0.0, 1.0, 0.05), 1.0 + np.arange(0.0, 2.0 + 1e-9, 0.15)])
    traj = _trajectories(_walk(x))
    v = centred_velocities_m_s(traj, frame_step=1)
    assert np.isnan(v[[0, -1]]).all() and v[1:-1, 1] == pytest.approx(0.0)
    assert v[1:20, 0] == pytest.approx(0.5) and v[20, 0] == pytest.approx(1.0) and v[21:-1, 0] == pytest.approx(1.5)
    prof = speed_profile(traj, direction=(2.0, 0.0), edges_m=[0.0, 1.0, 1.1, 3.0])
    assert prof.speed_m_s == pytest.approx([0.5, 1.0, 1.5]) and prof.rows.tolist() == [19, 1, 12]
    back = speed_profile(traj, direction=(-1.0, 0.0), edges_m=[-3.0, -1.05, -0.975, 0.0])  # bins: [lo, hi)
    assert back.speed_m_s == pytest.approx([-1.5, -1.0, -0.5])
    assert speed_profile(traj, direction=(-1.0, 0.0), edges_m=[-3.0, -1.1], magnitude=True).speed_m_s == \
        pytest.approx([1.5])
    # ±3 frames (0.6 s): rows 3-17 (x < 0.9 m) see only the slow walk; rows 18-22 straddle the change, each
    # 0.15 m further over 0.6 s than the one before (0.40 ... 0.80 m: 0.67 ... 1.33 m/s); rows 23-30 read 1.5
    wide = speed_profile(traj, direction=(1.0, 0.0), edges_m=[0.0, 0.9, 3.0], frame_step=3)
    assert wide.rows.tolist() == [15, 13] and wide.speed_m_s == pytest.approx([0.5, (5.0 + 8 * 1.5) / 13])


def test_only_rows_seen_at_every_frame_around_them_count_and_the_window_and_area_select():
    """Two walkers at 1 m/s (y = 0) and 2 m/s (y = 5); around a missing frame of the first no row has a velocity
    (across the gap it would read 1.5 m/s); the time window keeps the first second's rows, the area the second
    walker's, its edges included."""
    a = _walk(np.arange(0.0, 2.01, 0.1), pid=1)
    keep = np.ones(a[0].size, bool)
    keep[10] = False  # frame 10 missing
    a = tuple(c[keep] for c in a)
    b = _walk(np.arange(0.0, 4.01, 0.2), pid=2, y=5.0)
    traj = _trajectories(a, b)
    v = centred_velocities_m_s(traj, frame_step=1)
    assert np.isfinite(v[:, 0]).sum() == (20 - 4) + (21 - 2)  # walker 1 loses its ends and the two rows beside 10
    both = speed_profile(traj, direction=(1.0, 0.0), edges_m=[0.0, 5.0])
    assert both.rows.tolist() == [16 + 19] and both.speed_m_s[0] == pytest.approx((16 * 1.0 + 19 * 2.0) / 35)
    early = speed_profile(traj, direction=(1.0, 0.0), edges_m=[0.0, 5.0], window_s=(0.0, 1.0))
    assert early.rows.tolist() == [8 + 10]  # frames 1-8 of walker 1 (9 and 11 lack a side), 1-10 of walker 2
    upper = speed_profile(traj, direction=(1.0, 0.0), edges_m=[0.0, 2.0, 5.0], area=(-1.0, 5.0, 4.0, 6.0))
    assert upper.speed_m_s == pytest.approx([2.0, 2.0]) and upper.rows.tolist() == [9, 10]


def test_empty_bins_are_nan_with_no_rows_and_bad_arguments_are_named():
    traj = _trajectories(_walk(np.arange(0.0, 1.0, 0.1)))
    prof = speed_profile(traj, direction=(1.0, 0.0), edges_m=[0.0, 1.0, 2.0])
    assert prof.rows.tolist() == [8, 0] and np.isnan(prof.speed_m_s[1])
    for kwargs, match in (({"direction": (0.0, 0.0)}, "direction"), ({"direction": (np.nan, 1.0)}, "direction"),
                          ({"edges_m": [1.0, 1.0]}, "edges_m"), ({"edges_m": [2.0]}, "edges_m"),
                          ({"window_s": (2.0, 1.0)}, "window_s"), ({"frame_step": 0}, "frame_step"),
                          ({"frame_step": 1.5}, "frame_step"), ({"frame_step": True}, "frame_step")):
        args = {"direction": (1.0, 0.0), "edges_m": [0.0, 1.0], **kwargs}
        with pytest.raises(AnalysisError, match=match):
            speed_profile(traj, **args)
