"""Background pedestrians driven by a learned (observation) policy, and background policies by name.

The environment's ``background_policy`` option drives the pedestrians it does not control. Besides a
``policy(sim)`` callable (the calibrated :class:`~crowd_env.walking.agent.SocialForceAgent` by default) it
takes an *observation policy*: an object with ``actions(observations (n, D)) -> (n, 2)`` and
``env_overrides``, the environment options it was trained with (``n_neighbors``, ``n_rays``,
``neighbor_radius_m``, ``ray_range_m``, ``observation_frame``, ``frame_skip``, ``action_max_m_s``,
``heading_target``, ``observation_components``; those it does not name take the environment's
defaults), and optionally ``obs_dim``, the observation size it expects (checked against its options).
A trained policy file (:class:`baselines.trained.FilePolicy`) is one. :class:`ObservingBackground` runs it for the background
pedestrians exactly as the environment runs it for its agents:

- every ``frame_skip`` simulator steps of the policy (its own decision interval, whatever the
  environment's), the active background pedestrians are observed with the policy's observation options
  (the environment's own :class:`~crowd_env.envs.observations.ObservationBuilder`, so the observation is
  the one an agent would get), and their actions are computed in one batched call;
- an egocentric action is turned into the world frame at the decision and held there, as the
  environment does for its agents;
- the desired heading θ_d is the angle of the intent (the current heading for a zero intent), or the
  angle of e_d at every step with ``heading_target="desired_direction"``, the shoulders turned at a narrow
  aperture when the model turns them (``shoulder_turn_critical_ratio`` > 0,
  :func:`~crowd_env.walking.agent.facing_headings`);
- an action outside the policy's Box(-a_max, a_max) or not finite raises
  :class:`~crowd_env.errors.PolicyError` naming the pedestrians: nothing is clipped.

A test checks that pedestrians in the background of a policy move exactly as the same pedestrians do
when they are agents acting with it (``tests/envs/test_background.py``).

**Names.** ``background_policy`` may also be a name or a path: ``"calibrated"`` (alias ``"baseline"``,
the default) or anything a loader registered under the ``crowd_env_background_policies`` entry-point
group accepts. The project's ``baselines`` package registers :func:`baselines.trained.background_policy`,
which takes the name of a shipped trained policy (``baselines.trained.list_trained()``). A policy file
(``.npz``) loads without any plugin (:class:`FileObservationPolicy`). crowd_env itself never imports ``baselines`` (the layer contract): it finds the loader
through the package metadata, as Gymnasium finds environment plugins.
"""
from __future__ import annotations

import os
from importlib.metadata import entry_points

import numpy as np

from crowd_env.errors import EnvOptionError, PolicyError

from ..walking.agent import facing_headings
from .observations import ObservationBuilder, to_world_frame
from .policy_files import load_policy_file

__all__ = ["ObservingBackground", "OBSERVATION_POLICY_OPTIONS", "CALIBRATED_NAMES", "ENTRY_POINT_GROUP",
           "NAMES_ENTRY_POINT_GROUP", "shipped_policy_names", "is_observation_policy", "load_named_background",
           "FileObservationPolicy"]

# The environment options an observation policy depends on (its observation layout, decision interval, action).
OBSERVATION_POLICY_OPTIONS = ("n_neighbors", "n_rays", "neighbor_radius_m", "ray_range_m", "observation_frame",
                              "frame_skip", "action_max_m_s", "heading_target", "observation_components")
CALIBRATED_NAMES = ("calibrated", "baseline")
ENTRY_POINT_GROUP = "crowd_env_background_policies"
NAMES_ENTRY_POINT_GROUP = "crowd_env_trained_policy_names"


def is_observation_policy(policy) -> bool:
    """Whether ``policy`` is an observation policy: ``actions(observations)`` and an ``env_overrides`` dict."""
    return callable(getattr(policy, "actions", None)) and isinstance(getattr(policy, "env_overrides", None), dict)


class FileObservationPolicy:
    """A policy file (``.npz``, :mod:`crowd_env.envs.policy_files`) as an observation policy: batched
    :meth:`actions`, the ``env_overrides`` of its training (the :data:`OBSERVATION_POLICY_OPTIONS` its
    ``env_config`` names) and ``obs_dim``. The environment loads a file given as ``background_policy`` with it,
    without any plugin; :class:`baselines.trained.FilePolicy` adds the agent interface on top."""

    def __init__(self, path, name: str | None = None):
        self.path = os.fspath(path)
        self.file = load_policy_file(self.path)
        self.name = name or os.path.splitext(os.path.basename(self.path))[0]
        cfg = self.file.env_config  # the options its observation layout, decision interval and action depend on
        self.env_overrides = {k: cfg[k] for k in OBSERVATION_POLICY_OPTIONS if k in cfg}

    @property
    def obs_dim(self) -> int:
        """The size of the observations it acts on."""
        return self.file.obs_dim

    def actions(self, observations) -> np.ndarray:
        """Batched actions (n, 2) for observations (n, D), as the vector environments take them."""
        return self.file.actions(observations)


def load_named_background(spec):
    """The background policy named ``spec`` (a string or path): None for :data:`CALIBRATED_NAMES` (the
    environment's default), a :class:`FileObservationPolicy` for a policy file (``.npz``), else what the first loader of the :data:`ENTRY_POINT_GROUP` entry points that
    accepts it returns. A loader raises ``LookupError`` or ``ValueError`` for a name it does not know;
    :class:`~crowd_env.errors.EnvOptionError` gathers their messages when none knows it."""
    name = os.fspath(spec)
    if name in CALIBRATED_NAMES:
        return None
    if name.endswith(".npz"):
        return FileObservationPolicy(name)
    reasons = []
    for ep in sorted(entry_points(group=ENTRY_POINT_GROUP), key=lambda e: e.name):
        try:
            return ep.load()(name)
        except (LookupError, ValueError) as exc:
            reasons.append(f"{ep.name}: {exc}")
    known = f"{' or '.join(repr(n) for n in CALIBRATED_NAMES)}"
    if not reasons:
        raise EnvOptionError(f"unknown background policy {name!r}: give {known}, a policy(sim) callable or an "
                             f"observation policy (no loader is registered under the {ENTRY_POINT_GROUP!r} entry "
                             "points: is crowd_env installed with pip install -e .?)")
    raise EnvOptionError(f"unknown background policy {name!r}: give {known}, a policy(sim) callable, an observation "
                         "policy, or a name a loader knows (" + "; ".join(reasons) + ")")


def shipped_policy_names() -> list:
    """The names of the trained policies shipped beside crowd_env, as the :data:`NAMES_ENTRY_POINT_GROUP` entry
    points list them (``baselines.trained.list_trained``); empty without them."""
    names = []
    for ep in sorted(entry_points(group=NAMES_ENTRY_POINT_GROUP), key=lambda e: e.name):
        names.extend(str(n) for n in ep.load()())
    return sorted(set(names))


class ObservingBackground:
    """``policy(sim) -> intents (N, 2)`` (and desired headings with ``heading_target="desired_direction"``)
    for the background pedestrians (``background_mask``), from the observation policy ``policy``.

    ``options``: the resolved and checked :data:`OBSERVATION_POLICY_OPTIONS` (the policy's ``env_overrides``
    over the environment's defaults); ``navigation`` and ``walls``: the environment's; ``dt_s``: the simulator step;
    the bounds only set the observation builder's declared space. Rows of pedestrians it does not drive are
    zero (the environment overwrites its agents' rows)."""

    def __init__(self, policy, options: dict, *, navigation, walls, background_mask: np.ndarray, dt_s: float,
                 velocity_bound_m_s: float, travel_time_bound_s: float, period_m: float = 0.0):
        self.policy = policy
        self.options = dict(options)
        self.frame_skip = int(options["frame_skip"])
        self.action_max_m_s = float(options["action_max_m_s"])
        self.heading_target = options["heading_target"]
        self.observer = ObservationBuilder(navigation, walls, n_neighbors=int(options["n_neighbors"]),
                                           n_rays=int(options["n_rays"]),
                                           neighbor_radius_m=float(options["neighbor_radius_m"]),
                                           ray_range_m=float(options["ray_range_m"]),
                                           velocity_bound_m_s=velocity_bound_m_s, travel_time_bound_s=travel_time_bound_s,
                                           frame=options["observation_frame"], period_m=period_m,
                                           components=options.get("observation_components"))
        want = getattr(policy, "obs_dim", None)  # checked when the policy says
        if want is not None and int(want) != self.observer.size:
            raise PolicyError(f"background policy {getattr(policy, 'name', policy)!r} expects observations of size "
                              f"{want}; its options {self.options} give {self.observer.size}")
        self.navigation = navigation
        self.mask = np.asarray(background_mask, bool)
        self.dt_s = float(dt_s)
        self._sim = None
        self._next_step = 0
        self._intents = None

    def __call__(self, sim):
        st = sim.state
        k = int(round(sim.time_s / self.dt_s))
        if sim is not self._sim:  # a new episode (the environment makes a simulator per reset)
            self._sim, self._next_step = sim, 0
        if k >= self._next_step:
            self._intents = self._decide(st)
            self._next_step = k + self.frame_skip
        intents = self._intents
        if self.heading_target == "intent":
            return intents.copy()  # the environment takes θ_d from the intent
        heading = st.heading_rad.copy()
        idx = (self.mask & st.active).nonzero()[0]
        if idx.size:
            heading[idx] = facing_headings(self.navigation, sim, idx)
        return intents.copy(), heading

    def _decide(self, st) -> np.ndarray:
        """World-frame intents (N, 2) of the active background pedestrians at this decision."""
        intents = np.zeros((st.n, 2))
        idx = (self.mask & st.active).nonzero()[0]
        if idx.size == 0:
            return intents
        obs, _ = self.observer.build(st, idx)
        act = np.asarray(self.policy.actions(obs), dtype=np.float64)
        if act.shape != (idx.size, 2):
            raise PolicyError(f"background policy returned actions of shape {act.shape}, expected ({idx.size}, 2)")
        bad = ~(np.abs(act) <= self.action_max_m_s).all(axis=1)  # also true for NaN
        if bad.any():
            rows = np.flatnonzero(bad)
            raise PolicyError(f"background policy gave pedestrians {idx[rows[:10]].tolist()} actions outside its "
                              f"Box(-{self.action_max_m_s:g}, {self.action_max_m_s:g}) m/s: {act[rows[:3]].tolist()}; "
                              "nothing is clipped")
        if self.observer.frame == "egocentric":
            theta = st.heading_rad[idx]
            act = to_world_frame(act, np.cos(theta), np.sin(theta))
        intents[idx] = act
        return intents
