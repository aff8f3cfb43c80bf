"""Simulation core: rigid-disk pedestrians with Frémond non-smooth collisions. Knows nothing of RL."""
from .params import ModelParams, ParameterError, PedestrianDefaults
from .state import CrowdState, StateError, min_gap_m, sample_desired_speeds
from .segments import GeometryError
from .simulator import Simulator, StepResult
from crowd_env.errors import SimulationError

__all__ = ["ModelParams", "ParameterError", "PedestrianDefaults", "CrowdState", "StateError", "min_gap_m",
           "sample_desired_speeds", "GeometryError", "SimulationError", "Simulator", "StepResult"]
