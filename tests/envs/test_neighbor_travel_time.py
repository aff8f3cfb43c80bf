"""The plug-in component ``neighbor_travel_time``: T of each neighbour slot minus the own T, sampled independently."""
from __future__ import annotations

import numpy as np

from crowd_env.envs import crowd_v0
from crowd_env.envs.observations.neighbor_travel_time import PATH


def test_each_slot_holds_how_much_nearer_the_exit_that_neighbour_is():
    env = crowd_v0.parallel_env(scenario_options={"n_pedestrians": 12}, frame_skip=5, max_steps=40,
                                observation_frame="egocentric", n_neighbors=4,
                                observation_components=["neighbors", PATH])
    L = env.observation_layout
    assert list(L) == ["neighbors", "neighbor_mask", "neighbor_travel_time"]
    space = env.observation_space("ped_0")
    obs, _ = env.reset(seed=0)
    for _ in range(3):
        obs, *_ = env.step({a: np.array([0.8, 0.0]) for a in env.agents})
    st = env.sim.state
    _, travel = env.navigation.sample(st.position_m)
    on_floor = np.flatnonzero(st.active)
    checked = 0
    for a, o in obs.items():
        i = int(a[4:])
        assert space.contains(o)
        mask = o[L["neighbor_mask"]]
        offsets = o[L["neighbors"]].reshape(-1, 4)[:, :2]
        c, s = np.cos(st.heading_rad[i]), np.sin(st.heading_rad[i])
        world = np.column_stack([c * offsets[:, 0] - s * offsets[:, 1], s * offsets[:, 0] + c * offsets[:, 1]])
        for slot in range(4):
            got = o[L["neighbor_travel_time"]][slot]
            if mask[slot] == 0:
                assert got == 0.0
                continue
            # the slot's neighbour, found again by its offset (independently of the component's rows)
            j = on_floor[np.argmin(np.hypot(*(st.position_m[on_floor] - st.position_m[i] - world[slot]).T))]
            np.testing.assert_allclose(got, travel[j] - travel[i], rtol=1e-5, atol=1e-5)
            checked += 1
    assert checked > 10
