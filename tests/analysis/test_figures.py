"""The bottleneck figures (Figs. 11-15 analogues) are drawn from run records and summary rows: every figure file
is written, a valid PNG, and the lanes panel's title counts the lanes of the pooled histograms."""
from __future__ import annotations

import numpy as np

from crowd_env.analysis.figures import bottleneck_figures
from crowd_env.analysis.lanes import pooled_lanes


def _rows_and_records():
    rows, records = [], []
    edges = [-0.6, 0.05, 25]  # first edge, bin width, number of edges
    centers = -0.6 + 0.05 * (np.arange(24) + 0.5)
    for n in (20, 60):
        for b in (0.8, 1.2):
            rows.append({"n_pedestrians": n, "width_m": b, "runs": 2, "complete": 1, "stalled": 1, "incomplete": 0,
                         "specific_flow_mean": 1.9, "specific_flow_std": 0.1, "stationary_specific_flow": 1.8,
                         "flow_mean": 1.9 * b, "density_front": 3.5, "density_inside": 1.8, "speed_inside": 1.0})
            for seed in range(2):
                two_lanes = np.exp(-((centers - 0.2) / 0.06) ** 2) + np.exp(-((centers + 0.2) / 0.06) ** 2)
                counts = np.round(100 * (two_lanes if b > 1.0 else np.exp(-(centers / 0.08) ** 2))).astype(int)
                times = list(np.cumsum(np.full(n, 0.5)))
                records.append({"n_pedestrians": n, "width_m": b, "seed": seed, "lane_bin_edges_m": edges,
                                "lane_counts": counts.tolist(), "crossing_times_s": times})
    return rows, records


def test_every_bottleneck_figure_is_written(tmp_path):
    rows, records = _rows_and_records()
    paths = bottleneck_figures(records, rows, tmp_path)
    names = sorted(p.name for p in map(lambda p: tmp_path / p.name, paths))
    assert names == ["fig11_specific_flow.png", "fig12_density.png", "fig13_flow_linear.png", "fig14_lanes.png",
                     "fig15_discharge.png"]
    for p in paths:
        assert (tmp_path / p.name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    wide = [r for r in records if r["n_pedestrians"] == 60 and r["width_m"] == 1.2]
    narrow = [r for r in records if r["n_pedestrians"] == 60 and r["width_m"] == 0.8]
    assert pooled_lanes(wide).n_lanes == 2 and pooled_lanes(narrow).n_lanes == 1


def test_without_crossing_times_the_discharge_diagnostic_is_left_out(tmp_path):
    rows, records = _rows_and_records()
    for r in records:
        r.pop("crossing_times_s")
    assert len(bottleneck_figures(records, rows, tmp_path)) == 4
