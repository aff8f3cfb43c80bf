"""Giving way at contact (crowd_env.walking.give_way): the push into a touched walker ahead taken out, by hand-worked
cases; the parameters checked by name, off by default; the compiled rollout equals stepping."""
import numpy as np
import pytest

from crowd_env.core.params import ParameterError
from crowd_env.walking import ModelParams
from crowd_env.walking.give_way import GiveWay, give_way

R = 0.23


def _apply(positions, intents, times, *, share=1.0, gap_m=0.05, period_m=0.0, radius=R):
    positions = np.asarray(positions, float)
    out = np.asarray(intents, float).copy()
    n = len(positions)
    pairs = np.array([(a, b) for a in range(n) for b in range(a + 1, n)], np.int64).reshape(-1, 2)
    changed = give_way(out, positions, np.full(n, radius), np.arange(n), np.asarray(times, float), pairs,
                       float(period_m), GiveWay(share, gap_m).checked().resolved())
    return out, changed


def test_the_one_behind_loses_its_push_towards_the_one_ahead():
    """Walker 0 touches walker 1 ahead along +x (T_1 < T_0): 0's intent (1.0, 0.5) keeps only its tangential part
    (0, 0.5) at share 1, half its push (0.5, 0.5) at share 0.5; walker 1 (pushing away from 0) is unchanged."""
    pos = [(0.0, 0.0), (2 * R + 0.01, 0.0)]
    intents = [(1.0, 0.5), (1.2, -0.3)]
    out, changed = _apply(pos, intents, [5.0, 4.0])
    np.testing.assert_allclose(out, [(0.0, 0.5), (1.2, -0.3)], atol=1e-15)
    assert changed == 1
    out, _ = _apply(pos, intents, [5.0, 4.0], share=0.5)
    np.testing.assert_allclose(out, [(0.5, 0.5), (1.2, -0.3)], atol=1e-15)


def test_along_the_line_of_centres_at_any_angle():
    """The push is taken out along n = (x_j − x_i)/‖x_j − x_i‖ whatever its direction: the result is orthogonal to
    n and keeps the intent's tangential part."""
    rng = np.random.default_rng(0)
    for _ in range(20):
        angle = rng.uniform(-np.pi, np.pi)
        n = np.array([np.cos(angle), np.sin(angle)])
        u = rng.normal(size=2)
        if u @ n <= 0:
            u = -u
        out, changed = _apply([(0.0, 0.0), tuple(2 * R * n)], [u, (0.0, 0.0)], [2.0, 1.0])
        assert changed == 1
        assert abs(out[0] @ n) < 1e-12
        np.testing.assert_allclose(out[0], u - (u @ n) * n, atol=1e-12)


def test_nothing_changes_apart_equal_times_or_moving_away():
    """Beyond ``gap_m``, at equal travel times (nobody ahead), or when the one behind does not push towards the one
    ahead, the intents are untouched; share 0 switches the rule off."""
    intents = [(1.0, 0.0), (1.0, 0.0)]
    for pos, times, share, gap in [([(0, 0), (2 * R + 0.06, 0)], [2.0, 1.0], 1.0, 0.05),
                                   ([(0, 0), (2 * R, 0)], [1.0, 1.0], 1.0, 0.05),
                                   ([(0, 0), (-2 * R, 0)], [2.0, 1.0], 1.0, 0.05),
                                   ([(0, 0), (2 * R, 0)], [2.0, 1.0], 0.0, 0.05)]:
        out, changed = _apply(pos, intents, times, share=share, gap_m=gap)
        np.testing.assert_array_equal(out, intents)
        assert changed == 0
    out, changed = _apply([(0, 0), (2 * R + 0.06, 0)], intents, [2.0, 1.0], gap_m=0.1)  # within a larger gap
    assert changed == 1 and out[0, 0] == 0.0


def test_periodic_seam():
    """In a periodic corridor of length L the one ahead across the seam (x = 0.2 beside x = L − 0.25) is ahead
    along +x, by the nearest image."""
    L = 10.0
    out, changed = _apply([(L - 0.25, 0.0), (0.2, 0.0)], [(1.0, 0.3), (1.0, 0.0)], [3.0, 2.0], period_m=L)
    assert changed == 1
    np.testing.assert_allclose(out[0], (0.0, 0.3), atol=1e-15)
    out, changed = _apply([(L - 0.25, 0.0), (0.2, 0.0)], [(1.0, 0.3), (1.0, 0.0)], [3.0, 2.0])
    assert changed == 0  # not periodic: 9.55 m apart


def test_parameters_are_checked_by_name_and_default_off():
    assert ModelParams().give_way_share == 0.0
    assert ModelParams(give_way_share=0.5, give_way_gap_m=0.02).walking.give_way == GiveWay(0.5, 0.02)
    for name, value, match in [("give_way_share", 1.5, "give_way_share must be <= 1"),
                               ("give_way_share", -0.1, "give_way_share must be >= 0"),
                               ("give_way_gap_m", -0.01, "give_way_gap_m must be >= 0"),
                               ("give_way_gap_m", float("nan"), "give_way_gap_m must be a finite number")]:
        with pytest.raises(ParameterError, match=match):
            ModelParams(**{name: value})


def test_compiled_rollout_equals_stepping_with_give_way():
    from crowd_env.walking.presets import get_preset

    from .rollout_check import assert_rollout_equals_stepping

    assert_rollout_equals_stepping(get_preset("calibrated").params().replace(give_way_share=1.0, give_way_gap_m=0.05),
                                   n_pedestrians=40, max_time_s=6.0)


def test_the_narrowed_exit_clogs_without_the_rule_and_empties_with_it_at_a_distance():
    """The mechanism of docs/validation/virtual_experiments.md ("Giving way"), on the 0.70 m exit of the Jülich
    corridor (uo-180-180-070, 148 walkers, seed 0) as the virtual experiments run it: the calibrated preset wedges
    (the stall rule fires); giving way within 5 cm (contact) still wedges; giving way within 0.3 m lets everyone out
    without an overlap beyond 1 mm."""
    from crowd_env.experiments.validation.corridor_runs import corridor_tasks, run_corridor_one
    from crowd_env.walking.presets import get_preset

    base = get_preset("calibrated").params()
    runs = {gap: run_corridor_one(corridor_tasks(base if gap is None else base.replace(give_way_share=1.0,
                                                                                        give_way_gap_m=gap),
                                                 runs="uo-180-180-070", seeds=(0,))[0])
            for gap in (None, 0.05, 0.3)}
    assert runs[None]["stalled"] and runs[0.05]["stalled"]
    far = runs[0.3]
    assert far["complete"] and not far["stalled"] and far["n_evacuated"] == 148 and far["min_gap_m"] > -1e-3
