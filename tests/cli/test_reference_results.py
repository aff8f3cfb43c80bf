"""crowd-reference-results's command line (crowd_env.cli.reference_results): every option described, and a quick run's missed
targets explained."""
from crowd_env.cli.reference_results import budget_note, build_parser
from crowd_env.experiments.training.reference_results import BUDGETS, make_plan


def test_help_describes_every_option():
    """Regression (issue 37): five options had no description in --help."""
    ap = build_parser()
    undescribed = [a.option_strings for a in ap._actions if a.option_strings and not (a.help or "").strip()]
    assert not undescribed
    text = ap.format_help()
    for flag in ("--train-seeds", "--eval-seeds", "--out", "--backend", "--tasks", "--policies"):
        assert flag in text


def test_a_quick_plan_says_its_targets_are_expected_to_miss():
    """Regression (issue 37): --quick printed "holds NO" without saying tiny budgets are expected to miss."""
    note = budget_note(make_plan(quick=True), BUDGETS)
    assert "expected to miss the targets" in note and "ppo_timesteps 512" in note and "ppo_timesteps 2000000" in note
    assert "without --quick" in note
    reduced = budget_note(make_plan(budgets={"ppo_timesteps": 1000}), BUDGETS)
    assert reduced is not None and "ppo_timesteps 1000" in reduced and "mappo_frames" not in reduced
    assert budget_note(make_plan(), BUDGETS) is None
