"""crowd-video's command line (crowd_env.cli.video); the videos themselves: tests/experiments/output/test_video.py."""
import pytest

from crowd_env.cli.video import main


def test_a_missing_model_is_named_without_a_doubled_extension(tmp_path):
    """Regression (issue 37): crowd-video rollout --policy runs/ppo/model.zip reported 'model.zip.zip'."""
    with pytest.raises(SystemExit) as info:
        main(["rollout", "--policy", str(tmp_path / "runs" / "ppo" / "model.zip"), "--out", str(tmp_path / "v.gif")])
    assert "no saved SB3 model" in str(info.value) and "model.zip' does not exist" in str(info.value)
    assert ".zip.zip" not in str(info.value)
