"""A new scenario is one module and its test: ``tests/scenarios/stadium_gate.py``, registered by its decorator
when imported, is made by name, run and measured at its own line and area with no argument saying which, and
the documentation's lists of scenarios (docs/_ext/generated_lists.py) name it from its module alone."""
import importlib
import sys
from pathlib import Path

from crowd_env.experiments.running.runner import run_scenario
from crowd_env.scenarios import list_scenarios, make_scenario, registry
from crowd_env.walking.agent import SocialForceAgent

ROOT = Path(__file__).resolve().parents[2]


def test_a_new_scenario_is_one_module_and_its_test(monkeypatch):
    monkeypatch.setattr(registry, "_REGISTRY", dict(registry._REGISTRY))  # gone after the test (the soak would
    monkeypatch.setattr(registry, "_ALIASES", dict(registry._ALIASES))  # run every registered scenario)
    monkeypatch.delitem(sys.modules, "tests.scenarios.stadium_gate", raising=False)
    module = importlib.import_module("tests.scenarios.stadium_gate")
    assert {"stadium_gate", "gate"} <= set(list_scenarios()) and module.stadium_gate.__name__ == "stadium_gate"
    sc = make_scenario("gate", n_pedestrians=8, seed=1)
    result = run_scenario(sc, SocialForceAgent(sc.navigation()), max_time_s=30.0)  # its own line and area
    assert result.complete and result.n_passed == result.n_evacuated == 8 and result.specific_flow_per_m_s > 0
    assert list(result.density_per_m2) == ["forecourt"] and result.lateral_positions_m.size == 0
    monkeypatch.syspath_prepend(str(ROOT / "docs" / "_ext"))
    from generated_lists import automodules, scenario_table, tree_lines

    folder = Path(module.__file__).parent
    assert "| `stadium_gate` (`gate`) | A new scenario as a contributor writes it: this one module" in \
        scenario_table(folder, "tests.scenarios")
    assert tree_lines(folder).startswith("    stadium_gate.py                 a new scenario as a contributor writes")
    assert ".. automodule:: tests.scenarios.stadium_gate\n" in automodules(folder, "tests.scenarios")


def test_a_scenario_measures_only_lines_and_areas_its_geometry_has():
    import pytest

    from crowd_env.scenarios import Measurement, ScenarioError

    sc = make_scenario("seyfried_bottleneck", n_pedestrians=20)
    assert sc.measurement == Measurement("bottleneck", ("front", "inside"), "inside")
    assert make_scenario("juelich_corridor").measurement == Measurement("exit", ("measurement",))
    for bad, match in ((Measurement("exit"), "line 'exit'"), (Measurement(None, ("back",)), "area 'back'"),
                       (Measurement(lane_area="lane"), "area 'lane'")):
        with pytest.raises(ScenarioError, match=match):
            sc.__class__(sc.geometry, sc.position_m, measurement=bad)


def test_the_docs_scenario_table_lists_every_scenario_of_the_package(monkeypatch):
    monkeypatch.syspath_prepend(str(ROOT / "docs" / "_ext"))
    from generated_lists import scenario_table

    table = scenario_table()
    missing = [n for n in list_scenarios() if not n.startswith("rimea_") and f"`{n}`" not in table]
    assert not missing and "| `juelich_corridor` (`uo_corridor`) |" in table, missing
