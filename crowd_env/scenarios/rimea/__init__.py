"""The geometries and crowds of the RiMEA verification tests (RiMEA 4.1.1, Annex 1), as scenarios.

Each test's set-up is an ordinary :class:`~crowd_env.scenarios.Scenario` built with the public API
(:func:`~crowd_env.scenarios.scenario_from_polygon`, per-pedestrian parameters such as
``desired_speed_m_s`` and ``premovement_s``, destinations), registered under ``rimea_<test>_<name>`` so
that users can run, train on or modify it like any other scenario (``make_scenario("rimea_1_corridor")``).
Dimensions follow RiMEA 4.1.1 where its text gives them and JuPedSim's transcription of its figures
otherwise (docs/validation/rimea.md lists the sources test by test). One module per test (``t<nn>_*.py``),
each registering its scenarios when imported; options give the reduced versions of the default suite.
"""
import importlib
import pkgutil

from .base import RIMEA_RADIUS_M, rimea_scenario

for _module in sorted(m.name for m in pkgutil.iter_modules(__path__) if m.name.startswith("t")):
    importlib.import_module(f"{__name__}.{_module}")  # each registers its scenarios

__all__ = ["rimea_scenario", "RIMEA_RADIUS_M"]
