"""Argument checks shared by every layer: one rule for what counts as a number, one form of message.

A *number* is an ``int``, ``float`` or NumPy integer / floating scalar that is finite; ``bool`` is not
a number (``True`` is refused, not read as 1). An *integer* is an ``int`` or NumPy integer. Each check
raises the caller's error class (one of :mod:`crowd_env.errors`) with a message that names the
argument and repeats the value given, and returns the value converted (``float`` or ``int``)::

    check_number("dt_s", dt_s, error=ParameterError, positive=True)   # "dt_s must be a positive finite number, got 0"
    check_number("clearance_m", c, error=GeometryError, minimum=0.0)  # "... must be a finite number >= 0, got -1"
    check_integer("workers", w, error=EnvOptionError, minimum=1)       # "workers must be an integer >= 1, got 0"
    check_seed("seed", s, error=ScenarioError)                         # "seed must be None or an integer >= 0, got 'abc'"
"""
from __future__ import annotations

import math

import numpy as np

from crowd_env.errors import CrowdEnvError, InputError

__all__ = ["is_number", "is_integer", "check_number", "check_integer", "check_seed"]


def is_integer(value) -> bool:
    """Whether ``value`` is an ``int`` or NumPy integer scalar (``bool`` is not)."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


def is_number(value) -> bool:
    """Whether ``value`` is a finite ``int``, ``float`` or NumPy scalar number (``bool`` is not)."""
    return (isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
            and math.isfinite(value))


def _error_class(error) -> type[CrowdEnvError]:
    """``error``, which must be a class of the project's error hierarchy (:mod:`crowd_env.errors`)."""
    if not (isinstance(error, type) and issubclass(error, CrowdEnvError)):
        raise InputError(f"error must be a class of crowd_env.errors, got {error!r}")
    return error


def check_number(name: str, value, *, error: type[Exception], positive: bool = False, minimum: float | None = None,
                 suffix: str = "") -> float:
    """``value`` as a float; raises ``error`` unless it is a finite number, > 0 with ``positive``, >= ``minimum``
    when given. ``suffix`` ends the message (e.g. " or None" where the caller also accepts None)."""
    if positive and minimum is not None:
        raise InputError("check_number: give positive or minimum, not both")
    ok = is_number(value) and (not positive or value > 0) and (minimum is None or value >= minimum)
    if not ok:
        if positive:
            rule = "a positive finite number"
        elif minimum is not None:
            rule = f"a finite number >= {minimum:g}"
        else:
            rule = "a finite number"
        raise _error_class(error)(f"{name} must be {rule}{suffix}, got {value!r}")
    return float(value)


def check_integer(name: str, value, *, error: type[Exception], minimum: int | None = None,
                  whole_floats: bool = False) -> int:
    """``value`` as an int; raises ``error`` unless it is an integer (with ``whole_floats``, also a float of
    integral value such as 60.0), >= ``minimum`` when given."""
    whole = is_integer(value) or (whole_floats and is_number(value) and int(value) == value)
    if not (whole and (minimum is None or value >= minimum)):
        rule = "an integer" if minimum is None else f"an integer >= {minimum}"
        raise _error_class(error)(f"{name} must be {rule}, got {value!r}")
    return int(value)


def check_seed(name: str, value, *, error: type[Exception]) -> int | None:
    """``value`` as a random seed: None (fresh entropy from the operating system) or an ``int`` / NumPy integer
    >= 0 (what :func:`numpy.random.default_rng` takes as one number); raises ``error`` otherwise, for ``bool``,
    floats such as 1.5 and strings too, whose own NumPy messages do not name the argument."""
    if value is None:
        return None
    if not (is_integer(value) and value >= 0):
        raise _error_class(error)(f"{name} must be None or an integer >= 0, got {value!r}")
    return int(value)
