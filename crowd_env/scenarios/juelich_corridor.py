"""The Jülich unidirectional corridor runs ("UO", Zhang, Klingsch, Schadschneider, Seyfried 2011) as they were run.

Coordinates are the recordings' (metres, PedPy's example data ``uo-*``): the corridor spans x in [0, b_c],
y from +4 m (its start) to −4 m (the end wall); people walk towards −y. Set-up after the published sketch,
each dimension with its source (``metadata['confidence']``):

- a waiting area ``waiting_width_m`` = 5 m wide [sketch], as deep as N people need at
  ``waiting_density_per_m2`` = 3 /m² [sketch: "about 3 /m²"] (at least 1 m: a few walkers stand in its front rows
  nearest the entrance), behind
- a barrier ``barrier_thickness_m`` = 0.3 m thick [our choice: not documented] at y = 8 m [the recordings:
  people appear there, 4 m before the corridor] with the entrance b_e on the corridor's axis [the recordings'
  lateral positions at y = 7.5-8 m];
- 4 m of open floor, ``floor_width_m`` = 5 m wide [width our choice: the sketch shows open floor, the camera
  sees at least 3.8 m of it];
- the corridor, b_c wide and 8 m long [sketch];
- an end wall ``end_wall_thickness_m`` = 0.1 m thick [our choice: not documented] with the exit b_x on the
  axis [the recordings: lateral positions at y = −4 m]; with b_x = b_c the corridor simply ends;
- open floor beyond, ``outflow_width_m`` = 5 m wide and ``outflow_depth_m`` = 2.5 m deep, where people leave
  [our choice: beyond the camera, which sees to y ≈ −6 m; people leave 0.4 m further on].

Measurement (the shipped rows, :mod:`crowd_env.analysis.corridor_runs`): lines ``"entrance"`` (y = 8 m, across
the entrance), ``"y0"`` (y = 0) and ``"exit"`` (y = −4 m, across the exit), each counting walkers towards −y;
the area ``"measurement"``, x in [0, b_c], y in [−2, 0] (2 m of the corridor's whole width), where the Voronoi
density and speed were measured. The camera view (``metadata['view']``) bounds what the recordings hold.
"""
from __future__ import annotations

import numpy as np
from shapely.geometry import Polygon, box
from shapely.ops import unary_union

from ..core.geometry import Geometry
from .checks import check_clearance, check_count, check_positive, check_wall_slowdown
from .placement import place_pedestrians
from .registry import register_scenario
from .scenario import Measurement, Scenario, ScenarioError

__all__ = ["juelich_corridor", "juelich_corridor_geometry", "UO_CORRIDOR_START_Y_M", "UO_CORRIDOR_END_Y_M",
           "UO_BARRIER_Y_M", "UO_BARRIER_THICKNESS_M", "UO_END_WALL_THICKNESS_M", "UO_VIEW_Y_M", "UO_MEASUREMENT_Y_M",
           "UO_ENTRANCE_LINE_Y_M"]

UO_CORRIDOR_START_Y_M = 4.0  # the corridor's start (recordings' frame)
UO_CORRIDOR_END_Y_M = -4.0  # the end wall's upstream face, where the exit line lies
UO_BARRIER_Y_M = 8.0  # the entrance barrier's downstream face: 4 m of floor before the corridor
UO_ENTRANCE_LINE_Y_M = 7.6  # a line 0.4 m past the barrier: the camera sees everybody cross it (they appear at 7.8 m)
UO_BARRIER_THICKNESS_M = 0.3  # our choice (not documented): the barrier with the entrance
UO_END_WALL_THICKNESS_M = 0.1  # our choice (not documented): the end wall with the exit
UO_MEASUREMENT_Y_M = (-2.0, 0.0)  # the measurement area along y (PedPy's notebook for these runs)
UO_VIEW_Y_M = (-6.5, 8.0)  # y range of the camera view as PedPy's notebook bounds its walkable area
MIN_WAITING_DEPTH_M = 1.0  # the waiting area of a few walkers (N < 15 at 3 /m²): they stand in its front rows


def juelich_corridor_geometry(entrance_width_m: float = 1.8, exit_width_m: float = 1.8, *,
                              corridor_width_m: float = 1.8, n_pedestrians: int = 220,
                              corridor_length_m: float = 8.0, floor_length_m: float = 4.0,
                              floor_width_m: float = 5.0, waiting_width_m: float = 5.0,
                              waiting_density_per_m2: float = 3.0,
                              barrier_thickness_m: float = UO_BARRIER_THICKNESS_M,
                              end_wall_thickness_m: float = UO_END_WALL_THICKNESS_M, outflow_width_m: float = 5.0,
                              outflow_depth_m: float = 2.5, exit_depth_m: float = 0.5) -> tuple:
    """``(Geometry, waiting area)`` of the UO set-up (module docstring); the waiting area is deep enough for
    ``n_pedestrians`` at ``waiting_density_per_m2``. Raises :class:`ScenarioError` naming an opening wider than
    what it opens into or a corridor that is not 8 m from y = 4 to −4 with the default lengths."""
    check_positive(entrance_width_m=entrance_width_m, exit_width_m=exit_width_m, corridor_width_m=corridor_width_m,
                   corridor_length_m=corridor_length_m, floor_length_m=floor_length_m, floor_width_m=floor_width_m,
                   waiting_width_m=waiting_width_m, waiting_density_per_m2=waiting_density_per_m2,
                   barrier_thickness_m=barrier_thickness_m, end_wall_thickness_m=end_wall_thickness_m,
                   outflow_width_m=outflow_width_m, outflow_depth_m=outflow_depth_m, exit_depth_m=exit_depth_m)
    n = check_count("n_pedestrians", n_pedestrians)
    for name, opening, into, what in (("entrance_width_m", entrance_width_m, min(waiting_width_m, floor_width_m),
                                       "the waiting area and the floor (waiting_width_m, floor_width_m)"),
                                      ("exit_width_m", exit_width_m, corridor_width_m, "the corridor (corridor_width_m)"),
                                      ("corridor_width_m", corridor_width_m, min(floor_width_m, outflow_width_m),
                                       "the floor before and after it (floor_width_m, outflow_width_m)")):
        if opening > into + 1e-12:
            raise ScenarioError(f"{name} = {opening:g} m is wider than {what}: {into:g} m")
    if exit_depth_m >= outflow_depth_m:
        raise ScenarioError(f"exit_depth_m = {exit_depth_m:g} m must be smaller than outflow_depth_m = {outflow_depth_m:g} m")
    xc = 0.5 * corridor_width_m
    y_end = UO_CORRIDOR_START_Y_M - corridor_length_m  # the end wall's upstream face
    y_floor = UO_CORRIDOR_START_Y_M + floor_length_m  # the barrier's downstream face
    y_wait = y_floor + barrier_thickness_m
    # N at the density, at least MIN_WAITING_DEPTH_M deep (a few walkers stand in the front rows at the barrier)
    depth = max(n / (waiting_density_per_m2 * waiting_width_m), MIN_WAITING_DEPTH_M)
    y_out = y_end - end_wall_thickness_m
    y_leave = y_out - outflow_depth_m

    def centred(width, y0, y1):
        return box(xc - 0.5 * width, y0, xc + 0.5 * width, y1)

    waiting = centred(waiting_width_m, y_wait, y_wait + depth)
    parts = [waiting, centred(entrance_width_m, y_floor, y_wait), centred(floor_width_m, UO_CORRIDOR_START_Y_M, y_floor),
             box(0.0, y_end, corridor_width_m, UO_CORRIDOR_START_Y_M), centred(exit_width_m, y_out, y_end),
             centred(outflow_width_m, y_leave, y_out)]
    area = Polygon(unary_union(parts).exterior)
    exit_poly = centred(outflow_width_m, y_leave, y_leave + exit_depth_m)
    half_e, half_x = 0.5 * entrance_width_m, 0.5 * exit_width_m
    geometry = Geometry(
        area, exits=[exit_poly],
        measurement_lines={"entrance": [(xc - half_e, y_floor), (xc + half_e, y_floor)],
                           "y0": [(0.0, 0.0), (corridor_width_m, 0.0)],
                           "exit": [(xc - half_x, y_end), (xc + half_x, y_end)]},
        measurement_areas={"measurement": box(0.0, UO_MEASUREMENT_Y_M[0], corridor_width_m, UO_MEASUREMENT_Y_M[1])},
        name=f"juelich_corridor_e{entrance_width_m:g}_c{corridor_width_m:g}_x{exit_width_m:g}")
    return geometry, waiting


@register_scenario("juelich_corridor", aliases=("uo_corridor",))
def juelich_corridor(entrance_width_m: float = 1.8, exit_width_m: float = 1.8, n_pedestrians: int = 220,
                     seed: int | None = 0, corridor_width_m: float = 1.8, radius_m: float = 0.23,
                     floor_width_m: float = 5.0, waiting_width_m: float = 5.0, waiting_density_per_m2: float = 3.0,
                     barrier_thickness_m: float = UO_BARRIER_THICKNESS_M,
                     end_wall_thickness_m: float = UO_END_WALL_THICKNESS_M, outflow_width_m: float = 5.0,
                     navigation_clearance_m: float | None = None,
                     navigation_resolution_m: float = 0.02, navigation_wall_slowdown=None) -> Scenario:
    """One UO run: ``n_pedestrians`` start at ``waiting_density_per_m2`` in the waiting area and walk through
    the entrance (``entrance_width_m``), the corridor (``corridor_width_m`` x 8 m) and its exit
    (``exit_width_m``) to leave 2.5 m beyond it (module docstring). The defaults are the run uo-180-180-180.

    ``navigation_resolution_m`` is finer than elsewhere (0.02 m) so that the eikonal field of the disk centres
    (``navigation_clearance_m``, default the radius) has nodes in a 0.5 m entrance. ``navigation_wall_slowdown``:
    ``(distance_m, speed_factor)`` for a slower eikonal wavefront within that distance of a wall (Eq. 11's 0 < V < 1,
    which the paper describes but does not use: ways that keep off the walls), or None. Raises
    :class:`ScenarioError` naming an opening no wider than a pedestrian or any other impossible set-up.
    """
    check_positive(radius_m=radius_m, navigation_resolution_m=navigation_resolution_m)
    n = check_count("n_pedestrians", n_pedestrians)
    for name, width in (("entrance_width_m", entrance_width_m), ("exit_width_m", exit_width_m),
                        ("corridor_width_m", corridor_width_m)):
        check_positive(**{name: width})
        if width <= 2.0 * radius_m:
            raise ScenarioError(f"{name} = {width:g} m is not wider than a pedestrian (diameter {2 * radius_m:g} m): "
                                f"nobody can pass")
    geometry, waiting = juelich_corridor_geometry(
        entrance_width_m, exit_width_m, corridor_width_m=corridor_width_m, n_pedestrians=n, floor_width_m=floor_width_m,
        waiting_width_m=waiting_width_m, waiting_density_per_m2=waiting_density_per_m2,
        barrier_thickness_m=barrier_thickness_m, end_wall_thickness_m=end_wall_thickness_m,
        outflow_width_m=outflow_width_m)
    try:
        x0, y0, x1, _ = waiting.bounds
        front = n / (waiting_density_per_m2 * waiting_width_m) < MIN_WAITING_DEPTH_M  # a few: the front rows
        position = place_pedestrians(waiting, n, radius_m, np.random.default_rng(seed),
                                     density_per_m2=waiting_density_per_m2,
                                     toward=(0.5 * (x0 + x1), y0) if front else None)
    except ScenarioError as exc:
        raise ScenarioError(f"waiting area ({waiting_width_m:g} m wide at {waiting_density_per_m2:g} /m²): {exc}") from exc
    clearance = check_clearance(navigation_clearance_m, radius_m)
    slowdown = check_wall_slowdown(navigation_wall_slowdown)
    x0, y0, x1, y1 = waiting.bounds
    metadata = {
        "source": "Zhang, Klingsch, Schadschneider, Seyfried (2011) J. Stat. Mech. P06004, runs UO (Jülich data archive)",
        "run": f"uo-{round(100 * entrance_width_m):03d}-{round(100 * corridor_width_m):03d}-{round(100 * exit_width_m):03d}",
        "entrance_width_m": float(entrance_width_m), "corridor_width_m": float(corridor_width_m),
        "exit_width_m": float(exit_width_m), "width_m": float(exit_width_m), "n_pedestrians": n, "seed": seed,
        "waiting_area": [x0, y0, x1, y1], "waiting_density_per_m2": float(waiting_density_per_m2),
        "floor_width_m": float(floor_width_m), "barrier_thickness_m": float(barrier_thickness_m),
        "end_wall_thickness_m": float(end_wall_thickness_m), "outflow_width_m": float(outflow_width_m),
        "view": {"y_m": list(UO_VIEW_Y_M)}, "navigation_clearance_m": clearance,
        "navigation_wall_slowdown": None if slowdown is None else list(slowdown),
        "confidence": {"corridor": "high (sketch, recordings)", "entrance_and_exit_on_axis": "high (recordings)",
                       "waiting_area": "medium (sketch: 5 m wide, about 3 /m²)", "floor_length": "high (recordings)",
                       "floor_width": "assumption", "barrier_thickness": "assumption",
                       "end_wall_thickness": "assumption", "outflow": "assumption (beyond the camera)"},
    }
    return Scenario(geometry=geometry, position_m=position, pedestrian_params={"radius_m": float(radius_m)},
                    spawn_area=waiting, name="juelich_corridor", metadata=metadata, seed=seed,
                    navigation_resolution_m=navigation_resolution_m, navigation_clearance_m=clearance,
                    wall_slowdown=slowdown, measurement=Measurement("exit", ("measurement",)))
