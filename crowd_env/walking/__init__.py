"""The walking model of Kabalan et al. (2016): where pedestrians want to go and what pushes them apart.

``navigation``: the eikonal travel time and desired direction (Eq. 11-13); ``social_force``: Helbing's
anisotropic social repulsion (Eq. 16); ``vision`` and ``time_to_collision``: two additions to the paper, off by
default; ``agent``: the calibrated agent combining them into velocity intents for the simulator (Eq. 14-16), and
its parameters (:class:`WalkingParams`, a group beside each kernel); ``model``: :class:`ModelParams`, the core's
physics and the walking parameters paired, by the flat names presets and stored runs use; ``presets``: the named
models. Depends on :mod:`crowd_env.core` only.
"""
from .agent import SocialForceAgent, WalkingParams, baseline_intents
from .model import ModelParams, PhysicsParams
from .navigation import DestinationNavigation, NavigationField
from .presets import DEFAULT_PRESET, PRESETS, Preset, get_preset
from .social_force import social_repulsion, total_social_forces, wall_repulsion

__all__ = ["SocialForceAgent", "WalkingParams", "baseline_intents", "ModelParams", "PhysicsParams",
           "DEFAULT_PRESET", "PRESETS", "Preset", "get_preset", "DestinationNavigation", "NavigationField",
           "social_repulsion", "total_social_forces", "wall_repulsion"]
