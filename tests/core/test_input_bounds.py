"""The step's inputs at every magnitude (issue 37, items 6 and 8): ``Simulator.step`` either refuses an input
with an InputError naming the argument and the bound (``crowd_env.core.step.MAX_INPUT_SPEED_M_S``), or keeps
its invariants: every centre in the walkable area, no overlap beyond 1e-9 m, a finite energy."""
import functools
import math
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings, strategies as st
from shapely.geometry import Point

from crowd_env.core.state import min_gap_m
from crowd_env.core.step import MAX_INPUT_SPEED_M_S
from crowd_env.errors import InputError
from crowd_env.scenarios import make_scenario

N = 10
LARGEST = 1.7e308


@functools.lru_cache(maxsize=1)
def _scenario():
    return make_scenario("seyfried_bottleneck", n_pedestrians=N, seed=0)


def _check_invariants(sim, result, area):
    st_ = sim.state
    act = st_.active
    outside = [int(i) for i in np.flatnonzero(act) if not area.covers(Point(st_.position_m[i]))]
    assert not outside, f"centres outside the walkable area: {outside}"
    gap = min(min_gap_m(st_.position_m[act], st_.radius_m[act]), sim.min_gap_m())
    assert gap >= -1e-9, f"overlap of {-gap:.3g} m"
    assert math.isfinite(result.kinetic_energy_after_projection_j)
    assert np.isfinite(st_.velocity_m_s).all() and np.isfinite(st_.position_m).all()
    assert np.isfinite(st_.angular_velocity_rad_s).all() and np.isfinite(st_.heading_rad).all()


def test_huge_intents_of_the_issue_are_refused_naming_the_bound():
    """The reproduction: intents of 1e300 m/s used to leave 7 of 10 centres outside and the energy infinite."""
    sim = _scenario().make_simulator()
    before = sim.state.position_m.copy()
    with pytest.raises(InputError, match=r"intents_m_s of pedestrian 0 has magnitude 1\.414e\+300 m/s; the step "
                                         r"accepts at most 1000 m/s.*MAX_INPUT_SPEED_M_S"):
        sim.step(np.tile([1e300, -1e300], (N, 1)))
    np.testing.assert_array_equal(sim.state.position_m, before)  # refused before anything moved
    assert sim.step_count == 0


def test_external_force_bound_is_the_force_equivalent_to_the_largest_intent():
    """A force f stands for the intent τ f / m in Eq. 14: the bound is m u_max / τ per pedestrian."""
    sim = _scenario().make_simulator()
    st_ = sim.state
    limit = st_.mass_kg * MAX_INPUT_SPEED_M_S / st_.tau_s
    force = np.zeros((N, 2))
    force[:, 0] = 0.999 * limit
    sim.step(np.zeros((N, 2)), external_force_n=force)  # just below: accepted
    force[3, 0] = 1.001 * limit[3]
    with pytest.raises(InputError, match=rf"external_force_n of pedestrian 3 has magnitude .* N; the step accepts "
                                         rf"at most m u_max / tau = {re.escape(f'{limit[3]:.4g}')} N"):
        sim.step(np.zeros((N, 2)), external_force_n=force)


@pytest.mark.parametrize("value, message", [
    ("ab", r"intents_m_s must be an array of numbers of shape \(10, 2\) .*got str 'ab'"),
    (None, r"intents_m_s must be an array of numbers of shape \(10, 2\) .*got None"),
    ([[1.0, 2.0], [3.0]], r"intents_m_s must be an array of numbers .*got list"),
    (np.array([["a", "b"]] * N), r"intents_m_s must be an array of numbers .*dtype <U1"),
    ([1.0, 2.0], r"intents_m_s must have shape \(10, 2\) \(one row per pedestrian\), got a list of shape \(2,\)"),
    (np.zeros((N, 3)), r"intents_m_s must have shape \(10, 2\) .*got an array of shape \(10, 3\)"),
])
def test_step_inputs_that_are_not_arrays_of_the_shape_name_the_argument_and_what_was_given(value, message):
    """Issue 37, item 8: ``step("ab")`` named no argument, ``step(None)`` reported shape (1,)."""
    sim = _scenario().make_simulator()
    with pytest.raises(InputError, match=message):
        sim.step(value)
    if value is not None:  # None is the default "no force"
        with pytest.raises(InputError, match=message.replace("intents_m_s", "external_force_n")):
            sim.step(np.zeros((N, 2)), external_force_n=value)


_magnitude = st.one_of(st.floats(0.0, MAX_INPUT_SPEED_M_S), st.floats(0.0, LARGEST),
                       st.sampled_from([MAX_INPUT_SPEED_M_S, MAX_INPUT_SPEED_M_S * (1 + 1e-15), 1e8, 1e12, 1e300]))
_angle = st.floats(-math.pi, math.pi)
_row = st.tuples(_magnitude, _angle)
_rows = st.one_of(st.lists(_row, min_size=N, max_size=N), _row.map(lambda r: [r] * N))  # all alike: a crush


def _vectors(rows, scale=1.0):
    mag = np.array([m for m, _ in rows]) * scale
    ang = np.array([a for _, a in rows])
    with np.errstate(over="ignore"):  # a magnitude near the largest float may round to inf in a component
        out = np.c_[mag * np.cos(ang), mag * np.sin(ang)]
    return out


ROUNDING = 1e-12  # relative: two computations of one vector's norm differ by a few ulps


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(intents=_rows, forces=st.one_of(st.none(), _rows),
       headings=st.one_of(st.none(), st.lists(st.floats(-LARGEST, LARGEST), min_size=N, max_size=N)))
def test_extreme_inputs_are_refused_by_name_or_keep_the_invariants(intents, forces, headings):
    scenario = _scenario()
    area = scenario.geometry.walkable_area
    sim = scenario.make_simulator()
    # Forces as the fraction of each pedestrian's bound m u_max / τ times the drawn magnitude / u_max.
    unit = (sim.state.mass_kg / sim.state.tau_s)[:, None]
    u = _vectors(intents)
    with np.errstate(over="ignore"):
        f = None if forces is None else _vectors(forces) * unit
    theta = None if headings is None else np.array(headings)
    for _ in range(3):
        try:
            result = sim.step(u, desired_heading_rad=theta, external_force_n=f)
        except InputError as exc:
            text = str(exc)
            event("refused")
            if "is not finite" in text:  # a component rounded to inf when built; named as such
                assert text.startswith(("intents_m_s", "external_force_n"))
                return
            assert text.startswith(("intents_m_s of pedestrian", "external_force_n of pedestrian")), text
            assert "MAX_INPUT_SPEED_M_S" in text and "at most" in text
            speeds = np.hypot(u[:, 0], u[:, 1])
            # the step's norm and numpy's hypot may round a magnitude drawn at the bound to either side of it
            if text.startswith("intents_m_s"):
                assert (speeds > MAX_INPUT_SPEED_M_S * (1.0 - ROUNDING)).any()
            else:  # intents are checked first
                assert not (speeds > MAX_INPUT_SPEED_M_S * (1.0 + ROUNDING)).any() and f is not None
                assert (np.hypot(f[:, 0], f[:, 1]) / unit[:, 0] > 0.99 * MAX_INPUT_SPEED_M_S).any()
            return
        # accepted: then every input was within its bound and the invariants hold
        event("accepted")
        assert (np.hypot(u[:, 0], u[:, 1]) <= MAX_INPUT_SPEED_M_S * (1.0 + ROUNDING)).all()
        _check_invariants(sim, result, area)
