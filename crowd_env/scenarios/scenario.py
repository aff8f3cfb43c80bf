"""Scenarios as data: a geometry, initial pedestrians and metadata.

A :class:`Scenario` is what a user writes to define an experiment: it validates itself (positions
inside the walkable area and clear of walls and exits, no overlaps, every pedestrian able to reach an
exit, its own one with per-pedestrian destinations) and builds the
:class:`~crowd_env.core.state.CrowdState` and :class:`~crowd_env.core.simulator.Simulator` it starts from.
"""
from __future__ import annotations

from crowd_env.errors import ScenarioError

import math
from dataclasses import dataclass, field, replace

import numpy as np
import shapely
import shapely.affinity

from ..core.checks import check_number, is_integer
from ..core.geometry import Geometry, as_polygon
from ..core.params import PedestrianDefaults
from ..walking.model import ModelParams
from ..core.simulator import Simulator
from ..core.state import CrowdState, first_overlap
from ..walking.navigation import DestinationNavigation, NavigationField, RigidlyMovedNavigation
from ..walking.route_choice import QuickestExitNavigation
from .doors import door_widths_m

__all__ = ["Scenario", "ScenarioError", "Measurement", "ROUTE_CHOICES", "PEDESTRIAN_PARAMS"]


ROUTE_CHOICES = ("quickest",)
# A measurement line's walkers cross it when the navigation field at its midpoint makes more than this cosine with
# the line's normal (about 6° off the line's direction); below it the field runs along the line there.
LINE_MIN_CROSSING = 0.1
LINE_SIDE_STEPS = 2  # the field is read this many grid cells before and beyond the midpoint too


def _line_middle(ends, floor) -> np.ndarray:
    """The midpoint of the longest part of the segment ``ends`` (2, 2) across ``floor`` (its middle when it is
    all on the floor)."""
    parts = [p for p in shapely.get_parts(shapely.LineString(ends).intersection(floor)) if p.length > 0.0]
    if not parts:
        return 0.5 * (ends[0] + ends[1])
    best = np.asarray(max(parts, key=lambda p: p.length).coords)
    return 0.5 * (best[0] + best[-1])


PEDESTRIAN_PARAMS = ("radius_m", "mass_kg", "inertia_kg_m2", "desired_speed_m_s", "tau_s", "heading_stiffness",
                     "heading_damping", "velocity_m_s", "angular_velocity_rad_s", "premovement_s")


@dataclass(frozen=True)
class Measurement:
    """What a run of a scenario measures unless told otherwise
    (:func:`~crowd_env.experiments.running.runner.run_scenario`, the evaluation harness): the passages of the
    measurement ``line`` (a name of the geometry's lines; None: none), the densities and speeds in the
    ``density_areas`` (names of its areas) and the lateral positions in ``lane_area`` (None: none)."""

    line: str | None = None
    density_areas: tuple = ()
    lane_area: str | None = None

    def __post_init__(self):
        object.__setattr__(self, "density_areas", (self.density_areas,) if isinstance(self.density_areas, str)
                           else tuple(self.density_areas))


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
    any exit. ``measurement``: what a run measures unless told otherwise (:class:`Measurement`); None: the
    geometry's first measurement line, no areas. Validated on construction.
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
    measurement: Measurement | None = None

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
        self.measurement = self._check_measurement(self.measurement)
        self._navigation = None
        self.validate()

    def _check_measurement(self, measurement) -> Measurement:
        """``measurement`` (None: the first line, no areas) with names the geometry has, else ScenarioError."""
        g = self.geometry
        if measurement is None:
            return Measurement(next(iter(g.measurement_lines), None))
        if not isinstance(measurement, Measurement):
            raise ScenarioError(f"measurement must be a Measurement or None, got {measurement!r}")
        if measurement.line is not None and measurement.line not in g.measurement_lines:
            raise ScenarioError(f"measurement line {measurement.line!r} is not one of the geometry's lines "
                                f"{sorted(g.measurement_lines)}")
        for area in (*measurement.density_areas, *([measurement.lane_area] if measurement.lane_area else [])):
            if area not in g.measurement_areas:
                raise ScenarioError(f"measurement area {area!r} is not one of the geometry's areas "
                                    f"{sorted(g.measurement_areas)}")
        return measurement

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

        def move_line(name):
            spec = g.measurement_line_spec(name)
            if not isinstance(spec, dict):
                return move_points(spec)
            d = spec["direction"]
            return {**spec, "ends": move_points(spec["ends"]), "direction": (c * d[0] - s_ * d[1], s_ * d[0] + c * d[1])}

        g = self.geometry
        geometry = Geometry(move(g.walkable_area), [move(e) for e in g.exits],
                            measurement_lines={k: move_line(k) for k in g.measurement_lines},
                            measurement_areas={k: move(v) for k, v in g.measurement_areas.items()}, name=g.name)
        return replace(self, geometry=geometry, position_m=move_points(self.position_m),
                       heading_rad=np.asarray(self.heading_rad, dtype=np.float64) + phi,
                       spawn_area=None if self.spawn_area is None else move(self.spawn_area),
                       destination=None if self.destination is None else np.array(self.destination),
                       navigation_field=RigidlyMovedNavigation(self.navigation(), phi, t))

    def make_simulator(self, state: CrowdState | None = None, params: ModelParams | None = None,
                       rng: np.random.Generator | None = None) -> Simulator:
        """A :class:`Simulator` on this geometry starting from ``state`` (default: :meth:`make_state` with
        ``rng``), with this scenario's destinations, under ``params`` (default ``ModelParams()``, the paper's
        literal model)."""
        state = self.make_state(rng=rng) if state is None else state
        return Simulator(state, geometry=self.geometry, params=ModelParams() if params is None else params,
                         destination=self.destination)

    # -- measurement lines --------------------------------------------------------------------------
    def line_direction(self, name: str) -> np.ndarray:
        """The unit normal (2,) of measurement line ``name`` on the side it counts passages towards: the side of
        the direction the geometry gives it (:attr:`~crowd_env.core.geometry.Geometry.measurement_line_directions`),
        else the side the navigation field leads the walkers to at the line's midpoint (the middle of its
        longest part across the floor): towards their destination. Without walkers to tell (per-pedestrian
        destinations and nobody), the side it was drawn with (its clockwise normal). Checked for every line
        when the scenario is made (:meth:`validate`)."""
        if name not in self.geometry.measurement_lines:
            raise ScenarioError(f"scenario {self.name!r} has no measurement line {name!r}; it has "
                                f"{sorted(self.geometry.measurement_lines)}")
        known = self.__dict__.setdefault("_line_normals", {})
        if name not in known:
            known[name] = self._line_normal(name)
        return known[name].copy()

    def _line_normal(self, name: str) -> np.ndarray:
        """:meth:`line_direction`, resolved; :class:`ScenarioError` for a line given a direction against all its
        walkers (unless the geometry says so), and for a line without one that the field crosses both ways or
        runs along."""
        g = self.geometry
        ends = g.measurement_lines[name]
        t = ends[1] - ends[0]
        normal = np.array([t[1], -t[0]]) / float(np.hypot(t[0], t[1]))  # the clockwise normal
        middle = _line_middle(ends, g.navigable_area)
        walkers = self._walkers_across(middle, normal)  # the side each walker crosses to, or None: no walkers
        ahead = walkers is not None and bool((walkers > 0).any())
        behind = walkers is not None and bool((walkers < 0).any())
        given = g.measurement_line_directions.get(name)
        where = f"measurement line {name!r} of scenario {self.name!r} (midpoint {np.round(middle, 3).tolist()})"
        if given is not None:
            side = 1.0 if float(given @ normal) > 0.0 else -1.0
            if (behind if side > 0 else ahead) and not (ahead if side > 0 else behind) \
                    and name not in g.lines_against_walkers:
                raise ScenarioError(f"{where} counts towards {np.round(side * normal, 3).tolist()}, against its "
                                    "walkers, whom the navigation field leads the other way there: give the direction "
                                    "towards their destination, or against_walkers=True if that is meant")
            return side * normal
        if walkers is None:
            return normal
        if ahead and behind:
            raise ScenarioError(f"{where} is crossed both ways (walkers to different destinations): give it a "
                                "direction, measurement_lines={name: {'ends': ..., 'direction': (x, y)}}")
        if not (ahead or behind):
            raise ScenarioError(f"{where}: the navigation field runs along it there (or does not reach it), so the "
                                "side its walkers cross to is unknown: give it a direction")
        return normal if ahead else -normal

    def _walkers_across(self, point, normal):
        """The side each walker's field crosses the line at ``point`` to: +1 along ``normal``, −1 against it, 0 where
        it cannot tell (the field runs along the line, does not reach it, or turns there: a watershed nobody
        crosses). The field e_d is read at ``point`` and a step of :data:`LINE_SIDE_STEPS` grid cells before and
        beyond it, and the three must agree. One value for all without destinations; None without walkers to
        tell (per-pedestrian destinations and nobody)."""
        nav = self.navigation()
        step = LINE_SIDE_STEPS * float(self.navigation_resolution_m) * normal
        points = np.array([point - step, point, point + step])
        if not nav.per_pedestrian:
            e, _ = nav.sample(points)
            across = (e @ normal)[None]
        elif self.n_pedestrians:
            n = self.n_pedestrians
            e, _ = nav.sample(np.tile(points, (n, 1)), np.repeat(np.arange(n), 3))
            across = (e @ normal).reshape(n, 3)
        else:
            return None
        ahead = (across >= LINE_MIN_CROSSING).all(axis=1)
        behind = (across <= -LINE_MIN_CROSSING).all(axis=1)
        return ahead.astype(np.int64) - behind.astype(np.int64)

    # -- validation ---------------------------------------------------------------------------------
    def validate(self) -> None:
        """Raise naming the pedestrian when a start is outside the walkable area, crosses a wall, lies in
        an exit, overlaps another one, or cannot reach any exit; and naming the line when a measurement line
        counts against its walkers or cannot tell their side (:meth:`line_direction`)."""
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
            self._line_normals = {k: self._line_normal(k) for k in self.geometry.measurement_lines}
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
