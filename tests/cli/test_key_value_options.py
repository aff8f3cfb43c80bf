"""Every ``NAME=VALUE`` option of the commands (``--param``, ``--set``, ``--scenario-option``, ...): given once with
several items or repeated, every item counts; a name given twice is refused, never silently replaced."""
from __future__ import annotations

import importlib

import pytest

from crowd_env.cli.options import key_values
from crowd_env.errors import OptionError

# (module, the arguments before the option, the option)
OPTIONS = [
    ("virtual_experiments", [], "--param"),
    ("virtual_experiments", [], "--pedestrian"),
    ("virtual_experiments", [], "--corridor-option"),
    ("calibrate", ["optimize"], "--param"),
    ("calibrate", ["optimize"], "--x0"),
    ("calibrate", ["optimize"], "--weight"),
    ("reproduce_bottleneck", [], "--param"),
    ("stall_study", [], "--set"),
    ("evaluate", [], "--scenario-option"),
    ("imitate", ["train", "--out", "x"], "--set"),
    ("imitate", ["demonstrations", "--out", "x"], "--policy-option"),
    ("video", ["rollout", "--out", "x"], "--scenario-option"),
    ("fundamental_diagram", [], "--set"),
]


def _parse(module: str, before: list, argv: list):
    return importlib.import_module(f"crowd_env.cli.{module}").build_parser().parse_args(before + argv)


@pytest.mark.parametrize("module,before,flag", OPTIONS)
def test_a_repeated_option_keeps_every_item(module, before, flag):
    dest = flag.lstrip("-").replace("-", "_")
    repeated = getattr(_parse(module, before, [flag, "a=1", flag, "b=2"]), dest)
    together = getattr(_parse(module, before, [flag, "a=1", "b=2"]), dest)
    assert repeated == together == ["a=1", "b=2"]
    assert getattr(_parse(module, before, []), dest) == []


def test_a_name_given_twice_is_refused():
    assert key_values(["a=1", "b=[0.35, 0.5]", "c=text"], "--param expects NAME=VALUE") == \
        {"a": 1, "b": [0.35, 0.5], "c": "text"}
    with pytest.raises(OptionError, match="--param: 'a' is given twice"):
        key_values(["a=1", "b=2", "a=3"], "--param expects NAME=VALUE")
    with pytest.raises(OptionError, match="expects NAME=VALUE, got 'a'"):
        key_values(["a"], "--param expects NAME=VALUE")
    with pytest.raises(OptionError, match="expects NAME=VALUE, got '=1'"):  # a value without a name
        key_values(["=1"], "--param expects NAME=VALUE")
    # one function for every command: the calibration's values as text, the names without blanks around them
    assert key_values(["A = 300 ", "lambda=0.5"], "--x0 expects NAME=VALUE", parse=str.strip) == \
        {"A": "300", "lambda": "0.5"}
    with pytest.raises(OptionError, match="--x0: 'A' is given twice"):
        key_values(["A=300", " A=310"], "--x0 expects NAME=VALUE", parse=str.strip)


def test_the_fundamental_diagram_refuses_a_name_set_twice(tmp_path):
    from crowd_env.cli.fundamental_diagram import main

    for argv in (["--set", "vision_rays=3", "--set", "vision_rays=5"], ["--grid", "vision_rays=3,5", "vision_rays=7"]):
        with pytest.raises(SystemExit, match="'vision_rays' is given twice"):
            main(["--candidates", *argv, "--out", str(tmp_path / "x")])


def test_the_calibration_refuses_a_parameter_start_value_or_weight_given_twice(tmp_path):
    from crowd_env.cli.calibrate import main
    for argv, message in ((["--x0", "A=300", "--x0", "A=310"], "--x0: 'A' is given twice"),
                          (["--objective", "virtual", "--weight", "single_file=0", "--weight", "single_file=1"],
                           "--weight: 'single_file' is given twice"),
                          (["--param", "give_way_share=0.5", "--param", "give_way_share=1"],
                           "--param: 'give_way_share' is given twice")):
        with pytest.raises(SystemExit, match=message):
            main(["optimize", "--out", str(tmp_path / "c"), *argv])
