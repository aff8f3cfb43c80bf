"""The Seyfried et al. (2009) bottleneck experiment as simulated by Kabalan et al. (2016), Section 4.

Coordinates (metres): x along the flow with the bottleneck entrance at x = 0; y across, the corridor
axis at y = 0. Geometry and protocol follow the documentation page
``docs/validation/bottleneck.md`` (section "The experiment"; confidence in brackets):

- holding corridor 4 m wide (y in [-2, 2]) ending in a wall perpendicular to the flow at x = 0
  [medium]; it reaches back to the rear of the last holding section;
- channel (the bottleneck) of width b and length 2.8 m, x in [0, 2.8], centred on the axis
  [medium-high];
- beyond the channel an open outflow area (assumption: 2 m deep, as wide as the corridor, walls only
  along its sides); pedestrians leave when their centre enters the exit, the outflow's last 0.5 m
  (x in [4.3, 4.8]). The exit is set back from the channel end so that people who just left the
  channel still walk and interact as in the open hall, yet leave long before they could matter;
- measurement line "bottleneck" across the channel at its middle, x = 1.4 m [medium];
- measurement areas for densities (Kabalan Fig. 12): "front", a 1.0 m deep x 1.2 m wide box centred
  on the axis 1.0 m in front of the entrance (x in [-1.5, -0.5]; the README reports the jam density
  "1 m in front of the bottleneck"; the box size is our choice), and "inside", the whole channel;
- 3.3 persons/m² in holding sections 4 m x 1.515 m of 20 persons each [high], the nearest spanning
  2.24-3.755 m upstream of the entrance [low-medium]; N = 20 fills the nearest section, 40 the two
  nearest, 60 all three [inference]. Other N fill sections in order, a partial last section with the
  sites nearest the entrance centre; N > 60 adds sections further upstream. Disks lie entirely
  inside their section, so neighbouring sections never overlap.

Navigation (``navigation_clearance_m``). 0 solves Eq. 11-13 for points, as the paper does (V = 0 only
inside walls); its A = 790 N, B = 0.08 m were calibrated with such a field (preset ``paper``). The
default, the radius, solves it for the disk centres (presets ``calibrated`` and ``recalibrated``). For disks this
field aims pedestrians beside the entrance at the wall next to the opening (the geodesic of a point
grazes the corner vertex, which a centre cannot reach): a lone pedestrian starting 0.6 m off-axis
needs 4.7 s instead of 2.7 s to cross the empty 1 m bottleneck, and in crowds people stall at the
corners. ``navigation_clearance_m = radius_m`` solves the field in the configuration space of the
centres (walls inflated by r), which removes this (2.9 s), but then the paper's (A, B) give N = 60
flows about 20 % above the experiment: the corner brake of the point field was absorbed by the
calibration. See :class:`BottleneckScenario` and ``NavigationField(clearance_m=...)``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from shapely.geometry import Polygon, box
from shapely.ops import unary_union

from ..core.geometry import Geometry
from ..core.segments import GeometryError
from .checks import check_clearance, check_count, check_positive as _positive, check_wall_slowdown
from .placement import place_pedestrians
from .registry import register_scenario
from .scenario import Measurement, Scenario, ScenarioError

__all__ = ["seyfried_bottleneck", "bottleneck_geometry", "BottleneckScenario"]


@dataclass(eq=False)
class BottleneckScenario(Scenario):
    """The Seyfried bottleneck :class:`Scenario` (kept as a type for existing code): its
    ``navigation_clearance_m`` (a field of every Scenario) erodes the walkable area by this distance from
    the walls before solving Eq. 11 (see :class:`~crowd_env.walking.navigation.NavigationField`,
    ``clearance_m``); 0 gives the paper's literal point field.
    """


def bottleneck_geometry(width_m: float = 1.0, *, corridor_width_m: float = 4.0, corridor_length_m: float = 6.785,
                        channel_length_m: float = 2.8, outflow_depth_m: float = 2.0, outflow_width_m: float | None = None,
                        exit_depth_m: float = 0.5, front_area_depth_m: float = 1.0, front_area_width_m: float = 1.2,
                        front_area_distance_m: float = 1.0) -> Geometry:
    """Corridor x in [-corridor_length, 0], channel x in [0, L], outflow x in [L, L + outflow_depth].

    Raises :class:`GeometryError` when the channel is wider than the corridor or the outflow, or the
    exit is deeper than the outflow area.
    """
    outflow_width_m = corridor_width_m if outflow_width_m is None else outflow_width_m
    _positive(width_m=width_m, corridor_width_m=corridor_width_m, corridor_length_m=corridor_length_m,
              channel_length_m=channel_length_m, outflow_depth_m=outflow_depth_m, outflow_width_m=outflow_width_m,
              exit_depth_m=exit_depth_m, front_area_depth_m=front_area_depth_m, front_area_width_m=front_area_width_m,
              front_area_distance_m=front_area_distance_m)
    if width_m > corridor_width_m:
        raise GeometryError(f"bottleneck width {width_m} m is larger than the corridor width {corridor_width_m} m")
    if width_m > outflow_width_m:
        raise GeometryError(f"bottleneck width {width_m} m is larger than the outflow width {outflow_width_m} m")
    if exit_depth_m >= outflow_depth_m:
        raise GeometryError(f"exit_depth_m {exit_depth_m} must be smaller than outflow_depth_m {outflow_depth_m}")
    half = 0.5 * front_area_depth_m
    if front_area_distance_m - half < 0 or front_area_distance_m + half > corridor_length_m:
        raise GeometryError("the 'front' measurement area must lie in the corridor: front_area_distance_m "
                            f"{front_area_distance_m} +- half its depth {front_area_depth_m} leaves [0, {corridor_length_m}]")
    if front_area_width_m > corridor_width_m:
        raise GeometryError(f"front_area_width_m {front_area_width_m} exceeds the corridor width {corridor_width_m} m")
    hb, hc, ho = 0.5 * width_m, 0.5 * corridor_width_m, 0.5 * outflow_width_m
    length, end = channel_length_m, channel_length_m + outflow_depth_m
    corridor = box(-corridor_length_m, -hc, 0.0, hc)
    channel = box(0.0, -hb, length, hb)
    outflow = box(length, -ho, end, ho)
    area = unary_union([corridor, channel, outflow])
    area = Polygon(area.exterior)  # one simple polygon
    exit_poly = box(end - exit_depth_m, -ho, end, ho)
    xf = -front_area_distance_m
    return Geometry(
        area, exits=[exit_poly],
        measurement_lines={"bottleneck": [(0.5 * length, -hb), (0.5 * length, hb)]},
        measurement_areas={"front": box(xf - 0.5 * front_area_depth_m, -0.5 * front_area_width_m,
                                        xf + 0.5 * front_area_depth_m, 0.5 * front_area_width_m),
                           "inside": channel},
        name=f"seyfried_bottleneck_b{width_m:g}")


def _section_counts(n_pedestrians: int, n_sections, density_per_m2: float, corridor_width_m: float,
                    section_depth_m: float) -> tuple:
    """(persons per holding section, number of sections): round(density x area) each, 3 sections or as many
    as N needs; :class:`ScenarioError` when a section holds nobody or ``n_sections`` is too few."""
    per_section = int(round(density_per_m2 * corridor_width_m * section_depth_m))
    if per_section < 1:
        raise ScenarioError(f"a holding section of {corridor_width_m} m x {section_depth_m} m at "
                            f"{density_per_m2} /m² holds no pedestrian")
    needed = math.ceil(n_pedestrians / per_section)
    if n_sections is None:
        n_sections = max(3, needed)
    elif int(n_sections) != n_sections or n_sections < needed:
        raise ScenarioError(f"more pedestrians than fit in the holding area: {n_pedestrians} need {needed} sections "
                            f"of {per_section}, but n_sections = {n_sections!r}")
    return per_section, int(n_sections)


def _fill_sections(n_pedestrians: int, n_sections: int, per_section: int, rng, *, corridor_width_m: float,
                   section_depth_m: float, block_start_upstream_m: float, radius_m: float,
                   density_per_m2: float) -> tuple:
    """(the holding sections as boxes, (N, 2) start positions): sections filled nearest-first, a partly filled
    one packed towards its downstream edge's centre."""
    hc = 0.5 * corridor_width_m
    sections, positions = [], []
    left = n_pedestrians
    for k in range(n_sections):
        x1 = -(block_start_upstream_m + k * section_depth_m)
        section = box(x1 - section_depth_m, -hc, x1, hc)
        sections.append(section)
        count = min(left, per_section)
        if count:
            try:
                positions.append(place_pedestrians(section, count, radius_m, rng, density_per_m2=density_per_m2,
                                                   toward=None if count == per_section else (x1, 0.0)))
            except ScenarioError as exc:
                raise ScenarioError(f"holding section {k} ({corridor_width_m} m x {section_depth_m} m): {exc}") from exc
        left -= count
    return sections, np.vstack(positions)


@register_scenario("seyfried_bottleneck", aliases=("bottleneck",))
def seyfried_bottleneck(width_m: float = 1.0, n_pedestrians: int = 60, seed: int | None = 0,
                        corridor_width_m: float = 4.0, channel_length_m: float = 2.8,
                        initial_density_per_m2: float = 3.3, section_depth_m: float = 1.515,
                        block_start_upstream_m: float = 2.24, radius_m: float = 0.23, n_sections: int | None = None,
                        outflow_depth_m: float = 2.0, outflow_width_m: float | None = None,
                        exit_depth_m: float = 0.5, navigation_resolution_m: float = 0.05,
                        navigation_clearance_m: float | None = None, navigation_wall_slowdown=None) -> Scenario:
    """Seyfried et al. (2009) bottleneck of width ``width_m`` with ``n_pedestrians`` in the holding area.

    Sections of ``corridor_width_m`` x ``section_depth_m`` hold round(density x area) persons each (20 by
    default) and are filled nearest-first; the corridor holds ``n_sections`` of them (default: 3, or
    as many as N needs). Radii are ``radius_m`` for everybody (Table 2); desired speeds are drawn by
    :meth:`Scenario.make_state`. Raises :class:`ScenarioError` / :class:`GeometryError` naming the
    problem (bottleneck not wider than a pedestrian, wider than the corridor, non-positive values,
    more pedestrians than fit). ``navigation_clearance_m``: default the radius (the configuration space of
    the disk centres, as every other scenario and the ``calibrated`` preset); 0 is the paper's point
    field (preset ``paper``). ``navigation_wall_slowdown``: ``(distance_m, speed_factor)`` for a slower
    eikonal wavefront near walls (Eq. 11's 0 < V < 1, which the paper describes but does not use), or None.
    """
    _positive(width_m=width_m, corridor_width_m=corridor_width_m, channel_length_m=channel_length_m,
              initial_density_per_m2=initial_density_per_m2, section_depth_m=section_depth_m,
              block_start_upstream_m=block_start_upstream_m, radius_m=radius_m)
    n_pedestrians = check_count("n_pedestrians", n_pedestrians)
    clearance = check_clearance(navigation_clearance_m, radius_m)
    slowdown = check_wall_slowdown(navigation_wall_slowdown)
    if width_m <= 2.0 * radius_m:
        raise GeometryError(f"bottleneck width {width_m} m is not wider than a pedestrian (diameter "
                            f"{2 * radius_m} m): nobody can pass")
    per_section, n_sections = _section_counts(n_pedestrians, n_sections, initial_density_per_m2, corridor_width_m,
                                              section_depth_m)
    corridor_length_m = block_start_upstream_m + n_sections * section_depth_m
    geometry = bottleneck_geometry(width_m, corridor_width_m=corridor_width_m, corridor_length_m=corridor_length_m,
                                   channel_length_m=channel_length_m, outflow_depth_m=outflow_depth_m,
                                   outflow_width_m=outflow_width_m, exit_depth_m=exit_depth_m)
    sections, position = _fill_sections(n_pedestrians, n_sections, per_section, np.random.default_rng(seed),
                                        corridor_width_m=corridor_width_m, section_depth_m=section_depth_m,
                                        block_start_upstream_m=block_start_upstream_m, radius_m=radius_m,
                                        density_per_m2=initial_density_per_m2)
    metadata = {
        "source": "Seyfried et al. (2009) Transp. Sci. 43(3):395-406; Kabalan et al. (2016) Section 4",
        "width_m": float(width_m), "n_pedestrians": n_pedestrians, "seed": seed,
        "corridor_width_m": float(corridor_width_m), "corridor_length_m": float(corridor_length_m),
        "channel_length_m": float(channel_length_m), "initial_density_per_m2": float(initial_density_per_m2),
        "section_depth_m": float(section_depth_m), "pedestrians_per_section": per_section,
        "block_start_upstream_m": float(block_start_upstream_m), "holding_sections": [s.bounds for s in sections],
        "section_counts": [min(per_section, max(0, n_pedestrians - k * per_section)) for k in range(n_sections)],
        "measurement_line_x_m": 0.5 * channel_length_m, "navigation_clearance_m": clearance,
        "navigation_wall_slowdown": None if slowdown is None else list(slowdown),
        "confidence": {"widths": "high", "corridor_width": "medium", "channel_length": "medium-high",
                       "density_and_sections": "high (density), inference (which sections)",
                       "block_distance": "low-medium", "measurement_line": "medium",
                       "outflow_and_exit": "assumption", "front_area": "assumption"},
    }
    return BottleneckScenario(geometry=geometry, position_m=position, pedestrian_params={"radius_m": float(radius_m)},
                              spawn_area=unary_union(sections), name="seyfried_bottleneck", metadata=metadata,
                              seed=seed, navigation_resolution_m=navigation_resolution_m,
                              navigation_clearance_m=clearance, wall_slowdown=slowdown,
                              measurement=Measurement("bottleneck", ("front", "inside"), "inside"))
