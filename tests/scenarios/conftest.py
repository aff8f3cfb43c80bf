"""Shared helpers of the scenario tests: the default pedestrian radius, a run of a scenario on the
calibrated agent, and the exit each pedestrian left through."""
import numpy as np

from baselines import SocialForceAgent
from crowd_env.walking import ModelParams


R = 0.23


def run_baseline(scenario, max_time_s, params=None, on_step=None):
    """Everyone on the calibrated agent until all left or ``max_time_s``; returns the simulator."""
    sim = scenario.make_simulator(params=ModelParams() if params is None else params)
    agent = SocialForceAgent(scenario.navigation())
    while sim.state.active.any() and sim.time_s < max_time_s:
        intents, heading = agent(sim)
        sim.step(intents, desired_heading_rad=heading)
        if on_step is not None:
            on_step(sim)
    return sim


def exit_of(scenario, sim):
    """Index of the exit each pedestrian left through (positions freeze where they left), -1 if still in."""
    k = scenario.geometry.exit_index(sim.state.position_m)
    return np.where(sim.state.active, -1, k)
