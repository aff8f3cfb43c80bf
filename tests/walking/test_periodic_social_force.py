"""Social repulsion (Eq. 16) and the calibrated agent's intents in a periodic corridor: across the seam x = 0 ≡ L
they equal those of the same crowd away from it (and the dense non-periodic reference)."""
import numpy as np
import pytest

from crowd_env.core.neighbors import grid_pairs
from crowd_env.walking.presets import DEFAULT_PRESET, get_preset
from crowd_env.walking.social_force import social_forces_dense_reference, social_repulsion

L = 10.0


def _crowd(seed=0, n=16):
    """``n`` non-overlapping disks of radius 0.23 m in x ∈ [2.5, 7.5] m, y ∈ [-0.65, 0.65] m, with desired directions."""
    rng = np.random.default_rng(seed)
    pos = []
    while len(pos) < n:
        p = rng.uniform([2.5, -0.65], [7.5, 0.65])
        if all(np.hypot(*(p - q)) > 0.47 for q in pos):
            pos.append(p)
    e = rng.normal(size=(n, 2))
    return np.array(pos), np.full(n, 0.23), e / np.linalg.norm(e, axis=1, keepdims=True)


def _forces(pos, radius, e_d, params, period):
    walls = np.array([[-1.0, -0.9, L + 1.0, -0.9], [-1.0, 0.9, L + 1.0, 0.9]])
    from crowd_env.core.segments import endpoint_owners

    pairs = grid_pairs(pos, np.arange(pos.shape[0], dtype=np.int64), 2 * 0.23 + params.social_cutoff_m, period)
    return social_repulsion(pos, radius, e_d, pairs, walls, endpoint_owners(walls), params.walking.social,
                            params.walking.wall_social, period_m=period), pairs


@pytest.mark.parametrize("shift", [-5.0, -3.3, 1.7 + 3.0])
def test_social_forces_across_the_seam(shift):
    """The crowd in the middle of the strip, and moved by ``shift`` and wrapped so that it straddles the seam:
    the same neighbour pairs and the same forces on everybody (to 1e-9 N of forces up to a few hundred N), both
    equal to the dense non-periodic reference of the crowd in the middle."""
    params = get_preset(DEFAULT_PRESET).params()
    pos, radius, e_d = _crowd()
    moved = pos.copy()
    moved[:, 0] = np.mod(moved[:, 0] + shift, L)
    assert moved[:, 0].min() < 1.0 and moved[:, 0].max() > L - 1.0  # straddles the seam
    away, pairs_away = _forces(pos, radius, e_d, params, L)
    seam, pairs_seam = _forces(moved, radius, e_d, params, L)
    assert sorted(map(tuple, pairs_away.tolist())) == sorted(map(tuple, pairs_seam.tolist()))
    assert np.abs(away).max() > 50.0
    np.testing.assert_allclose(seam, away, rtol=0, atol=1e-9)
    walls = np.array([[-1.0, -0.9, L + 1.0, -0.9], [-1.0, 0.9, L + 1.0, 0.9]])
    ref = social_forces_dense_reference(pos, radius, e_d, walls, params.social_strength_n, params.social_range_m,
                                        params.social_anisotropy, params.social_cutoff_m, params.wall_strength_n,
                                        params.wall_range_m)
    np.testing.assert_allclose(away, ref, rtol=1e-12, atol=1e-9)
    # without the period the crowd across the seam falls apart into two: the pairs across it are lost
    _, pairs_cut = _forces(moved, radius, e_d, params, 0.0)
    assert len(pairs_cut) < len(pairs_away)


def test_agent_intents_across_the_seam():
    """The calibrated agent (e_d from the corridor's fields, Eq. 16 forces, walls) decides the same intents for
    the periodic corridor's crowd and for the same crowd moved by L/2 along the corridor (to 1e-9 m/s)."""
    from crowd_env.scenarios import make_scenario
    from crowd_env.walking.agent import SocialForceAgent

    sc = make_scenario("periodic_corridor", length_m=L, density_per_m2=2.5, westbound_fraction=0.5, seed=4)
    a = sc.make_simulator()
    state = sc.make_state()
    state.position_m[:, 0] += 0.5 * L  # wrapped into [0, L) by the simulator
    b = sc.make_simulator(state)
    agent = SocialForceAgent(sc.navigation())
    ia, ha = agent(a)
    ib, hb = agent(b)
    np.testing.assert_allclose(ib, ia, rtol=0, atol=1e-9)
    np.testing.assert_allclose(hb, ha, rtol=0, atol=1e-12)
    assert np.abs(ia - sc.make_state().desired_speed_m_s[:, None] * np.cos(ha)[:, None] * [1, 0]).max() > 0.01
