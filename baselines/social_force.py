"""The calibrated eikonal + social-force agent of Kabalan et al. (2016), as a policy.

It returns each pedestrian's velocity intent (architecture.md, "The key equivalence")::

    u_int = ‖u_d‖ e_d + (τ/m) Σ f_social,

so that the core's driving force m (u_int − u)/τ equals the paper's driving force (Eq. 14) plus
Helbing's social repulsion (Eq. 16) exactly: with every pedestrian on this agent the environment
runs the paper's model. e_d comes from the eikonal field (Eq. 11-13); the desired heading θ_d of
the heading spring-damper (Eq. 15) is the angle of e_d.
"""
from __future__ import annotations

import numpy as np

from crowd_env.core.forces import social_repulsion


class SocialForceAgent:
    """Policy object: ``agent(sim) -> (intents (N, 2), desired_heading (N,))`` for a :class:`Simulator`.

    ``navigation``: an object with ``direction(points) -> (n, 2)`` (a
    :class:`~crowd_env.core.navigation.NavigationField`), or, when its ``per_pedestrian`` attribute is
    true, ``direction(points, index)`` (a :class:`~crowd_env.core.navigation.DestinationNavigation`:
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
        return social_repulsion(pos, radius, e_d, pairs, sim.walls, sim._wall_owner, p)

    def __call__(self, sim):
        st = sim.state
        idx = sim.active_index
        intents = np.zeros((st.n, 2))
        heading = st.heading_rad.copy()
        if idx.size == 0:
            return intents, heading
        e_d = self.desired_direction(sim, idx)
        u_int = st.desired_speed_m_s[idx, None] * e_d
        if sim.params.social_forces:
            f = self.social_force(sim, e_d)
            u_int += (st.tau_s[idx] / st.mass_kg[idx])[:, None] * f
        intents[idx] = u_int
        heading[idx] = np.arctan2(e_d[:, 1], e_d[:, 0])
        return intents, heading
