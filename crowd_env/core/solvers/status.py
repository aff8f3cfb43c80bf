"""What every solver of the package reports: the status codes, and the error raised when none can solve.

A solver never returns an answer it has not checked: it returns ``STATUS_OK`` with the solution, or
another status (and leaves its input alone), and the :class:`~crowd_env.core.solvers.cascade.SolverCascade`
hands the problem to the next method in line. When no method is left (every one failed, or the one
that would serve is an optional solver that is not installed), the cascade raises
:class:`~crowd_env.errors.SimulationError` rather than continue with a wrong or unchecked state.
"""
from __future__ import annotations

STATUS_OK = 0
STATUS_MAX_ITER = 1  # no certified solution within the iteration budget (the input is left alone)
STATUS_TOO_LARGE = 2  # the problem exceeds the size limit of the method (the input is left alone)


