"""The calibrated agent's one compiled call per decision (crowd_env.walking.agent.python_decide) and the neighbour
pairs it hands to the step: the pairs are brute force's within pair_radius_m, the simulator keeps them for its
step and for neighbor_pairs, pairs built before the decision are reused (a superset), and the decision is the
compiled agent's (agent_step) to the bit."""
import numpy as np
import pytest

from crowd_env.core.bundles import Bodies, World
from crowd_env.errors import InputError
from crowd_env.scenarios import make_scenario
from crowd_env.walking.agent import SocialForceAgent, agent_step, compiled_agent, pair_radius_m, walking_bundle
from crowd_env.walking.presets import get_preset


def _running_sim(steps=40):
    """The calibrated crowd at b = 1.0 m, N = 30, after ``steps`` steps, and its agent."""
    scenario = make_scenario("seyfried_bottleneck", width_m=1.0, n_pedestrians=30, seed=2)
    sim = scenario.make_simulator(params=get_preset("calibrated").params())
    agent = SocialForceAgent(scenario.navigation())
    for _ in range(steps):
        intents, heading = agent(sim)
        sim.step(intents, desired_heading_rad=heading)
    return sim, agent


def _brute_pairs(sim, radius_m):
    idx = sim.active_index
    pos = sim.state.position_m[idx]
    d = np.linalg.norm(pos[:, None] - pos[None], axis=-1)
    return sorted(zip(*map(np.ndarray.tolist, np.nonzero(np.triu(d <= radius_m, k=1)))))


def test_the_decision_hands_its_pairs_to_the_step():
    sim, agent = _running_sim()
    assert sim.built_pairs()[1] == -1.0  # a new step: none built yet
    intents, heading = agent(sim)
    pairs, radius = sim.built_pairs()
    expected_radius = pair_radius_m(Bodies(*sim.state.array_fields()), sim.active_index, walking_bundle(sim.params))
    assert radius == expected_radius > 0.0
    assert sorted(map(tuple, pairs.tolist())) == _brute_pairs(sim, radius)
    assert sim.neighbor_pairs(radius) is pairs and sim.neighbor_pairs(0.5 * radius) is pairs  # reused, not rebuilt
    with pytest.raises(InputError, match="already covered"):
        sim.keep_pairs(pairs, radius)
    # The compiled agent decides the same, to the bit, and builds the same pairs.
    compiled = compiled_agent(agent.compiled(sim.state.n), sim.params)
    decision = agent_step(Bodies(*sim.state.array_fields()), World(*sim.world_fields()), sim.active_index,
                          compiled.navigation, compiled.walking, sim.time_s)
    np.testing.assert_array_equal(decision.intents_m_s, intents)
    np.testing.assert_array_equal(decision.desired_heading_rad, heading)
    np.testing.assert_array_equal(decision.pairs, pairs)
    assert decision.pair_radius_m == radius
    sim.step(intents, desired_heading_rad=heading)
    assert sim.built_pairs()[1] == -1.0  # kept for one step only


def test_pairs_built_before_the_decision_are_reused():
    """Wider pairs built earlier in the step (an observation's, say) serve the decision as they are (a superset);
    the intents are those decided on the agent's own pairs up to the order of the sums (the kernels filter by
    distance; a wider grid lists the pairs in another order)."""
    sim, agent = _running_sim()
    own_intents, own_heading = agent(sim)
    radius = sim.built_pairs()[1]
    sim2, agent2 = _running_sim()
    wide = sim2.neighbor_pairs(radius + 1.0)
    intents, heading = agent2(sim2)
    kept, kept_radius = sim2.built_pairs()
    assert kept is wide and kept_radius == radius + 1.0
    assert sorted(map(tuple, wide.tolist())) == _brute_pairs(sim2, radius + 1.0)
    np.testing.assert_allclose(intents, own_intents, rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(heading, own_heading, rtol=0.0, atol=1e-12)
