"""RiMEA test 16: single file on a closed oval ring one pedestrian wide (no exit, no overtaking).

RiMEA 4.1.1 (A 4, test 16) prefers a ring "the width of one agent, so agents can move freely without being
able to overtake", where "the ring is the starting and measuring area and there is no exit". The ring
here is JuPedSim's (``jupedsim-web-community:scripts/scenario_builders/rimea16_loop.py``): an oval of two
4 m straights and two half circles of 3 m centreline radius, 0.8 m wide, so the centreline is
8 + 6π ≈ 26.85 m. Two disks of radius 0.23 m side by side need 0.92 m > 0.8 m: nobody can pass.

Navigation: :class:`~crowd_env.walking.circulation.CirculationNavigation` on the centreline (each
pedestrian heads for the centreline point ``lookahead_m`` ahead), given as the scenario's
``navigation_field``, so the scenario's validation checks reachability against the loop (every start must
lie on the loop's corridor) instead of against an exit. :class:`~crowd_env.core.geometry.Geometry` needs
one exit; the ring's is *sealed*: a 0.2 m × 0.04 m strip inside the walkable area 1-5 cm from the outer
wall of the lower straight, which disk centres (always at least 0.23 m from a wall) cannot reach. The walls
stay whole (the strip does not touch them), so nobody ever leaves. For JuPedSim the metadata carry a cyclic
list of waypoints along the centreline (``jupedsim_waypoints``, about 1 m apart) and the distance at which
one counts as reached (``jupedsim_waypoint_distance_m``: the corridor's half width).
"""
from __future__ import annotations

import math

import numpy as np
import shapely

from ...core.geometry import Geometry
from ...core.state import sample_desired_speeds
from ...walking.circulation import CirculationNavigation, oval_centreline
from ..checks import check_count, check_positive
from ..registry import register_scenario
from ..scenario import Scenario, ScenarioError
from .base import RIMEA_RADIUS_M

__all__ = ["rimea_16_ring", "ring_geometry"]

WALL_SPACING_M = 0.1  # vertex spacing of the curved walls (chord sagitta < 0.6 mm on the inner 2.6 m radius)
CENTRELINE_SPACING_M = 0.05


def ring_geometry(straight_m: float = 4.0, radius_m: float = 3.0, width_m: float = 0.8) -> tuple:
    """``(Geometry, centreline (K, 2), sealed exit polygon)`` of the oval ring: walls the ovals of radius
    ``radius_m`` ± ``width_m``/2 about the same centres, the centreline walked anticlockwise from
    (0, −``radius_m``)."""
    check_positive(straight_m=straight_m, radius_m=radius_m, width_m=width_m)
    hw = 0.5 * width_m
    if hw >= radius_m:
        raise ScenarioError(f"the ring's half width {hw} m must be below the centreline radius {radius_m} m")
    outer = oval_centreline(straight_m, radius_m + hw, WALL_SPACING_M)
    inner = oval_centreline(straight_m, radius_m - hw, WALL_SPACING_M)
    area = shapely.Polygon(outer, [inner[::-1]])
    x_mid = 0.5 * straight_m
    wall_y = -radius_m - hw
    sealed = shapely.box(x_mid - 0.1, wall_y + 0.01, x_mid + 0.1, wall_y + 0.05)
    geometry = Geometry(area, [sealed], name="rimea_16_ring")
    return geometry, oval_centreline(straight_m, radius_m, CENTRELINE_SPACING_M), sealed


def rimea_16_ring(seed: int = 0, n_pedestrians: int = 10, straight_m: float = 4.0, radius_m: float = 3.0,
                  width_m: float = 0.8, lookahead_m: float = 1.0, desired_speed_m_s: float | None = None) -> Scenario:
    """Test 16: ``n_pedestrians`` disks of radius 0.23 m evenly spaced along the centreline of the oval ring
    (1D density n / L), heading along it, circulating without end. Desired speeds: ``desired_speed_m_s`` for
    everybody, or (None) drawn from the preset's distribution (N(1.34, 0.26) m/s truncated at 2σ) with
    ``seed``, stored in the scenario so that every backend walks with the same ones."""
    n = check_count("n_pedestrians", n_pedestrians)
    geometry, centreline, sealed = ring_geometry(straight_m, radius_m, width_m)
    nav = CirculationNavigation(centreline, lookahead_m=lookahead_m, half_width_m=0.5 * width_m)
    length = nav.length_m
    spacing = length / n
    if spacing < 2.0 * RIMEA_RADIUS_M + 1e-6:
        raise ScenarioError(f"{n} pedestrians do not fit on the ring: {length:.4g} m of centreline gives {spacing:.4g} m "
                            f"each, less than a body ({2 * RIMEA_RADIUS_M} m); at most "
                            f"{int(length / (2 * RIMEA_RADIUS_M + 1e-6))}")
    s0 = 0.5 * spacing
    position = nav.point_at(s0 + spacing * np.arange(n))
    if desired_speed_m_s is None:
        speeds = sample_desired_speeds(n, np.random.default_rng(seed))
    else:
        check_positive(desired_speed_m_s=desired_speed_m_s)
        speeds = np.full(n, float(desired_speed_m_s))
    n_way = max(3, int(round(length / 1.0)))
    waypoints = nav.point_at(length * np.arange(n_way) / n_way)
    meta = {"rimea_test": "16", "n_pedestrians": n, "seed": seed, "ring_length_m": length,
            "density_per_m": n / length, "straight_m": float(straight_m), "radius_m": float(radius_m),
            "width_m": float(width_m), "lookahead_m": float(lookahead_m), "closed_ring": True,
            "walkable_area": geometry.walkable_area.wkt, "exits": [sealed.wkt],
            "sealed_exit": "Geometry requires an exit: a 0.2 m x 0.04 m strip 1-5 cm from the outer wall, out of "
                           "reach of disk centres (>= 0.23 m from walls); nobody can leave",
            "centreline": centreline.tolist(),
            "jupedsim_waypoints": [tuple(map(float, p)) for p in waypoints],
            "jupedsim_waypoint_distance_m": 0.5 * float(width_m)}
    return Scenario(geometry=geometry, position_m=position, heading_rad=None,
                    pedestrian_params={"radius_m": RIMEA_RADIUS_M, "desired_speed_m_s": speeds},
                    spawn_area=geometry.walkable_area, name="rimea_16_ring", metadata=meta, seed=seed,
                    navigation_field=nav)


def ring_capacity(straight_m: float = 4.0, radius_m: float = 3.0) -> int:
    """How many disks of radius 0.23 m fit evenly spaced on the ring's centreline."""
    length = 2.0 * straight_m + 2.0 * math.pi * radius_m
    return int(length / (2.0 * RIMEA_RADIUS_M + 1e-6))


register_scenario("rimea_16_ring", rimea_16_ring)
