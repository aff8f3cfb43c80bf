"""Scenarios as data: a geometry, initial pedestrians and metadata, plus placement helpers and a registry.

A :class:`Scenario` is what a user writes to define an experiment: it validates itself (positions
inside the walkable area and clear of walls and exits, no overlaps, every pedestrian able to reach an
exit, its own one with per-pedestrian destinations) and builds the
:class:`~crowd_env.core.state.CrowdState` and :class:`~crowd_env.core.simulator.Simulator` it starts from.
"""
from __future__ import annotations

from crowd_env.errors import ScenarioError

import inspect
import math
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np
import shapely
import shapely.affinity
from scipy.spatial import cKDTree

from ..core.checks import check_integer, check_number, check_seed, is_integer
from ..core.geometry import Geometry, as_polygon
from ..walking.navigation import DestinationNavigation, NavigationField, RigidlyMovedNavigation
from ..walking.route_choice import QuickestExitNavigation
from ..core.params import ModelParams, PedestrianDefaults
from ..core.simulator import Simulator
from ..core.state import CrowdState, first_overlap

__all__ = ["Scenario", "ScenarioError", "place_pedestrians", "form_groups", "register_scenario", "make_scenario",
           "list_scenarios", "scenario_options", "check_positive", "check_count", "check_clearance", "door_exit"]

ROUTE_CHOICES = ("quickest",)

# Per-pedestrian quantities a scenario may set; anything else is passed as a CrowdState default.
PEDESTRIAN_PARAMS = ("radius_m", "mass_kg", "inertia_kg_m2", "desired_speed_m_s", "tau_s", "heading_stiffness",
                     "heading_damping", "velocity_m_s", "angular_velocity_rad_s", "premovement_s")


def check_positive(**values) -> None:
    """Raise :class:`ScenarioError` naming the first value that is not a positive finite number."""
    for name, value in values.items():
        check_number(name, value, error=ScenarioError, positive=True)


def check_clearance(value, radius_m: float) -> float:
    """The navigation clearance in m: ``radius_m`` for None (the disk centres' configuration space), else
    ``value`` checked to be finite and >= 0."""
    if value is None:
        return float(radius_m)
    return check_number("navigation_clearance_m", value, error=ScenarioError, minimum=0.0, suffix=" or None")


def door_exit(segment, walkable_area, depth_m: float = 0.5, what: str = "exit"):
    """An exit polygon behind a door: the rectangle of depth ``depth_m`` on the outer side of ``segment``
    ((2, 2) end points or a shapely LineString), which must lie on the boundary of ``walkable_area``.
    Pedestrians leave when their centre crosses the door line."""
    line = segment if isinstance(segment, shapely.LineString) else None
    pts = np.asarray(line.coords if line is not None else segment, dtype=np.float64)
    if pts.shape != (2, 2) or not np.all(np.isfinite(pts)):
        raise ScenarioError(f"{what}: a door segment must be two finite end points of shape (2, 2), got {pts.shape}")
    d = pts[1] - pts[0]
    length = math.hypot(*d)
    if length <= 1e-9:
        raise ScenarioError(f"{what}: the door segment has zero length")
    check_positive(exit_depth_m=depth_m)
    line = shapely.LineString(pts)
    on_boundary = line.difference(walkable_area.boundary.buffer(1e-9)).length
    if on_boundary > 1e-6:
        raise ScenarioError(f"{what}: the door segment {pts.tolist()} does not lie on the boundary of the walkable "
                            f"area ({on_boundary:.4g} m of it lie off the boundary)")
    normal = np.array([-d[1], d[0]]) / length
    mid = 0.5 * (pts[0] + pts[1])
    probe = 1e-4 * max(1.0, length)
    if walkable_area.contains(shapely.Point(*(mid + probe * normal))):
        normal = -normal
    if walkable_area.contains(shapely.Point(*(mid + probe * normal))):
        raise ScenarioError(f"{what}: the door segment {pts.tolist()} has walkable area on both sides")
    return shapely.Polygon([pts[0], pts[1], pts[1] + depth_m * normal, pts[0] + depth_m * normal])


def door_widths_m(geometry) -> np.ndarray:
    """(E,) the width of each exit's door: the length of the exit polygon's edge on the walkable area's
    boundary, or, for an exit inside the walkable area, the shorter side of its minimum rectangle."""
    area = geometry.walkable_area
    out = []
    for poly in geometry.exits:
        opening = poly.intersection(area.boundary).length
        if opening <= 1e-9:
            x, y = np.asarray(poly.minimum_rotated_rectangle.exterior.coords).T
            sides = np.hypot(np.diff(x), np.diff(y))
            opening = float(sides[sides > 1e-9].min())
        out.append(float(opening))
    return np.array(out)


def check_count(name: str, value, minimum: int = 1) -> int:
    """``value`` as an int >= ``minimum`` (a float of integral value too), or :class:`ScenarioError` naming
    ``name``."""
    return check_integer(name, value, error=ScenarioError, minimum=minimum, whole_floats=True)


@dataclass(eq=False)
class Scenario:
    """Geometry plus N initial pedestrians (all lengths in metres, angles in radians).

    ``position_m`` (N, 2) start positions; ``heading_rad`` (N,) or None for the desired direction e_d
    (Eq. 13) at the start; ``pedestrian_params``: per-pedestrian overrides of
    :class:`~crowd_env.core.params.PedestrianDefaults` (names in ``PEDESTRIAN_PARAMS``, scalars or
    (N,) arrays; desired speeds not given are drawn in :meth:`make_state`); ``links`` (L, 2)
    hand-holding pairs with ``link_offsets_m`` (L, 4) shoulder points (x_i, y_i, x_j, y_j) in body
    frames (default: the shoulder of each facing the other, Eq. 2); ``spawn_area``: where pedestrians
    start/appear (informative); ``metadata``: free-form provenance.

    Destinations: ``exit_names`` names the geometry's exits in order (default ``exit_0``, ``exit_1``,
    ...). ``destination`` None: everybody walks to the nearest exit and leaves through any (the
    paper's setting). Otherwise (N,) exit indices or names (-1 = nearest/any exit): pedestrian i
    follows the eikonal field of its own exit (Eq. 11-13 with T = 0 on that exit only, see
    :class:`~crowd_env.walking.navigation.DestinationNavigation`) and leaves only through it; other exits
    are floor for it, so every exit that is somebody's "other" exit must be closed by walls (lie
    inside the walkable area without removing any wall), or pedestrians could walk out through it.
    ``navigation_clearance_m``: the eikonal field is solved on the walkable area minus this band
    along the walls (0: the paper's point field; the radius: the disk centres' configuration space;
    see :class:`~crowd_env.walking.navigation.NavigationField`). ``navigation_field``: a prebuilt
    navigation to use instead of solving Eq. 11-13 on the geometry (:meth:`moved` sets it).
    ``route_choice``: None, or ``"quickest"``: with ``destination`` None and two or more exits, each
    pedestrian heads for the exit it expects to leave by soonest, re-chosen as the crowd moves
    (:class:`~crowd_env.walking.route_choice.QuickestExitNavigation`; RiMEA test 11), and leaves through
    any exit. Validated on construction.
    """

    geometry: Geometry
    position_m: np.ndarray
    heading_rad: np.ndarray | None = None
    pedestrian_params: dict = field(default_factory=dict)
    links: np.ndarray | None = None
    link_offsets_m: np.ndarray | None = None
    spawn_area: object = None
    name: str = "custom"
    metadata: dict = field(default_factory=dict)
    seed: int | None = None
    navigation_resolution_m: float = 0.05
    wall_slowdown: tuple | None = None
    navigation_clearance_m: float = 0.0
    destination: object = None
    exit_names: tuple | None = None
    navigation_field: object = field(default=None, repr=False, compare=False)
    route_choice: str | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.geometry, Geometry):
            raise ScenarioError(f"geometry must be a crowd_env.core.geometry.Geometry, got {type(self.geometry).__name__}")
        pos = np.array(self.position_m, dtype=np.float64)
        if pos.size == 0:
            pos = pos.reshape(0, 2)
        if pos.ndim != 2 or pos.shape[1] != 2:
            raise ScenarioError(f"position_m must have shape (N, 2), got {pos.shape}")
        bad = np.flatnonzero(~np.isfinite(pos).all(axis=1))
        if bad.size:
            raise ScenarioError(f"pedestrian {int(bad[0])} has a non-finite start position {pos[bad[0]].tolist()}")
        self.position_m = pos
        n = pos.shape[0]
        unknown = sorted(set(self.pedestrian_params) - set(PEDESTRIAN_PARAMS))
        if unknown:
            raise ScenarioError(f"unknown pedestrian parameter(s) {unknown}; known: {list(PEDESTRIAN_PARAMS)}")
        self.pedestrian_params = dict(self.pedestrian_params)
        if self.spawn_area is not None:
            self.spawn_area = as_polygon(self.spawn_area, "spawn area")
        self.metadata = dict(self.metadata)
        if self.links is not None or self.link_offsets_m is not None:
            links = np.zeros((0, 2), np.int64) if self.links is None else np.asarray(self.links)
            if links.size == 0:
                links = links.reshape(0, 2)
            if links.ndim != 2 or links.shape[1] != 2 or not np.issubdtype(links.dtype, np.integer):
                raise ScenarioError(f"links must be an (L, 2) integer array of pedestrian indices, got {links.shape} "
                                    f"{links.dtype}")
            if links.size and (links.min() < 0 or links.max() >= n):
                raise ScenarioError(f"links refer to pedestrians outside [0, {n})")
            if np.any(links[:, 0] == links[:, 1]):
                k = int(np.flatnonzero(links[:, 0] == links[:, 1])[0])
                raise ScenarioError(f"link {k} joins pedestrian {int(links[k, 0])} to itself")
            self.links = links.astype(np.int64)
        self.navigation_clearance_m = check_number("navigation_clearance_m", self.navigation_clearance_m,
                                                   error=ScenarioError, minimum=0.0)
        self.exit_names = self._check_exit_names(self.exit_names)
        self.destination = self._check_destination(self.destination, n)
        if self.route_choice is not None:
            if self.route_choice not in ROUTE_CHOICES:
                raise ScenarioError(f"route_choice must be None or one of {ROUTE_CHOICES}, got {self.route_choice!r}")
            if self.destination is not None or len(self.geometry.exits) < 2:
                raise ScenarioError("route_choice needs two or more exits and no fixed destinations (destination=None)")
        self._navigation = None
        self.validate()

    def _check_exit_names(self, names) -> tuple:
        n_exits = len(self.geometry.exits)
        if names is None:
            return tuple(f"exit_{k}" for k in range(n_exits))
        names = tuple(names) if not isinstance(names, str) else (names,)
        if len(names) != n_exits or not all(isinstance(x, str) and x for x in names):
            raise ScenarioError(f"exit_names must be {n_exits} non-empty strings (one per exit of geometry "
                                f"{self.geometry.name!r}), got {names!r}")
        if len(set(names)) != n_exits:
            raise ScenarioError(f"exit_names must be distinct, got {names!r}")
        return names

    def exit_number(self, exit) -> int:
        """Index into ``geometry.exits`` of an exit given by name or index (-1 stays -1: any exit)."""
        n_exits = len(self.geometry.exits)
        if isinstance(exit, str):
            if exit not in self.exit_names:
                raise ScenarioError(f"unknown exit {exit!r}; exits are {list(self.exit_names)}")
            return self.exit_names.index(exit)
        if is_integer(exit) and -1 <= exit < n_exits:
            return int(exit)
        raise ScenarioError(f"an exit is a name in {list(self.exit_names)} or an index in [-1, {n_exits}) "
                            f"(-1: any exit), got {exit!r}")

    def _check_destination(self, destination, n: int):
        """None or a read-only (N,) int64 array of exit indices (names translated); exits that are somebody's
        "other" exit must be closed (see the class docstring)."""
        if destination is None:
            return None
        items = np.asarray(destination, dtype=object)
        if items.ndim == 0:
            items = np.full(n, items.item(), dtype=object)
        if items.shape != (n,):
            raise ScenarioError(f"destination must have one entry per pedestrian ({n},), got shape {items.shape}")
        dest = np.array([self.exit_number(x) for x in items.tolist()], dtype=np.int64).reshape(n)
        chosen = np.unique(dest[dest >= 0])
        area = self.geometry.walkable_area
        for k, poly in enumerate(self.geometry.exits):
            others_bound = chosen[chosen != k]
            if not others_bound.size:
                continue
            opening = poly.intersection(area.boundary).length
            outside = poly.difference(area).area
            if opening > 1e-9 or outside > 1e-9:
                raise ScenarioError(
                    f"exit {k} ({self.exit_names[k]!r}) is open to the outside ({opening:.3g} m of wall removed, "
                    f"{outside:.3g} m² outside the walkable area), but pedestrians bound for exit(s) "
                    f"{[self.exit_names[d] for d in others_bound]} may walk into it: with per-pedestrian "
                    "destinations every exit that is not everybody's destination must lie inside the walkable "
                    "area, closed by walls")
        dest.setflags(write=False)
        return dest

    # -- derived quantities -------------------------------------------------------------------------
    @property
    def n_pedestrians(self) -> int:
        return self.position_m.shape[0]

    def radius_m(self) -> np.ndarray:
        """(N,) radii: ``pedestrian_params['radius_m']`` or the Table 2 default."""
        r = np.asarray(self.pedestrian_params.get("radius_m", PedestrianDefaults().radius_m), dtype=np.float64)
        r = np.broadcast_to(r, (self.n_pedestrians,)) if r.ndim == 0 else r
        if r.shape != (self.n_pedestrians,):
            raise ScenarioError(f"radius_m must be a scalar or have shape ({self.n_pedestrians},), got {r.shape}")
        bad = np.flatnonzero(~(r > 0) | ~np.isfinite(r))
        if bad.size:
            raise ScenarioError(f"pedestrian {int(bad[0])} has radius_m {r[bad[0]]!r}; it must be > 0")
        return np.array(r)

    def navigation(self):
        """The eikonal field (Eq. 11-13): a :class:`NavigationField` to the nearest exit without destinations,
        else a :class:`DestinationNavigation` (one field per destination). Fields are cached per geometry.
        ``navigation_field``, when given, is returned as it is."""
        if self.navigation_field is not None:
            return self.navigation_field
        if self.route_choice == "quickest":
            if self._navigation is None:
                fields = {k: self._field((k,)) for k in range(len(self.geometry.exits))}
                self._navigation = QuickestExitNavigation(fields, door_widths_m(self.geometry), self.position_m)
            return self._navigation
        if self.destination is None:
            return self._field(None)
        if self._navigation is None:
            fields = {int(d): self._field(None if d < 0 else (int(d),)) for d in np.unique(self.destination)}
            self._navigation = DestinationNavigation(fields, self.destination)
        return self._navigation

    def _field(self, exits) -> NavigationField:
        return NavigationField.cached(self.geometry, self.navigation_resolution_m, self.wall_slowdown,
                                      clearance_m=self.navigation_clearance_m, exits=exits)

    def moved(self, rotation_rad: float, translation_m=(0.0, 0.0)) -> "Scenario":
        """This scenario carried by the rigid motion p ↦ R(φ) p + t (φ = ``rotation_rad``, about the origin):
        geometry, measurement lines and areas, start positions, headings (+ φ) and spawn area move; body-frame
        quantities (link shoulders), pedestrian parameters and destinations stay. Its navigation is this
        one's field moved along (:class:`~crowd_env.walking.navigation.RigidlyMovedNavigation`), not solved
        anew, so the two are the same task to rounding: e.g. a corridor running north from one running east."""
        if self.geometry.period_x_m:
            raise ScenarioError(f"scenario {self.name!r} is periodic along x (period_x_m = {self.geometry.period_x_m:g} m) "
                                "and cannot be moved: its periodicity is tied to the x axis")
        phi = float(rotation_rad)
        t = np.asarray(translation_m, dtype=np.float64).reshape(-1)
        if not math.isfinite(phi) or t.shape != (2,) or not np.isfinite(t).all():
            raise ScenarioError(f"moved() needs a finite rotation_rad and a finite (2,) translation_m, got {rotation_rad!r} "
                                f"and {translation_m!r}")

        def move(geom):
            turned = shapely.affinity.rotate(geom, phi, origin=(0.0, 0.0), use_radians=True)
            return shapely.affinity.translate(turned, float(t[0]), float(t[1]))

        c, s_ = math.cos(phi), math.sin(phi)

        def move_points(p):
            p = np.asarray(p, dtype=np.float64).reshape(-1, 2)
            return np.stack((c * p[:, 0] - s_ * p[:, 1] + t[0], s_ * p[:, 0] + c * p[:, 1] + t[1]), axis=1)

        g = self.geometry
        geometry = Geometry(move(g.walkable_area), [move(e) for e in g.exits],
                            measurement_lines={k: move_points(v) for k, v in g.measurement_lines.items()},
                            measurement_areas={k: move(v) for k, v in g.measurement_areas.items()}, name=g.name)
        return replace(self, geometry=geometry, position_m=move_points(self.position_m),
                       heading_rad=np.asarray(self.heading_rad, dtype=np.float64) + phi,
                       spawn_area=None if self.spawn_area is None else move(self.spawn_area),
                       destination=None if self.destination is None else np.array(self.destination),
                       navigation_field=RigidlyMovedNavigation(self.navigation(), phi, t))

    def make_simulator(self, state: CrowdState | None = None, params: ModelParams | None = None,
                       rng: np.random.Generator | None = None) -> Simulator:
        """A :class:`Simulator` on this geometry starting from ``state`` (default: :meth:`make_state` with
        ``rng``), with this scenario's destinations."""
        state = self.make_state(rng=rng) if state is None else state
        return Simulator(state, geometry=self.geometry, params=params, destination=self.destination)

    # -- validation ---------------------------------------------------------------------------------
    def validate(self) -> None:
        """Raise naming the pedestrian when a start is outside the walkable area, crosses a wall, lies in
        an exit, overlaps another one, or cannot reach any exit."""
        pos = self.position_m
        n = pos.shape[0]
        r = self.radius_m()
        if n:
            inside = self.geometry.contains(pos)
            if not inside.all():
                i = int(np.flatnonzero(~inside)[0])
                raise ScenarioError(f"pedestrian {i} starts at {pos[i].tolist()}, outside the walkable area "
                                    f"of geometry {self.geometry.name!r}")
            in_exit = self.geometry.in_exit(pos)
            if in_exit.any():
                i = int(np.flatnonzero(in_exit)[0])
                raise ScenarioError(f"pedestrian {i} starts at {pos[i].tolist()}, inside an exit (it would leave at once)")
            if self.geometry.walls.shape[0]:
                gap = self.geometry.distance_to_walls(pos) - r
                if np.any(gap < -1e-9):
                    i = int(np.argmin(gap))
                    raise ScenarioError(f"pedestrian {i} at {pos[i].tolist()} overlaps a wall by {-gap[i]:.4g} m "
                                        f"(radius {r[i]:.4g} m)")
            pair = first_overlap(pos, r, 1e-9, self.geometry.period_x_m)  # across the seam of a periodic one too
            if pair is not None:
                i, j, overlap = pair
                raise ScenarioError(f"pedestrians {i} and {j} overlap by {overlap:.4g} m at start "
                                    f"(positions {pos[i].tolist()} and {pos[j].tolist()})")
            nav = self.navigation()
            if nav.per_pedestrian:
                nav.check_reachable(pos, np.arange(n), what="pedestrian")
            else:
                nav.check_reachable(pos, what="pedestrian")
        if self.heading_rad is None:
            self.heading_rad = self._initial_headings()
        heading = np.array(self.heading_rad, dtype=np.float64)
        heading = np.full(n, float(heading)) if heading.ndim == 0 else heading
        if heading.shape != (n,) or not np.all(np.isfinite(heading)):
            raise ScenarioError(f"heading_rad must be finite with shape ({n},), got shape {heading.shape}")
        self.heading_rad = heading
        if self.links is not None and self.link_offsets_m is None:
            self.link_offsets_m = self._facing_shoulders(r)
        if self.links is not None:
            off = np.asarray(self.link_offsets_m, dtype=np.float64)
            if off.shape != (self.links.shape[0], 4) or not np.all(np.isfinite(off)):
                raise ScenarioError(f"link_offsets_m must be finite with shape ({self.links.shape[0]}, 4), got {off.shape}")
            self.link_offsets_m = off

    def _initial_headings(self) -> np.ndarray:
        if self.n_pedestrians == 0:
            return np.zeros(0)
        nav = self.navigation()
        if nav.per_pedestrian:
            direction, _ = nav.sample(self.position_m, np.arange(self.n_pedestrians))
        else:
            direction, _ = nav.sample(self.position_m)
        return np.arctan2(direction[:, 1], direction[:, 0])

    def _facing_shoulders(self, r: np.ndarray) -> np.ndarray:
        """Default shoulder points: for each link, the lateral shoulder of each pedestrian facing the other."""
        i, j = self.links[:, 0], self.links[:, 1]
        off = np.zeros((self.links.shape[0], 4))
        for col, a, b in ((1, i, j), (3, j, i)):
            h = self.heading_rad[a]
            d = self.position_m[b] - self.position_m[a]
            side = np.sign(np.cos(h) * d[:, 1] - np.sin(h) * d[:, 0])  # + : the other is on the left
            off[:, col] = np.where(side == 0, 1.0, side) * r[a]
        return off

    def make_state(self, rng: np.random.Generator | None = None,
                   defaults: PedestrianDefaults = PedestrianDefaults()) -> CrowdState:
        """The initial :class:`CrowdState`; desired speeds not set are drawn from ``rng`` (default: ``seed``)."""
        if rng is None:
            rng = np.random.default_rng(self.seed)
        return CrowdState.create(self.position_m, heading_rad=self.heading_rad, links=self.links,
                                 link_offsets_m=self.link_offsets_m, rng=rng, defaults=defaults,
                                 **self.pedestrian_params)


# -- placement ---------------------------------------------------------------------------------------
def _lattice(inner, nx: int, ny: int, hexagonal: bool):
    """Sites of an nx x ny lattice stretched over ``inner``'s bounding box (hex: odd rows shifted by sx/2)."""
    x0, y0, x1, y1 = inner.bounds
    w, h = x1 - x0, y1 - y0
    sx = w / (nx - 1) if nx > 1 else math.inf
    sy = h / (ny - 1) if ny > 1 else math.inf
    xs = x0 + np.arange(nx) * sx if nx > 1 else np.array([0.5 * (x0 + x1)])
    ys = y0 + np.arange(ny) * sy if ny > 1 else np.array([0.5 * (y0 + y1)])
    if hexagonal and nx > 1:
        pts = [np.column_stack([xs if r % 2 == 0 else xs[:-1] + 0.5 * sx, np.full(nx - (r % 2), y)])
               for r, y in enumerate(ys)]
        pts = np.vstack(pts)
        spacing = min(sx, math.hypot(0.5 * sx, sy))
    else:
        xx, yy = np.meshgrid(xs, ys, indexing="ij")
        pts = np.column_stack([xx.ravel(), yy.ravel()])
        spacing = min(sx, sy)
    keep = shapely.intersects_xy(inner, pts[:, 0], pts[:, 1])
    return pts[keep], spacing


def _best_lattice(inner, n: int, spacing_min: float):
    """The lattice with at least n sites in ``inner`` whose closest pair is farthest apart, or the capacity."""
    x0, y0, x1, y1 = inner.bounds
    w, h = x1 - x0, y1 - y0
    max_rows = int(h / (spacing_min * math.sqrt(3) / 2) + 1e-9) + 1
    max_cols = int(w / spacing_min + 1e-9) + 1
    best, best_spacing, capacity = None, -1.0, 0
    for ny in range(1, max_rows + 1):
        for hexagonal in (False, True):
            nx = max(1, min(math.ceil(n / ny), max_cols))  # from the widest admissible row when n is too many
            while nx <= max_cols + 1:
                pts, spacing = _lattice(inner, nx, ny, hexagonal)
                if spacing < spacing_min - 1e-12:
                    break
                capacity = max(capacity, pts.shape[0])
                if pts.shape[0] >= n:
                    if spacing > best_spacing:
                        best, best_spacing = pts, spacing
                    break
                nx += 1
    return best, best_spacing, capacity


def place_pedestrians(region, n: int | None = None, radius_m: float = 0.23, rng: np.random.Generator | None = None, *,
                      density_per_m2: float | None = None, min_gap_m: float = 0.0, margin_m: float | None = None,
                      toward=None, relax_sweeps: int = 40) -> np.ndarray:
    """Centres (n, 2) of n non-overlapping disks of radius ``radius_m`` inside ``region``, seeded by ``rng``.

    Give ``n``, ``density_per_m2`` (then n = round(density x region area)) or both: then the lattice has
    round(density x area) sites and n <= that of them are occupied (random ones, or the nearest to
    ``toward``), i.e. n pedestrians at that local density. Disks stay ``margin_m`` (default: their
    radius, i.e. entirely) inside the region and at least ``min_gap_m`` apart. Method: the lattice
    (rectangular or hexagonal, stretched over the region) with enough sites whose closest pair is
    farthest apart; then ``relax_sweeps`` sweeps of hard-disk Monte Carlo moves to disorder it. This
    succeeds at densities above the random-sequential-addition jamming limit (3.3 /m² of r = 0.23 m
    disks is packing fraction 0.55 > 0.547). Raises :class:`ScenarioError` naming the
    numbers when n disks do not fit.
    """
    poly = as_polygon(region, "placement region")
    rng = np.random.default_rng() if rng is None else rng
    for name, value in (("radius_m", radius_m),):
        if not (np.isfinite(value) and value > 0):
            raise ScenarioError(f"{name} must be > 0, got {value!r}")
    if not (np.isfinite(min_gap_m) and min_gap_m >= 0):
        raise ScenarioError(f"min_gap_m must be >= 0, got {min_gap_m!r}")
    if density_per_m2 is not None:
        if not (np.isfinite(density_per_m2) and density_per_m2 > 0):
            raise ScenarioError(f"density_per_m2 must be > 0, got {density_per_m2!r}")
        n_sites = int(round(density_per_m2 * poly.area))
        if n is None:
            n = n_sites
        elif n > density_per_m2 * poly.area + 0.5:
            raise ScenarioError(f"{n} pedestrians in a region of {poly.area:.4g} m² exceed the requested density "
                                f"{density_per_m2:.4g} /m² (at most {n_sites} pedestrians)")
    if n is None:
        raise ScenarioError("give the number of pedestrians n or density_per_m2")
    n = check_count("the number of pedestrians n", n, minimum=0)
    n_sites = n if density_per_m2 is None else max(n, n_sites)
    if n == 0:
        return np.zeros((0, 2))
    margin = radius_m if margin_m is None else float(margin_m)
    inner = poly.buffer(-margin, join_style="mitre") if margin > 0 else poly
    if inner.is_empty:
        raise ScenarioError(f"more pedestrians than fit in the holding area: {n} requested, but the region "
                            f"({poly.area:.4g} m²) is too small for even one disk of radius {radius_m} m")
    shapely.prepare(inner)
    spacing_min = 2.0 * radius_m + min_gap_m
    sites, spacing, capacity = _best_lattice(inner, n_sites, spacing_min)
    if sites is None:
        raise ScenarioError(f"more pedestrians than fit in the holding area: {n_sites} requested at "
                            f"{n_sites / poly.area:.4g} /m² in {poly.area:.4g} m², but at most {capacity} disks of radius "
                            f"{radius_m} m fit there (min gap {min_gap_m} m)")
    if toward is None:
        chosen = rng.choice(sites.shape[0], size=n, replace=False)
    else:
        target = np.asarray(toward, dtype=np.float64).reshape(2)
        d = np.linalg.norm(sites - target, axis=1)
        chosen = np.lexsort((rng.random(sites.shape[0]), np.round(d, 9)))[:n]
    pos = np.array(sites[chosen], dtype=np.float64)
    step = max(spacing - spacing_min, 0.05 * spacing_min)
    if not math.isfinite(step):  # a single site (spacing inf): moves up to the size of the region
        x0, y0, x1, y1 = inner.bounds
        step = max(x1 - x0, y1 - y0, 0.05 * spacing_min)
    pos = _relax_hard_disks(pos, inner, spacing_min, step, rng, int(relax_sweeps))
    return pos


def form_groups(position_m, sizes, radius_m: float, region, rng: np.random.Generator, *, walking_direction=(1.0, 0.0),
                gap_m: float = 0.05, min_gap_m: float = 0.0, max_turn_deg: float = 20.0):
    """Turn some of the placed pedestrians ``position_m`` (N, 2) into hand-holding groups standing side by side.

    ``sizes``: one entry per group (2 = pair, 3 = triple, ...), formed largest first. A group is a row
    of disks with centres ``2 radius_m + gap_m`` apart across the walking direction
    (``walking_direction``: a (2,) vector, or ``f(points (n, 2)) -> (n, 2)`` unit vectors such as an
    eikonal field's e_d), turned by at most ``max_turn_deg``. For each group a random unassigned
    pedestrian keeps its place as one member of the row and the unassigned pedestrians nearest to the
    other places of the row move there; the row is accepted only if every disk lies inside ``region``
    and at least ``min_gap_m`` from every other pedestrian, else other rows and pedestrians are tried.
    Returns the new positions (a copy), the groups (index arrays, in row order) and the hand links
    (L, 2): neighbours in each row (a triple's middle member holds both others, Eq. 2). Raises
    :class:`ScenarioError` when a group finds no room.
    """
    pos = np.array(position_m, dtype=np.float64)
    n = pos.shape[0]
    check_positive(radius_m=radius_m)
    if not (np.isfinite(gap_m) and gap_m >= 0) or not (np.isfinite(min_gap_m) and min_gap_m >= 0):
        raise ScenarioError(f"gap_m and min_gap_m must be finite and >= 0, got {gap_m!r}, {min_gap_m!r}")
    sizes = [check_count("group size", s, 2) for s in sizes]
    if sum(sizes) > n:
        raise ScenarioError(f"groups of sizes {sizes} need {sum(sizes)} pedestrians, but only {n} are placed")
    inner = as_polygon(region, "group region").buffer(-radius_m, join_style="mitre")
    shapely.prepare(inner)
    if callable(walking_direction):
        forward = np.asarray(walking_direction(pos), dtype=np.float64).reshape(n, 2)
    else:
        fixed = np.asarray(walking_direction, dtype=np.float64).reshape(2)
        if not np.all(np.isfinite(fixed)) or np.hypot(*fixed) <= 0:
            raise ScenarioError(f"walking_direction must be a non-zero (2,) vector or a callable, got {walking_direction!r}")
        forward = np.broadcast_to(fixed / np.hypot(*fixed), (n, 2))
    turns = np.deg2rad(float(max_turn_deg)) * np.array([0.0, 0.5, -0.5, 1.0, -1.0])
    spacing = 2.0 * radius_m + gap_m
    clearance = 2.0 * radius_m + min_gap_m - 1e-12
    free = np.ones(n, dtype=bool)
    groups, links = [], []
    for k, size in sorted(enumerate(sizes), key=lambda t: -t[1]):
        members = _fit_row(pos, free, size, spacing, clearance, inner, forward, turns, rng)
        if members is None:
            raise ScenarioError(f"no room to form group {k} of {size} side by side (gap {gap_m} m) among the "
                                f"{int(free.sum())} pedestrians not yet grouped; lower the density or the number "
                                "of groups")
        members, slots = members
        pos[members] = slots
        free[members] = False
        groups.append(members)
        links.extend(zip(members[:-1].tolist(), members[1:].tolist()))
    return pos, groups, np.array(links, dtype=np.int64).reshape(-1, 2)


def _fit_row(pos, free, size, spacing, clearance, inner, forward, turns, rng):
    """(members in row order, their new positions) of the first row that fits, or None (see form_groups)."""
    offsets = np.arange(size) * spacing
    for anchor in rng.permutation(np.flatnonzero(free)):
        cand = np.flatnonzero(free)
        cand = cand[cand != anchor]
        f = forward[anchor]
        for turn in turns:
            c, s_ = np.cos(turn), np.sin(turn)
            lateral = np.array([-(s_ * f[0] + c * f[1]), c * f[0] - s_ * f[1]])  # f turned by 90° + turn
            for j in range(size):  # the anchor's place in the row
                slots = pos[anchor] + np.outer(offsets - offsets[j], lateral)
                if not shapely.contains_xy(inner, slots[:, 0], slots[:, 1]).all():
                    continue
                members = np.empty(size, np.int64)
                members[j] = anchor
                left = cand
                for q in (q for q in range(size) if q != j):
                    nearest = int(np.argmin(np.linalg.norm(pos[left] - slots[q], axis=1)))
                    members[q] = left[nearest]
                    left = np.delete(left, nearest)
                others = np.ones(pos.shape[0], dtype=bool)
                others[members] = False
                d = np.linalg.norm(pos[others][:, None, :] - slots[None, :, :], axis=2)
                if d.size == 0 or d.min() >= clearance:
                    return members, slots
    return None


def _relax_hard_disks(pos, inner, spacing_min, step, rng, sweeps):
    """Hard-disk Monte Carlo: simultaneous random moves, each accepted if it stays inside ``inner`` and
    keeps at least ``spacing_min`` to every other disk's old and new position (so any accepted set is
    valid). The step adapts towards ~40 % acceptance, capped at twice its start so that a partly
    filled lattice does not spread out."""
    n = pos.shape[0]
    max_step = 2.0 * step
    for _ in range(sweeps):
        prop = pos + rng.uniform(-step, step, size=(n, 2))
        ok = shapely.intersects_xy(inner, prop[:, 0], prop[:, 1])
        if n > 1:
            conflict = np.zeros(n, dtype=bool)
            tree_new = cKDTree(prop)
            pairs = tree_new.query_pairs(spacing_min, output_type="ndarray")
            if pairs.size:
                close = np.linalg.norm(prop[pairs[:, 0]] - prop[pairs[:, 1]], axis=1) < spacing_min
                conflict[pairs[close].ravel()] = True
            sdm = tree_new.sparse_distance_matrix(cKDTree(pos), spacing_min, output_type="ndarray")
            bad = (sdm["i"] != sdm["j"]) & (sdm["v"] < spacing_min)
            conflict[sdm["i"][bad]] = True
            ok &= ~conflict
        pos[ok] = prop[ok]
        rate = ok.mean()
        step *= 1.25 if rate > 0.5 else (0.75 if rate < 0.3 else 1.0)
        step = min(step, max_step)
    return pos


# -- registry ----------------------------------------------------------------------------------------
_REGISTRY: dict[str, Callable[..., Scenario]] = {}


def register_scenario(name: str, factory: Callable[..., Scenario], *, aliases=(), overwrite: bool = False) -> None:
    """Register ``factory(**options) -> Scenario`` under ``name`` (and ``aliases``)."""
    if not callable(factory):
        raise ScenarioError(f"scenario factory for {name!r} is not callable")
    for key in (name, *aliases):
        if not isinstance(key, str) or not key:
            raise ScenarioError(f"scenario names must be non-empty strings, got {key!r}")
        if key in _REGISTRY and _REGISTRY[key] is not factory and not overwrite:
            raise ScenarioError(f"a scenario named {key!r} is already registered (pass overwrite=True)")
    for key in (name, *aliases):
        _REGISTRY[key] = factory


def list_scenarios() -> list:
    """Registered scenario names (aliases included), sorted."""
    return sorted(_REGISTRY)


def scenario_options(name: str) -> dict:
    """Option name -> default value of a registered scenario."""
    factory = _lookup(name)
    return {p.name: p.default for p in inspect.signature(factory).parameters.values()
            if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}


def _lookup(name: str):
    if name not in _REGISTRY:
        raise ScenarioError(f"unknown scenario {name!r}; known: {list_scenarios()}")
    return _REGISTRY[name]


def make_scenario(name: str, **options) -> Scenario:
    """Build the registered scenario ``name``; unknown names or options raise listing the known ones, and a
    ``seed`` that is not None or an integer >= 0 raises :class:`ScenarioError` naming it."""
    factory = _lookup(name)
    params = inspect.signature(factory).parameters
    if not any(p.kind == p.VAR_KEYWORD for p in params.values()):
        unknown = sorted(set(options) - set(params))
        if unknown:
            raise ScenarioError(f"unknown option(s) {unknown} for scenario {name!r}; known: {sorted(params)}")
    if "seed" in options:
        options["seed"] = check_seed("seed", options["seed"], error=ScenarioError)
    return factory(**options)
