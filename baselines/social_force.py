"""The calibrated eikonal + social-force agent of Kabalan et al. (2016) (Eq. 11-16), as a baseline policy.

The agent's maths lives in :mod:`crowd_env.walking.agent` (the environment uses it as its default
background policy, and ``crowd_env`` never imports ``baselines``); this module names it among the
baselines users compare against::

    from baselines.social_force import SocialForceAgent
    agent = SocialForceAgent(scenario.navigation())
    intents, desired_heading = agent(sim)
"""
from crowd_env.walking.agent import SocialForceAgent

__all__ = ["SocialForceAgent"]
