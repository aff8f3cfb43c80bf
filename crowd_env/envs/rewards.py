"""Rewards of the crowd environment.

A reward function has the signature ``reward_fn(env, agent_ids, info) -> rewards``: ``agent_ids`` is
the list of agents that acted this step (live at its start), ``info`` a dict of arrays aligned with
it (see :data:`REWARD_INFO_KEYS`), and the result a sequence of ``len(agent_ids)`` finite numbers
(or a dict agent -> number). Every quantity covers the whole environment step (all ``frame_skip``
simulator steps).
"""
from __future__ import annotations

from crowd_env.errors import InputError

from dataclasses import dataclass

import numba as nb
import numpy as np

from ..core.checks import check_number

__all__ = ["DefaultReward", "REWARD_INFO_KEYS"]

REWARD_INFO_KEYS = {
    "agent_index": "(n,) int: pedestrian index of each agent (agent 'ped_i' has index i)",
    "progress_s": "(n,) T_before − T_after: decrease of the travel time to the nearest exit, s of travel at the "
                  "field's speed (1 m/s: m along the geodesic)",
    "travel_time_before_s": "(n,) T at the start of the step",
    "travel_time_s": "(n,) T at the end of the step (0 once in an exit)",
    "contact_percussion_kg_m_s": "(n,) sum of |normal percussion| over all contacts of the agent this step, kg m/s",
    "n_contacts": "(n,) number of contacts with a non-zero percussion (each simulator step counted)",
    "speed_m_s": "(n,) speed at the end of the step",
    "exited": "(n,) bool: the agent left through an exit this step",
    "dt_s": "float: simulated duration of the step (frame_skip × dt)",
}


@dataclass(frozen=True)
class DefaultReward:
    """r = progress_weight × (T_before − T_after) − collision_weight × P − time_cost_per_s × Δt
    (+ exit_bonus on the step the agent leaves).

    P is the sum of the normal percussions (kg m/s) the agent received in contacts this step
    (impacts and the non-penetration projection), T the eikonal travel time in s, Δt the step's
    simulated duration. With the defaults, a typical impact in a dense crowd (~20 kg m/s) costs about
    0.2 s of travel, standing still costs 0.1 per simulated second and walking at 1.34 m/s along the
    geodesic earns about 1.24 per second. Summed over an episode, the progress term telescopes to
    T_start − T_end (the exit bonus and time cost make leaving early pay).
    """

    progress_weight: float = 1.0
    collision_weight: float = 0.01
    time_cost_per_s: float = 0.1
    exit_bonus: float = 1.0

    def __post_init__(self):
        for name in ("progress_weight", "collision_weight", "time_cost_per_s", "exit_bonus"):
            check_number(f"DefaultReward.{name}", getattr(self, name), error=InputError)

    def __call__(self, env, agent_ids, info) -> np.ndarray:
        return _default_reward(info["progress_s"], info["contact_percussion_kg_m_s"], info["exited"],
                               float(self.progress_weight), float(self.collision_weight),
                               float(self.time_cost_per_s) * info["dt_s"], float(self.exit_bonus))


@nb.njit(cache=True)
def _default_reward(progress, percussion, exited, progress_weight, collision_weight, time_cost, exit_bonus):
    """``progress_weight × progress − collision_weight × percussion − time_cost + exit_bonus × exited`` per
    agent, in one compiled loop."""
    out = np.empty(progress.shape[0])
    for a in range(out.shape[0]):
        out[a] = (progress_weight * progress[a] - collision_weight * percussion[a] - time_cost
                  + exit_bonus * (1.0 if exited[a] else 0.0))
    return out
