"""crowd-generalise: a tiny grid end to end (runs, per-geometry folders, resume, table, CSV, figure) and
impossible set-ups refused by name."""
from __future__ import annotations

import csv
import json

import pytest

from crowd_env.cli import generalisation as gen
from crowd_env.cli import reproduce_bottleneck as rb
from crowd_env.experiments.validation.generalisation import geometry_config
from crowd_env.experiments.running.store import config_hash


def test_default_preset_follows_the_reproduction():
    assert gen.build_parser().get_default("preset") == rb.build_parser().get_default("preset")
    args = gen.build_parser().parse_args([])
    n_runs = (len(args.corridor_widths) * len(args.channel_lengths) * len(args.widths) * len(args.sizes)
              * args.seeds)
    assert n_runs >= 300
    assert min(args.corridor_widths) >= 4 and max(args.corridor_widths) <= 8
    assert min(args.channel_lengths) >= 0.4 and max(args.channel_lengths) <= 5
    assert min(args.sizes) >= 20 and max(args.sizes) <= 250
    assert min(args.widths) >= 0.8 and max(args.widths) <= 2.5


def test_tiny_grid_end_to_end_and_resumes(tmp_path, capsys):
    out = tmp_path / "gen"
    argv = ["--corridor-widths", "5", "--channel-lengths", "0.6", "1.5", "--widths", "0.9", "1.3", "1.8",
            "--sizes", "8", "--seeds", "1", "--jobs", "1", "--max-time", "60", "--out", str(out)]
    assert gen.main(argv) == 0
    text = capsys.readouterr().out
    assert "== corridor 5 m, channel 0.6 m" in text and "== corridor 5 m, channel 1.5 m" in text
    assert "N = 8: J(b) = " in text and "residual norm" in text
    assert "runs: 6; complete 6, stalled 0, incomplete at the time limit 0; smallest gap below -1 mm" in text
    rows = list(csv.DictReader(open(out / "generalisation.csv")))
    assert len(rows) == 6
    assert {(r["corridor_width_m"], r["channel_length_m"]) for r in rows} == {("5.0", "0.6"), ("5.0", "1.5")}
    for col in ("complete", "stalled", "min_gap_m", "specific_flow_per_m_s", "stall_time_s"):
        assert col in rows[0]
    assert (out / "generalisation_specific_flow.png").stat().st_size > 1000
    # each geometry is a crowd-bottleneck output folder for that geometry
    folder = out / "corridor5m_channel0.6m"
    config = json.loads((folder / "config.json").read_text())
    args = rb.build_parser().parse_args(["--corridor-width", "5", "--channel-length", "0.6", "--max-time", "60"])
    assert config_hash(config) == config_hash(rb.config_of(args, rb.model_params_from_args(args)))
    record = folder / "runs" / "b0.900_n8_s0.json"
    stamp = record.stat().st_mtime_ns
    assert gen.main(argv + ["--no-figures"]) == 0  # resumed: nothing rerun
    assert record.stat().st_mtime_ns == stamp
    other = next(p for p in sorted(rb.PRESETS) if p != gen.build_parser().get_default("preset"))
    with pytest.raises(SystemExit, match="different configuration"):
        gen.main(argv + ["--preset", other])


@pytest.mark.parametrize("extra, match", [
    (["--corridor-widths", "1.0", "--widths", "1.2"],
     r"corridor 1 m, channel 2 m, b = 1.2 m, N = 8: .*larger than the corridor"),
    (["--widths", "0.4"], r"b = 0.4 m, N = 8: bottleneck width 0.4 m is not wider than a pedestrian"),
    (["--corridor-widths", "0.1", "--widths", "0.05"], r"impossible set-up: corridor 0.1 m"),
    (["--sizes", "1"], r"--sizes must be distinct and >= 2"),
])
def test_impossible_setups_are_refused_by_name_before_anything_runs(tmp_path, extra, match):
    out = tmp_path / "gen"
    base = {"--corridor-widths": ["5"], "--channel-lengths": ["2"], "--widths": ["1.0"], "--sizes": ["8"]}
    for i in range(0, len(extra), 2):
        base[extra[i]] = [extra[i + 1]]
    argv = [a for k, v in base.items() for a in [k, *v]] + ["--seeds", "1", "--jobs", "1", "--out", str(out)]
    with pytest.raises(SystemExit, match=match):
        gen.main(argv)
    assert not out.exists()


def test_large_crowd_fits_a_narrow_corridor():
    """N = 250 in a 4 m corridor: 13 holding sections of 20, the corridor long enough for them."""
    from crowd_env.scenarios import make_scenario

    config = geometry_config(gen.build_parser().get_default("preset"), 4.0, 5.0, 300.0)
    sc = make_scenario("seyfried_bottleneck", width_m=2.5, n_pedestrians=250, seed=0, **config["geometry"])
    assert sc.n_pedestrians == 250 and len(sc.metadata["holding_sections"]) == 13
    assert sc.metadata["corridor_length_m"] == pytest.approx(2.24 + 13 * 1.515)
    assert sc.position_m[:, 0].min() > -sc.metadata["corridor_length_m"]
