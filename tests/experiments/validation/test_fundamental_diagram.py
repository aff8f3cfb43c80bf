"""The fundamental-diagram sweep (periodic corridor and single-file ring) against the shipped experiments, reduced:
a few densities and seeds. The ``vision`` preset has a density-speed relation; ``calibrated`` has none (issue 36)."""
import numpy as np
import pytest

from crowd_env.analysis.fd_reference import juelich_corridor, single_file, weidmann_speed_m_s
from crowd_env.walking.presets import get_preset
from crowd_env.experiments.validation.fundamental_diagram import fd_tasks, headway_fit, run_fd_one, summarise_fd


def _summary(preset, corridor=(), single=(), seeds=(0, 1)):
    tasks = fd_tasks([s for s, d in (("corridor", corridor), ("single_file", single)) if d],
                     {"corridor": corridor, "single_file": single}, seeds, get_preset(preset).params(),
                     max_time_s=25.0, transient_s=10.0)
    return summarise_fd([run_fd_one(t) for t in tasks])


def test_vision_corridor_speeds_follow_the_juelich_bins():
    s = _summary("vision", corridor=(1.0, 1.6, 2.6))
    speeds = [r["speed_m_s"] for r in s["corridor"]]
    assert speeds[0] > speeds[1] > speeds[2]  # never rising with density
    for r in s["corridor"]:
        assert abs(r["difference_m_s"]) <= 0.15, r
        assert r["min_gap_m"] >= -1e-9  # no overlap across the seam or anywhere


def test_calibrated_preset_has_no_fundamental_diagram():
    """The defect issue 36 names, measured: at 2.6 /m² the calibrated crowd walks at more than twice the
    experiment's speed."""
    s = _summary("calibrated", corridor=(2.6,), seeds=(0,))
    r = s["corridor"][0]
    assert r["speed_m_s"] > 2.0 * r["experiment_speed_m_s"]


def test_vision_single_file_follows_seyfried():
    s = _summary("vision", single=(0.7, 1.4))
    for r in s["single_file"]:
        assert abs(r["difference_m_s"]) <= 0.1, r
    a, b, k = s["single_file_fit"]
    assert k > 100 and 0.1 < a < 0.5 and 0.8 < b < 1.6  # a space that grows with speed, as measured


def test_headway_fit_recovers_a_line():
    v = np.linspace(0.1, 1.2, 50)
    a, b, k = headway_fit(0.34 + 1.08 * v, v)
    assert (a, b, k) == (pytest.approx(0.34), pytest.approx(1.08), 50)
    assert np.isnan(headway_fit([1.0], [0.5])[0])


def test_reference_tables():
    jc, sf = juelich_corridor(), single_file()
    assert jc.density.size == 14 and sf.density.size == 6
    assert jc.speed_at(1.629) == pytest.approx(0.989) and np.isnan(jc.speed_at(5.0))
    # Weidmann: free speed at low density, zero at the jam density
    assert weidmann_speed_m_s(0.01) == pytest.approx(1.34, abs=1e-6) and weidmann_speed_m_s(5.4) == 0.0


def test_corridor_width_sets_the_strip_and_is_checked():
    params = get_preset("vision").params()
    (task,) = fd_tasks(["corridor"], {"corridor": [1.6]}, [0], params, corridor_width_m=1.0)
    assert task["width_m"] == 1.0 and task["n_pedestrians"] == round(1.6 * 20.0 * 1.0)
    (default,) = fd_tasks(["corridor"], {"corridor": [1.6]}, [0], params)
    assert default["width_m"] == 1.8
    from crowd_env.errors import InputError
    for bad in (0.0, -1.0, float("nan"), True, "1.0"):
        with pytest.raises(InputError, match="corridor_width_m"):
            fd_tasks(["corridor"], {"corridor": [1.6]}, [0], params, corridor_width_m=bad)


def test_vision_channel_of_a_door_is_slower_than_the_wide_corridor():
    """The door's deficit located (docs/validation/fundamental_diagram.md, "The door's channel"): at 1.6 /m² the
    vision crowd walks slower in a periodic channel 1 m wide than in the 1.8 m corridor, where Seyfried's 1 m
    channel walks faster (0.94-1.22 m/s) than the Jülich corridor (0.99 m/s)."""
    params = get_preset("vision").params()
    speed = {}
    for width in (1.0, 1.8):
        tasks = fd_tasks(["corridor"], {"corridor": [1.6]}, [0, 1], params, max_time_s=25.0, transient_s=10.0,
                         corridor_width_m=width)
        speed[width] = np.mean([run_fd_one(t)["speed_m_s"] for t in tasks])
    assert speed[1.0] < speed[1.8] - 0.05, speed
