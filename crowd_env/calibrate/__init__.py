"""Calibration of the social force (A, B, ...) against Seyfried et al. (2009), Kabalan Section 4.1.2.

``grid``: ε_T (Eq. 24) on an (A, B) grid, valley of minima and A(B) = a exp(c B) (Fig. 10);
``optimize``: Nelder–Mead / Powell on ε_T (Eq. 25). Runs are single bottleneck runs (A, B, b, N, seed)
distributed by Ray (local or cluster), a process pool or serially, saved as they finish (resumable).
Command line: ``crowd-calibrate`` / ``scripts/calibrate.py``.
"""
from .backends import BACKENDS, ProcessBackend, RayBackend, SerialBackend, check_reachable, execute, make_backend
from .grid import GridResult, analyse_surface, evaluate_grid, point_tasks, surface_figure, write_grid_outputs
from .optimize import FREE_PARAMETERS, METHODS, OptimResult, optimise
from .runs import PEDESTRIAN_FIELDS, RunStore, base_config, canonical, make_task, run_task, task_key

__all__ = ["BACKENDS", "ProcessBackend", "RayBackend", "SerialBackend", "check_reachable", "execute", "make_backend",
           "GridResult", "analyse_surface", "evaluate_grid", "point_tasks", "surface_figure", "write_grid_outputs",
           "FREE_PARAMETERS", "METHODS", "OptimResult", "optimise",
           "PEDESTRIAN_FIELDS", "RunStore", "base_config", "canonical", "make_task", "run_task", "task_key"]
