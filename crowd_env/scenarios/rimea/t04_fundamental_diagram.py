"""RiMEA test 4: a long corridor filled at a given density, with three 2 m × 2 m measuring areas.

RiMEA 4.1.1 (A 2, test 4) fills a corridor of 1000 m × 10 m at 0.5 ... 6 P/m² and reads the mean speed in
three 2 m × 2 m measuring areas (a main one and two controls) over 60 s after a 10 s transient. The model
has no periodic boundary, so the density is held the way RiMEA's own set-up holds it: by length. The
crowd fills the whole corridor (back wall at x = 0, an open end across the full width at x =
``length_m``) and the measuring areas sit far enough from both ends that what the ends do does not reach
them during the measurement: the tail, which follows the crowd at most at the free speed (≤ 1.34 m/s ×
70 s ≈ 94 m), and the front, where the crowd streams out and a release wave runs upstream (the
``back_margin_m`` and ``front_margin_m`` options; docs in :mod:`crowd_env.experiments.validation.rimea.t04_fundamental_diagram`).
Desired speeds are equal for everybody ("as equal as possible", RiMEA), 1.34 m/s (Weidmann's free speed).
"""
from __future__ import annotations

import math

import numpy as np
import shapely

from ...core.geometry import Geometry
from ..checks import check_positive
from ..doors import door_exit
from ..placement import place_pedestrians
from ..registry import register_scenario
from ..scenario import Scenario, ScenarioError
from .base import RIMEA_RADIUS_M

__all__ = ["rimea_4_fundamental_diagram", "fd_measuring_areas", "MEASURING_AREA_NAMES"]

MEASURING_AREA_NAMES = ("main", "control_downstream", "control_lateral")


def fd_measuring_areas(main_x_m: float, width_m: float, size_m: float = 2.0, downstream_m: float = 10.0) -> dict:
    """The three measuring areas (name -> shapely box) around the main area's centre x = ``main_x_m``.

    ``main``: centred across the corridor; ``control_downstream``: the same box ``downstream_m`` further on
    (towards the open end); ``control_lateral``: beside the main one, 1 m from the wall (y in [1, 1 + size]).
    RiMEA's Fig. 5 places a main and two control areas; its exact positions were not available, so these two
    controls test the two ways the state may not be homogeneous (along the corridor: the ends; across it: the
    walls). Downstream rather than upstream because the crowd's tail comes from behind at the free speed."""
    h = 0.5 * size_m
    yc = 0.5 * width_m
    return {"main": shapely.box(main_x_m - h, yc - h, main_x_m + h, yc + h),
            "control_downstream": shapely.box(main_x_m + downstream_m - h, yc - h, main_x_m + downstream_m + h, yc + h),
            "control_lateral": shapely.box(main_x_m - h, 1.0, main_x_m + h, 1.0 + size_m)}


def rimea_4_fundamental_diagram(seed: int = 0, density_per_m2: float = 1.0, width_m: float = 10.0,
                                back_margin_m: float = 100.0, front_margin_m: float = 200.0,
                                desired_speed_m_s: float = 1.34, downstream_m: float = 10.0) -> Scenario:
    """Test 4: a ``width_m`` wide corridor of length ``back_margin_m + front_margin_m`` filled with
    ``density_per_m2`` pedestrians per m² (round(ρ × area) disks of radius 0.23 m, placed by
    :func:`~crowd_env.scenarios.place_pedestrians`, which raises :class:`ScenarioError` with the capacity
    when they do not fit), all at ``desired_speed_m_s``. The main measuring area is centred at x =
    ``back_margin_m`` (measured from the back wall), ``front_margin_m`` before the open end; the geometry
    carries the three measuring areas (:func:`fd_measuring_areas`)."""
    check_positive(density_per_m2=density_per_m2, width_m=width_m, back_margin_m=back_margin_m,
                   front_margin_m=front_margin_m, desired_speed_m_s=desired_speed_m_s, downstream_m=downstream_m)
    if front_margin_m - downstream_m < 2.0 or back_margin_m < 2.0 or width_m < 8.0:
        raise ScenarioError("the measuring areas need front_margin_m >= downstream_m + 2 m, back_margin_m >= 2 m and "
                            "width_m >= 8 m (the lateral area beside the main one), got "
                            f"front_margin_m={front_margin_m}, back_margin_m={back_margin_m}, width_m={width_m}")
    length = float(back_margin_m + front_margin_m)
    area = shapely.box(0.0, 0.0, length, width_m)
    exit_poly = door_exit([(length, 0.0), (length, width_m)], area)
    areas = fd_measuring_areas(float(back_margin_m), float(width_m), downstream_m=float(downstream_m))
    geometry = Geometry(area, [exit_poly], measurement_areas=areas, name="rimea_4_fundamental_diagram")
    n = int(round(density_per_m2 * area.area))
    # Every pedestrian strictly behind the door line (a centre on it would leave at once).
    region = shapely.box(0.0, 0.0, length - 1e-6, width_m)
    try:
        position = place_pedestrians(region, n, RIMEA_RADIUS_M, np.random.default_rng(seed))
    except ScenarioError as exc:
        raise ScenarioError(f"{density_per_m2:g} P/m² in the {length:g} m x {width_m:g} m corridor: {exc} "
                            f"(hexagonal packing: {hexagonal_capacity_per_m2():.3g} /m²)") from exc
    meta = {"rimea_test": "4", "density_per_m2": float(density_per_m2), "nominal_density_per_m2": n / area.area,
            "length_m": length, "width_m": float(width_m), "main_x_m": float(back_margin_m),
            "front_margin_m": float(front_margin_m), "measuring_areas": {k: v.wkt for k, v in areas.items()},
            "walkable_area": area.wkt, "exits": [exit_poly.wkt], "n_pedestrians": n, "seed": seed}
    return Scenario(geometry=geometry, position_m=position, heading_rad=np.zeros(n),
                    pedestrian_params={"radius_m": RIMEA_RADIUS_M, "desired_speed_m_s": float(desired_speed_m_s)},
                    spawn_area=area, name="rimea_4_fundamental_diagram", metadata=meta, seed=seed,
                    navigation_clearance_m=RIMEA_RADIUS_M)


def hexagonal_capacity_per_m2(radius_m: float = RIMEA_RADIUS_M) -> float:
    """The densest packing of disks of ``radius_m`` (hexagonal): 1 / (2 √3 r²) per m² (5.46 /m² at 0.23 m)."""
    return 1.0 / (2.0 * math.sqrt(3.0) * radius_m ** 2)


register_scenario("rimea_4_fundamental_diagram", rimea_4_fundamental_diagram)
