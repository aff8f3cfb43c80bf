"""Behaviour cloning and its DAgger rounds (crowd_env.experiments.training.imitation): what the collection records
with the teacher driving and with another driver, and the rounds' bookkeeping."""
import csv

import numpy as np
import pytest

from baselines.reference_policies import as_policy
from crowd_env.errors import TrainingError
from crowd_env.experiments.training.imitation import collect_demonstrations, train_behaviour_cloning

CFG = {"scenario": "seyfried_bottleneck", "scenario_options": {"width_m": 1.0, "n_pedestrians": 8},
       "controlled": "all", "frame_skip": 10}


def test_a_driver_moves_the_crowd_and_the_teacher_labels_the_states_it_reaches():
    teacher = as_policy("baseline")
    x_t, y_t, steps_t = collect_demonstrations(CFG, [3], teacher=teacher, every=50, max_time_s=3.0)
    x_z, y_z, steps_z = collect_demonstrations(CFG, [3], teacher=teacher, every=50, max_time_s=3.0,
                                               driver=lambda obs: np.zeros((obs.shape[0], 2)))
    assert x_t.shape == x_z.shape == (8 * 6, x_t.shape[1]) and steps_t == steps_z == 8 * 300  # 3 s of 0.01 s
    np.testing.assert_array_equal(x_z[:8], x_t[:8])  # the same start, the same teacher label
    np.testing.assert_array_equal(y_z[:8], y_t[:8])
    speed_t = np.hypot(x_t[-8:, 0], x_t[-8:, 1])  # world frame: the first two entries are the velocity
    speed_z = np.hypot(x_z[-8:, 0], x_z[-8:, 1])
    assert speed_t.mean() > 0.5 and speed_z.max() < 0.05  # the teacher walks them; the zero driver holds them
    assert np.hypot(y_z[-8:, 0], y_z[-8:, 1]).mean() > 0.5  # still labelled with the teacher's intents to walk


def test_dagger_rounds_add_the_clone_s_states_and_refit(tmp_path):
    s = train_behaviour_cloning(CFG, str(tmp_path), teacher=as_policy("baseline"), seed=0, demo_seeds=[1],
                                dagger_seeds=[[2], [3]], epochs=2, max_time_s=4.0, progress=lambda *a: None)
    assert s["dagger_seeds"] == [[2], [3]] and len(s["samples_per_round"]) == 3
    assert s["samples"] == sum(s["samples_per_round"])
    with open(tmp_path / "progress.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [(int(r["round"]), int(r["epoch"])) for r in rows] == [(r, e) for r in range(3) for e in (1, 2)]
    with pytest.raises(TrainingError, match="epochs must be an integer >= 1"):
        train_behaviour_cloning(CFG, str(tmp_path), teacher=as_policy("baseline"), epochs=0)
