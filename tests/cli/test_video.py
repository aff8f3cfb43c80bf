"""crowd-video's command line (crowd_env.cli.video); the videos themselves: tests/experiments/output/test_video.py."""
import pytest

from crowd_env.cli.video import main


def test_a_missing_model_is_named_without_a_doubled_extension(tmp_path):
    """Regression (issue 37): crowd-video rollout --policy runs/ppo/model.zip reported 'model.zip.zip'."""
    with pytest.raises(SystemExit) as info:
        main(["rollout", "--policy", str(tmp_path / "runs" / "ppo" / "model.zip"), "--out", str(tmp_path / "v.gif")])
    assert "no saved SB3 model" in str(info.value) and "model.zip' does not exist" in str(info.value)
    assert ".zip.zip" not in str(info.value)


def test_a_saved_model_is_filmed_on_its_recorded_configuration(tmp_path, capsys):
    """Regression (issue 52): crowd-video rollout --policy MODEL.zip filmed a model trained with 8 walkers at 1.2 m
    among 60 at 1.0 m; it now runs on the env_config.json beside the model, as crowd-evaluate --model does."""
    pytest.importorskip("stable_baselines3")
    from tests.cli import save_tiny_model
    from tests.cli.test_evaluate import RECORDED

    run = tmp_path / "run"
    save_tiny_model(run, {**RECORDED, "scenario_options": {"width_m": 1.2, "n_pedestrians": 4}, "max_steps": 2})
    assert main(["rollout", "--policy", str(run / "model.zip"), "--fps", "10", "--out", str(tmp_path / "v.gif")]) == 0
    out = capsys.readouterr().out
    assert f"video configuration: recorded with the model: {run / 'env_config.json'}" in out
    assert "seyfried_bottleneck(n_pedestrians=4,width_m=1.2)" in out and "at most 0.2 s simulated" in out
    assert "0.20 s simulated" in out and "/4 evacuated" in out
    # a flag given explicitly wins, and is named
    assert main(["rollout", "--policy", str(run / "model.zip"), "--max-time", "0.1", "--fps", "10",
                 "--out", str(tmp_path / "w.gif")]) == 0
    out = capsys.readouterr().out
    assert "overridden by --max-time" in out and "0.10 s simulated" in out and "/4 evacuated" in out
