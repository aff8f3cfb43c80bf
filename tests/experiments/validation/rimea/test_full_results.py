"""The kept result of the full RiMEA test 4 (``docs/validation/rimea/full``, written by ``crowd-rimea 4``) and what
the verification page says of it: the suite reads it back with the full version's settings, the shared
conditions hold, the verdict is the one the page explains, and the page's table and cost are that result's."""
import math
import os

import pytest

from crowd_env.experiments.validation.rimea.suite import OUTSIDE_LIMIT_M, load_test_result
from tests.conftest import ROOT

FULL = os.path.join("docs", "validation", "rimea", "full")
PAGE = os.path.join(ROOT, "docs", "validation", "rimea.md")


@pytest.fixture(scope="module")
def full_4():
    cwd = os.getcwd()
    os.chdir(ROOT)  # the kept figure path is relative to the repository, as the command wrote it
    try:
        res = load_test_result(FULL, "4", quick=False, seed=0, backends=["crowd_env"])
    finally:
        os.chdir(cwd)
    assert res is not None, "the full test 4's kept result is not read back with the full version's settings"
    return res


@pytest.fixture(scope="module")
def page():
    with open(PAGE, encoding="utf-8") as fh:
        return fh.read()


def test_the_full_run_is_complete_without_overlap_or_excursion(full_4):
    assert not full_4.quick
    assert full_4.complete["crowd_env"]
    assert full_4.min_gap_m["crowd_env"] >= -1.3e-11  # the page: no overlap beyond 1.2e-11 m
    assert full_4.outside_m["crowd_env"] <= OUTSIDE_LIMIT_M


def test_the_full_run_fails_on_the_flows_at_4_and_5_only(full_4):
    details = full_4.verdicts["crowd_env"].details
    assert [row["nominal_density_per_m2"] for row in details["table"]] == [0.5, 1.0, 2.0, 3.0, 4.0, 5.0]
    assert list(details["unplaceable"]) == ["6"]
    assert details["monotone"]
    assert details["flow_consistent"] == [True, True, True, True, False, False]
    assert full_4.passed("crowd_env") is False


def _cell(x: float) -> str:
    return f"{x:.2f}".replace("-", "−")


def test_the_page_shows_the_kept_rows_and_cost(full_4, page):
    for row in full_4.verdicts["crowd_env"].details["table"]:
        rho_fl, v_fl = row["main_density_first_last_per_m2"], row["main_speed_first_last_m_s"]
        line = (f"| {row['nominal_density_per_m2']:g} | {row['n_pedestrians']} | {_cell(row['main_density_per_m2'])} | "
                f"{_cell(row['main_speed_m_s'])} | {_cell(row['main_flow_per_m_s'])} | "
                f"{_cell(row['main_line_flow_per_m_s'])} | {_cell(rho_fl[0])} / {_cell(rho_fl[1])} | "
                f"{_cell(v_fl[0])} / {_cell(v_fl[1])} | {_cell(row['weidmann_speed_m_s'])} |")
        assert line in page, line
    minutes = full_4.wall_time_s["crowd_env"] / 60.0
    hours, rest = divmod(round(minutes / 10.0) * 10, 60)
    assert f"{hours} h {rest} min" in page  # 99.5 min: "1 h 40 min"
    assert math.isclose(minutes, 99.5, abs_tol=0.1)
    assert "(rimea/full/rimea_4.png)" in page and os.path.exists(os.path.join(ROOT, FULL, "rimea_4.png"))
