"""The environment on the periodic corridor: no exits, so episodes end by truncation at max_steps; observations
see neighbours across the seam at their nearest image; the travel-time progress has no jump at the seam;
rendering works."""
import numpy as np

from crowd_env.envs import crowd_v0


def test_periodic_corridor_env_runs_to_max_steps():
    env = crowd_v0.parallel_env(scenario="periodic_corridor",
                                scenario_options={"density_per_m2": 2.0, "length_m": 6.0, "westbound_fraction": 0.5},
                                max_steps=40, render_mode="rgb_array", observation_frame="world",
                                neighbor_radius_m=2.5, frame_skip=10)
    obs, _ = env.reset(seed=0)
    layout = env.observation_layout
    seen_across = 0
    steps = 0
    while env.agents:
        for a, o in obs.items():
            nb = o[layout["neighbors"]].reshape(-1, 4)
            mask = o[layout["neighbor_mask"]] > 0
            assert mask.any() and np.all(np.hypot(nb[mask, 0], nb[mask, 1]) <= 2.5 + 1e-5)  # nearest images only
        x = env.unwrapped.sim.state.position_m[:, 0].copy()
        obs, rew, term, trunc, info = env.step({a: np.array([0.8, 0.0], np.float32) for a in env.agents})
        steps += 1
        x1 = env.unwrapped.sim.state.position_m[:, 0]
        seen_across += int(np.count_nonzero(np.abs(x1 - x) > 3.0))
        assert np.all(np.abs(list(rew.values())) < 3.0)  # no reward spike of ±L = 6 at a seam crossing
        assert not any(term.values())
    assert steps == 40 and all(trunc.values()) and seen_across > 0
    assert env.render().ndim == 3
    assert env.state().shape == env.state_space.shape


def test_contact_lines_across_the_seam_are_short():
    """A rendered contact between pedestrians on either side of the seam runs to the nearest image (0.4 m),
    not across the whole corridor."""
    from crowd_env.envs.rendering import contact_segments

    pos = np.array([[0.1, 0.0], [9.7, 0.1]])
    contacts = (np.array([0]), np.array([1]), np.array([-1]), np.array([2.0]))
    seg, _ = contact_segments(pos, np.ones(2, bool), np.zeros((0, 4)), contacts, period_m=10.0)
    np.testing.assert_allclose(seg[0], [[0.1, 0.0], [-0.3, 0.1]])
    seg, _ = contact_segments(pos, np.ones(2, bool), np.zeros((0, 4)), contacts)
    np.testing.assert_allclose(seg[0], pos)
