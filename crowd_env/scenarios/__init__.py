"""Scenarios: geometry + initial pedestrians + exits + measurement lines, as data (see :class:`Scenario`).

Importing this package imports every module of it, and each registers its scenarios by name
(:func:`register_scenario`, as a decorator of the factory): a new scenario is a module of this package and nothing
else. :func:`list_scenarios` names them; the documentation's scenario table is generated from the registry. Among
them: "seyfried_bottleneck" (alias "bottleneck"), "bottleneck_groups", "corridor_bidirectional" (alias
"corridor"), "juelich_corridor" (alias "uo_corridor"), "room_pillar", "corner_90" (alias "corner"),
"periodic_corridor", "polygon" (alias "custom"; any user geometry from coordinates or WKT), and the set-ups of the
RiMEA verification tests ("rimea_<test>_<name>", :mod:`crowd_env.scenarios.rimea`). Each carries what a run of
it measures by default (:class:`~crowd_env.scenarios.scenario.Measurement`).
"""
import importlib
import pkgutil

from .checks import check_clearance
from .doors import door_exit
from .placement import form_groups, place_pedestrians
from .registry import body_options, list_scenarios, make_scenario, register_scenario, scenario_options
from .scenario import Measurement, Scenario, ScenarioError
from .bottleneck import bottleneck_geometry, seyfried_bottleneck
from .corner import corner_90
from .corridor import corridor_bidirectional
from .groups import bottleneck_groups
from .juelich_corridor import juelich_corridor
from .periodic_corridor import periodic_corridor
from .polygon import scenario_from_polygon
from .demographics import RIMEA_ADULTS, WEIDMANN_SPEEDS_BY_AGE_M_S, desired_speeds_for_ages
from .rimea import rimea_scenario
from .room import room_pillar

__all__ = ["Scenario", "ScenarioError", "Measurement", "body_options", "list_scenarios", "make_scenario",
           "place_pedestrians", "register_scenario", "scenario_options", "form_groups", "door_exit", "check_clearance",
           "bottleneck_geometry",
           "seyfried_bottleneck", "bottleneck_groups", "corridor_bidirectional", "juelich_corridor", "room_pillar", "corner_90",
           "scenario_from_polygon", "periodic_corridor", "rimea_scenario", "desired_speeds_for_ages", "RIMEA_ADULTS",
           "WEIDMANN_SPEEDS_BY_AGE_M_S"]


def _import_every_module() -> None:
    """Import every module of this package: each registers its scenarios when imported."""
    for info in pkgutil.iter_modules(__path__):
        importlib.import_module(f"{__name__}.{info.name}")


_import_every_module()
