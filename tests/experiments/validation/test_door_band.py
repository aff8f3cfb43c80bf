"""The door-against-corridor band (crowd_env.experiments.validation.door_band): points from a calibration's
evaluations and a targets.json, failed points named and never drawn, the experiment's own figures."""
from __future__ import annotations

import json

import pytest

from crowd_env.analysis.figures import pyplot
from crowd_env.errors import InputError
from crowd_env.experiments.validation import door_band
from crowd_env.experiments.validation.door_band import BAND_FIGURES, DOOR, ENTRANCE, QUEUE, band_points, write_band


def _figures(door, queue, entrance):
    return {DOOR: door, QUEUE: queue, ENTRANCE: entrance, "speed_m_s uo-180-180-180": 1.0}


@pytest.fixture()
def files(tmp_path):
    evaluations = tmp_path / "evaluations.jsonl"
    entries = [{"values": {"A": 200.0, "B": 0.3}, "failed_point": False, "figures": _figures(1.8, 3.2, 1.5)},
               {"values": {"A": 250.0, "B": 0.35}, "failed_point": True, "figures": {}},
               {"values": {"A": 300.0, "B": 0.4}, "failed_point": False, "figures": {DOOR: 1.7}}]
    evaluations.write_text("\n".join(json.dumps(e) for e in entries) + "\n")
    targets = tmp_path / "targets.json"
    targets.write_text(json.dumps({"figures": {"calibrated": _figures(1.95, 4.3, 0.9), "joint": _figures(1.82, 3.3, 1.34)}}))
    return evaluations, targets


def test_points_carry_every_figure_and_the_others_are_named_with_their_reason(files):
    points, missing = band_points(files)
    assert [p["label"] for p in points] == ["A=200, B=0.3", "calibrated", "joint"]
    assert points[1][QUEUE] == 4.3 and set(BAND_FIGURES) <= set(points[0])
    assert [(label, "failed" in reason) for _, label, reason in missing] == [("A=250, B=0.35", True),
                                                                            ("A=300, B=0.4", False)]
    assert QUEUE in missing[1][2] and ENTRANCE in missing[1][2]  # the absent figures are named


def test_the_experiment_is_the_shipped_rows():
    exp = door_band._experiment()
    assert exp == {DOOR: pytest.approx(1.90, abs=0.005), QUEUE: pytest.approx(2.45, abs=0.005),
                   ENTRANCE: pytest.approx(1.64, abs=0.005)}


def test_write_band_writes_the_table_and_the_figure(files, tmp_path):
    paths, missing = write_band(tmp_path / "out", files, highlight=("joint",))
    lines = paths[0].read_text().splitlines()
    assert lines[0] == "source,label,door_js_per_m_s,queue_density_per_m2,entrance_flow_per_s" and len(lines) == 4
    assert paths[1].stat().st_size > 10_000 and len(missing) == 2


def test_unreadable_inputs_are_refused_by_name(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        band_points([tmp_path / "absent.jsonl"])
    old = tmp_path / "targets.json"
    old.write_text(json.dumps({"objective": {}}))
    with pytest.raises(InputError, match="without figures"):
        band_points([old])
    bad = tmp_path / "other.jsonl"
    bad.write_text('{"x": 1}\n')
    with pytest.raises(InputError, match="line 1: not a calibration evaluation"):
        band_points([bad])
    with pytest.raises(InputError, match="no point"):
        door_band.band_figure([], tmp_path / "x.png")


def test_a_virtual_experiments_table_gives_its_point_labelled_by_its_folder(tmp_path):
    folder = tmp_path / "virtual_joint"
    folder.mkdir()
    rows = ["experiment,case,quantity,model",
            "bottleneck,\"b = 1.0 m, N = 60\",J_s (1/(m s)),1.82",
            "bottleneck,\"b = 1.0 m, N = 60\",speed inside (m/s),1.27",
            "corridor,\"uo-180-180-095 (entrance 1.80 m, exit 0.95 m, N = 159)\",density (1/m²),3.33",
            "corridor,\"uo-070-180-180 (entrance 0.70 m, exit 1.80 m, N = 111)\",exit flow (1/s),1.34",
            "corridor,\"uo-070-180-180 (entrance 0.70 m, exit 1.80 m, N = 111)\",density (1/m²),0.55"]
    (folder / "virtual_experiments.csv").write_text("\n".join(rows) + "\n")
    points, missing = band_points([folder / "virtual_experiments.csv"])
    assert not missing and points[0]["label"] == "virtual_joint"
    assert (points[0][DOOR], points[0][QUEUE], points[0][ENTRANCE]) == (1.82, 3.33, 1.34)
    (folder / "virtual_experiments.csv").write_text("\n".join(rows[:3]) + "\n")  # no corridor runs: named, not drawn
    points, missing = band_points([folder / "virtual_experiments.csv"])
    assert not points and QUEUE in missing[0][2]
    (folder / "virtual_experiments.csv").write_text("a,b\n1,2\n")
    with pytest.raises(InputError, match="not a table of crowd-virtual-experiments"):
        band_points([folder / "virtual_experiments.csv"])


def test_each_calibration_is_a_family_of_its_own_named_by_its_folder(files, tmp_path, monkeypatch):
    evaluations, targets = files
    other = tmp_path / "calibration_vision" / "optimise" / "evaluations.jsonl"
    other.parent.mkdir(parents=True)
    other.write_text(json.dumps({"values": {"T": 1.0}, "failed_point": False, "figures": _figures(1.5, 2.6, 0.9)}) + "\n")
    assert door_band.calibration_name(other) == "calibration_vision"
    assert door_band.calibration_name(evaluations) == tmp_path.name  # not under optimise/: its own folder
    drawn = {}

    def keep(fig, path):
        drawn["fig"] = fig
        return path

    monkeypatch.setattr(door_band, "save_figure", keep)
    points, _ = band_points([evaluations, other, targets])
    door_band.band_figure(points, tmp_path / "band.png")
    ax = drawn["fig"].axes[0]
    names = [t.get_text() for t in ax.get_legend().get_texts()]
    assert names == [f"calibration {tmp_path.name}", "calibration calibration_vision", "presets and tables",
                     "experiments"]
    offsets = [c.get_offsets() for c in ax.collections]
    assert [len(o) for o in offsets[:3]] == [1, 1, 2]  # each family holds its own points, the presets together
    assert tuple(offsets[1][0]) == (2.6, 1.5)
    from matplotlib.colors import to_rgba

    colours = [tuple(c.get_facecolor()[0]) for c in ax.collections[:2]]
    assert colours[0] != colours[1] and to_rgba("C3") not in colours  # two families; C3 is the highlight's
    pyplot().close(drawn["fig"])
