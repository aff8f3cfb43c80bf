"""The walking model of Kabalan et al. (2016): where pedestrians want to go and what pushes them apart.

``navigation``: the eikonal travel time and desired direction (Eq. 11-13); ``social_force``: Helbing's
anisotropic social repulsion (Eq. 16); ``agent``: the calibrated agent combining them into velocity
intents for the simulator (Eq. 14-16). Depends on :mod:`crowd_env.core` only.
"""
from .agent import SocialForceAgent, baseline_intents
from .navigation import DestinationNavigation, NavigationField
from .social_force import social_repulsion, total_social_forces, wall_repulsion

__all__ = ["SocialForceAgent", "baseline_intents", "DestinationNavigation", "NavigationField", "social_repulsion",
           "total_social_forces", "wall_repulsion"]
