"""The human-likeness scorecard (crowd_env.experiments.validation.scorecard, crowd-scorecard): the quick path runs
end to end; the calibrated model's row is the calibration's own (the same tasks and the same terms); the
bootstrap interval collapses when every seed gives the same runs; a learned policy drives only its share of a
mixed crowd; bad policies are refused by name."""
from __future__ import annotations

import json

import numpy as np
import pytest

from crowd_env.walking.presets import get_preset
from crowd_env.errors import InputError, PolicyError
from crowd_env.experiments.running.crowd_policy import crowd_policy, policy_entry
from crowd_env.experiments.validation.bottleneck import bottleneck_config
from crowd_env.experiments.validation.calibration.objective import target_error
from crowd_env.experiments.validation.calibration.optimize import target_tasks
from crowd_env.experiments.validation.calibration.tasks import FDPlan, base_config, make_fd_tasks
from crowd_env.experiments.validation.scorecard import (EXPERIMENT_TERMS, QUICK_PLAN, ScorecardPlan,
                                                        bootstrap_intervals, distances, parse_policy,
                                                        scorecard_tasks)
from crowd_env.scenarios import make_scenario

pytest.importorskip("baselines.trained")


def _config(max_time_s: float = 300.0) -> dict:
    preset = get_preset("calibrated")
    params = preset.params()
    geometry = bottleneck_config(params, navigation_clearance_m=preset.navigation_clearance_m,
                                 max_time_s=max_time_s)["geometry"]
    return base_config(geometry, params, max_time_s)


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    """crowd-scorecard --quick on the calibrated model and the shipped behaviour clone, serially."""
    from crowd_env.cli.scorecard import main

    out = tmp_path_factory.mktemp("scorecard")
    assert main(["--quick", "--policies", "bottleneck_bc", "--backend", "serial", "--draws", "200",
                 "--out", str(out), "--no-figure"]) == 0
    return out, json.loads((out / "scorecard.json").read_text())


def test_the_quick_scorecard_scores_the_calibrated_model_first_and_a_learned_policy(quick):
    out, card = quick
    rows = card["rows"]
    assert [r["policy"] for r in rows] == ["calibrated", "bottleneck_bc"]
    for r in rows:
        assert r["failed_runs"] == 0 and r["runs"] == 12  # 3 bottleneck runs and 3 sweep runs, 2 seeds
        for name in EXPERIMENT_TERMS:
            lo, hi = r[f"{name}_ci"]
            assert np.isfinite(r[name]) and r[name] >= 0 and 0 <= lo <= hi
    assert (out / "scorecard.csv").read_text().startswith("policy,runs,failed_runs")
    assert "bottleneck distance" in (out / "scorecard.md").read_text()
    assert (out / "calibrated" / "runs").is_dir() and (out / "bottleneck_bc" / "runs").is_dir()


def test_the_calibrated_row_is_the_calibrations_own(quick):
    # the same tasks as crowd-calibrate targets --fd (full widths: with the capacity runs) ...
    config = _config()
    plan = ScorecardPlan(seeds=(0, 1), fd=FDPlan(corridor_densities=(1.147,), single_file_densities=(0.87,)))
    assert scorecard_tasks(config, None, plan) == (target_tasks(config, {}, {}, plan.widths_m, plan.seeds)
                                                   + make_fd_tasks(config, {}, {}, plan.fd))
    # ... and the same terms: the distances are sums of target_error's terms of the same records
    from crowd_env.experiments.running.store import RunStore
    from crowd_env.experiments.validation.calibration.objective import fd_terms

    out, card = quick
    config = _config()
    store = RunStore(out / "calibrated", config, keyed_by="task")
    records = [store.load(t) for t in scorecard_tasks(config, None, QUICK_PLAN)]
    score = target_error([r for r in records if "setup" not in r], fd=False)
    fd, _ = fd_terms([r for r in records if "setup" in r])
    row = card["rows"][0]
    assert row["bottleneck"] == sum(score.terms[k] for k in EXPERIMENT_TERMS["bottleneck"])
    assert row["corridor"] == fd["corridor_fd"] + fd["corridor_monotone"]
    assert row["single_file"] == fd["single_file"] + fd["headway_fit"]
    assert distances(records)["bottleneck"] == row["bottleneck"]


def test_the_interval_collapses_when_every_seed_gives_the_same_runs(quick):
    from crowd_env.experiments.running.store import RunStore

    out, _ = quick
    config = _config()
    store = RunStore(out / "calibrated", config, keyed_by="task")
    seed0 = [store.load(t) for t in scorecard_tasks(config, None, QUICK_PLAN) if t["seed"] == 0]
    twins = seed0 + [dict(r, seed=1) for r in seed0]
    d = distances(twins)
    ci = bootstrap_intervals(twins, (0, 1), draws=50)
    for name in EXPERIMENT_TERMS:
        assert ci[name][0] == pytest.approx(d[name], rel=1e-12) and ci[name][1] == pytest.approx(d[name], rel=1e-12)


def test_a_learned_policy_drives_only_its_share_of_a_mixed_crowd():
    scenario = make_scenario("seyfried_bottleneck", n_pedestrians=10, seed=0, navigation_clearance_m=0.23)
    params = get_preset("calibrated").params()
    sim = scenario.make_simulator(params=params)
    calibrated = crowd_policy({}, scenario, params)
    mixed = crowd_policy({"policy": policy_entry("bottleneck_bc", 0.5)}, scenario, params)
    alone = crowd_policy({"policy": policy_entry("bottleneck_bc", 1.0)}, scenario, params)
    want, want_heading = calibrated(sim)
    got, _ = mixed(sim)
    learned = mixed.learned_mask
    assert learned.sum() == 5
    np.testing.assert_array_equal(got[~learned], want[~learned])
    assert not np.allclose(got[learned], want[learned])
    np.testing.assert_array_equal(got[learned], alone(sim)[0][learned])
    # with the model's social force: the learned ones' intents plus (τ/m) Σ f_social, as the agent adds it to its own
    pushed = crowd_policy({"policy": policy_entry("bottleneck_bc", 0.5, social_force=True)}, scenario, params)
    got_pushed, _ = pushed(sim)
    idx = sim.active_index
    force = np.zeros((scenario.n_pedestrians, 2))
    force[idx] = calibrated.social_force(sim, calibrated.desired_direction(sim, idx))
    scale = (sim.state.tau_s / sim.state.mass_kg)[:, None]
    assert np.abs(force[learned]).max() > 1.0  # the crowd stands close enough for the force to matter
    np.testing.assert_allclose(got_pushed[learned], got[learned] + scale[learned] * force[learned], atol=1e-12)
    np.testing.assert_array_equal(got_pushed[~learned], want[~learned])  # the calibrated ones have it already
    # gated: in full at rest, none from the gate's speed on, linear between
    speed = np.array([0.0, 0.05, 0.1, 0.2, 1.0, 0.0, 0.05, 0.1, 0.2, 1.0])
    sim.state.velocity_m_s[:] = np.column_stack([speed, np.zeros(10)])
    gated = crowd_policy({"policy": policy_entry("bottleneck_bc", 0.5, social_force=True,
                                                 social_force_below_m_s=0.1)}, scenario, params)
    got_gated, _ = gated(sim)
    plain, _ = crowd_policy({"policy": policy_entry("bottleneck_bc", 0.5)}, scenario, params)(sim)  # same velocities
    share = np.clip(1.0 - speed / 0.1, 0.0, 1.0)[:, None]
    np.testing.assert_allclose(got_gated[learned], plain[learned] + (share * scale * force)[learned], atol=1e-12)


def test_bad_policies_are_refused_by_name():
    assert parse_policy("bottleneck_ppo@0.25") == ("bottleneck_ppo@0.25", "bottleneck_ppo", 0.25)
    with pytest.raises(InputError, match="fraction"):
        parse_policy("bottleneck_ppo@half")
    with pytest.raises(PolicyError, match="learned_fraction"):
        policy_entry("bottleneck_ppo", 1.5)
    with pytest.raises(Exception, match="no_such_policy"):
        policy_entry("no_such_policy")
    with pytest.raises(PolicyError, match="no observation policy"):
        policy_entry("math:pi")
    assert policy_entry("calibrated") is None
    assert policy_entry("bottleneck_bc") == {"name": "bottleneck_bc", "learned_fraction": 1.0}  # as before the option
    assert policy_entry("bottleneck_bc", social_force=True)["social_force"] is True
    with pytest.raises(PolicyError, match="has it already"):
        policy_entry("calibrated", social_force=True)
    assert policy_entry("bottleneck_bc", social_force=True, social_force_below_m_s=0.1)["social_force_below_m_s"] == 0.1
    for bad, on in ((0.0, True), (float("nan"), True), ("0.1", True), (0.1, False)):
        with pytest.raises(PolicyError, match="social_force_below_m_s gates"):
            policy_entry("bottleneck_bc", social_force=on, social_force_below_m_s=bad)
    with pytest.raises(PolicyError, match="social_force_below_m_s gates"):  # a gate for the calibrated agent too
        policy_entry("calibrated", social_force_below_m_s=0.3)


def test_the_flow_per_width_is_the_mean_of_the_runs_that_got_everybody_out():
    """A failed run gives no flow figure: the table's J_s of N = 60 is the mean of the complete runs, and says
    over how many (here 1 of 2 at 0.9 m, none at 1.0 m)."""
    from crowd_env.experiments.validation.scorecard import _js60_of_complete_runs

    def run(b, js, complete=True, stalled=False, n=60):
        return {"width_m": b, "n_pedestrians": n, "specific_flow_per_m_s": js, "complete": complete, "stalled": stalled}

    records = [run(0.9, 1.8), run(0.9, float("nan"), complete=False), run(0.9, 9.0, n=20),
               run(1.0, float("nan"), stalled=True), run(1.0, 1.2, complete=False),
               {"setup": "corridor", "speed_m_s": 1.0}]
    means, complete, runs = _js60_of_complete_runs(records, ScorecardPlan(widths_m=(0.9, 1.0), seeds=(0, 1)))
    assert means[0] == 1.8 and np.isnan(means[1]) and complete == [1, 0] and runs == [2, 2]


def test_the_quick_plan_says_what_it_does_not_measure(tmp_path, capsys, monkeypatch):
    """Regression (issue 52): --help said the quick plan has two corridor bins where it has one (1.147 /m², where
    the default model scores a corridor distance of 0.0000 although the fundamental diagram is not reproduced), and
    the console did not say what a quick score leaves out. The help is written from the plan, and the command
    prints every part of the full plan the quick one does not measure."""
    import crowd_env.cli.scorecard as cli
    from crowd_env.experiments.validation.scorecard import plan_limits

    assert len(QUICK_PLAN.fd.corridor_densities) == 1
    assert "1 corridor and 2 single-file bins" in " ".join(cli.build_parser().format_help().split())
    limits = plan_limits(QUICK_PLAN)
    assert limits[:3] == ["the bottleneck at b = 0.8, 1.0, 1.1, 1.2 m", "the door's capacity (N = 120 at b = 1.0, 1.2 m)",
                          "12 of the 13 corridor bins (corridor measured at 1.147 /m² only, the full plan 0.39-3.36 /m²)"]
    assert plan_limits(ScorecardPlan()) == []
    monkeypatch.setattr(cli, "run_scorecard", lambda *a, **k: [])
    monkeypatch.setattr(cli, "format_scorecard", lambda rows: "")
    monkeypatch.setattr(cli, "write_scorecard", lambda *a, **k: [])
    assert cli.main(["--quick", "--backend", "serial", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert f"not measured by this plan: {'; '.join(limits)}. A distance of 0 here says only" in out
    assert cli.main(["--backend", "serial", "--out", str(tmp_path)]) == 0
    assert "not measured" not in capsys.readouterr().out


@pytest.mark.parametrize("n_rows", [1, 2])
def test_the_figure_lays_out_without_matplotlib_s_warning(tmp_path, n_rows):
    """Regression (issue 52): the scorecard's figure raised matplotlib's 'Tight layout not applied' warning (the
    words written for a distance of 0 or a failed one lay outside their panel)."""
    import warnings

    from crowd_env.experiments.validation.scorecard import EXPERIMENTS, _figure

    rows = []
    for k, values in enumerate([(0.01, 0.0, 1.2), (None, 3.0, 0.5)][:n_rows]):
        r = {"policy": f"policy {k}"}
        for name, v in zip(EXPERIMENTS, values):
            r[name] = v
            r[f"{name}_ci"] = (float("nan"), float("nan")) if v is None else (0.5 * v, 2.0 * v)
        rows.append(r)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        path = _figure(rows, tmp_path / "scorecard.png")
    assert (tmp_path / "scorecard.png").stat().st_size > 0 and str(path).endswith("scorecard.png")
