"""The step's stage list (crowd_env.core.step.STAGES) is the order a staged step runs and times its stages."""
import numpy as np

from crowd_env.core import CrowdState, Simulator
from crowd_env.walking import ModelParams
from crowd_env.core.step import STAGES


def test_staged_step_times_the_documented_stages_in_order():
    st = CrowdState.create([[0.0, 0.0], [0.465, 0.0]], velocity_m_s=[[1.0, 0.0], [0.0, 0.0]], radius_m=0.23)
    sim = Simulator(st, params=ModelParams(), profile=True)
    res = sim.step(np.array([[1.0, 0.0], [0.0, 0.0]]))
    assert tuple(res.timings_s) == STAGES
    assert sim.n_staged_steps == 1 and res.contact_i.size == 1  # the two collided within the step
