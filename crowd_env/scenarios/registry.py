"""The registry of scenarios by name: :func:`register_scenario` (a decorator of the factory, or a call),
:func:`make_scenario` (options checked against the factory's signature), :func:`list_scenarios`,
:func:`scenario_options`, :func:`scenario_aliases`."""
from __future__ import annotations

from crowd_env.errors import ScenarioError

import inspect
from typing import Callable

from ..core.checks import check_seed
from .scenario import Scenario

__all__ = ["register_scenario", "make_scenario", "list_scenarios", "scenario_options", "scenario_factory",
           "scenario_aliases", "body_options"]


_REGISTRY: dict[str, Callable[..., Scenario]] = {}
_ALIASES: dict[str, tuple] = {}  # name -> the aliases registered with it


def register_scenario(name: str, factory: Callable[..., Scenario] | None = None, *, aliases=(),
                      overwrite: bool = False):
    """Register ``factory(**options) -> Scenario`` under ``name`` (and ``aliases``); returns the factory. Without
    a factory, a decorator that registers the function it decorates and returns it::

        @register_scenario("stadium", aliases=("arena",))
        def stadium(n_pedestrians: int = 100, seed: int | None = 0) -> Scenario:
            ...
    """
    if factory is None:
        def register(function):
            return register_scenario(name, function, aliases=aliases, overwrite=overwrite)
        return register
    if not callable(factory):
        raise ScenarioError(f"scenario factory for {name!r} is not callable")
    for key in (name, *aliases):
        if not isinstance(key, str) or not key:
            raise ScenarioError(f"scenario names must be non-empty strings, got {key!r}")
        if key in _REGISTRY and _REGISTRY[key] is not factory and not overwrite:
            raise ScenarioError(f"a scenario named {key!r} is already registered (pass overwrite=True)")
    for key in (name, *aliases):
        _REGISTRY[key] = factory
    _ALIASES[name] = tuple(aliases)
    return factory


def scenario_aliases(name: str) -> tuple:
    """The aliases registered with the scenario ``name`` (``()`` for an alias itself or an unknown name)."""
    return _ALIASES.get(name, ())


def list_scenarios() -> list:
    """Registered scenario names (aliases included), sorted."""
    return sorted(_REGISTRY)


def scenario_options(name: str) -> dict:
    """Option name -> default value of a registered scenario."""
    factory = scenario_factory(name)
    return {p.name: p.default for p in inspect.signature(factory).parameters.values()
            if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}


def scenario_factory(name: str):
    """The factory registered under ``name``; :class:`ScenarioError` listing the known names otherwise."""
    if name not in _REGISTRY:
        raise ScenarioError(f"unknown scenario {name!r}; known: {list_scenarios()}")
    return _REGISTRY[name]


def make_scenario(name: str, **options) -> Scenario:
    """Build the registered scenario ``name``; unknown names or options raise listing the known ones, and a
    ``seed`` that is not None or an integer >= 0 raises :class:`ScenarioError` naming it."""
    factory = scenario_factory(name)
    params = inspect.signature(factory).parameters
    if not any(p.kind == p.VAR_KEYWORD for p in params.values()):
        unknown = sorted(set(options) - set(params))
        if unknown:
            raise ScenarioError(f"unknown option(s) {unknown} for scenario {name!r}; known: {sorted(params)}")
    if "seed" in options:
        options["seed"] = check_seed("seed", options["seed"], error=ScenarioError)
    return factory(**options)


def body_options(name: str, options: dict | None, radius_m: float | None) -> dict:
    """``options`` of the registered scenario ``name`` with every pedestrian's radius ``radius_m`` (a preset's body,
    :attr:`~crowd_env.walking.presets.Preset.body_radius_m`) when its factory takes ``radius_m`` and ``options`` set none;
    a copy of ``options`` otherwise (``radius_m`` None: the factory's own default)."""
    out = dict(options or {})
    if radius_m is not None and "radius_m" not in out and "radius_m" in scenario_options(name):
        out["radius_m"] = float(radius_m)
    return out
