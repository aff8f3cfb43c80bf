"""Simulation core: rigid-disk pedestrians with Frémond non-smooth collisions. Knows nothing of RL, nor of the walking
model (whose parameters, paired with the core's :class:`PhysicsParams`, are :class:`crowd_env.walking.ModelParams`)."""
from .params import ParameterError, PedestrianDefaults, PhysicsParams
from .state import CrowdState, StateError, min_gap_m, sample_desired_speeds
from .segments import GeometryError
from .simulator import Simulator, StepResult
from crowd_env.errors import SimulationError

__all__ = ["PhysicsParams", "ParameterError", "PedestrianDefaults", "CrowdState", "StateError", "min_gap_m",
           "sample_desired_speeds", "GeometryError", "SimulationError", "Simulator", "StepResult"]
