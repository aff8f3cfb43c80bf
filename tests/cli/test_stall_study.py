"""crowd-stall-study picks the first stall of the first preset (other than calibrated) that stalls and draws it
beside calibrated's run of the same seed; the runs are faked here (the real ones take minutes)."""
import numpy as np

import crowd_env.cli.stall_study as cli


def _row(job, stalled):
    snap = None
    if "snapshot_s" in job:
        p = np.array([[-0.2, 0.26], [-0.2, -0.25]])
        snap = {"time_s": job["snapshot_s"], "position_m": p, "e_d": np.array([[0.0, -1.0], [0.0, 1.0]]),
                "force_n": np.zeros((2, 2)), "speed_m_s": np.zeros(2), "intent_m_s": np.zeros((2, 2))}
    outline = np.array([[-8.0, -2.0], [0.0, -2.0], [0.0, 2.0], [-8.0, 2.0], [-8.0, -2.0]])
    return {**job, "complete": not stalled, "stalled": stalled, "stall_time_s": 50.0 if stalled else np.nan,
            "n_passed": 18 if stalled else 20, "specific_flow_per_m_s": np.nan if stalled else 1.0,
            "min_gap_m": 0.0, "time_s": 50.0, "snapshot": snap, "outline_m": outline}


def test_the_first_stall_of_any_preset_is_drawn_beside_calibrated(tmp_path, monkeypatch, capsys):
    drawn = []

    def fake_run_jobs(jobs, workers):
        return [_row(j, stalled=(j["preset"] == "vision" and j["seed"] >= 1)) for j in jobs]

    def fake_figure(stalled, calibrated, path, title=None):
        drawn.append((stalled["preset"], stalled["seed"], calibrated["preset"], calibrated["seed"], title))
        return path

    monkeypatch.setattr(cli, "run_jobs", fake_run_jobs)
    monkeypatch.setattr(cli, "figure", fake_figure)
    assert cli.main(["--presets", "calibrated", "vision", "--seeds", "3", "--out", str(tmp_path)]) == 0
    assert "vision: 2 of 3 stalled" in capsys.readouterr().out
    (preset, seed, other, other_seed, title), = drawn
    assert (preset, seed, other, other_seed) == ("vision", 1, "calibrated", 1)
    assert "preset vision stalled" in title


def test_the_stall_figure_draws_any_preset(tmp_path):
    from crowd_env.experiments.validation.stall_study import figure

    stalled = _row({"preset": "vision", "seed": 6, "width_m": 0.8, "n": 20, "snapshot_s": 50.0}, True)
    other = _row({"preset": "calibrated", "seed": 6, "width_m": 0.8, "n": 20, "snapshot_s": 50.0}, False)
    path = figure(stalled, other, tmp_path / "s.png", "a title")
    assert path.stat().st_size > 0
