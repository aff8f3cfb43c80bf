"""Scenarios: geometry + initial pedestrians + exits + measurement lines, as data (see :class:`Scenario`).

Importing this package registers the built-in scenarios: "seyfried_bottleneck" (alias "bottleneck"),
"bottleneck_groups" (hand-holding pairs and triples in the bottleneck crowd), "corridor_bidirectional"
(alias "corridor"; two groups with opposite destinations), "juelich_corridor" (alias "uo_corridor"; the
Jülich unidirectional corridor runs with their entrance and exit, as run), "room_pillar" (room evacuation with a
pillar before the door), "corner_90" (alias "corner"; L-shaped corridor), "periodic_corridor" (a strip
periodic along x, no exits: the fundamental diagram's instrument) and "polygon" (alias
"custom"; any user geometry from coordinates or WKT), and the set-ups of the RiMEA verification tests
("rimea_<test>_<name>", :mod:`crowd_env.scenarios.rimea`).
"""
from .checks import check_clearance
from .doors import door_exit
from .placement import form_groups, place_pedestrians
from .registry import body_options, list_scenarios, make_scenario, register_scenario, scenario_options
from .scenario import Scenario, ScenarioError
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

__all__ = ["Scenario", "ScenarioError", "body_options", "list_scenarios", "make_scenario", "place_pedestrians", "register_scenario",
           "scenario_options", "form_groups", "door_exit", "check_clearance", "bottleneck_geometry",
           "seyfried_bottleneck", "bottleneck_groups", "corridor_bidirectional", "juelich_corridor", "room_pillar", "corner_90",
           "scenario_from_polygon", "periodic_corridor", "rimea_scenario", "desired_speeds_for_ages", "RIMEA_ADULTS",
           "WEIDMANN_SPEEDS_BY_AGE_M_S"]
