"""A preset's body (Preset.radius_m): the environment and the commands give it to every scenario whose factory takes
a radius, unless the options set one; the presets of Kabalan's body change nothing."""
from __future__ import annotations

import numpy as np
import pytest

from crowd_env.walking import presets
from crowd_env.walking.presets import PRESETS, Preset, get_preset
from crowd_env.scenarios import body_options


@pytest.fixture()
def slim(monkeypatch):
    """A preset of the calibrated model with pedestrians of r = 0.2 m, registered for the test."""
    base = get_preset("calibrated")
    preset = Preset("slim_test", dict(base.model), 0.2, "test", radius_m=0.2)
    monkeypatch.setitem(presets.PRESETS, "slim_test", preset)
    return preset


def test_body_options_set_the_radius_only_where_the_factory_takes_one_and_the_options_leave_it():
    assert body_options("juelich_corridor", {"n_pedestrians": 20}, 0.2) == {"n_pedestrians": 20, "radius_m": 0.2}
    assert body_options("juelich_corridor", {"radius_m": 0.25}, 0.2) == {"radius_m": 0.25}
    assert body_options("juelich_corridor", None, None) == {}
    # Kabalan's body: nothing to pass; only the joint calibration freed the body
    assert {name for name, p in PRESETS.items() if p.body_radius_m is not None} == {"joint"}


def test_every_presets_field_is_the_point_field_or_its_own_bodys_configuration_space():
    """A configuration-space field (Eq. 11-13 with walls inflated by r) is only right for the body it was built for."""
    for name, p in PRESETS.items():
        assert p.navigation_clearance_m in (0.0, p.radius_m), name


def test_the_environment_builds_its_scenario_with_the_presets_body(slim):
    from crowd_env.envs import crowd_v0

    env = crowd_v0.parallel_env(scenario="juelich_corridor", scenario_options={"n_pedestrians": 12}, preset="slim_test")
    env.reset(seed=0)
    assert np.all(env.sim.state.radius_m == 0.2)
    own = crowd_v0.parallel_env(scenario="juelich_corridor", scenario_options={"n_pedestrians": 12, "radius_m": 0.22},
                                preset="slim_test")
    own.reset(seed=0)
    assert np.all(own.sim.state.radius_m == 0.22)  # the options' own radius wins
    default = crowd_v0.parallel_env(scenario="juelich_corridor", scenario_options={"n_pedestrians": 12})
    default.reset(seed=0)
    assert np.all(default.sim.state.radius_m == 0.23)


def test_the_bottleneck_commands_take_the_presets_body_unless_given(slim):
    from crowd_env.cli.options import config_of, model_params_from_args
    from crowd_env.cli.reproduce_bottleneck import build_parser

    args = build_parser().parse_args(["--preset", "slim_test"])  # the parser's choices are the presets now
    geometry = config_of(args, model_params_from_args(args))["geometry"]
    assert geometry["radius_m"] == 0.2 and geometry["navigation_clearance_m"] == 0.2
    args.radius = 0.21
    assert config_of(args, model_params_from_args(args))["geometry"]["radius_m"] == 0.21


def test_a_radius_given_on_the_command_line_moves_the_field_of_a_body_with_it(slim):
    """crowd-calibrate targets --radius R (and every command reading config_of) ran the bottleneck with R-disks in
    the field of the preset's body; the field now follows the body as with_body moves it for the virtual
    experiments, unless --navigation-clearance is given or the preset's field is the point field."""
    from crowd_env.cli.options import config_of, model_params_from_args
    from crowd_env.cli.reproduce_bottleneck import build_parser
    from crowd_env.experiments.validation.calibration.tasks import with_body

    def geometry(*argv):
        args = build_parser().parse_args(list(argv))
        return config_of(args, model_params_from_args(args))["geometry"]

    g = geometry("--preset", "vision", "--radius", "0.179")
    assert (g["radius_m"], g["navigation_clearance_m"]) == (0.179, 0.179)
    moved = with_body({"geometry": geometry("--preset", "vision")}, 0.179)["geometry"]  # the virtual experiments' way
    assert moved["navigation_clearance_m"] == g["navigation_clearance_m"]
    assert geometry("--preset", "vision", "--radius", "0.179", "--navigation-clearance", "0.1")[
        "navigation_clearance_m"] == 0.1
    assert geometry("--preset", "paper", "--radius", "0.2")["navigation_clearance_m"] == 0.0  # a point field
    assert geometry("--preset", "slim_test", "--radius", "0.21")["navigation_clearance_m"] == 0.21
