"""Calibration of the social force (A, B, ...) against Seyfried et al. (2009), Kabalan Section 4.1.2.

``grid``: ε_T (Eq. 24) on an (A, B) grid, valley of minima and A(B) = a exp(c B) (Fig. 10);
``optimize``: Nelder–Mead / Powell on ε_T (Eq. 25) or on every target of the experiment;
``landscape``: the objective along one parameter; ``targets``: presets against the targets;
``tasks``: the calibration's runs in the bottleneck task format, and with ``--objective targets+fd`` the
fundamental-diagram sweep's runs of every point (:class:`~.tasks.FDPlan`). Runs are single runs (bottleneck:
A, B, b, N, seed; sweep: set-up, density, seed) executed by :mod:`crowd_env.experiments.running.backends` (Ray, a
process pool or serially) and saved as they finish in a :class:`~crowd_env.experiments.running.store.RunStore` (resumable).
Command line: ``crowd-calibrate``.
"""
from .grid import GridResult, analyse_surface, evaluate_grid, point_tasks, surface_figure, write_grid_outputs
from .optimize import FREE_PARAMETERS, METHODS, OptimResult, PointEvaluator, optimise
from .tasks import PEDESTRIAN_FIELDS, FDPlan, base_config, canonical, make_fd_tasks, make_task, run_calibration_task

__all__ = ["GridResult", "analyse_surface", "evaluate_grid", "point_tasks", "surface_figure", "write_grid_outputs",
           "FREE_PARAMETERS", "METHODS", "OptimResult", "PointEvaluator", "optimise",
           "PEDESTRIAN_FIELDS", "base_config", "canonical", "make_task", "FDPlan", "make_fd_tasks",
           "run_calibration_task"]
