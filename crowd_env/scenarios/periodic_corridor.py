"""Periodic corridor: a straight strip, periodic along its axis, the instrument of the fundamental diagram.

Coordinates (metres): x ∈ [0, L) along the corridor, periodic with period L = ``length_m`` (x = 0 and x = L
are the same place, :class:`~crowd_env.core.geometry.Geometry` ``period_x_m``); walls at y = ±W/2 (W =
``width_m``, 1.8 m by default as in the Jülich corridor experiments). There are no exits: nobody leaves,
the global density N/(L W) stays what it was set to, and a run ends at its time limit. Pedestrians walk
east (e_d = (+1, 0)) or west (e_d = (−1, 0)); a fraction ``westbound_fraction`` of them, drawn at random,
walk west (0: unidirectional flow; 0.5: balanced counterflow). Their navigation is a pair of uniform fields
(:meth:`~crowd_env.walking.navigation.NavigationField.uniform`) combined per pedestrian by a
:class:`~crowd_env.walking.navigation.DestinationNavigation` (keys 0 east, 1 west), which the compiled
rollout samples. Start positions: :func:`~crowd_env.scenarios.placement.place_pedestrians` in the strip, at least
a radius from the walls and from the seam (so nobody overlaps across it), at rest.

A width below 4 r (e.g. 0.7 m with r = 0.23 m) leaves no room to pass: a single file, the straight ring of
the single-file fundamental diagram (``width_m=0.7``). The measurements are
:mod:`crowd_env.analysis.periodic` (global density, mean speed along each one's walking direction, specific
flow, unwrapped trajectories); :func:`crowd_env.experiments.validation.periodic.fundamental_diagram_point` runs one point.
"""
from __future__ import annotations

import numpy as np
from shapely.geometry import box

from ..core.geometry import Geometry
from ..walking.navigation import DestinationNavigation, NavigationField
from .checks import check_count, check_positive
from .placement import place_pedestrians
from .registry import register_scenario
from .scenario import Scenario, ScenarioError

__all__ = ["periodic_corridor", "EAST", "WEST", "DEFAULT_DENSITY_PER_M2"]

EAST, WEST = 0, 1  # the navigation keys of the two walking directions
DEFAULT_DENSITY_PER_M2 = 1.0  # when neither density_per_m2 nor n_pedestrians is given


@register_scenario("periodic_corridor")
def periodic_corridor(length_m: float = 20.0, width_m: float = 1.8, density_per_m2: float | None = None,
                      n_pedestrians: int | None = None, westbound_fraction: float = 0.0, seed: int | None = 0,
                      radius_m: float = 0.23, navigation_resolution_m: float = 0.1) -> Scenario:
    """A ``length_m`` x ``width_m`` corridor periodic along x, filled at ``density_per_m2`` (N = round(ρ L W))
    or with ``n_pedestrians`` (give one; neither: 1 /m²), a ``westbound_fraction`` of them walking west.
    Raises :class:`ScenarioError` naming the argument (non-positive sizes, a fraction outside [0, 1], a
    density or count that does not fit)."""
    check_positive(length_m=length_m, width_m=width_m, radius_m=radius_m, navigation_resolution_m=navigation_resolution_m)
    if density_per_m2 is not None and n_pedestrians is not None:
        raise ScenarioError(f"give density_per_m2 or n_pedestrians, not both (got {density_per_m2!r} and "
                            f"{n_pedestrians!r})")
    if n_pedestrians is None:
        density_per_m2 = DEFAULT_DENSITY_PER_M2 if density_per_m2 is None else density_per_m2
        check_positive(density_per_m2=density_per_m2)
        asked, name = {"density_per_m2": float(density_per_m2)}, "density_per_m2"
    else:
        asked, name = {"n": check_count("n_pedestrians", n_pedestrians)}, "n_pedestrians"
    if not (isinstance(westbound_fraction, (int, float, np.integer, np.floating)) and 0.0 <= westbound_fraction <= 1.0):
        raise ScenarioError(f"westbound_fraction must be a number in [0, 1], got {westbound_fraction!r}")
    if width_m <= 2.0 * radius_m:
        raise ScenarioError(f"width_m = {width_m} m leaves no room for a pedestrian of radius {radius_m} m")
    hw = 0.5 * width_m
    strip = box(0.0, -hw, length_m, hw)
    geometry = Geometry(strip, exits=(), name=f"periodic_corridor_{length_m:g}x{width_m:g}", period_x_m=length_m)
    rng = np.random.default_rng(seed)
    try:
        position = place_pedestrians(strip, radius_m=radius_m, rng=rng, **asked)
    except ScenarioError as exc:
        value = asked.get("density_per_m2", asked.get("n"))
        raise ScenarioError(f"{name} = {value!r} cannot be placed in the {length_m:g} m x {width_m:g} m periodic "
                            f"corridor: {exc}") from exc
    n = position.shape[0]
    if n == 0:
        raise ScenarioError(f"{name} = {asked.get('density_per_m2', asked.get('n'))!r} puts nobody in the "
                            f"{length_m:g} m x {width_m:g} m corridor")
    n_west = int(round(float(westbound_fraction) * n))
    heading_to = np.full(n, EAST, np.int64)
    heading_to[rng.choice(n, size=n_west, replace=False)] = WEST
    fields = {EAST: NavigationField.uniform(geometry, (1.0, 0.0), navigation_resolution_m),
              WEST: NavigationField.uniform(geometry, (-1.0, 0.0), navigation_resolution_m)}
    metadata = {"length_m": float(length_m), "width_m": float(width_m), "period_m": float(length_m),
                "n_pedestrians": n, "density_per_m2": n / (length_m * width_m), "n_westbound": n_west,
                "westbound_fraction": float(westbound_fraction), "seed": seed,
                "direction_x": np.where(heading_to == WEST, -1.0, 1.0).tolist(),
                "single_file": bool(width_m < 4.0 * radius_m)}
    return Scenario(geometry=geometry, position_m=position, pedestrian_params={"radius_m": float(radius_m)},
                    spawn_area=strip, name="periodic_corridor", metadata=metadata, seed=seed,
                    navigation_resolution_m=navigation_resolution_m,
                    navigation_field=DestinationNavigation(fields, heading_to))
