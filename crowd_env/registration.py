"""Gymnasium ids of crowd_env (single-agent views, :class:`crowd_env.envs.gym_single.CrowdSingleAgentEnv`).

``import crowd_env`` makes these ids available to ``gymnasium.make``; to keep that import light,
gymnasium itself is not imported for it: when gymnasium is already loaded the ids are registered at
once, otherwise a one-shot import hook registers them as soon as gymnasium is imported (or call
:func:`register_envs` yourself; it is idempotent).

======================================  ========================================================
id                                      environment
======================================  ========================================================
``crowd_env/Bottleneck-v0``             Seyfried bottleneck, b = 1.0 m, 60 pedestrians; learner ped_0
``crowd_env/BottleneckSmall-v0``        the same with 20 pedestrians (quick experiments)
``crowd_env/BottleneckWide-v0``         b = 1.6 m, 60 pedestrians
``crowd_env/BottleneckGroups-v0``       b = 1.2 m, 40 pedestrians with 4 hand-holding pairs and
                                        2 triples (scenario ``bottleneck_groups``)
``crowd_env/CorridorBidirectional-v0``  10 m x 3 m corridor, 10 pedestrians walking each way, each
                                        to its own exit (ped_0 walks east)
``crowd_env/RoomPillar-v0``             8 m x 6 m room, 30 pedestrians, 1 m door, a pillar in
                                        front of it
``crowd_env/Corner90-v0``               2 m wide L-shaped corridor (legs 8 m and 6 m), 20
                                        pedestrians
``crowd_env/Custom-v0``                 a user geometry (scenario ``"polygon"``); by default an
                                        example 8 m x 6 m room with a square hole and a door, 20
                                        pedestrians: pass your own ``scenario_options`` (see
                                        :func:`crowd_env.scenarios.polygon.scenario_from_polygon`)
======================================  ========================================================

All use decisions every 0.1 s (``frame_skip=10``) and truncate after 60 s (``max_steps=600``, also the
spec's ``max_episode_steps``); keyword arguments of ``gymnasium.make`` override any option
(``scenario_options`` as a whole). ``gymnasium.make_vec(id, num_envs)`` builds the native vector environment
(the ids' ``vector_entry_point``, :func:`crowd_env.envs.vector.gym_vector_env`: slot c is the learner of
copy c, stepped in arrays, Gymnasium's same-step autoreset); ``vectorization_mode="sync"`` or ``"async"``
still gives Gymnasium's own vector environments of the single-agent view.
"""
from __future__ import annotations

import importlib.abc
import importlib.util
import sys

__all__ = ["ENV_IDS", "register_envs"]

_ENTRY = "crowd_env.envs.gym_single:CrowdSingleAgentEnv"
_VECTOR_ENTRY = "crowd_env.envs.vector:gym_vector_env"
_COMMON = {"frame_skip": 10, "max_steps": 600}
ENV_IDS = {
    "crowd_env/Bottleneck-v0": {"scenario": "seyfried_bottleneck",
                                "scenario_options": {"width_m": 1.0, "n_pedestrians": 60}, **_COMMON},
    "crowd_env/BottleneckSmall-v0": {"scenario": "seyfried_bottleneck",
                                     "scenario_options": {"width_m": 1.0, "n_pedestrians": 20}, **_COMMON},
    "crowd_env/BottleneckWide-v0": {"scenario": "seyfried_bottleneck",
                                    "scenario_options": {"width_m": 1.6, "n_pedestrians": 60}, **_COMMON},
    "crowd_env/BottleneckGroups-v0": {"scenario": "bottleneck_groups", "scenario_options": {}, **_COMMON},
    "crowd_env/CorridorBidirectional-v0": {"scenario": "corridor_bidirectional", "scenario_options": {}, **_COMMON},
    "crowd_env/RoomPillar-v0": {"scenario": "room_pillar", "scenario_options": {}, **_COMMON},
    "crowd_env/Corner90-v0": {"scenario": "corner_90", "scenario_options": {}, **_COMMON},
    "crowd_env/Custom-v0": {"scenario": "polygon", "scenario_options": {
        "walkable_area": "POLYGON ((0 0, 8 0, 8 6, 0 6, 0 0), (4 2.5, 5 2.5, 5 3.5, 4 3.5, 4 2.5))",
        "exits": ["LINESTRING (8 2.5, 8 3.5)"], "spawn_area": "POLYGON ((0 0, 3 0, 3 6, 0 6, 0 0))",
        "n_pedestrians": 20}, **_COMMON},
}
_done = False


def register_envs() -> None:
    """Register :data:`ENV_IDS` with gymnasium (idempotent)."""
    global _done
    if _done:
        return
    import gymnasium

    for env_id, kwargs in ENV_IDS.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(id=env_id, entry_point=_ENTRY, vector_entry_point=_VECTOR_ENTRY,
                               max_episode_steps=kwargs["max_steps"], kwargs=kwargs)
    _done = True


class _RegisterOnImport(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds ``gymnasium`` with the other finders, lets it load, then registers the ids (once)."""

    _busy = False

    def find_spec(self, fullname, path=None, target=None):
        if fullname != "gymnasium" or self._busy:
            return None
        self._busy = True
        try:
            spec = importlib.util.find_spec(fullname)
        finally:
            self._busy = False
        if spec is None or spec.loader is None:
            return None
        self._loader = spec.loader
        spec.loader = self
        return spec

    def create_module(self, spec):
        return self._loader.create_module(spec)

    def exec_module(self, module):
        # Hand the module back to its real loader before running it, and leave sys.meta_path.
        module.__loader__ = self._loader
        if module.__spec__ is not None:
            module.__spec__.loader = self._loader
        if self in sys.meta_path:
            sys.meta_path.remove(self)
        self._loader.exec_module(module)
        try:
            register_envs()
        except Exception:  # pragma: no cover - never break the user's import of gymnasium
            pass


def _install() -> None:
    if "gymnasium" in sys.modules:
        register_envs()
    elif not any(isinstance(f, _RegisterOnImport) for f in sys.meta_path):
        sys.meta_path.insert(0, _RegisterOnImport())


_install()
