"""User-defined geometry: a scenario from walkable-area coordinates or WKT, exits, a spawn area and N.

::

    from . import make_scenario
    sc = make_scenario("polygon",
                       walkable_area=[(0, 0), (8, 0), (8, 6), (0, 6)], holes=[[(4, 2.5), (5, 2.5), (5, 3.5), (4, 3.5)]],
                       exits=[[(8, 2.5), (8, 3.5)]],                   # a door segment in the wall x = 8
                       spawn_area=[(0, 0), (3, 0), (3, 6), (0, 6)], n_pedestrians=20, seed=0)
    # the same from WKT:
    sc = make_scenario("polygon", walkable_area="POLYGON ((0 0, 8 0, 8 6, 0 6, 0 0), (4 2.5, 5 2.5, 5 3.5, 4 3.5, 4 2.5))",
                       exits=["LINESTRING (8 2.5, 8 3.5)"], spawn_area="POLYGON ((0 0, 3 0, 3 6, 0 6, 0 0))",
                       n_pedestrians=20, seed=0)

Exits are polygons (where a pedestrian whose centre enters leaves; they must overlap the walkable
area or share a boundary stretch with it) or door segments on the boundary (the exit is then the
strip of ``exit_depth_m`` behind the door, :func:`~crowd_env.scenarios.doors.door_exit`). The
polygons are normalised (shapely.normalize), so the same shape given as coordinates or WKT, in either
orientation, gives the identical geometry. The eikonal field is solved for the disk centres
(``navigation_clearance_m`` = radius by default), so a passage narrower than a pedestrian blocks it.
"""
from __future__ import annotations

import numpy as np
import shapely
from scipy import ndimage
from shapely.geometry import LineString, Polygon
from shapely.geometry.base import BaseGeometry

from ..core.geometry import Geometry, GeometryError, as_polygon, ring_coordinates
from ..walking.navigation import NavigationField
from .checks import check_clearance, check_count, check_positive
from .doors import door_exit, door_widths_m
from .placement import place_pedestrians
from .registry import register_scenario
from .scenario import Measurement, Scenario, ScenarioError

__all__ = ["scenario_from_polygon", "walkable_polygon", "exit_polygons"]


def walkable_polygon(walkable_area, holes=()):
    """A normalised valid shapely (Multi)Polygon from WKT, a shapely geometry or (K, 2) outer-ring
    coordinates, minus ``holes`` ((K, 2) rings, WKT or shapely polygons). Raises :class:`GeometryError`
    naming the problem (self-intersection, fewer than 3 vertices, non-finite values, hole outside)."""
    holes = list(holes or ())
    if isinstance(walkable_area, (str, BaseGeometry)):
        area = as_polygon(walkable_area, "walkable area")
    else:
        outer = ring_coordinates(walkable_area, "walkable area")
        rings = [ring_coordinates(h, f"hole {k}") for k, h in enumerate(holes) if not isinstance(h, (str, BaseGeometry))]
        area = as_polygon(Polygon(outer, rings), "walkable area (with its holes)")
        holes = [h for h in holes if isinstance(h, (str, BaseGeometry))]
    for k, h in enumerate(holes):
        hole = as_polygon(h, f"hole {k}")
        if not area.contains(hole):
            raise GeometryError(f"hole {k} does not lie inside the walkable area")
        area = area.difference(hole)
    return shapely.normalize(area)


def _is_coordinates(obj) -> bool:
    """True for a (K, 2) array of numbers (one ring or segment), False for a list of exits."""
    try:
        arr = np.asarray(obj, dtype=np.float64)
    except (TypeError, ValueError):
        return False
    return arr.ndim == 2 and arr.shape[1] == 2


def exit_polygons(exits, walkable_area, depth_m: float = 0.5) -> list:
    """Exit polygons from a list of polygons ((K >= 3, 2) coordinates, WKT POLYGON, shapely) and door
    segments ((2, 2) end points, WKT LINESTRING, shapely LineString) on the boundary of ``walkable_area``."""
    if exits is None:
        raise GeometryError("the geometry has no exit: give at least one exit polygon or door segment")
    if isinstance(exits, (str, BaseGeometry)):
        exits = [exits]
    elif not isinstance(exits, dict) and _is_coordinates(exits):
        exits = [exits]  # one exit given as coordinates
    items = list(exits.values()) if isinstance(exits, dict) else list(exits)
    if not items:
        raise GeometryError("the geometry has no exit: give at least one exit polygon or door segment")
    out = []
    for k, e in enumerate(items):
        what = f"exit {k}"
        if isinstance(e, str):
            try:
                e = shapely.from_wkt(e)
            except Exception as exc:  # shapely raises its own error types
                raise GeometryError(f"{what}: cannot parse WKT ({exc})") from exc
        if isinstance(e, LineString):
            out.append(shapely.normalize(door_exit(e, walkable_area, depth_m, what)))
            continue
        if not isinstance(e, BaseGeometry):
            pts = np.asarray(e, dtype=np.float64)
            if pts.shape == (2, 2):
                out.append(shapely.normalize(door_exit(pts, walkable_area, depth_m, what)))
                continue
            e = Polygon(ring_coordinates(pts, what))
        out.append(shapely.normalize(as_polygon(e, what)))
    return out


@register_scenario("polygon", aliases=("custom",))
def scenario_from_polygon(walkable_area, exits, spawn_area, n_pedestrians: int, holes=(), seed: int | None = 0,
                          radius_m: float = 0.23, density_per_m2: float | None = None, exit_depth_m: float = 0.5,
                          exit_names=None, destination=None, measurement_lines=None,
                          navigation_clearance_m: float | None = None, navigation_resolution_m: float = 0.05,
                          name: str = "polygon", measurement: Measurement | None = None) -> Scenario:
    """A validated :class:`Scenario` on a user geometry with ``n_pedestrians`` placed in ``spawn_area``.

    ``walkable_area``: (K, 2) outer-ring coordinates (with ``holes``: a list of (K, 2) rings) or a WKT
    string / shapely polygon (holes inside it; extra ``holes`` are subtracted too). ``exits``: list
    of exit polygons and/or door segments (or a dict name -> exit, which also names them).
    ``spawn_area``: polygon (coordinates, WKT or shapely) inside the walkable area. ``destination``:
    optional per-pedestrian exit names/indices (see :class:`Scenario`). ``measurement_lines`` (see
    :class:`~crowd_env.core.geometry.Geometry`) and ``measurement`` (:class:`~crowd_env.scenarios.scenario.Measurement`,
    default: the first line) say what a run measures. Raises
    :class:`~crowd_env.core.segments.GeometryError` / :class:`ScenarioError` naming the problem: an
    invalid (e.g. self-intersecting) polygon, no exit, an exit not touching the walkable area or
    unreachable from the spawn area, a spawn area outside the walkable area, N too large for it.
    """
    check_positive(radius_m=radius_m, exit_depth_m=exit_depth_m, navigation_resolution_m=navigation_resolution_m)
    n = check_count("n_pedestrians", n_pedestrians)
    if density_per_m2 is not None:
        check_positive(density_per_m2=density_per_m2)
    area = walkable_polygon(walkable_area, holes)
    if isinstance(exits, dict) and exit_names is None:
        exit_names = tuple(str(k) for k in exits)
    geometry = Geometry(area, exits=exit_polygons(exits, area, exit_depth_m), measurement_lines=measurement_lines,
                        name=name)
    spawn = as_polygon(ring_coordinates(spawn_area, "spawn area") if not isinstance(spawn_area, (str, BaseGeometry))
                       else spawn_area, "spawn area")
    outside = spawn.difference(area).area
    if outside > 1e-9:
        raise ScenarioError(f"the spawn area must lie inside the walkable area: {outside:.4g} m² of its "
                            f"{spawn.area:.4g} m² lie outside (beyond the boundary, in a hole or a wall)")
    clearance = check_clearance(navigation_clearance_m, radius_m)
    _check_doors_passable(geometry, radius_m, clearance, exit_names)
    _check_exits_reachable(geometry, spawn, navigation_resolution_m, clearance)
    try:
        position = place_pedestrians(spawn, n, radius_m, np.random.default_rng(seed), density_per_m2=density_per_m2)
    except ScenarioError as exc:
        raise ScenarioError(f"spawn area ({spawn.area:.4g} m²): {exc}") from exc
    metadata = {"walkable_area": area.wkt, "exits": [e.wkt for e in geometry.exits], "spawn_area": spawn.wkt,
                "n_pedestrians": n, "seed": seed}
    return Scenario(geometry=geometry, position_m=position, pedestrian_params={"radius_m": float(radius_m)},
                    spawn_area=spawn, name=name, metadata=metadata, seed=seed,
                    navigation_resolution_m=navigation_resolution_m, navigation_clearance_m=clearance,
                    destination=destination, exit_names=exit_names, measurement=measurement)


def _check_doors_passable(geometry: Geometry, radius_m: float, clearance_m: float, exit_names=None) -> None:
    """Raise :class:`GeometryError` naming every exit behind a door (an exit outside the walkable area, on a
    stretch of its boundary) that is no wider than 2 max(radius_m, clearance_m): a disk cannot pass it, and
    the eikonal field, solved for the disk centres (``navigation_clearance_m``), has no node in it to start
    from; as the bottleneck scenarios refuse a channel no wider than a pedestrian."""
    need = 2.0 * max(float(radius_m), float(clearance_m))
    area = geometry.walkable_area
    names = list(exit_names) if exit_names is not None and len(exit_names) == len(geometry.exits) else None
    narrow = []
    for k, (poly, width) in enumerate(zip(geometry.exits, door_widths_m(geometry))):
        if poly.intersection(area).area > 1e-9 or width > need:
            continue  # an exit inside the walkable area (no door), or a door wide enough
        door = poly.intersection(area.boundary)
        ends = np.asarray(shapely.get_coordinates(door))
        label = f"exit {k}" + (f" ({names[k]!r})" if names is not None else "")
        where = (f", the door from ({ends[0, 0]:g}, {ends[0, 1]:g}) to ({ends[-1, 0]:g}, {ends[-1, 1]:g}),"
                 if ends.shape[0] >= 2 else "")
        narrow.append(f"{label}{where} is {width:.4g} m wide")
    if narrow:
        raise GeometryError(f"{'; '.join(narrow)}: a pedestrian of radius {radius_m:g} m needs a door wider than "
                            f"{need:.4g} m (2 x max(radius_m, navigation_clearance_m) = 2 x "
                            f"max({radius_m:g}, {clearance_m:g})) to pass, so nobody can reach "
                            f"{'it' if len(narrow) == 1 else 'them'}; widen the door(s) or make the pedestrians "
                            "smaller (radius_m)")


def _check_exits_reachable(geometry: Geometry, spawn, resolution_m: float, clearance_m: float) -> None:
    """Raise :class:`ScenarioError` naming the first exit that no path of a disk centre (the eikonal grid,
    4-connected as fast marching) joins to the spawn area."""
    try:
        field = NavigationField.cached(geometry, resolution_m, clearance_m=clearance_m)
    except GeometryError as exc:
        widths = ", ".join(f"exit {k} {w:.4g} m" for k, w in enumerate(door_widths_m(geometry)))
        raise GeometryError(f"no exit can be reached on the navigation grid (navigation_resolution_m = "
                            f"{resolution_m:g} m) by the centre of a pedestrian kept {clearance_m:g} m "
                            f"(navigation_clearance_m) from the walls: the exits' openings ({widths} wide) leave "
                            f"no grid node {clearance_m:g} m from both their sides; widen them beyond "
                            f"{2 * clearance_m:.4g} m by a grid cell or more, or give a finer navigation_resolution_m "
                            f"({exc})") from exc
    nodes = field.raster.node_points()
    walkable = field.walkable
    labels, _ = ndimage.label(walkable)
    in_spawn = shapely.intersects_xy(spawn, nodes[:, 0], nodes[:, 1]).reshape(walkable.shape) & walkable
    reached = set(np.unique(labels[in_spawn]).tolist()) - {0}
    if not reached:
        raise ScenarioError(f"the spawn area has no grid node where a pedestrian fits ({clearance_m} m from the "
                            "walls); make it larger")
    for k, poly in enumerate(geometry.exits):
        at_exit = shapely.intersects_xy(poly, nodes[:, 0], nodes[:, 1]).reshape(walkable.shape) & walkable
        if not reached & set(np.unique(labels[at_exit]).tolist()):
            raise ScenarioError(f"exit {k} is unreachable from the spawn area: no path for a pedestrian of radius "
                                f"{clearance_m} m (navigation_clearance_m) joins them")
