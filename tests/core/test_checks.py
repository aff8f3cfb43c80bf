"""The shared argument checks: what counts as a number, the message form, and the callers' error classes."""
import math
import re

import numpy as np
import pytest

from crowd_env.core.checks import check_integer, check_number, check_seed, is_integer, is_number
from crowd_env.errors import EnvOptionError, GeometryError, InputError, ScenarioError


@pytest.mark.parametrize("value, number, integer", [
    (3, True, True), (np.int32(3), True, True), (2.5, True, False), (np.float32(2.5), True, False),
    (True, False, False), (np.bool_(False), False, False), (math.nan, False, False), (math.inf, False, False),
    (-math.inf, False, False), ("3", False, False), (None, False, False), (np.array([1.0]), False, False),
    (3.0, True, False),
])
def test_what_counts_as_a_number(value, number, integer):
    assert is_number(value) is number
    assert is_integer(value) is integer


def test_check_number_converts_and_names_the_argument():
    assert check_number("x_m", 2, error=GeometryError) == 2.0 and type(check_number("x_m", 2, error=GeometryError)) is float
    assert check_number("x_m", 0.0, error=GeometryError, minimum=0.0) == 0.0
    assert check_number("x_m", -1.5, error=GeometryError) == -1.5
    cases = [(dict(positive=True), 0.0, "x_m must be a positive finite number, got 0.0"),
             (dict(positive=True), True, "x_m must be a positive finite number, got True"),
             (dict(minimum=0.0), -1e-12, "x_m must be a finite number >= 0, got -1e-12"),
             (dict(minimum=0.5), 0.25, "x_m must be a finite number >= 0.5, got 0.25"),
             ({}, math.nan, "x_m must be a finite number, got nan"),
             ({}, "1", "x_m must be a finite number, got '1'"),
             (dict(positive=True, suffix=" or None"), -2, "x_m must be a positive finite number or None, got -2")]
    for kwargs, value, message in cases:
        with pytest.raises(GeometryError) as err:
            check_number("x_m", value, error=GeometryError, **kwargs)
        assert str(err.value) == message
    with pytest.raises(InputError, match="positive or minimum"):
        check_number("x_m", 1.0, error=GeometryError, positive=True, minimum=0.0)


def test_check_integer_refuses_bools_and_fractions():
    assert check_integer("k", np.int64(4), error=EnvOptionError, minimum=0) == 4
    assert type(check_integer("k", np.int64(4), error=EnvOptionError)) is int
    for value in (True, 1.5, 2.0, "2", -1, None):
        with pytest.raises(EnvOptionError, match=r"^k must be an integer >= 0, got "):
            check_integer("k", value, error=EnvOptionError, minimum=0)
    assert check_integer("n", 60.0, error=ScenarioError, minimum=1, whole_floats=True) == 60
    for value in (60.5, math.nan, math.inf, False, 0):
        with pytest.raises(ScenarioError, match=r"^n must be an integer >= 1, got "):
            check_integer("n", value, error=ScenarioError, minimum=1, whole_floats=True)
    with pytest.raises(ScenarioError, match=r"^n must be an integer, got 'a'$"):
        check_integer("n", "a", error=ScenarioError)


def test_the_error_class_must_be_of_the_hierarchy():
    with pytest.raises(InputError, match="error must be a class of crowd_env.errors, got <class 'ValueError'>"):
        check_number("x", "bad", error=ValueError)
    assert check_number("x", 1.0, error=ValueError) == 1.0  # checked when raising


def test_callers_raise_their_own_error_class():
    """The same rule behind the scenarios, the environment and the navigation field, each with its error."""
    from crowd_env.envs import crowd_v0
    from crowd_env.scenarios import make_scenario

    with pytest.raises(ScenarioError, match="n_pedestrians must be an integer >= 1, got True"):
        make_scenario("seyfried_bottleneck", n_pedestrians=True)
    with pytest.raises(EnvOptionError, match="frame_skip must be an integer >= 1, got 2.0"):
        crowd_v0.parallel_env(frame_skip=2.0)
    with pytest.raises(EnvOptionError, match=r"action_max_m_s must be a positive finite number, got nan"):
        crowd_v0.parallel_env(action_max_m_s=float("nan"))


@pytest.mark.parametrize("value", ["abc", 1.5, 1.0, -1, True, np.bool_(True), np.float64(2.0), [1, 2], math.nan])
def test_check_seed_refuses_what_default_rng_would_refuse_or_misread_naming_the_argument(value):
    """Issue 37, item 8: numpy's own messages ("SeedSequence expects int ...", "expected non-negative
    integer") do not name the argument; True was read as 1."""
    with pytest.raises(ScenarioError, match=rf"^seed must be None or an integer >= 0, got {re.escape(repr(value))}$"):
        check_seed("seed", value, error=ScenarioError)


def test_check_seed_accepts_none_and_non_negative_integers():
    assert check_seed("seed", None, error=EnvOptionError) is None
    assert check_seed("seed", 0, error=EnvOptionError) == 0
    value = check_seed("seed", np.int64(2**40), error=EnvOptionError)
    assert value == 2**40 and type(value) is int
