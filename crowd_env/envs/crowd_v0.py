"""``crowd_v0``: the PettingZoo environment of the Kabalan et al. (2016) crowd model.

Use :func:`parallel_env` (a :class:`pettingzoo.ParallelEnv`) or :func:`env` (the AEC version, through
PettingZoo's ``parallel_to_aec`` converter, which adds the order-enforcing wrapper)::

    from . import crowd_v0
    env = crowd_v0.parallel_env(scenario="seyfried_bottleneck",
                                scenario_options={"width_m": 1.0, "n_pedestrians": 20},
                                controlled="all", frame_skip=10)
    obs, infos = env.reset(seed=0)
    while env.agents:
        actions = {a: env.action_space(a).sample() for a in env.agents}
        obs, rewards, terminations, truncations, infos = env.step(actions)

Agents
    Every pedestrian of the scenario has a stable id ``"ped_<i>"`` (``i`` = its index in the
    scenario). The ``controlled`` option picks which of them are agents (``possible_agents``); the
    others are driven each simulator step by the ``background_policy`` (default: the calibrated
    eikonal + social-force agent, :class:`crowd_env.walking.agent.SocialForceAgent`; or a trained
    policy by name, e.g. ``background_policy="bottleneck_ppo"``, which :mod:`crowd_env.envs.background`
    runs for them as the environment runs it for its agents).

Actions
    A velocity intent ``(2,)`` in m/s in ``Box(-a_max, a_max)`` (world frame, or the body frame with
    ``observation_frame="egocentric"``: forward and left of the heading at the start of the
    environment step, turned into the world frame once and held there for the ``frame_skip``
    sub-steps), ``a_max =
    action_max_m_s`` (default 2.5 m/s, a brisk run; note that the calibrated baseline's intents include
    the social force and can exceed it in dense crowds, up to about 6.5 m/s at the Seyfried bottleneck).
    The intent drives the pedestrian through m (u_int − u)/τ; the desired heading θ_d of the heading
    spring-damper is the angle of the intent (the current heading for a zero intent), or the angle of
    e_d with ``heading_target="desired_direction"`` (the baseline's choice; the shoulders turned at a narrow
    aperture when the model turns them, ``shoulder_turn_critical_ratio`` > 0). Actions are held for
    ``frame_skip`` simulator steps of ``params.dt_s`` (0.01 s by default).
    A pedestrian whose premovement time (the scenario's ``premovement_s``, RiMEA's reaction time) has
    not come stands still: its action is read and validated but held at zero until then.
    The environment never clips or repairs an action: :meth:`CrowdParallelEnv.step` raises
    ``ValueError`` naming the agent(s) for an action outside the Box, a non-finite or wrongly shaped
    action, an unknown or no-longer-live agent id, or a live agent without an action. Actions are read
    as float64 without rounding.

Observations
    A float32 vector per agent (``k = n_neighbors``, ``R = n_rays``), in the frame chosen by
    ``observation_frame``:

    ===========================  =======================================  =====================================
    field                        ``"world"`` (default), 7 + 5k + R        ``"egocentric"``, 5 + 5k + R
    ===========================  =======================================  =====================================
    ``velocity`` (2)             (u_x, u_y), m/s                          (forward, left) of the heading, m/s
    ``heading`` (2)              (cos θ, sin θ)                           left out (it is the frame)
    ``desired_direction`` (2)    e_d (Eq. 13), unit vector                e_d in the body frame
    ``travel_time`` (1)          T, s (the geodesic distance at 1 m/s)    same
    ``neighbors`` (4k)           k nearest: Δx, Δy (m), Δu (m/s)          same, body frame
    ``neighbor_mask`` (k)        1 real, 0 padding                        same
    ``wall_rays`` (R)            wall distance along θ + 2πr/R, m         same
    ===========================  =======================================  =====================================

    Field by field: :mod:`crowd_env.envs.observations` (``OBSERVATION_FIELDS``,
    ``EGOCENTRIC_OBSERVATION_FIELDS``, :attr:`CrowdParallelEnv.observation_layout`). In the egocentric
    frame a rotated or shifted copy of the scenario gives the same observations, and the same actions
    give the same (rotated) trajectories (``tests/envs/test_frames.py``). The fields come from named
    components (``observation_components``; built-ins such as ``"free_distance"`` and
    ``"local_density"``, or a component of one's own module as ``"module:Class"``), and the space's
    bounds from theirs.

State
    :meth:`CrowdParallelEnv.state` (PettingZoo's global state, for centralised critics): a float32
    vector of ``11 N + 1 + 2 E`` entries (N pedestrians, E exits) in :attr:`CrowdParallelEnv.state_space`:
    per pedestrian, controlled or not, present, controlled, position, velocity, heading (cos, sin),
    e_d and T (zeros once it has left, so the size never changes); the episode fraction; the exits'
    centres. World frame, or with ``observation_frame="egocentric"`` the scenario frame (origin at
    the walkable area's centroid, x towards the first exit), which rotations and shifts of the
    scenario carry along. Block by block: :mod:`crowd_env.envs.state`.

Rewards
    Default :class:`~crowd_env.envs.rewards.DefaultReward`: progress along the travel-time field
    (T_before − T_after, s of travel) − 0.01 × normal percussion received (kg m/s) − 0.1 per simulated
    second + 1 on leaving: the terms ``progress``, ``contact_percussion``, ``time`` and ``exit``; with
    ``reward_terms_in_infos=True``, each agent's share of each in its info (``infos[a]["reward_terms"]``, in the
    order of ``env.reward_term_names``; ``env.reward_terms(infos[a])["progress"]``). Name other terms and
    weights with ``reward_terms`` (a term of one's own module as ``"module:Class"``), or pass
    ``reward_fn(env, agent_ids, info) -> rewards`` (:mod:`crowd_env.envs.rewards` lists the info arrays).

Infos
    Per agent: ``contact_percussion_kg_m_s`` (sum of the normal percussions' magnitudes over its contacts this step),
    ``n_contacts``, ``travel_time_s`` (T after the step), ``speed_m_s``; with ``reward_terms_in_infos=True``
    also ``reward_terms`` (a list of floats: each term's weighted contribution in the order of
    ``env.reward_term_names``, summing to the reward; zeros at reset; plain numbers, as TorchRL's PettingZoo
    wrapper needs them).

Episode end
    A pedestrian whose centre enters an exit (its own destination exit in scenarios with per-pedestrian
    destinations, e.g. ``corridor_bidirectional``; another exit is floor for it) leaves: its agent
    gets ``terminations[a] = True`` on that step (with its final observation) and is removed from
    ``agents``. Observations and rewards use each agent's own destination field. After ``max_steps`` environment
    steps every live agent is truncated. A periodic scenario (``periodic_corridor``: no exits) ends that way
    only; its travel time falls along the walking direction and jumps by L/V at the seam, so the progress
    T_before − T_after is taken to its nearest image modulo L/V (a crossing earns the distance walked). ``step({})`` with no live agent returns five empty dicts
    (SuperSuit's ``black_death_v3`` relies on it); ``step_background()`` then moves the pedestrians
    still on the floor on (the background policy's), for measuring the whole crowd when only some
    pedestrians are agents. ``reset(options=...)`` ignores its options.

Determinism
    ``reset(seed=s)`` seeds everything random: the start positions (a named scenario is rebuilt with a
    seed drawn from the env's RNG, unless its ``seed`` option is pinned; see ``reseed_scenario``) and
    the desired speeds; the same seed and actions give bitwise identical observations, rewards and
    infos. Without a seed the first reset draws fresh entropy and later ones continue the stream.

Equivalence
    With every pedestrian controlled and fed the calibrated agent's intents (``action_max_m_s`` large
    enough, e.g. 50, and ``heading_target="desired_direction"``), the trajectories are bitwise those of
    the plain simulator with everyone on the baseline (tests/envs/test_env.py).

Decision interval
    ``frame_skip × params.dt_s``: 0.01 s by default (``frame_skip=1``); the registered Gymnasium ids and
    ``crowd-train-ppo`` use ``frame_skip=10`` (0.1 s).
"""
from __future__ import annotations

import functools

from crowd_env.errors import ActionError, EnvOptionError, EnvStateError, PolicyError, UnknownOptionError

import math
import os
import warnings

import numba as nb
import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv
from pettingzoo.utils.conversions import parallel_to_aec

from ..core.checks import check_integer, check_seed
from ..core.periodic import minimum_image_dx
from ..core.simulator import Simulator
from ..walking.presets import get_preset
from ..scenarios import Scenario, body_options, make_scenario
from ..walking.agent import SocialForceAgent, facing_headings, hold_waiting
from .background import is_observation_policy, load_named_background
from .config import (DEFAULT_ACTION_MAX_M_S, ENV_DEFAULTS, ENV_OPTIONS, OPTION_ALIASES, CrowdEnvConfig, agent_id,
                     make_config, resolve_options, select_controlled, unknown_options_message)
from .drivers import intents_and_headings, observing_driver
from .observations import OBSERVATION_FIELDS, ObservationBuilder, to_world_frame
from .state import GlobalStateBuilder

__all__ = ["CrowdParallelEnv", "CrowdEnvConfig", "parallel_env", "env", "EnvOptionError", "UnknownOptionError",
           "ResetOptionsWarning", "ENV_OPTIONS", "ENV_DEFAULTS", "OPTION_ALIASES", "resolve_options",
           "unknown_options_message", "OBSERVATION_FIELDS", "DEFAULT_ACTION_MAX_M_S", "default_background_policy",
           "agent_id", "decisions_for_time"]

DEFAULT_EPISODE_TIME_S = 60.0


class ResetOptionsWarning(UserWarning):
    """reset() was given options, which it ignores (the environment is configured when made)."""


def decisions_for_time(time_s: float, decision_dt_s: float) -> int:
    """The number of decisions of ``decision_dt_s`` that cover ``time_s`` (at least one): the ``max_steps``
    of an episode of that simulated length."""
    return max(1, int(math.ceil(time_s / decision_dt_s - 1e-9)))


def default_background_policy(scenario):
    """The calibrated eikonal + social-force agent for ``scenario``
    (:class:`crowd_env.walking.agent.SocialForceAgent`, which ``baselines.social_force`` names for users)."""
    return SocialForceAgent(scenario.navigation())


class CrowdParallelEnv(ParallelEnv):
    """PettingZoo parallel environment of the crowd model (see the module docstring for the full spec).

    Options: a :class:`~crowd_env.envs.config.CrowdEnvConfig` (positional), keywords (over it, or over the
    defaults), checked there:

    - ``scenario``: a registered scenario name (``crowd_env.scenarios.list_scenarios()``) or a
      :class:`~crowd_env.scenarios.Scenario` (any geometry); ``scenario_options``: dict for the named
      factory (unknown names raise listing the known ones).
    - ``controlled``: ``"all"``, a count k (k pedestrians evenly spread over the indices), a fraction
      in (0, 1], or a list of ids (``"ped_3"`` or ``3``).
    - ``background_policy``: ``policy(sim) -> intents (N, 2)`` or ``(intents, desired_heading (N,))``
      for the pedestrians not controlled; default: the calibrated social-force agent. Also an observation
      policy (``actions(observations)`` and ``env_overrides``, e.g. a trained policy file), run for the
      background pedestrians with its own observation options and decision interval, or a name:
      ``"calibrated"``, a shipped trained policy (``baselines.trained.list_trained()``) or a ``.npz``
      policy file (:mod:`crowd_env.envs.background`).
    - ``preset``: the model configuration (:mod:`crowd_env.walking.presets`; default ``"calibrated"``,
      calibrated on every figure of the Seyfried experiment); ``params``: a
      :class:`~crowd_env.walking.model.ModelParams` used as it is instead, or a dict of fields that
      override the preset's. The preset's navigation clearance applies to the bottleneck scenarios
      through their factory defaults (the radius), not here: pass ``navigation_clearance_m`` in
      ``scenario_options`` to change it.
    - ``max_steps``: environment steps before truncation (default: 60 s of simulated time);
      :func:`parallel_env` and :func:`env` also take it as ``max_cycles``, PettingZoo's name.
    - ``action_max_m_s``: a_max of the action Box (default 2.5 m/s; at most 1e3/√2 m/s, the core's bound on intents).
    - ``n_neighbors`` (k, default 6), ``neighbor_radius_m`` (4 m), ``n_rays`` (R, default 8),
      ``ray_range_m`` (5 m): observation settings.
    - ``reward_fn``: ``reward_fn(env, agent_ids, info) -> rewards`` (default
      :class:`~crowd_env.envs.rewards.DefaultReward`); or ``reward_terms``: the terms of a
      :class:`~crowd_env.envs.rewards.TermReward` (names, ``"module:Class"`` paths, term objects, or a dict
      of them to weights, or ``"least_effort"``; :func:`~crowd_env.envs.rewards.resolve_terms`).
    - ``reward_terms_in_infos``: True puts each agent's share of each term in its info (and
      :attr:`reward_term_names`; the vector environment then reports them as one array). Off by default:
      the reward function's info arrays always hold them, but the agents' lists of plain floats cost about
      8 % of a step in this dict API (15 µs at N = 100; ``benchmarks/env_step_parts.py --terms``).
    - ``observation_components``: the observation's components, in order (names, ``"module:Class"``
      paths or component objects; default the seven fields above:
      :func:`~crowd_env.envs.observations.resolve_components`).
    - ``render_mode``: None, ``"human"`` or ``"rgb_array"``.
    - ``frame_skip``: simulator steps per environment step (decision interval frame_skip × dt; default 1).
    - ``heading_target``: ``"intent"`` (θ_d = angle of the action) or ``"desired_direction"`` (angle of e_d,
      turned at a narrow aperture as the model turns shoulders: :func:`~crowd_env.walking.agent.facing_headings`).
    - ``observation_frame``: ``"world"`` (default) or ``"egocentric"`` (observations, actions and the
      state in the body frame, resp. the scenario frame; see the module docstring).
    - ``reseed_scenario``: rebuild a named scenario with a seed drawn from the env's RNG at each reset,
      so that start positions vary with the seed (a few tens of ms per reset). Default None = auto: on
      for a named scenario whose factory takes a ``seed``, unless ``scenario_options`` pins ``seed``;
      off for a Scenario object (then the seed only draws the desired speeds, which matter to the
      background policy only).
    """

    metadata = {"name": "crowd_v0", "render_modes": ["human", "rgb_array"], "render_fps": 10,
                "is_parallelizable": True}

    def __init__(self, config: CrowdEnvConfig | None = None, /, **options):
        config = make_config(config, options, "CrowdParallelEnv", "CrowdParallelEnv")
        self.config = config
        self._init_scenario(config)
        self._init_model(config)
        self._init_agents(config)
        self._init_spaces(config)
        self._init_run_state()

    def _init_scenario(self, config: CrowdEnvConfig) -> None:
        scenario = config.scenario
        if isinstance(scenario, Scenario):
            self._scenario_name, self._scenario_kwargs = None, {}
        else:  # a preset that calibrated its body gives it to the scenario (Preset.radius_m)
            preset, _ = config.model()
            body = None if preset is None else get_preset(preset).body_radius_m
            self._scenario_name, self._scenario_kwargs = scenario, body_options(scenario, config.scenario_options, body)
            scenario = make_scenario(scenario, **self._scenario_kwargs)
        self._scenario = scenario
        self._base_positions = scenario.position_m
        if scenario.n_pedestrians < 1:
            raise EnvOptionError("the scenario has no pedestrian")
        self.reseed_scenario = config.reseeds()

    def _init_model(self, config: CrowdEnvConfig) -> None:
        self.preset, self.params = config.model()  # preset None when a ModelParams object was given
        self.frame_skip = config.frame_skip
        max_steps = config.max_steps
        if max_steps is None:
            max_steps = decisions_for_time(DEFAULT_EPISODE_TIME_S, self.params.dt_s * self.frame_skip)
        self.max_steps = max_steps
        self.action_max_m_s, self.n_neighbors, self.n_rays = config.action_max_m_s, config.n_neighbors, config.n_rays
        self.heading_target, self.observation_frame = config.heading_target, config.observation_frame
        self.render_mode = config.render_mode
        self.reward_fn = config.make_reward_fn()
        # the names of the reward's terms, in the order of each agent's info["reward_terms"] (None: no terms)
        self._terms_in_infos = bool(config.reward_terms_in_infos)
        self._terms_dtype = None  # the dtype of info["reward_terms"] last checked (_check_terms)
        self.reward_term_names = getattr(self.reward_fn, "names", None) if self._terms_in_infos else None
        background_policy = config.background_policy
        if isinstance(background_policy, (str, os.PathLike)):
            background_policy = load_named_background(background_policy)
        self._background_policy = background_policy

    def _init_agents(self, config: CrowdEnvConfig) -> None:
        n = self._scenario.n_pedestrians
        self._controlled_index = select_controlled(config.controlled, n)
        self._ids = [agent_id(i) for i in range(n)]
        self.possible_agents = [self._ids[i] for i in self._controlled_index]
        self._index_of = {a: int(i) for a, i in zip(self.possible_agents, self._controlled_index)}
        self._controlled_mask = np.zeros(n, dtype=bool)
        self._controlled_mask[self._controlled_index] = True
        self._background_mask = ~self._controlled_mask
        self._has_background = bool(self._background_mask.any())
        self.agents = []

    def _init_spaces(self, config: CrowdEnvConfig) -> None:
        """Navigation, the observation assembler, the global state and the spaces (and an observing background)."""
        scenario = self._scenario
        self.navigation = scenario.navigation()
        t_bound = self.navigation.max_travel_time_s + 1.0
        self.velocity_bound_m_s = max(20.0, 2.0 * self.action_max_m_s)
        self._observer = ObservationBuilder(self.navigation, scenario.geometry.walls, n_neighbors=self.n_neighbors,
                                            n_rays=self.n_rays, neighbor_radius_m=config.neighbor_radius_m,
                                            ray_range_m=config.ray_range_m, velocity_bound_m_s=self.velocity_bound_m_s,
                                            travel_time_bound_s=t_bound, frame=self.observation_frame,
                                            period_m=scenario.geometry.period_x_m,
                                            components=config.observation_components)
        self.observation_layout = dict(self._observer.layout)
        policy = self._background_policy
        if is_observation_policy(policy):  # a learned background: observed and acting with its own options
            self._background_policy = observing_driver(
                policy, scenario, navigation=self.navigation, mask=self._background_mask, dt_s=self.params.dt_s,
                velocity_bound_m_s=self.velocity_bound_m_s, travel_time_bound_s=t_bound)
        elif policy is not None and not callable(policy):
            raise EnvOptionError("background_policy must be a name, a callable policy(sim) or an observation policy "
                                 f"(actions(observations) and env_overrides), got {policy!r}")
        self._state_builder = GlobalStateBuilder(self.navigation, scenario.geometry, self._controlled_mask,
                                                 frame=self.observation_frame,
                                                 velocity_bound_m_s=self.velocity_bound_m_s, travel_time_bound_s=t_bound)
        self.state_space = self._state_builder.space
        self.state_layout = dict(self._state_builder.layout)
        a = np.float32(self.action_max_m_s)
        self._observation_spaces = {ag: spaces.Box(self._observer.low, self._observer.high, dtype=np.float32)
                                    for ag in self.possible_agents}
        self._action_spaces = {ag: spaces.Box(-a, a, shape=(2,), dtype=np.float32) for ag in self.possible_agents}
        # Accept |a| <= a_max whether the action is float64 (the option's value) or float32 (the Box's bound).
        self._a_max_check = max(float(a), self.action_max_m_s)
        self.metadata = {**type(self).metadata, "render_fps": 1.0 / (self.params.dt_s * self.frame_skip)}

    def _init_run_state(self) -> None:
        self._rng = None
        self._sim = None
        self._steps = 0
        self._agent_index = np.zeros(0, np.int64)
        self._travel_time = np.full(self._scenario.n_pedestrians, np.nan)
        self._speed_c = np.zeros(0)  # the live agents' speeds (agents' order) at the end of the last step
        self._progress_period_s = _travel_time_period_s(self.navigation, self._scenario.geometry.period_x_m)
        self._renderer = None
        self.substep_hooks = []
        self._percussions = None
        self._last_premovement_s = 0.0
        if self.render_mode is not None:  # frames show the contact percussions of the steps since the last frame
            from .rendering import ContactPercussions

            self._percussions = ContactPercussions()
            self.substep_hooks.append(self._percussions)

    # ------------------------------------------------------------------ spaces
    def observation_space(self, agent):
        """The (cached) observation Box of ``agent``."""
        try:
            return self._observation_spaces[agent]
        except KeyError:
            raise ActionError(f"unknown agent {agent!r}; agents are {self._ids_summary()}") from None

    def action_space(self, agent):
        """The (cached) action Box(-a_max, a_max, (2,)) of ``agent``: a velocity intent in m/s."""
        try:
            return self._action_spaces[agent]
        except KeyError:
            raise ActionError(f"unknown agent {agent!r}; agents are {self._ids_summary()}") from None

    def require_reset(self, call: str) -> None:
        """Before the first :meth:`reset`, raise :class:`~crowd_env.errors.EnvStateError` saying "call reset()
        before" the method named ``call``."""
        if self._sim is None:
            raise EnvStateError(f"call reset() before {call}()")

    def state(self) -> np.ndarray:
        """The global state (float32, :attr:`state_space`; see the module docstring and
        :mod:`crowd_env.envs.state`). Raises :class:`~crowd_env.errors.EnvStateError` before :meth:`reset`."""
        self.require_reset("state")
        return self._state_builder.build(self._sim.state, self._steps / self.max_steps)

    def _ids_summary(self) -> str:
        p = self.possible_agents
        return str(p) if len(p) <= 8 else f"[{', '.join(p[:4])}, ..., {p[-1]}] ({len(p)})"

    # ------------------------------------------------------------------ read-only views
    @property
    def max_cycles(self) -> int:
        """PettingZoo's name of :attr:`max_steps` (environment steps before every live agent is truncated);
        setting it sets ``max_steps``, as PettingZoo's ``parallel_api_test`` does."""
        return self.max_steps

    @max_cycles.setter
    def max_cycles(self, value) -> None:
        self.max_steps = check_integer("max_cycles", value, error=EnvOptionError, minimum=1)

    @property
    def sim(self) -> Simulator:
        """The current :class:`~crowd_env.core.simulator.Simulator` (None before the first reset)."""
        return self._sim

    @property
    def scenario(self) -> Scenario:
        """The :class:`~crowd_env.scenarios.Scenario` the environment was built from."""
        return self._scenario

    @property
    def geometry(self):
        """The scenario's :class:`~crowd_env.core.geometry.Geometry` (walls, exits, measurement lines)."""
        return self._scenario.geometry

    @property
    def walkable_area(self):
        """The walkable area (shapely polygon, obstacles removed)."""
        return self._scenario.geometry.walkable_area

    @property
    def n_pedestrians(self) -> int:
        """Number of pedestrians N of the scenario (controlled or not, on the floor or gone)."""
        return self._scenario.n_pedestrians

    @property
    def dt_s(self) -> float:
        """Simulated duration of one environment step (frame_skip × params.dt_s)."""
        return self.params.dt_s * self.frame_skip

    @property
    def time_s(self) -> float:
        """Simulated time of the episode in s (0 before the first reset)."""
        return 0.0 if self._sim is None else self._sim.time_s

    @property
    def controlled_mask(self) -> np.ndarray:
        """(N,) bool: pedestrians controlled by agents (a copy)."""
        return self._controlled_mask.copy()

    def _per_pedestrian(self, array) -> dict:
        if self._sim is None:
            return {}
        idx = np.flatnonzero(self._sim.state.active)
        ids = self._ids
        return {ids[i]: v for i, v in zip(idx.tolist(), np.array(array[idx], copy=True))}

    @property
    def positions_m(self) -> dict:
        """id -> position (2,) in m of every pedestrian still on the floor (controlled or not)."""
        return self._per_pedestrian(self._sim.state.position_m) if self._sim else {}

    @property
    def velocities_m_s(self) -> dict:
        """id -> velocity (2,) in m/s of every pedestrian still on the floor."""
        return self._per_pedestrian(self._sim.state.velocity_m_s) if self._sim else {}

    @property
    def headings_rad(self) -> dict:
        """id -> heading in rad of every pedestrian still on the floor."""
        return {k: float(v) for k, v in self._per_pedestrian(self._sim.state.heading_rad).items()} if self._sim else {}

    @property
    def radii_m(self) -> dict:
        """id -> radius in m of every pedestrian still on the floor."""
        return {k: float(v) for k, v in self._per_pedestrian(self._sim.state.radius_m).items()} if self._sim else {}

    @property
    def destinations(self) -> dict:
        """id -> name of the destination exit of every pedestrian still on the floor (``"any"``: the nearest
        exit; every pedestrian's in a scenario without destinations)."""
        if self._sim is None:
            return {}
        dest = self._scenario.destination
        names = self._scenario.exit_names
        idx = np.flatnonzero(self._sim.state.active)
        return {self._ids[i]: "any" if dest is None or dest[i] < 0 else names[dest[i]] for i in idx.tolist()}

    # ------------------------------------------------------------------ API
    def reset(self, seed=None, options=None):
        """Start an episode; returns ``(observations, infos)`` of all ``possible_agents``.

        The episode is configured when the environment is made (:data:`ENV_OPTIONS`): ``options`` are
        accepted as the PettingZoo API requires, ignored, and named in a :class:`ResetOptionsWarning`.
        """
        if options:
            keys = sorted(options) if isinstance(options, dict) else options
            warnings.warn(f"reset() ignores its options {keys!r}; pass environment options to parallel_env(...) / "
                          "env(...) or gymnasium.make(...)", ResetOptionsWarning, stacklevel=2)
        seed = check_seed("seed", seed, error=EnvOptionError)
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        elif self._rng is None:
            self._rng = np.random.default_rng()
        scenario = self._scenario
        if self.reseed_scenario:
            sub = int(self._rng.integers(0, 2**31 - 1))
            fresh = make_scenario(self._scenario_name, **{**self._scenario_kwargs, "seed": sub})
            if fresh.n_pedestrians != scenario.n_pedestrians:
                raise EnvStateError("reseeded scenario changed its number of pedestrians")
            new, old = fresh.destination, scenario.destination
            if (new is None) != (old is None) or (new is not None and not np.array_equal(new, old)):
                raise EnvStateError("reseeded scenario changed its pedestrians' destinations")
            scenario = fresh
        state = scenario.make_state(rng=self._rng)
        self._sim = Simulator(state, geometry=self._scenario.geometry, params=self.params,
                              destination=self._scenario.destination)
        self._last_premovement_s = float(state.premovement_s.max(initial=0.0))
        if hasattr(self.navigation, "update"):  # a navigation that changes with the crowd starts afresh
            self.navigation.update(self._sim)
        if self._background_policy is None and not self._controlled_mask.all():
            self._background_policy = default_background_policy(self._scenario)
        self._steps = 0
        if self._percussions is not None:
            self._percussions.clear()  # nothing of the last episode on the first frame
        self.agents = self.possible_agents[:]
        self._agent_index = self._controlled_index.copy()
        obs, travel = self._observer.build(state, self._agent_index)
        self._travel_time[:] = np.nan
        self._travel_time[self._agent_index] = travel
        speed = np.hypot(*state.velocity_m_s[self._agent_index].T)
        self._speed_c = speed
        infos = {a: {"contact_percussion_kg_m_s": 0.0, "n_contacts": 0, "travel_time_s": float(t),
                     "speed_m_s": float(s)}
                 for a, t, s in zip(self.agents, travel.tolist(), speed.tolist())}
        if self.reward_term_names is not None:  # the same keys as after a step: zero contributions
            for info in infos.values():
                info["reward_terms"] = [0.0] * len(self.reward_term_names)
        if self.render_mode == "human":
            self.render()
        return dict(zip(self.agents, obs)), infos

    def _actions_array(self, actions) -> np.ndarray:
        """Validate ``actions`` against the live agents; returns (n_live, 2) float64 in ``self.agents`` order."""
        if not isinstance(actions, dict):
            raise ActionError(f"actions must be a dict agent id -> (2,) velocity intent, got {type(actions).__name__}")
        live = self.agents
        if len(actions) == len(live) and list(actions) == live:  # the usual dict(zip(env.agents, ...)): in order
            values = list(actions.values())
        else:
            self._check_action_keys(actions)
            values = [actions[a] for a in live]
        try:
            arr = real_actions(values, live)
        except ActionError:
            raise
        except (TypeError, ValueError):
            arr = None
        if arr is None or arr.shape != (len(live), 2):
            for a in live:
                try:
                    v = np.asarray(actions[a], dtype=np.float64)
                except (TypeError, ValueError):
                    raise ActionError(f"action of {a} is not numeric: {actions[a]!r}") from None
                if v.shape != (2,):
                    raise ActionError(f"action of {a} must have shape (2,) (a velocity intent in m/s), got shape "
                                     f"{v.shape}: {actions[a]!r}")
            raise ActionError("actions could not be stacked into an (n, 2) array")  # pragma: no cover
        if not actions_within(arr, self._a_max_check, _EVERY_ROW):  # also false for NaN: name the culprits
            finite = np.isfinite(arr).all(axis=1)
            if not finite.all():
                i = np.flatnonzero(~finite)
                raise ActionError(f"non-finite action(s) for {named_rows([live[k] for k in i], arr[i])}")
            i = np.flatnonzero((np.abs(arr) > self._a_max_check).any(axis=1))
            raise ActionError(f"action(s) of {named_rows([live[k] for k in i], arr[i])} outside the action space "
                              f"Box(-{self.action_max_m_s:g}, {self.action_max_m_s:g}) m/s; the environment does not "
                              "clip")
        return arr

    def _check_action_keys(self, actions) -> None:
        """Raise :class:`~crowd_env.errors.ActionError` unless ``actions`` has exactly the live agents' ids."""
        live = self.agents
        if len(actions) == len(live) and actions.keys() == set(live):
            return
        known = self._index_of
        unknown = [a for a in actions if a not in known]
        if unknown:
            raise ActionError(f"unknown agent id(s) {unknown[:10]}; agents are {self._ids_summary()}")
        live_set = set(live)
        dead = [a for a in actions if a not in live_set]
        if dead:
            raise ActionError(f"agent(s) {dead[:10]} are no longer live (terminated or truncated); "
                             "give actions only for env.agents")
        missing = [a for a in live if a not in actions]
        raise ActionError(f"missing action(s) for live agent(s) {missing[:10]} ({len(missing)} in all): every "
                         "agent in env.agents needs an action each step")

    def step(self, actions):
        """Advance ``frame_skip`` simulator steps; returns ``(obs, rewards, terminations, truncations, infos)``."""
        self.require_reset("step")
        if not self.agents:
            if actions:
                raise ActionError(f"no live agent, but actions were given for {list(actions)[:10]}: the episode is "
                                 "over, call reset()")
            return {}, {}, {}, {}, {}
        intent_c = self._actions_array(actions)
        agents = self.agents
        obs, rewards, exited, truncated, info = self._advance(intent_c)
        obs_d = dict(zip(agents, obs))
        rew_d = dict(zip(agents, rewards.tolist()))
        if len(self.agents) == len(agents):  # nobody ended (the usual step): one dict of False, copied
            term_d = dict.fromkeys(agents, False)
            trunc_d = term_d.copy()
        else:
            term_d = dict(zip(agents, exited.tolist()))
            trunc_d = dict(zip(agents, truncated.tolist()))
        columns = (agents, info["contact_percussion_kg_m_s"].tolist(), info["n_contacts"].tolist(),
                   info["travel_time_s"].tolist(), info["speed_m_s"].tolist())
        terms = info.get("reward_terms") if self._terms_in_infos else None
        if terms is None:
            info_d = {a: {"contact_percussion_kg_m_s": p, "n_contacts": c, "travel_time_s": t, "speed_m_s": v}
                      for a, p, c, t, v in zip(*columns)}
        else:  # each agent's row of the reward's terms (rewards.TermReward), in the order of reward_term_names
            self.reward_term_names = terms.dtype.names
            info_d = {a: {"contact_percussion_kg_m_s": p, "n_contacts": c, "travel_time_s": t, "speed_m_s": v,
                          "reward_terms": r} for a, p, c, t, v, r in zip(*columns, term_rows(terms).tolist())}
        if self.render_mode == "human":
            self.render()
        return obs_d, rew_d, term_d, trunc_d, info_d

    def step_background(self) -> bool:
        """After every agent has left, one environment step (``frame_skip`` simulator steps) of the
        pedestrians still on the floor, driven by the background policy, with the sub-step hooks as in
        :meth:`step`; returns False, doing nothing, once nobody is on the floor or ``max_steps`` is reached.
        The evaluation harness runs it so that a crowd's measures (evacuation, flow) cover the whole crowd
        when only some pedestrians are agents: ``while env.step_background(): ...``."""
        self.require_reset("step_background")
        if self.agents:
            raise EnvStateError(f"{len(self.agents)} agent(s) are live: step() them; step_background() moves the "
                                "crowd on after they have left")
        if self._steps >= self.max_steps or not self._sim.state.active.any():
            return False
        self._advance(np.zeros((0, 2)))
        if self.render_mode == "human":
            self.render()
        return True

    def _advance(self, intent_c: np.ndarray):
        """One environment step of the live agents with validated intents ``intent_c`` (n_live, 2) float64 in
        ``self.agents`` order (in the action frame). Returns arrays in that order: ``(observations (n, D)
        float32, rewards (n,), terminated (n,) bool, truncated (n,) bool, info)`` (``info``: the arrays of
        :data:`~crowd_env.envs.rewards.REWARD_INFO_KEYS`); agents that ended leave ``self.agents``. The
        dict API (:meth:`step`) and the vector environment both call it; the work per agent is compiled
        (:func:`_set_agent_inputs`, :func:`_add_contacts`, :func:`_step_arrays`, the observation pass)."""
        sim = self._sim
        st = sim.state
        n = st.n
        idx_c = self._agent_index
        agents = self.agents
        if self.observation_frame == "egocentric":  # body frame at the decision -> world, held for the sub-steps
            theta0 = st.heading_rad[idx_c]
            intent_c = to_world_frame(intent_c, np.cos(theta0), np.sin(theta0))
        t_before = self._travel_time[idx_c]
        speed_before = self._speed_c
        percussion = np.zeros(n)
        contacts = np.zeros(n, np.int64)
        by_intent = self.heading_target == "intent"
        theta_c = _NO_ANGLES
        hooks = self.substep_hooks
        if self._percussions is not None:  # frames show this step's contacts only (crowd_env.envs.rendering)
            self._percussions.clear()
        update = getattr(self.navigation, "update", None)  # route choice: re-chosen from the crowd each step
        for _ in range(self.frame_skip):
            if update is not None:
                update(sim)
            if self._has_background and (self._background_mask & st.active).any():
                intents, heading = self._background(sim)
            elif not sim.active_index.shape[0]:  # flatnonzero(state.active), kept for the step
                break
            else:
                intents = np.zeros((n, 2))
                heading = st.heading_rad.copy()
            if not by_intent:
                theta_c = facing_headings(self.navigation, sim, idx_c)
            _set_agent_inputs(intents, heading, st.heading_rad, idx_c, intent_c, theta_c, by_intent)
            if sim.time_s < self._last_premovement_s:  # somebody has not started yet: hold them still
                hold_waiting(intents, heading, st.heading_rad, st.premovement_s, sim.time_s, sim.active_index)
            if hooks:
                prev_pos, prev_t = st.position_m.copy(), sim.time_s
            res = sim.step(intents, desired_heading_rad=heading)
            if res.contact_i.size:
                _add_contacts(percussion, contacts, res.contact_i, res.contact_j, res.percussion_normal)
            for hook in hooks:
                hook(self, res, prev_pos, prev_t)
        self._steps += 1
        obs, t_after, speed = self._observer.observe(st, idx_c)
        self._speed_c = speed
        m = idx_c.shape[0]  # the outputs are made here: numba hands an array back to Python for 0.3 µs each
        progress, perc_c, contacts_c = np.empty(m), np.empty(m), np.empty(m, np.int64)
        exited, truncated = np.empty(m, np.bool_), np.empty(m, np.bool_)
        n_done = _step_arrays(st.active, idx_c, (t_before, t_after), self._travel_time, (percussion, contacts),
                              self._steps >= self.max_steps, (progress, perc_c, contacts_c, exited, truncated))
        if self._progress_period_s > 0.0:  # periodic corridor: T jumps by L/V at the seam (module docstring)
            progress = minimum_image_dx(progress, self._progress_period_s)
        info = {"agent_index": idx_c.copy(), "progress_s": progress, "travel_time_before_s": t_before,
                "travel_time_s": t_after, "contact_percussion_kg_m_s": perc_c, "n_contacts": contacts_c,
                "speed_m_s": speed, "speed_before_m_s": speed_before, "exited": exited, "dt_s": self.dt_s}
        rewards = self._rewards(agents, info)
        if n_done:
            keep = ~(exited | truncated)
            self._agent_index = idx_c[keep]
            self._speed_c = speed[keep]
            self.agents = [a for a, k in zip(agents, keep.tolist()) if k]
        return obs, rewards, exited, truncated, info

    def reward_terms(self, info: dict) -> dict:
        """An agent's ``info`` turned into term name -> its contribution to the reward (the names are
        :attr:`reward_term_names`; ``{}`` without terms)."""
        values = info.get("reward_terms")
        if values is None or self.reward_term_names is None:
            return {}
        return dict(zip(self.reward_term_names, values))

    def _background(self, sim):
        return intents_and_headings(self._background_policy(sim), sim.state)

    def _rewards(self, agents, info) -> np.ndarray:
        out = self.reward_fn(self, agents, info)
        n = len(agents)
        terms = info.get("reward_terms")
        if terms is not None and (type(terms) is not np.ndarray or terms.dtype is not self._terms_dtype
                                  or terms.shape != (n,)):
            self._terms_dtype = _check_terms(terms, n)
        if type(out) is np.ndarray and out.shape == (n,) and out.dtype == np.float64 and _all_finite(out):
            return out  # DefaultReward's: nothing to convert
        if isinstance(out, dict):
            missing = [a for a in agents if a not in out]
            if missing:
                raise PolicyError(f"reward_fn returned no reward for {missing[:10]}")
            out = [out[a] for a in agents]
        r = np.asarray(out, dtype=np.float64)
        if r.shape != (len(agents),):
            raise PolicyError(f"reward_fn must return {len(agents)} rewards (one per agent), got shape {r.shape}")
        if not np.isfinite(r).all():
            raise PolicyError(f"reward_fn returned non-finite rewards for {[agents[i] for i in np.flatnonzero(~np.isfinite(r))[:10]]}")
        return r

    def render(self):
        """``rgb_array``: an (H, W, 3) uint8 image; ``human``: draw in a window (headless: warn once) and return None."""
        if self.render_mode is None:
            warnings.warn("render() called with render_mode=None; create the environment with "
                          "render_mode='rgb_array' or 'human'", UserWarning, stacklevel=2)
            return None
        self.require_reset("render")
        if self._renderer is None:
            from .rendering import CrowdRenderer

            self._renderer = CrowdRenderer(self._scenario.geometry, self._controlled_mask, self.render_mode,
                                           fps=self.metadata["render_fps"], body_depth_m=self._sim.physics.body_depth_m)
        return self._renderer.draw(self._sim.state, self._sim.time_s, len(self.agents), contacts=self._percussions.peek())

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def __getstate__(self):
        state = self.__dict__.copy()
        state["_renderer"] = None  # figures do not travel (SuperSuit pickles environments to copy them)
        return state


_NO_ANGLES = np.zeros(0)


@nb.njit(cache=True)
def _set_agent_inputs(intents, heading, state_heading, idx_c, intent_c, theta_c, by_intent):
    """Write the agents' intents and θ_d into the simulator's (N, 2) and (N,) inputs. θ_d: with
    ``by_intent`` the intent's angle (atan2 as :func:`~crowd_env.core.angles.direction_angles_rad`), or the
    current heading for an intent of speed <= 1e-12; else ``theta_c``."""
    for a in range(idx_c.shape[0]):
        i = idx_c[a]
        ux = intent_c[a, 0]
        uy = intent_c[a, 1]
        intents[i, 0] = ux
        intents[i, 1] = uy
        if not by_intent:
            heading[i] = theta_c[a]
        elif np.hypot(ux, uy) <= 1e-12:
            heading[i] = state_heading[i]
        else:
            heading[i] = np.arctan2(uy, ux)


@nb.njit(cache=True)
def _add_contacts(percussion, contacts, contact_i, contact_j, percussion_normal):
    """Add one simulator step's contacts to the per-pedestrian sums: |normal percussion| and a count to
    each pedestrian of a contact (j < 0: a wall), summed as two bincounts (first i, then j) were."""
    n = percussion.shape[0]
    for side in range(2):
        part = np.zeros(n)
        for c in range(contact_i.shape[0]):
            p = contact_i[c] if side == 0 else contact_j[c]
            if p >= 0:
                part[p] += abs(percussion_normal[c])
                contacts[p] += 1
        for p in range(n):
            percussion[p] += part[p]


def _travel_time_period_s(navigation, period_m: float) -> float:
    """L / V, the jump of the travel time of ``navigation`` across the seam of a geometry periodic with period L
    (0 when it is not periodic); its fields must share one wavefront speed V."""
    if not period_m:
        return 0.0
    fields = navigation.fields.values() if hasattr(navigation, "fields") else [navigation]
    speeds = {float(getattr(f, "speed_m_s", 1.0)) for f in fields}
    if len(speeds) != 1:
        raise EnvOptionError(f"a periodic scenario's navigation fields must share one speed_m_s, got {sorted(speeds)}")
    return float(period_m) / speeds.pop()


@nb.njit(cache=True)
def _step_arrays(active, idx_c, times, travel_time, touched, at_limit, out):
    """Write the agents' step arrays ``out`` = ``(progress, percussions, contact counts, exited, truncated)``:
    progress T_before − T_after (``times`` = ``(T_before, T_after)``), their percussions and contact counts (of
    ``touched`` = ``(percussion, contacts)`` per pedestrian), exited, truncated (not exited at the step limit);
    returns how many ended; stores T_after in ``travel_time``."""
    t_before, t_after = times
    percussion, contacts = touched
    progress, perc, cont, exited, truncated = out
    m = idx_c.shape[0]
    n_done = 0
    for a in range(m):
        i = idx_c[a]
        progress[a] = t_before[a] - t_after[a]
        travel_time[i] = t_after[a]
        perc[a] = percussion[i]
        cont[a] = contacts[i]
        exited[a] = not active[i]
        truncated[a] = active[i] and at_limit
        n_done += exited[a] or truncated[a]
    return n_done


_EVERY_ROW = np.zeros(0, np.bool_)


def real_actions(values, names=None) -> np.ndarray:
    """``values`` (an (n, 2) array, or a sequence of (2,) intents) as a float64 array: the conversion of the dict
    and vector APIs' actions. A complex one raises :class:`~crowd_env.errors.ActionError`, naming the ``names`` of
    the complex rows when given (numpy would drop the imaginary parts with a mere warning); values that are not
    numeric, or ragged, raise numpy's ``TypeError`` or ``ValueError``."""
    arr = np.asarray(values)
    if arr.dtype.kind == "c":
        rows = [i for i, v in enumerate(values) if np.iscomplexobj(v)] if names is not None else []
        who = f" of {[names[i] for i in rows[:10]]}" if rows else ""
        raise ActionError(f"complex action(s){who}: a velocity intent is two real numbers in m/s (the imaginary "
                          "part would be dropped)")
    return arr.astype(np.float64, copy=False)


def named_rows(names, rows, shown: int = 5) -> str:
    """``name [x, y]`` for the first ``shown`` of ``names`` with their ``rows``, and how many in all when there are
    more: the offending actions an error lists, each beside its agent."""
    text = ", ".join(f"{n} {[float(x) for x in r]}" for n, r in zip(names[:shown], rows[:shown]))
    return text + (f" ({len(names)} in all)" if len(names) > shown else "")


@nb.njit(cache=True)
def actions_within(actions, bound, live):
    """Whether every |component| of the (n, 2) ``actions`` is <= ``bound`` (False for NaN) in the rows where
    ``live`` is True (every row when ``live`` is empty): the action check of the dict and vector APIs."""
    every = live.shape[0] == 0
    for i in range(actions.shape[0]):
        if every or live[i]:
            for k in range(actions.shape[1]):
                if not abs(actions[i, k]) <= bound:
                    return False
    return True


@nb.njit(cache=True)
def _all_finite(values):
    for v in values:
        if not np.isfinite(v):
            return False
    return True


def parallel_env(**options) -> CrowdParallelEnv:
    """The PettingZoo parallel environment; options as in :class:`CrowdParallelEnv` (unknown ones raise
    :class:`~crowd_env.errors.UnknownOptionError`), and ``max_cycles``, PettingZoo's name of ``max_steps``."""
    return CrowdParallelEnv(make_config(None, options))


def env(**options):
    """The AEC version: ``parallel_to_aec(parallel_env(...))`` (PettingZoo adds its order-enforcing wrapper).

    Actions are not clipped, so PettingZoo's clip/assert-out-of-bounds wrappers are not applied; the
    parallel environment raises on invalid actions itself.
    """
    return parallel_to_aec(parallel_env(**options))


def _check_terms(terms, n: int) -> np.dtype:
    """The dtype of a reward function's ``info["reward_terms"]``; raises :class:`~crowd_env.errors.PolicyError`
    naming what was given unless it is an (n,) structured array with one numeric field per term."""
    expected = (f"info['reward_terms'] must be an ({n},) structured array, one row per agent and one numeric field "
                "per term (as TermReward writes it)")
    if not isinstance(terms, np.ndarray) or terms.dtype.names is None:
        raise PolicyError(f"reward_fn put a {type(terms).__name__} in info['reward_terms']; {expected}")
    if terms.shape != (n,):
        raise PolicyError(f"reward_fn put an array of shape {terms.shape} in info['reward_terms']; {expected}")
    odd = [name for name in terms.dtype.names if terms.dtype.fields[name][0].kind not in "biuf"]
    if odd:
        raise PolicyError(f"info['reward_terms'] field(s) {odd} are not numbers; {expected}")
    return terms.dtype


def term_rows(terms) -> np.ndarray:
    """The (n,) structured array of the terms' contributions as (n, T) float64 rows (a view when every field is
    float64, as TermReward's are)."""
    dtype = terms.dtype
    if _plain_float_fields(dtype) and terms.flags.c_contiguous:
        return np.ndarray((len(terms), len(dtype.names)), np.float64, terms)
    from numpy.lib import recfunctions

    return recfunctions.structured_to_unstructured(terms, dtype=np.float64)


@functools.lru_cache(maxsize=64)
def _plain_float_fields(dtype) -> bool:
    """Whether the structured ``dtype`` is float64 fields packed one after the other (once per dtype)."""
    return all(dtype.fields[name][0] == np.float64 for name in dtype.names) and dtype.itemsize == 8 * len(dtype.names)
