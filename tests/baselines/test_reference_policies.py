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



def test_a_missing_saved_model_is_named_as_given(tmp_path):
    """Regression (issue 37): a missing model.zip was reported as 'model.zip.zip' (Stable-Baselines3 adds the
    extension when the file is not found)."""
    from baselines.reference_policies import SB3Policy
    from crowd_env.errors import MissingFileError

    path = str(tmp_path / "runs" / "ppo" / "model.zip")
    with pytest.raises(MissingFileError, match=r"no saved SB3 model: '.*model\.zip' does not exist") as info:
        as_policy(path)
    assert ".zip.zip" not in str(info.value) and isinstance(info.value, FileNotFoundError)
    with pytest.raises(MissingFileError, match=r"'.*model' does not exist \(nor '.*model\.zip'\)"):
        SB3Policy(str(tmp_path / "model"))  # SB3's own convention: the extension may be left out
