"""Argument checks of the scenario factories: each names the option and raises :class:`~crowd_env.errors.ScenarioError`."""
from __future__ import annotations

from crowd_env.errors import ScenarioError
from ..core.checks import check_integer, check_number
from ..core.segments import GeometryError
from ..walking.navigation import NavigationField

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


def check_wall_slowdown(value) -> tuple | None:
    """The navigation field's wall slowdown ``(distance_m, speed_factor)`` (Eq. 11's V < 1 near walls) as a tuple
    of floats, or None; :class:`ScenarioError` naming what is wrong
    (:meth:`~crowd_env.walking.navigation.NavigationField.check_wall_slowdown`)."""
    try:
        return NavigationField.check_wall_slowdown(value)
    except GeometryError as exc:
        raise ScenarioError(f"navigation_wall_slowdown: {exc}") from exc


def check_count(name: str, value, minimum: int = 1) -> int:
    """``value`` as an int >= ``minimum`` (a float of integral value too), or :class:`ScenarioError` naming
    ``name``."""
    return check_integer(name, value, error=ScenarioError, minimum=minimum, whole_floats=True)
