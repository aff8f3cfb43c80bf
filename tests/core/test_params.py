"""ModelParams (crowd_env.core.params): bad names and values are refused by name."""
import pytest

from crowd_env.core import ParameterError
from crowd_env.walking import ModelParams


def test_bad_model_params():
    with pytest.raises(ParameterError, match=r"unknown model parameter\(s\): \['dt'\]"):
        ModelParams.from_dict({"dt": 0.01})
    with pytest.raises(ParameterError, match=r"unknown model parameter\(s\): \['kn'\]"):
        ModelParams().replace(kn=1.0)
    with pytest.raises(ParameterError, match="unknown solver 'clarabel'"):
        ModelParams(solver="clarabel")
    with pytest.raises(ParameterError, match="dt_s must be > 0"):
        ModelParams(dt_s=0.0)
    with pytest.raises(ParameterError, match="normal_dissipation_kg must be a finite number"):
        ModelParams(normal_dissipation_kg=float("nan"))
    with pytest.raises(ParameterError, match="tangential_dissipation_kg must be >= 0"):
        ModelParams().replace(tangential_dissipation_kg=-1.0)
    with pytest.raises(ParameterError, match=r"social_anisotropy \(lambda\) must lie in \[0, 1\]"):
        ModelParams(social_anisotropy=1.5)
    with pytest.raises(ParameterError, match="rotation must be True or False"):
        ModelParams(rotation="yes")
    with pytest.raises(ParameterError, match="unknown model parameter"):
        ModelParams(extra={"foo": 1})
    assert ModelParams.from_dict({"dt_s": 0.005}).dt_s == 0.005
    assert ModelParams().replace(solver="cvxpy").solver == "cvxpy"
