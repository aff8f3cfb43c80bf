"""The calibrated walking agent of Kabalan et al. (2016): eikonal direction plus social force, as a velocity intent.

Each pedestrian's intent is

    u_int = ‖u_d‖ e_d + (τ/m) Σ f_social,

so that the core's driving force m (u_int − u)/τ equals the paper's driving force (Eq. 14) plus
Helbing's social repulsion (Eq. 16) exactly: with every pedestrian on this agent the simulator runs the
paper's model. e_d comes from the eikonal field (Eq. 11-13, :mod:`crowd_env.walking.navigation`); the
desired heading θ_d of the heading spring-damper (Eq. 15) is the angle of e_d. The environment's
default background policy and the experiments use it; ``baselines.social_force`` names it for users.
"""
from __future__ import annotations

import numba as nb
import numpy as np

from ..core.angles import direction_angles_rad
from .social_force import social_repulsion, total_social_forces


@nb.njit(cache=True)
def baseline_intents(position, radius, index, e_d, desired_speed, tau, mass, heading, pairs, walls, wall_owner,
                     social, strength_n, range_m, anisotropy, cutoff_m, wall_strength_n, wall_range_m):
    """u_int = ‖u_d‖ e_d + (τ/m) Σ f_social (Eq. 14, 16) and θ_d = angle of e_d, in one compiled call.

    ``index`` (n,) active pedestrians, ``e_d`` (n, 2) their desired directions (Eq. 13), ``pairs``
    rows into ``index``. Returns full (N, 2) intents (zero for inactive rows) and (N,) desired
    headings (the current heading for inactive rows). The forces are :func:`social_repulsion`'s
    compiled core, :func:`~crowd_env.walking.social_force.total_social_forces`.
    """
    n = index.shape[0]
    intents = np.zeros((position.shape[0], 2))
    theta_d = heading.copy()
    force = np.zeros((n, 2))
    if social and n:
        pos = np.empty((n, 2))
        rad = np.empty(n)
        for k in range(n):
            pos[k, 0] = position[index[k], 0]
            pos[k, 1] = position[index[k], 1]
            rad[k] = radius[index[k]]
        total_social_forces(pos, rad, e_d, pairs, np.arange(n), walls, wall_owner, strength_n, range_m, anisotropy,
                            cutoff_m, wall_strength_n, wall_range_m, force)
    angles = direction_angles_rad(e_d)
    for k in range(n):
        i = index[k]
        scale = tau[i] / mass[i]
        intents[i, 0] = desired_speed[i] * e_d[k, 0] + scale * force[k, 0]
        intents[i, 1] = desired_speed[i] * e_d[k, 1] + scale * force[k, 1]
        theta_d[i] = angles[k]
    return intents, theta_d


class SocialForceAgent:
    """Policy object: ``agent(sim) -> (intents (N, 2), desired_heading (N,))`` for a :class:`Simulator`.

    ``navigation``: an object with ``direction(points) -> (n, 2)`` (a
    :class:`~crowd_env.walking.navigation.NavigationField`), or, when its ``per_pedestrian`` attribute is
    true, ``direction(points, index)`` (a :class:`~crowd_env.walking.navigation.DestinationNavigation`:
    each pedestrian follows the field of its own destination exit). Social parameters (A, B, λ,
    cut-off, on/off) are read from the simulator's :class:`~crowd_env.core.params.ModelParams`.
    """

    def __init__(self, navigation):
        self.navigation = navigation

    def desired_direction(self, sim, index=None) -> np.ndarray:
        """e_d (Eq. 13) at the positions of pedestrians ``index`` (default: the active ones)."""
        idx = sim.active_index if index is None else index
        if getattr(self.navigation, "per_pedestrian", False):
            return self.navigation.direction(sim.state.position_m[idx], idx)
        return self.navigation.direction(sim.state.position_m[idx])

    def social_force(self, sim, e_d: np.ndarray) -> np.ndarray:
        """Σ f_social (N) on every active pedestrian, from pedestrians and walls (Eq. 16); compact rows."""
        st = sim.state
        p = sim.params
        idx = sim.active_index
        pos = st.position_m[idx]
        radius = st.radius_m[idx]
        pairs = sim.neighbor_pairs(2.0 * float(radius.max()) + p.social_cutoff_m) if idx.size else np.zeros((0, 2), np.int64)
        return social_repulsion(pos, radius, e_d, pairs, sim.walls, sim.wall_owner, p)

    def __call__(self, sim):
        st = sim.state
        p = sim.params
        idx = sim.active_index
        if idx.size == 0:
            return np.zeros((st.n, 2)), st.heading_rad.copy()
        e_d = self.desired_direction(sim, idx)
        pairs = sim.neighbor_pairs(2.0 * float(st.radius_m[idx].max()) + p.social_cutoff_m) if p.social_forces \
            else np.zeros((0, 2), np.int64)
        return baseline_intents(st.position_m, st.radius_m, idx, e_d, st.desired_speed_m_s, st.tau_s, st.mass_kg,
                                st.heading_rad, pairs, sim.walls, sim.wall_owner, p.social_forces,
                                float(p.social_strength_n), float(p.social_range_m), float(p.social_anisotropy),
                                float(p.social_cutoff_m), float(p.wall_strength_n), float(p.wall_range_m))
