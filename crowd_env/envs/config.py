"""The configuration of ``crowd_v0``: every option of the environment in one checked, frozen dataclass.

:class:`CrowdEnvConfig` holds the keywords of :class:`~crowd_env.envs.crowd_v0.CrowdParallelEnv` (and of
``parallel_env``, the vector environment and the Gymnasium ids), checks each when made and raises
:class:`~crowd_env.errors.EnvOptionError` naming the option; what only the scenario can tell (how many
pedestrians ``controlled`` may pick, the scenario's own options) is checked when the environment is built.
:func:`make_config` turns keyword options (PettingZoo's ``max_cycles`` too) into one, refusing unknown names
with :class:`~crowd_env.errors.UnknownOptionError`.
"""
from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass

import numpy as np

from crowd_env.errors import EnvOptionError, UnknownOptionError

from ..core.checks import check_integer, check_number
from ..core.params import ParameterError
from ..walking.model import ModelParams
from ..walking.presets import DEFAULT_PRESET, get_preset
from ..core.step import MAX_INPUT_SPEED_M_S
from ..core.timestep import check_time_step_floor
from ..scenarios import Scenario
from ..scenarios import scenario_options as _scenario_option_defaults
from .background import OBSERVATION_POLICY_OPTIONS, is_observation_policy
from .observations import check_frame, resolve_components
from .rewards import resolve_terms

__all__ = ["CrowdEnvConfig", "make_config", "ENV_DEFAULTS", "ENV_OPTIONS", "OPTION_ALIASES", "RENDER_MODES",
           "DEFAULT_ACTION_MAX_M_S", "resolve_options", "unknown_options_message", "observation_policy_options",
           "select_controlled", "agent_id"]

DEFAULT_ACTION_MAX_M_S = 2.5
RENDER_MODES = ("human", "rgb_array")


def agent_id(index: int) -> str:
    """The agent id of pedestrian ``index``: ``"ped_<index>"``."""
    return f"ped_{int(index)}"


def _positive_number(name, value):
    return check_number(name, value, error=EnvOptionError, positive=True)


def _count(name, value, minimum=0):
    return check_integer(name, value, error=EnvOptionError, minimum=minimum)


def _action_max(name, value) -> float:
    """a_max, positive and small enough that an action's norm (up to a_max √2) stays within the core's bound on
    intents (:data:`~crowd_env.core.step.MAX_INPUT_SPEED_M_S`)."""
    a = _positive_number(name, value)
    if a * math.sqrt(2.0) > MAX_INPUT_SPEED_M_S:
        raise EnvOptionError(f"{name} must be at most {MAX_INPUT_SPEED_M_S / math.sqrt(2.0):.6g} m/s (an action's norm, "
                             f"up to {name} x sqrt(2), must stay within the core's bound on intents "
                             f"crowd_env.core.step.MAX_INPUT_SPEED_M_S = {MAX_INPUT_SPEED_M_S:g} m/s), got {value!r}")
    return a


def _check_heading_target(name, value) -> str:
    if value not in ("intent", "desired_direction"):
        raise EnvOptionError(f"{name} must be 'intent' or 'desired_direction', got {value!r}")
    return value


def _check_components(name, value):
    if value is None:
        return None
    resolve_components(value)  # raises naming the option
    return tuple(value) if isinstance(value, (list, tuple)) else value


_OPTION_CHECKS = {  # the options an observation policy depends on (OBSERVATION_POLICY_OPTIONS), checked
    "frame_skip": lambda n, v: _count(n, v, minimum=1),
    "action_max_m_s": _action_max,
    "n_neighbors": _count,
    "n_rays": _count,
    "neighbor_radius_m": _positive_number,
    "ray_range_m": _positive_number,
    "heading_target": _check_heading_target,
    "observation_frame": lambda n, v: check_frame(v),
    "observation_components": _check_components,
}


def observation_policy_options(values: dict, what: str = "") -> dict:
    """``values`` of the :data:`~crowd_env.envs.background.OBSERVATION_POLICY_OPTIONS`, checked and converted
    as the environment's own options are; ``what`` starts the message of an :class:`EnvOptionError` (e.g.
    whose options they are)."""
    try:
        return {k: _OPTION_CHECKS[k](k, v) for k, v in values.items()}
    except EnvOptionError as exc:
        if not what:
            raise
        raise EnvOptionError(f"{what}{exc}") from None


def _controlled_count(controlled, n) -> np.ndarray:
    """Pedestrians of a count or a fraction, evenly spread over the indices (n None: only check)."""
    if isinstance(controlled, (float, np.floating)):
        if not (0.0 < controlled <= 1.0):
            raise EnvOptionError(f"a fraction of controlled pedestrians must lie in (0, 1], got {controlled!r}")
        if n is None:
            return None
        k = max(1, int(round(controlled * n)))
    else:
        k = int(controlled)
        if n is None:
            if k < 1:
                raise EnvOptionError(f"controlled = {k} pedestrians: give at least 1")
            return None
        if not 1 <= k <= n:
            raise EnvOptionError(f"controlled = {k} pedestrians, but the scenario has {n}; give 1..{n}")
    # Evenly spread over the pedestrian indices (deterministic; spacing >= 1 keeps them distinct).
    return np.unique(np.round(np.linspace(0, n - 1, k)).astype(np.int64)) if k > 1 else np.zeros(1, np.int64)


def _controlled_ids(items, n) -> np.ndarray:
    """Pedestrians of a list of ids or indices (n None: check their form only)."""
    if not items:
        raise EnvOptionError("controlled selects no pedestrian: give at least one")
    out, bad = [], []
    for item in items:
        if isinstance(item, (int, np.integer)) and not isinstance(item, (bool, np.bool_)):
            i = int(item)
        elif isinstance(item, str) and item.startswith("ped_") and item[4:].isdigit():
            i = int(item[4:])
        else:
            bad.append(item)
            continue
        if i < 0 or (n is not None and i >= n):
            bad.append(item)
            continue
        out.append(i)
    if bad:
        last = "N - 1" if n is None else n - 1
        raise EnvOptionError(f"unknown pedestrian id(s) in controlled: {bad}; ids are 'ped_0'..'ped_{last}' "
                             f"(or indices 0..{last})")
    if len(set(out)) != len(out):
        dup = sorted({agent_id(i) for i in out if out.count(i) > 1})
        raise EnvOptionError(f"duplicate id(s) in controlled: {dup}")
    return np.array(sorted(out), dtype=np.int64)


def select_controlled(controlled, n: int | None) -> np.ndarray | None:
    """Sorted pedestrian indices the ``controlled`` option selects among ``n``; with ``n`` None only checks
    its form (returns None)."""
    if isinstance(controlled, str):
        if controlled == "all":
            return None if n is None else np.arange(n)
        raise EnvOptionError(f"controlled must be 'all', a count, a fraction in (0, 1] or a list of ids, got {controlled!r}")
    if isinstance(controlled, (bool, np.bool_)):
        raise EnvOptionError(f"controlled must be 'all', a count, a fraction or a list of ids, got {controlled!r}")
    if isinstance(controlled, (int, np.integer, float, np.floating)):
        return _controlled_count(controlled, n)
    try:
        items = list(controlled)
    except TypeError:
        raise EnvOptionError(f"controlled must be 'all', a count, a fraction or a list of ids, got {controlled!r}") from None
    out = _controlled_ids(items, n)
    return None if n is None else out


@dataclass(frozen=True)
class CrowdEnvConfig:
    """Every option of ``crowd_v0``, checked when made (see :class:`~crowd_env.envs.crowd_v0.CrowdParallelEnv`
    for what each means). Numbers are converted (``frame_skip`` to int, ranges to float); a bad value raises
    :class:`~crowd_env.errors.EnvOptionError` naming the option. ``dataclasses.replace(config, ...)``
    checks the changed copy again."""

    scenario: object = "seyfried_bottleneck"
    scenario_options: dict | None = None
    controlled: object = "all"
    background_policy: object = None
    preset: str | None = None
    params: object = None
    max_steps: int | None = None
    action_max_m_s: float = DEFAULT_ACTION_MAX_M_S
    n_neighbors: int = 6
    n_rays: int = 8
    neighbor_radius_m: float = 4.0
    ray_range_m: float = 5.0
    reward_fn: object = None
    render_mode: str | None = None
    frame_skip: int = 1
    heading_target: str = "intent"
    observation_frame: str = "world"
    reseed_scenario: bool | None = None
    observation_components: tuple | None = None
    reward_terms: object = None
    reward_terms_in_infos: bool = False

    def __post_init__(self):
        self._check_scenario()
        select_controlled(self.controlled, None)
        self.model()
        for name, value in observation_policy_options({k: getattr(self, k) for k in _OPTION_CHECKS}).items():
            object.__setattr__(self, name, value)
        if self.max_steps is not None:
            object.__setattr__(self, "max_steps", _count("max_steps", self.max_steps, minimum=1))
        if self.render_mode is not None and self.render_mode not in RENDER_MODES:
            raise EnvOptionError(f"render_mode must be None or one of {list(RENDER_MODES)}, got {self.render_mode!r}")
        self._check_reward()
        bg = self.background_policy
        if not (bg is None or isinstance(bg, (str, os.PathLike)) or callable(bg) or is_observation_policy(bg)):
            raise EnvOptionError("background_policy must be a name, a callable policy(sim) or an observation policy "
                                 f"(actions(observations) and env_overrides), got {bg!r}")

    def _check_scenario(self) -> None:
        scenario, options = self.scenario, self.scenario_options
        if isinstance(scenario, Scenario):
            if options:
                raise EnvOptionError("scenario_options apply to a scenario given by name, not to a Scenario object "
                                     f"(got {sorted(options)})")
        elif isinstance(scenario, str):
            if options is not None and not isinstance(options, dict):
                raise EnvOptionError(f"scenario_options must be a dict, got {type(options).__name__}")
        else:
            raise EnvOptionError(f"scenario must be a registered scenario name or a Scenario, got {type(scenario).__name__}")
        reseed = self.reseed_scenario
        if reseed is None:
            return
        if not isinstance(reseed, (bool, np.bool_)):
            raise EnvOptionError(f"reseed_scenario must be None, True or False, got {reseed!r}")
        if reseed and not self.can_reseed():
            raise EnvOptionError("reseed_scenario=True needs a scenario given by name whose factory takes a 'seed'")

    def can_reseed(self) -> bool:
        """Whether the scenario is given by name and its factory takes a ``seed``."""
        return isinstance(self.scenario, str) and "seed" in _scenario_option_defaults(self.scenario)

    def reseeds(self) -> bool:
        """``reseed_scenario`` resolved: None (auto) reseeds a named scenario whose factory takes a seed,
        unless ``scenario_options`` pins it."""
        if self.reseed_scenario is None:
            return self.can_reseed() and "seed" not in (self.scenario_options or {})
        return bool(self.reseed_scenario)

    def model(self) -> tuple:
        """``(preset name or None, ModelParams)``: ``params`` as given (a ModelParams), or the preset's with the
        fields of a ``params`` dict overridden."""
        preset, params = self.preset, self.params
        if preset is not None and isinstance(params, ModelParams):
            raise EnvOptionError("give preset or a ModelParams as params, not both (a dict of params overrides the "
                                 "preset's fields)")
        if params is not None and not isinstance(params, (dict, ModelParams)):
            raise EnvOptionError(f"params must be a ModelParams or a dict, got {type(params).__name__}")
        if isinstance(params, ModelParams):
            name, model = None, params
        else:
            try:
                base = get_preset(DEFAULT_PRESET if preset is None else preset)
            except ParameterError as exc:
                raise EnvOptionError(str(exc)) from None
            name, model = base.name, base.params(**(params or {}))
        check_time_step_floor(model.dt_s, error=EnvOptionError, name="params dt_s")  # refused here, not at reset
        return name, model

    def _check_reward(self) -> None:
        if not isinstance(self.reward_terms_in_infos, (bool, np.bool_)):
            raise EnvOptionError(f"reward_terms_in_infos must be True or False, got {self.reward_terms_in_infos!r}")
        if self.reward_fn is not None and not callable(self.reward_fn):
            raise EnvOptionError(f"reward_fn must be callable reward_fn(env, agent_ids, info), got {self.reward_fn!r}")
        if self.reward_terms is not None:
            if self.reward_fn is not None:
                raise EnvOptionError("give reward_fn or reward_terms, not both (reward_terms makes the reward_fn)")
            resolve_terms(self.reward_terms)  # raises naming the option

    def make_reward_fn(self):
        """The reward function: ``reward_fn``, the :class:`~crowd_env.envs.rewards.TermReward` of ``reward_terms``,
        or the :class:`~crowd_env.envs.rewards.DefaultReward`."""
        from .rewards import DefaultReward

        if self.reward_fn is not None:
            return self.reward_fn
        return DefaultReward() if self.reward_terms is None else resolve_terms(self.reward_terms)

    def observation_options(self) -> dict:
        """The :data:`~crowd_env.envs.background.OBSERVATION_POLICY_OPTIONS` of this configuration."""
        return {k: getattr(self, k) for k in OBSERVATION_POLICY_OPTIONS}

    def options(self) -> dict:
        """Every option as a keyword dict (``CrowdEnvConfig(**config.options()) == config``)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}


ENV_DEFAULTS = {f.name: f.default for f in dataclasses.fields(CrowdEnvConfig)}
ENV_OPTIONS = tuple(ENV_DEFAULTS)

# Other names of options, as the ecosystem spells them: PettingZoo's environments call the episode length
# in environment steps ``max_cycles``.
OPTION_ALIASES = {"max_cycles": "max_steps"}


def unknown_options_message(unknown, known, what: str, call: str) -> str:
    """The message of :class:`~crowd_env.errors.UnknownOptionError` for the unknown keyword options ``unknown``
    of ``call`` (e.g. ``"crowd_v0.parallel_env"``): it names them and the ``known`` ones, in Python's own
    wording for the first (``got an unexpected keyword argument 'name'``, which wrappers such as TorchRL's
    ``GymEnv`` act on)."""
    unknown = sorted(unknown)
    return (f"unknown option(s) {unknown} for {what}: {call}() got an unexpected keyword argument {unknown[0]!r}; "
            f"known: {list(known)}")


def resolve_options(options: dict, what: str = "crowd_v0", call: str = "crowd_v0.parallel_env",
                    extra=()) -> dict:
    """``options`` with the aliases of :data:`OPTION_ALIASES` renamed (``max_cycles`` -> ``max_steps``; giving
    both raises); unknown options (not in :data:`ENV_OPTIONS` or ``extra``) raise
    :class:`~crowd_env.errors.UnknownOptionError`."""
    options = dict(options)
    for alias, name in OPTION_ALIASES.items():
        if alias in options:
            if name in options:
                raise EnvOptionError(f"give {name} or its PettingZoo name {alias}, not both (got {name}="
                                     f"{options[name]!r} and {alias}={options[alias]!r})")
            options[name] = options.pop(alias)
    known = list(ENV_OPTIONS) + [k for k in extra if k not in ENV_OPTIONS]
    unknown = set(options) - set(known)
    if unknown:
        raise UnknownOptionError(unknown_options_message(unknown, known + list(OPTION_ALIASES), what, call))
    return options


def make_config(config: CrowdEnvConfig | None = None, options: dict | None = None, what: str = "crowd_v0",
                call: str = "crowd_v0.parallel_env") -> CrowdEnvConfig:
    """``config`` (default: the defaults) with the keyword ``options`` over it (:func:`resolve_options`)."""
    if config is not None and not isinstance(config, CrowdEnvConfig):
        raise EnvOptionError(f"config must be a CrowdEnvConfig, got {type(config).__name__}")
    options = resolve_options(options or {}, what, call)
    if config is None:
        return CrowdEnvConfig(**options)
    return dataclasses.replace(config, **options) if options else config
