"""RiMEA tests 5, 7, 9, 10, 11 and the features they need: premovement, speeds by age, assigned exits and
route choice between exits."""
import numpy as np
import pytest

from crowd_env.errors import ScenarioError
from crowd_env.experiments.validation.rimea import run_suite
from crowd_env.experiments.validation.rimea.base import run_crowd_env, start_times_s
from crowd_env.scenarios import make_scenario
from crowd_env.scenarios.demographics import WEIDMANN_SPEEDS_BY_AGE_M_S, desired_speeds_for_ages
from crowd_env.scenarios.rimea import rimea_scenario

ROOM = [(0.0, 0.0), (8.0, 0.0), (8.0, 5.0), (0.0, 5.0)]


def _two_walkers(premovement):
    return rimea_scenario("premovement_pair", ROOM, [[(0.0, 2.0), (0.0, 3.0)]], [(5.0, 0.5), (7.5, 0.5), (7.5, 4.5), (5.0, 4.5)],
                          2, position_m=[[6.0, 1.0], [6.0, 4.0]], premovement_s=premovement, desired_speed_m_s=1.2)


def test_a_pedestrian_stands_still_until_its_premovement_time_then_walks():
    run = run_crowd_env(_two_walkers([0.0, 3.0]), seed=0, max_time_s=30.0)
    start = start_times_s(run)
    # the one without premovement moves 5 cm within tau-ish (v = v0 (1 - exp(-t/tau)): 0.29 s at 1.2 m/s);
    # the other not a frame before 3 s, then just as fast
    assert 0.2 <= start[0] <= 0.4
    assert 3.2 <= start[1] <= 3.4
    t, xy = run.positions(1)
    assert np.abs(xy[t < 3.0] - xy[0]).max() == 0.0  # not a hair before its time
    assert run.complete


def test_premovement_reaches_the_rl_environment():
    from crowd_env.envs import crowd_v0

    env = crowd_v0.parallel_env(scenario=_two_walkers([0.0, 1.0]), frame_skip=10)
    env.reset(seed=0)
    start = env.sim.state.position_m.copy()
    for _ in range(5):  # 0.5 s of walking at 1 m/s along -x, for both agents
        env.step({a: np.array([-1.0, 0.0], np.float32) for a in env.agents})
    moved = np.hypot(*(env.sim.state.position_m - start).T)
    # ped_0 from rest towards 1 m/s with tau = 0.5 s: x(t) = t - tau (1 - exp(-t/tau)) = 0.184 m at 0.5 s;
    # ped_1's action is held at zero until t = 1 s
    assert moved[0] == pytest.approx(0.5 - 0.5 * (1 - np.exp(-1.0)), abs=0.01) and moved[1] == 0.0


def test_negative_premovement_is_refused_by_name():
    with pytest.raises(Exception, match="premovement_s"):
        _two_walkers([0.0, -1.0]).make_state()


def test_speeds_by_age_lie_in_their_bands_and_unknown_ages_are_refused():
    rng = np.random.default_rng(0)
    ages = np.repeat(list(WEIDMANN_SPEEDS_BY_AGE_M_S), 200)
    v = desired_speeds_for_ages(ages, rng)
    for a, (lo, hi) in WEIDMANN_SPEEDS_BY_AGE_M_S.items():
        sel = v[ages == a]
        assert sel.min() >= lo and sel.max() <= hi
        if hi > lo:  # uniform in the band: its mean near the middle (200 draws: sd of the mean ~ 0.02 (hi-lo))
            assert abs(sel.mean() - 0.5 * (lo + hi)) < 0.1 * (hi - lo)
    with pytest.raises(ScenarioError, match=r"no speed band for age\(s\) \[25.0\]"):
        desired_speeds_for_ages([25], rng)


def test_quickest_exit_choice_moves_pedestrians_to_the_far_door_as_the_near_one_queues():
    sc = make_scenario("rimea_11_route_choice", n_pedestrians=120)
    nearest = make_scenario("rimea_11_route_choice", n_pedestrians=120, route_choice=None)
    np.testing.assert_array_equal(sc.position_m, nearest.position_m)
    nav = sc.navigation()
    assert np.all(nav.destination == 0)  # at the start the near door is everybody's nearest
    run = run_crowd_env(sc, seed=0, max_time_s=300.0)
    assert run.complete and nav.n_switches > 0
    plain = run_crowd_env(nearest, seed=0, max_time_s=300.0)
    # nearest-exit routing sends everybody to the near door; route choice shares the load and empties the room sooner
    from crowd_env.experiments.validation.rimea.base import exits_used

    assert np.all(exits_used(plain, nearest.geometry) == 0)
    used = exits_used(run, sc.geometry)
    assert 0 < np.sum(used == 1) < np.sum(used == 0) + 10
    assert run.evacuation_time_s < 0.8 * plain.evacuation_time_s


def test_route_choice_needs_two_exits_and_no_fixed_destinations():
    from dataclasses import replace

    with pytest.raises(ScenarioError, match="route_choice needs two or more exits"):
        replace(make_scenario("rimea_1_corridor"), route_choice="quickest")
    with pytest.raises(ScenarioError, match="route_choice must be None or one of"):
        replace(make_scenario("rimea_11_route_choice", n_pedestrians=10), route_choice="fastest")


def test_the_quick_behaviour_tests():
    """Tests 7, 9 (quick: 200 persons), 10 and 11 (quick: 300) pass; test 5 fails for a measured cause: a
    pedestrian who starts walks into one still waiting and pushes it before its time (the calibrated
    model has no avoidance of a standing person beyond the social repulsion, which is weak at contact)."""
    results = {r.number: r for r in run_suite(["5", "7", "9", "10", "11"], quick=True, progress=None)}
    for n in ("7", "9", "10", "11"):
        assert results[n].passed() is True, (n, results[n].verdicts["crowd_env"].measured)
    v5 = results["5"].verdicts["crowd_env"]
    delay = np.asarray(v5.details["delay_s"])
    assert results["5"].passed() is False and np.nanmin(delay) < -1.0  # moved (pushed) long before its time
    free = delay[delay >= 0]
    assert free.size >= 3 and np.all(free <= 0.5)  # those not pushed start within 0.5 s of their time
    for r in results.values():
        assert r.min_gap_m["crowd_env"] >= -1e-3 and r.outside_m["crowd_env"] == 0.0
