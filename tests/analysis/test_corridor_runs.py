"""The Jülich corridor runs as measured (crowd_env.analysis.corridor_runs): a hand-made lattice whose Voronoi density,
speed and flows are known exactly, and the nine recordings measured back to their shipped rows."""
from __future__ import annotations

import numpy as np
import pytest
import shapely

pytest.importorskip("pedpy")

from crowd_env.analysis.corridor_runs import (STEADY_CROSSING_FRACTIONS, UO_FRAME_RATE_PER_S, crossing_times_s,
                                              juelich_uo_runs, measure_uo_run, recorded_uo_trajectories,
                                              steady_frames, uo_measurement_walkable_area, uo_run)
from crowd_env.analysis.trajectories import Trajectories
from crowd_env.errors import InputError, NotFoundError


def _lattice(*, columns_x_m, row_spacing_m, speed_m_s, frames, fps=UO_FRAME_RATE_PER_S):
    """Columns of walkers at ``columns_x_m``, rows ``row_spacing_m`` apart, all walking towards −y at ``speed_m_s``,
    from y = 7.9 m down to −6.4 m (inside the measurement's walkable area); ids follow each walker."""
    frame, ids, x, y = [], [], [], []
    n_rows = int(np.ceil((7.9 + 6.4 + speed_m_s * frames / fps) / row_spacing_m)) + 1
    for f in range(frames):
        t = f / fps
        for row in range(n_rows):
            yy = 7.9 - row * row_spacing_m + speed_m_s * frames / fps - speed_m_s * t
            if -6.4 <= yy <= 7.9:
                for c, xx in enumerate(columns_x_m):
                    frame.append(f)
                    ids.append(row * len(columns_x_m) + c)
                    x.append(xx)
                    y.append(yy)
    return Trajectories(np.array(frame), np.array(ids), np.array(x), np.array(y), None, fps)


def test_a_lattice_measures_its_exact_density_speed_and_flows():
    """Three columns 0.6 m apart (cells 0.6 m wide between the walls x = 0 and 1.8 m), rows 0.5 m apart, all at
    1 m/s: every Voronoi cell in the area is 0.6 m x 0.5 m, so ρ = 1 / 0.3 m² exactly, v = 1 m/s, and each
    column passes a line every 0.5 s: 6 per second across y = 0 and the exit."""
    traj = _lattice(columns_x_m=(0.3, 0.9, 1.5), row_spacing_m=0.5, speed_m_s=1.0, frames=400)
    m = measure_uo_run(traj, corridor_width_m=1.8, steady=(80, 320))
    assert m.density_per_m2 == pytest.approx(1 / 0.3, rel=1e-9) and m.density_sd_per_m2 == pytest.approx(0.0, abs=1e-9)
    assert m.speed_m_s == pytest.approx(1.0, rel=1e-9) and m.speed_sd_m_s == pytest.approx(0.0, abs=1e-9)
    duration = (320 - 80) / UO_FRAME_RATE_PER_S
    for flow in (m.flow_y0_per_s, m.flow_exit_per_s):
        assert abs(flow - 6.0) <= 3 / duration  # 6 per second, to the crossing at each end of the window
    # an exit line narrower than the corridor counts only the columns through it
    narrow = measure_uo_run(traj, corridor_width_m=1.8, exit_width_m=0.7, steady=(80, 320))
    assert abs(narrow.flow_exit_per_s - 2.0) <= 1 / duration and narrow.flow_y0_per_s == m.flow_y0_per_s
    # the window from the passages: the 15 % to the 90 % passage across y = 0
    auto = measure_uo_run(traj, corridor_width_m=1.8)
    times = crossing_times_s(traj, y_m=0.0, x_range_m=(0.0, 1.8))
    k0, k1 = (int(round(f * (times.size - 1))) for f in STEADY_CROSSING_FRACTIONS)
    assert (auto.steady_from_frame, auto.steady_to_frame) == (int(np.ceil(times[k0] * 16 - 1e-9)),
                                                              int(np.ceil(times[k1] * 16 - 1e-9)))
    assert auto.density_per_m2 == pytest.approx(1 / 0.3, rel=1e-9)


def test_rows_outside_the_camera_view_are_left_out():
    """A walker outside the measurement's walkable area (beside the floor, x = 3.5 m) would make PedPy refuse the
    frame; it is left out, and the figures are the lattice's."""
    traj = _lattice(columns_x_m=(0.3, 0.9, 1.5), row_spacing_m=0.5, speed_m_s=1.0, frames=200)
    extra = Trajectories(np.concatenate([traj.frame, np.arange(200)]), np.concatenate([traj.id, np.full(200, 10_000)]),
                         np.concatenate([traj.x_m, np.full(200, 3.5)]), np.concatenate([traj.y_m, np.full(200, 6.0)]),
                         None, UO_FRAME_RATE_PER_S)
    assert not uo_measurement_walkable_area(1.8).contains(shapely.Point(3.5, 6.0))
    m = measure_uo_run(extra, corridor_width_m=1.8, steady=(40, 160))
    assert m.density_per_m2 == pytest.approx(1 / 0.3, rel=1e-9)


def test_steady_frames_and_bad_input():
    assert steady_frames([1.0, 2.0, 3.0], frame_rate_per_s=16.0, fractions=(0.0, 1.0)) == (16, 48)
    with pytest.raises(InputError, match="at least two passages"):
        steady_frames([1.0], frame_rate_per_s=16.0)
    with pytest.raises(InputError, match="fractions"):
        steady_frames([1.0, 2.0], frame_rate_per_s=16.0, fractions=(0.5, 0.5))
    with pytest.raises(NotFoundError, match="uo-180-180-070"):
        uo_run("uo-999")
    traj = _lattice(columns_x_m=(0.9,), row_spacing_m=0.5, speed_m_s=1.0, frames=50)
    with pytest.raises(InputError, match="holds no recorded frame"):
        measure_uo_run(traj, steady=(500, 600))


def test_the_recordings_measure_back_to_their_rows():
    """Reference data: with each run's hand-chosen steady frames the measurement gives the shipped row (PedPy 1.5);
    with the rule a model run is measured by (the 15 % to 90 % passages across y = 0) it stays within 7 % in
    density, 0.05 m/s in speed and 7 % in exit flow of every row."""
    runs = juelich_uo_runs()
    assert [r.name for r in runs][:1] == ["uo-050-180-180"] and len(runs) == 9
    for run in runs:
        traj = recorded_uo_trajectories(run.name)
        assert traj.n_pedestrians == run.n_pedestrians
        hand = measure_uo_run(traj, corridor_width_m=run.corridor_width_m, exit_width_m=run.exit_width_m,
                              steady=(run.steady_from_frame, run.steady_to_frame))
        duration = (run.steady_to_frame - run.steady_from_frame) / UO_FRAME_RATE_PER_S
        # the low-density runs' cells differ in the third digit from the shipped ones (1.4 % at most)
        assert hand.density_per_m2 == pytest.approx(run.density_per_m2, rel=0.015), run.name
        assert hand.speed_m_s == pytest.approx(run.speed_m_s, abs=1e-3), run.name
        assert hand.flow_exit_per_s == pytest.approx(run.flow_exit_per_s, abs=1e-3), run.name
        assert abs(hand.flow_y0_per_s - run.flow_y0_per_s) <= 1.01 / duration, run.name
        assert hand.n_crossings_y0 == hand.n_crossings_exit == run.n_pedestrians
        rule = measure_uo_run(traj, corridor_width_m=run.corridor_width_m, exit_width_m=run.exit_width_m)
        assert rule.density_per_m2 == pytest.approx(run.density_per_m2, rel=0.07), run.name
        assert rule.speed_m_s == pytest.approx(run.speed_m_s, abs=0.05), run.name
        assert rule.flow_exit_per_s == pytest.approx(run.flow_exit_per_s, rel=0.07), run.name


def _walking(paths, fps):
    """Long-format trajectories of walkers following ``paths`` (callables of the time since their start, giving
    (x, y) or None once gone), each with its start time, sampled at ``fps``."""
    frame, ids, x, y = [], [], [], []
    for pid, (start, path) in enumerate(paths):
        f = int(round(fps * start))
        while (xy := path(f / fps - start)) is not None:
            frame.append(f)
            ids.append(pid)
            x.append(xy[0])
            y.append(xy[1])
            f += 1
    return Trajectories(np.array(frame), np.array(ids), np.array(x), np.array(y), None, fps)


def test_opening_entries_of_a_file_in_line_and_of_walkers_coming_from_beside():
    """An opening between y = 0.3 and 0 m, x in [0.65, 1.15] m (0.5 m wide). One file on its axis at 1 m/s, 1 m
    apart: when one leaves, the next is 0.7 m before the upstream face, on the axis, and enters 0.7 s later. Walkers
    that come down 0.4 m beside the axis to y = 0.6 m, slide sideways onto it and walk through, one every 1.5 s
    (each 1 s down, 0.4 s sideways, 0.6 s to leave): when one leaves the next has walked 0.5 m down, stands 0.8 m
    before the face and 0.4 m off the axis, beside the opening's span, and enters 1.2 s later."""
    from crowd_env.analysis.corridor_runs import opening_entries

    fps = UO_FRAME_RATE_PER_S
    line = _walking([(1.0 * i, lambda t: (0.9, 3.0 - t) if t <= 5.0 else None) for i in range(20)], fps)
    e = opening_entries(line, upstream_y_m=0.3, downstream_y_m=0.0, x_range_m=(0.65, 1.15),
                        window_frames=(0, int(fps * 100)))
    assert e.n_pairs == 19
    assert e.wait_median_s == pytest.approx(0.7, abs=1e-9) and e.before_median_m == pytest.approx(0.7, abs=1e-9)
    assert e.offset_median_m == pytest.approx(0.0, abs=1e-12) and e.share_beside == 0.0
    assert e.speed_median_m_s == pytest.approx(1.0, rel=1e-9)

    def beside(side):
        def path(t):
            if t <= 1.0:
                return 0.9 + 0.4 * side, 1.6 - t
            if t <= 1.4:
                return 0.9 + side * (0.4 - (t - 1.0)), 0.6
            return (0.9, 0.6 - (t - 1.4)) if t <= 4.0 else None
        return path

    sides = _walking([(1.5 * i, beside(1 if i % 2 else -1)) for i in range(12)], fps)
    e = opening_entries(sides, upstream_y_m=0.3, downstream_y_m=0.0, x_range_m=(0.65, 1.15),
                        window_frames=(0, int(fps * 100)))
    assert e.n_pairs == 11 and e.share_beside == 1.0
    assert e.wait_median_s == pytest.approx(1.2, abs=1e-9) and e.before_median_m == pytest.approx(0.8, abs=1e-9)
    assert e.offset_median_m == pytest.approx(0.4, abs=1e-9) and e.speed_median_m_s == pytest.approx(1.0, rel=1e-9)
    signs = np.sign([p[0] for p in e.positions_m])  # each next one from the other side, 0.4 m off, 0.8 m before
    assert len(e.positions_m) == 11 and np.all(signs[1:] == -signs[:-1])
    np.testing.assert_allclose(np.abs(e.positions_m), [[0.4, 0.8]] * 11, atol=1e-9)
    # the window counts the pairs by the follower's exit: walkers 1-5 leave at 3.5, 5, ..., 9.5 s
    assert opening_entries(sides, upstream_y_m=0.3, downstream_y_m=0.0, x_range_m=(0.65, 1.15),
                           window_frames=(int(fps * 3.0), int(fps * 10.0))).n_pairs == 5
    # trajectories that start past the upstream face (the recordings of the entrances) measure nothing
    late = _walking([(1.0 * i, lambda t: (0.9, 0.2 - t) if t <= 3.0 else None) for i in range(5)], fps)
    none = opening_entries(late, upstream_y_m=0.3, downstream_y_m=0.0, x_range_m=(0.65, 1.15),
                           window_frames=(0, int(fps * 100)))
    assert none.n_pairs == 0 and np.isnan(none.wait_median_s) and np.isnan(none.share_beside) and none.positions_m == ()
    with pytest.raises(InputError, match="upstream face"):
        opening_entries(line, upstream_y_m=0.0, downstream_y_m=0.3, x_range_m=(0.65, 1.15), window_frames=(0, 10))


def test_door_passage_and_approach_profile_of_a_known_stream():
    """Walkers at 0.8 m/s along x = 0.8 and 1.0 m alternately, one every 0.5 s: headways 0.5 s, speed 0.8 m/s at the
    line, crossing points 0.8 and 1.0 m, each passer 0.4 m behind and 0.2 m beside the one before (one file of them:
    0.8 m behind, in line); the lattice's bands hold their exact count."""
    from crowd_env.analysis.corridor_runs import approach_profile, door_passage

    fps = UO_FRAME_RATE_PER_S
    frame, ids, x, y = [], [], [], []
    for pid in range(40):
        start = 0.5 * pid  # enters at y = 0 at this time
        for f in range(int(fps * start), int(fps * (start + 7.0))):
            t = f / fps
            yy = -0.8 * (t - start)
            if yy < -5.5:
                break
            frame.append(f)
            ids.append(pid)
            x.append(0.8 if pid % 2 else 1.0)
            y.append(yy)
    traj = Trajectories(np.array(frame), np.array(ids), np.array(x), np.array(y), None, fps)
    d = door_passage(traj, y_m=-4.0, x_range_m=(0.55, 1.25), window_frames=(int(fps * 8), int(fps * 20)))
    assert d.headway_median_s == pytest.approx(0.5, abs=1e-9) and d.headway_mean_s == pytest.approx(0.5, abs=1e-9)
    assert d.speed_median_m_s == pytest.approx(0.8, rel=1e-9)
    assert d.n_passages == 24 + 1  # crossings at 8.0, 8.5, ..., 20.0 s: 13 at x = 1.0 m, 12 at 0.8 m
    assert d.lateral_sd_m == pytest.approx(np.std([1.0] * 13 + [0.8] * 12), rel=1e-9)
    assert (d.lateral_p10_m, d.lateral_p90_m) == (0.8, 1.0)
    assert np.isnan(d.share_off_axis)  # not asked
    # a zipper: each passer 0.8 m/s × 0.5 s = 0.4 m behind the one before and 0.2 m beside it
    assert d.following_median_m == pytest.approx(0.4, rel=1e-9)
    assert d.lateral_step_median_m == pytest.approx(0.2, rel=1e-9)
    assert d.side_alternation == 1.0  # x = 0.8 and 1.0 m about the middle 0.9 m, strictly in turn
    for off, share in ((0.05, 1.0), (0.15, 0.0)):  # every walker 0.1 m off the middle of (0.55, 1.25)
        assert door_passage(traj, y_m=-4.0, x_range_m=(0.55, 1.25), window_frames=(int(fps * 8), int(fps * 20)),
                            off_axis_m=off).share_off_axis == share
    with pytest.raises(InputError, match="off_axis_m"):
        door_passage(traj, y_m=-4.0, x_range_m=(0.55, 1.25), window_frames=(0, 10), off_axis_m=-0.1)
    narrow = door_passage(traj, y_m=-4.0, x_range_m=(0.9, 1.25), window_frames=(int(fps * 8), int(fps * 20)))
    assert narrow.headway_median_s == pytest.approx(1.0, abs=1e-9)  # only the walkers at x = 1.0 m
    assert narrow.following_median_m == pytest.approx(0.8, rel=1e-9)  # one file: 1 s apart at 0.8 m/s, in line
    assert narrow.lateral_step_median_m == 0.0
    assert narrow.side_alternation == 0.0
    centres, density, speed = approach_profile(traj, corridor_width_m=1.8, window_frames=(int(fps * 10), int(fps * 18)))
    # one walker every 0.4 m along y: 0.5 m bands hold 1.25 walkers on average, over 0.9 m² of corridor
    np.testing.assert_allclose(density, 1.25 / 0.9, rtol=0.03)
    np.testing.assert_allclose(speed, 0.8, rtol=1e-9)
    assert centres[0] == -3.75 and centres[-1] == -0.25


def test_neighbour_spacing_of_a_lattice_by_bearing():
    """Three files 0.35 m apart, rows 0.6 m apart, walking towards −y at 0.8 m/s: within 1 m a walker has the next row
    ahead and behind at 0.6 m (bearing 0°), the files beside at 0.35 and 0.70 m (90°) and the diagonals at
    0.695 m (30.3°) and 0.922 m (49.4°); beside, 4 of the 6 pairs of a row are closer than 0.46 m. Walkers slower
    than the threshold are not counted."""
    from crowd_env.analysis.corridor_runs import neighbour_spacing, uo_measurement_area

    traj = _lattice(columns_x_m=(0.5, 0.85, 1.2), row_spacing_m=0.6, speed_m_s=0.8, frames=64)
    sp = neighbour_spacing(traj, area=uo_measurement_area(1.8), window_frames=(20, 40), quantiles=(0.01, 0.5, 1.0))
    np.testing.assert_allclose(sp.distance_m[0], 0.6, atol=1e-9)  # 0-15°: the rows ahead and behind
    assert np.isnan(sp.distance_m[1]).all() and sp.n_pairs[1] == 0  # 15-30°: nobody
    np.testing.assert_allclose(sp.distance_m[2], np.hypot(0.35, 0.6), atol=1e-9)
    np.testing.assert_allclose(sp.distance_m[3], np.hypot(0.7, 0.6), atol=1e-9)
    assert sp.n_pairs[4] == 0
    np.testing.assert_allclose(sp.distance_m[5], [0.35, 0.35, 0.70], atol=1e-9)  # beside: 0.35 (4 of 6), 0.70
    assert sp.share_closer[5] == pytest.approx(4 / 6) and sp.share_closer[0] == 0.0
    assert 4 * sp.n_pairs[5] == 3 * sp.n_pairs[2]  # per row: 6 pairs beside, 8 on the 30° diagonals
    slow = neighbour_spacing(_lattice(columns_x_m=(0.5, 0.85, 1.2), row_spacing_m=0.6, speed_m_s=0.05, frames=64),
                             area=uo_measurement_area(1.8), window_frames=(20, 40))
    assert slow.n_pairs.sum() == 0 and np.isnan(slow.distance_m).all()


@pytest.mark.parametrize("bad", [{"bearing_edges_deg": (0.0, 100.0)}, {"bearing_edges_deg": (30.0, 10.0)},
                                 {"quantiles": (0.5, 1.5)}, {"max_distance_m": 0.0}, {"window_frames": (40, 20)}])
def test_neighbour_spacing_refuses_bad_input(bad):
    from crowd_env.analysis.corridor_runs import neighbour_spacing, uo_measurement_area
    from crowd_env.errors import ExperimentError

    traj = _lattice(columns_x_m=(0.5,), row_spacing_m=0.6, speed_m_s=0.8, frames=20)
    with pytest.raises(ExperimentError):
        neighbour_spacing(traj, **{"area": uo_measurement_area(1.8), "window_frames": (5, 15), **bad})


def _stream(start_times_s, *, speed_m_s=1.0, x_m=0.9, fps=UO_FRAME_RATE_PER_S):
    """One walker per start time, at x = ``x_m`` (a number or one per walker), walking towards −y at ``speed_m_s``
    from y = 9 m, where it stands at its start time: each crosses y = 8 − d at start + (1 + d) / speed."""
    frame, ids, x, y = [], [], [], []
    xs = np.broadcast_to(np.asarray(x_m, dtype=np.float64), (len(start_times_s),))
    for pid, start in enumerate(start_times_s):
        for f in range(int(np.ceil(start * fps)), int((start + 12.0 / speed_m_s) * fps)):
            frame.append(f)
            ids.append(pid)
            x.append(xs[pid])
            y.append(9.0 - speed_m_s * (f / fps - start))
    return Trajectories(np.array(frame), np.array(ids), np.array(x), np.array(y), None, fps)


def test_passage_lapses_are_the_gaps_between_successive_passages_over_the_lines_steady_state():
    from crowd_env.analysis.corridor_runs import lapse_summary, passage_lapses

    starts = np.cumsum([0.0, 0.5, 0.7, 3.0, 0.4, 0.6, 0.5, 0.8, 0.5, 0.6, 0.9])  # 11 walkers, one blocked 3 s
    traj = _stream(starts, x_m=[0.9, 0.9, 0.9, 0.9, 0.9, 0.9, 3.0, 0.9, 0.9, 0.9, 0.9])
    every = passage_lapses(traj, y_m=7.6, x_range_m=(-5.0, 5.0), fractions=(0.0, 1.0))
    np.testing.assert_allclose(every, np.diff(starts), atol=1e-9)  # the same speed for all: lapses of the starts
    # the line's own steady state: the 15 % to the 90 % passage of the 11 (ranks round(1.5) = 2 to round(9.0) = 9)
    np.testing.assert_allclose(passage_lapses(traj, y_m=7.6, x_range_m=(-5.0, 5.0)), np.diff(starts)[2:9], atol=1e-9)
    # only the passages within the line's x range: walker 6 passed beside it, its two lapses become one
    narrow = passage_lapses(traj, y_m=7.6, x_range_m=(0.5, 1.3), fractions=(0.0, 1.0))
    np.testing.assert_allclose(narrow, np.diff(np.delete(starts, 6)), atol=1e-9)
    s = lapse_summary(every)
    lapses = np.diff(starts)
    assert s.median_s == pytest.approx(np.median(lapses)) and s.mean_s == pytest.approx(lapses.mean())
    assert s.longest_s == pytest.approx(3.0) and s.q95_s == pytest.approx(np.quantile(lapses, 0.95))
    assert s.share_of_time_in_long == pytest.approx(3.0 / lapses.sum())  # the one lapse over 2 s
    assert s.flow_without_long_per_s == pytest.approx(9 / (lapses.sum() - 3.0))  # the nine others
    assert lapse_summary(every, long_s=0.65).share_of_time_in_long == pytest.approx((0.7 + 3.0 + 0.8 + 0.9)
                                                                                    / lapses.sum())
    with pytest.raises(InputError, match="at least two passages"):
        passage_lapses(traj, y_m=20.0, x_range_m=(-5.0, 5.0))
    with pytest.raises(InputError, match="x_range_m"):
        passage_lapses(traj, y_m=7.6, x_range_m=(1.0, 1.0))
    with pytest.raises(InputError, match="fractions"):
        passage_lapses(traj, y_m=7.6, x_range_m=(-5.0, 5.0), fractions=(0.5, 0.2))
    for bad in ([], [0.5, -0.1], [np.nan]):
        with pytest.raises(InputError, match="lapses_s must be"):
            lapse_summary(bad)
    with pytest.raises(InputError, match="long_s"):
        lapse_summary(every, long_s=0.0)


def test_no_narrowed_opening_of_the_recordings_is_blocked_for_two_seconds():
    """The recordings' lapses at the opening that limits each run (the entrance line 0.4 m past the barrier, or the
    narrowed exit): never 2 s or longer, the figure the docs compare the model's tail with."""
    from crowd_env.analysis.corridor_runs import lapse_summary
    from crowd_env.experiments.validation.corridor_runs import recorded_passage_figures

    for run in juelich_uo_runs():
        key = "exit_lapses_s" if run.exit_width_m < run.entrance_width_m else "entrance_lapses_s"
        lapses = recorded_passage_figures(run.name)[key]
        assert 40 <= len(lapses) < run.n_pedestrians  # the 15-90 % passages of everybody seen crossing
        s = lapse_summary(lapses)
        assert s.longest_s < 2.0 and s.share_of_time_in_long == 0.0, (run.name, s)
        if key == "exit_lapses_s":  # the mean lapse is the inverse of the exit flow (over another window: 3 %)
            assert 1.0 / s.mean_s == pytest.approx(run.flow_exit_per_s, rel=0.03), (run.name, 1.0 / s.mean_s)
