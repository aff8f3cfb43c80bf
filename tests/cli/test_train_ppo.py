"""crowd-train-ppo's command line (crowd_env.cli.train_ppo): it shows its progress while it trains. (The
training itself: tests/experiments/training/test_ppo.py.)"""
import pytest

from crowd_env.experiments.training.ppo import progress_line


def test_the_command_prints_progress_while_it_trains(tmp_path, capsys):
    """Regression (issue 37): crowd-train-ppo printed nothing between the random policy's score and the end."""
    pytest.importorskip("stable_baselines3")
    from crowd_env.cli.train_ppo import main

    assert main(["--timesteps", "400", "--out", str(tmp_path / "ppo"), "--n-pedestrians", "6", "--max-steps", "20",
                 "--copies", "1", "--n-steps", "32", "--batch-size", "64", "--n-epochs", "1", "--eval-seeds", "5",
                 "--checkpoint-every", "0", "--progress-every", "0"]) == 0
    lines = capsys.readouterr().out.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("training PPO: 0 -> 400 timesteps"))
    during = [line for line in lines[start + 1:] if "/ 400 timesteps" in line]
    assert len(during) >= 2  # one per rollout of 6 slots x 32 steps
    assert lines.index(during[-1]) < next(i for i, line in enumerate(lines) if line.startswith("trained policy"))
    with pytest.raises(SystemExit, match="--progress-every must be >= 0"):
        main(["--progress-every", "-1", "--out", str(tmp_path / "other")])


def test_progress_line():
    line = progress_line(5000, 20000, 0, 10.0, [1.0, 2.0])
    assert line == ("  5000 / 20000 timesteps (25 %), 10 s, about 30 s left; mean per-agent episode return of the "
                    "last 2 episodes 1.500")
    assert "remaining time not known yet" in progress_line(0, 100, 0, 0.0, []) and "no episode finished yet" in \
        progress_line(0, 100, 0, 0.0, [])


@pytest.mark.parametrize("flags, match", [
    (["--width", "0.1"], r"cannot be built: bottleneck width 0.1 m is not wider than a pedestrian"),
    (["--scenario-option", "no_such_option=1"], r"cannot be built: .*no_such_option"),
])
def test_an_environment_the_scenario_refuses_is_one_line_and_writes_nothing(tmp_path, flags, match):
    """Regression (issue 52): crowd-train-ppo --width 0.1 raised a traceback (GeometryError) after writing
    env_config.json into --out."""
    pytest.importorskip("stable_baselines3")
    from crowd_env.cli.train_ppo import main

    out = tmp_path / "ppo"
    with pytest.raises(SystemExit, match=r"^error: the environment to train on " + match):
        main(["--timesteps", "100", "--out", str(out), *flags])
    assert not out.exists()
