"""Shared helpers of the experiment tests: the reproduction's bottleneck geometry with the point field, and
a calibration configuration on it."""
from crowd_env.walking import ModelParams
from crowd_env.experiments.validation.bottleneck import GEOMETRY_OPTIONS
from crowd_env.experiments.validation.calibration import base_config


def point_field_geometry():
    """The reproduction's geometry options at their defaults, with the paper's literal point field
    (``navigation_clearance_m`` 0): a new dict on each call."""
    return {**{opt: d for _, (opt, d) in GEOMETRY_OPTIONS.items()}, "navigation_clearance_m": 0.0}


GEOMETRY = point_field_geometry()


def config(**changes):
    """The calibration's configuration on :data:`GEOMETRY`: ModelParams() with ``changes``, runs of at most 300 s."""
    return base_config(GEOMETRY, ModelParams().replace(**changes), 300.0)
