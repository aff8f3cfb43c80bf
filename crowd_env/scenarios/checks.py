"""Argument checks of the scenario factories: each names the option and raises :class:`~crowd_env.errors.ScenarioError`."""
from __future__ import annotations

from crowd_env.errors import ScenarioError
from ..core.checks import check_integer, check_number

__all__ = ["check_positive", "check_clearance", "check_count"]


def check_positive(**values) -> None:
    """Raise :class:`ScenarioError` naming the first value that is not a positive finite number."""
    for name, value in values.items():
        check_number(name, value, error=ScenarioError, positive=True)


def check_clearance(value, radius_m: float) -> float:
    """The navigation clearance in m: ``radius_m`` for None (the disk centres' configuration space), else
    ``value`` checked to be finite and >= 0."""
    if value is None:
        return float(radius_m)
    return check_number("navigation_clearance_m", value, error=ScenarioError, minimum=0.0, suffix=" or None")


def check_count(name: str, value, minimum: int = 1) -> int:
    """``value`` as an int >= ``minimum`` (a float of integral value too), or :class:`ScenarioError` naming
    ``name``."""
    return check_integer(name, value, error=ScenarioError, minimum=minimum, whole_floats=True)
