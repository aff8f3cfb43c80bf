"""The reference policies (baselines.reference_policies): what as_policy makes of each kind of spec."""
import pytest

from baselines.reference_policies import CalibratedPolicy, CallablePolicy, RandomPolicy, as_policy


def test_as_policy_specs():
    assert isinstance(as_policy("baseline"), CalibratedPolicy)
    assert isinstance(as_policy("random"), RandomPolicy)
    assert isinstance(as_policy(lambda o: o[:, :2]), CallablePolicy)
    with pytest.raises(ValueError, match="unknown policy"):
        as_policy("genius")
    with pytest.raises(TypeError):
        as_policy(42)
