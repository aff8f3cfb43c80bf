"""Every error crowd_env raises, in one hierarchy.

Each class derives from :class:`CrowdEnvError` *and* from the builtin that fits it (``ValueError``
for bad input, ``RuntimeError`` for a computation that failed, ``KeyError`` for an unknown name,
``TypeError`` where a wrong kind of object was passed), so callers may catch either
``CrowdEnvError`` (anything from this package) or the builtin. Messages name the offending
pedestrian, wall, agent, option or file. The modules that raise an error re-export its class, so
``from crowd_env.core.params import ParameterError`` and ``from crowd_env.errors import
ParameterError`` are the same class.

This module imports nothing from crowd_env (every layer may import it).
"""
from __future__ import annotations


class CrowdEnvError(Exception):
    """Base class of every crowd_env error."""


class InputError(CrowdEnvError, ValueError):
    """A function got a malformed array or value (shape, finiteness, range)."""


class NotFoundError(CrowdEnvError, KeyError):
    """An unknown name: a measurement line or area, a scenario, an agent."""

    def __str__(self) -> str:  # KeyError quotes its message; show it as written
        return str(self.args[0]) if self.args else ""


class MissingFileError(CrowdEnvError, FileNotFoundError):
    """A file the call needs does not exist (the message names it)."""


class UntrustedFileError(CrowdEnvError, ValueError):
    """A file that could run code when read, refused unread: a pickle (a run or training checkpoint) that this
    account's crowd_env did not sign (:func:`crowd_env.files.read_signed`), or a ``.pt`` policy or checkpoint holding
    more than numbers, strings, lists, dicts and tensors."""


class MissingDependencyError(CrowdEnvError, ImportError):
    """An optional dependency is not installed (the message names the extra that provides it)."""


# --- simulation core ---------------------------------------------------------------------------------------
class ParameterError(CrowdEnvError, ValueError):
    """Invalid or unknown model parameter (``ModelParams``, ``PedestrianDefaults``, presets)."""


class UnknownParameterError(ParameterError, TypeError):
    """A model parameter name that does not exist (``ModelParams(dt=...)``, ``.replace``, ``from_dict``, ``--param``):
    a :class:`ParameterError` and, as Python's constructors raise for an unexpected keyword, a ``TypeError``."""


class StateError(CrowdEnvError, ValueError):
    """Invalid crowd state: shapes, non-positive mass/radius/τ, overlapping pedestrians."""


class GeometryError(CrowdEnvError, ValueError):
    """Impossible geometry: degenerate walls, no reachable exit, self-intersecting polygons."""


class SimulationError(CrowdEnvError, RuntimeError):
    """A step could not be completed correctly (no solver converged; the state would be wrong)."""


class SolverError(SimulationError):
    """A contact or projection solver failed (status not optimal)."""


class NotPositiveDefiniteError(SolverError, ValueError):
    """A Cholesky factorisation met a non-positive pivot (raised from compiled code)."""


# --- scenarios and environments ----------------------------------------------------------------------------
class ScenarioError(CrowdEnvError, ValueError):
    """Invalid scenario options or a scenario that cannot be built as asked."""


class OptionError(CrowdEnvError, ValueError, TypeError):
    """An unknown option or an option of the wrong type or value."""


class EnvOptionError(OptionError):
    """Invalid environment option (``crowd_v0.parallel_env(...)``)."""


class UnknownOptionError(EnvOptionError, TypeError):
    """An unknown keyword option of an environment constructor. Its message carries Python's own wording,
    ``... got an unexpected keyword argument 'name'``, on which ecosystem wrappers act as on the builtin
    ``TypeError`` (TorchRL's ``GymEnv`` drops its ``frameskip`` argument on it)."""


class ActionError(CrowdEnvError, ValueError):
    """An action that is not a finite (2,) velocity intent inside the action space, or for an agent
    that does not exist or is no longer live."""


class EnvStateError(CrowdEnvError, RuntimeError):
    """An environment used out of order (``step()`` before ``reset()`` or after the episode ended), or a
    scenario that broke its contract on a reseed."""


class WorkerError(CrowdEnvError, RuntimeError):
    """A worker process of a vector environment raised (its traceback in the message) or died."""


class PolicyError(CrowdEnvError, ValueError, TypeError):
    """A policy or reward function that returned a wrong output, an object that is not a policy, or an
    import path that does not name one."""


# --- analysis ----------------------------------------------------------------------------------------------
class AnalysisError(CrowdEnvError, ValueError):
    """Base of the measurement errors (bad trajectories, windows, areas, tables)."""


class FlowError(AnalysisError):
    """Bad crossing times, widths or measurement lines."""


class DensityError(AnalysisError):
    """Bad measurement areas or positions."""


class LaneError(AnalysisError):
    """Bad lateral positions or bins."""


class ExperimentError(AnalysisError):
    """A request for experimental data that does not exist or a malformed table."""


class TrajectoryFormatError(AnalysisError):
    """A trajectory or geometry file that is not in the expected format."""


class RecorderError(AnalysisError):
    """Bad recording options (frame rate not a multiple of the step)."""


class CalibrationError(AnalysisError):
    """Bad calibration input (grids, reference tables, free parameters) or an unusable run record."""


# --- experiments -------------------------------------------------------------------------------------------
class SetupError(CrowdEnvError, ValueError, TypeError):
    """An experiment set-up that cannot run (impossible geometry options, unknown options)."""


class SweepError(CrowdEnvError, RuntimeError):
    """Runs of a sweep raised; the others are stored and the failures logged."""


class RunStoreError(CalibrationError):
    """A run folder of another configuration, or a store used inconsistently."""


class BackendError(CalibrationError):
    """A distribution backend that cannot start or reach its cluster."""


class GeneralisationError(CrowdEnvError, ValueError):
    """An impossible generalisation grid."""


class TrainingError(CrowdEnvError, ValueError):
    """Bad training options or a checkpoint folder that cannot be resumed."""


class SoakError(CrowdEnvError, ValueError):
    """Bad soak options (unknown cases, nothing to run)."""
