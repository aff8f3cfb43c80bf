"""crowd-evaluate (crowd_env.cli.evaluate): a saved model is evaluated on the configuration recorded beside it
unless flags say otherwise, and the command says which one it uses."""
import csv
import json

import pytest

from crowd_env.cli.evaluate import build_parser, evaluation_setup, main
from tests.cli import save_tiny_model

RECORDED = {"scenario": "seyfried_bottleneck", "scenario_options": {"width_m": 1.0, "n_pedestrians": 4},
            "controlled": "all", "frame_skip": 10, "max_steps": 3, "n_neighbors": 6, "n_rays": 8,
            "reseed_scenario": None, "observation_frame": "world"}


def _setup(*argv):
    return evaluation_setup(build_parser().parse_args(list(argv)))


def test_a_model_is_evaluated_on_its_recorded_configuration_unless_told_otherwise(tmp_path):
    (tmp_path / "env_config.json").write_text(json.dumps(RECORDED))
    model = str(tmp_path / "model.zip")
    (spec,), options, max_time, source = _setup("--model", model)
    assert spec.scenario == "seyfried_bottleneck" and spec.scenario_options == {"width_m": 1.0, "n_pedestrians": 4}
    assert max_time == pytest.approx(0.3) and options["frame_skip"] == 10 and options["controlled"] == "all"
    assert source == f"recorded with the model: {tmp_path / 'env_config.json'}"
    # explicit flags override the recorded values, and are named
    specs, options, max_time, source = _setup("--model", model, "--widths", "0.9", "1.2", "--max-time", "5",
                                              "--controlled", "2", "--scenario-option", "n_pedestrians=6")
    assert [s.scenario_options for s in specs] == [{"width_m": w, "n_pedestrians": 6} for w in (0.9, 1.2)]
    assert max_time == 5.0 and options["controlled"] == 2
    assert source.endswith("overridden by --scenario-option --widths --max-time --controlled")
    # another scenario starts from its own defaults; --no-recorded-config ignores the file
    (spec,), _, _, _ = _setup("--model", model, "--scenario", "room_pillar")
    assert spec.scenario == "room_pillar" and spec.scenario_options is None
    (spec,), options, max_time, source = _setup("--model", model, "--no-recorded-config")
    assert spec.scenario_options is None and max_time == 90.0 and "--no-recorded-config" in source
    # no model: the command's defaults
    (spec,), options, max_time, source = _setup()
    assert spec.scenario == "seyfried_bottleneck" and max_time == 90.0 and source == "the command's defaults and flags"


def test_the_command_prints_and_uses_the_recorded_configuration(tmp_path, capsys):
    """Regression (issue 37): crowd-evaluate --model evaluated 60 pedestrians for 90 s whatever the model was
    trained on."""
    pytest.importorskip("stable_baselines3")
    run = tmp_path / "run"
    save_tiny_model(run, RECORDED)
    assert main(["--model", str(run / "model.zip"), "--policies", "zero", "--seeds", "0",
                 "--out", str(tmp_path / "eval")]) == 0
    out = capsys.readouterr().out
    assert f"evaluation configuration: recorded with the model: {run / 'env_config.json'}" in out
    assert "seyfried_bottleneck(n_pedestrians=4,width_m=1.0)" in out and "at most 0.3 s simulated" in out
    assert "95 % intervals of the means" in out
    with open(tmp_path / "eval" / "results.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["policy"] for r in rows] == ["zero", "model"]
    assert all(r["n_pedestrians"] == "4" and float(r["simulated_time_s"]) == pytest.approx(0.3) for r in rows)
    summary = (tmp_path / "eval" / "summary.txt").read_text()
    assert summary.startswith("evaluation configuration: recorded with the model")


def test_a_missing_model_is_named_without_a_doubled_extension(tmp_path):
    missing = str(tmp_path / "runs" / "ppo" / "model.zip")
    with pytest.raises(SystemExit, match=r"no saved SB3 model: '.*model\.zip' does not exist") as info:
        main(["--model", missing, "--policies", "zero", "--out", str(tmp_path / "eval")])
    assert ".zip.zip" not in str(info.value)
