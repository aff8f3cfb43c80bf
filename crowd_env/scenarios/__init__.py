"""Scenarios: geometry + initial pedestrians + exits + measurement lines, as data (see :class:`Scenario`).

Importing this package registers the built-in scenarios ("seyfried_bottleneck", alias "bottleneck").
"""
from .base import (Scenario, ScenarioError, list_scenarios, make_scenario, place_pedestrians, register_scenario,
                   scenario_options)
from .bottleneck import bottleneck_geometry, seyfried_bottleneck

__all__ = ["Scenario", "ScenarioError", "list_scenarios", "make_scenario", "place_pedestrians", "register_scenario",
           "scenario_options", "bottleneck_geometry", "seyfried_bottleneck"]
