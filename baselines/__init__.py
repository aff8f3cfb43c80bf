"""Policies for crowd_env: the calibrated eikonal + social-force agent and simple reference policies."""
from .social_force import SocialForceAgent

__all__ = ["SocialForceAgent"]
