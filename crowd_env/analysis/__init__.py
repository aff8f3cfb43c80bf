"""Measurements on simulated (or experimental) trajectories: passages and specific flow (Eq. 22),
density, lanes, the Seyfried et al. (2009) reference, and trajectories in PedPy's
formats. Measures only: it runs no simulation (that is :mod:`crowd_env.experiments`) and knows nothing of RL. The calibration's errors
(Eq. 23-24) and objective live with the calibration, in :mod:`crowd_env.experiments.validation.calibration`."""
from .density import (DensityError, as_polygon, density_in_area, density_time_series, force_balance_jam_density_per_m2,
                      hexagonal_density_per_m2, stationary_mean)
from .experiment import (DIP_N20_WIDTH_M, GROUP_SIZES, PUBLISHED_SPECIFIC_FLOW_N60_PER_M_S, RESIDUAL_NORM_BY_GROUP,
                         SPECIFIC_FLOW_RANGE_N20_N40_PER_M_S, WIDTHS_M, ExperimentError, ExperimentTable, seyfried_2009)
from .flow import (FlowError, FlowResult, LinearFit, MeasurementLine, PassageCounter, line_crossings, linear_fit,
                   linear_fit_residual_norm, specific_flow, trajectory_crossings)
from .lanes import (LaneError, LaneResult, LateralHistogram, detect_lanes, lane_order_parameter, lateral_histogram,
                    mixed_lane_order_parameter)
from .recorder import RecorderError, TrajectoryRecorder
from .trajectories import Trajectories, TrajectoryFormatError, export_run, read_geometry, write_geometry

__all__ = [
    "DensityError", "as_polygon", "density_in_area", "density_time_series", "force_balance_jam_density_per_m2",
    "hexagonal_density_per_m2", "stationary_mean",
    "DIP_N20_WIDTH_M", "GROUP_SIZES", "PUBLISHED_SPECIFIC_FLOW_N60_PER_M_S", "RESIDUAL_NORM_BY_GROUP",
    "SPECIFIC_FLOW_RANGE_N20_N40_PER_M_S", "WIDTHS_M", "ExperimentError", "ExperimentTable", "seyfried_2009",
    "FlowError", "FlowResult", "LinearFit", "MeasurementLine", "PassageCounter", "line_crossings", "linear_fit",
    "linear_fit_residual_norm", "specific_flow", "trajectory_crossings",
    "LaneError", "LaneResult", "LateralHistogram", "detect_lanes", "lateral_histogram", "lane_order_parameter",
    "mixed_lane_order_parameter",
    "RecorderError", "TrajectoryRecorder",
    "Trajectories", "TrajectoryFormatError", "export_run", "read_geometry", "write_geometry",
]
