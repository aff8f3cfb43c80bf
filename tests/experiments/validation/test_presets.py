"""The presets (crowd_env.walking.presets) on reduced cases of the experiment's targets: the calibrated preset's
J_s at b = 1.0 m, and the capacity criterion separating it from the paper's point."""
import numpy as np

from crowd_env.experiments.validation.calibration.objective import CAPACITY_RANGE


def _runs(preset_name, width_m, n, seeds):
    from baselines import SocialForceAgent
    from crowd_env.walking.presets import get_preset
    from crowd_env.experiments.running.runner import run_scenario
    from crowd_env.scenarios import make_scenario

    preset = get_preset(preset_name)
    out = []
    for seed in seeds:
        sc = make_scenario("seyfried_bottleneck", width_m=width_m, n_pedestrians=n, seed=seed,
                           navigation_clearance_m=preset.navigation_clearance_m)
        out.append(run_scenario(sc, SocialForceAgent(sc.navigation()), preset.params(), max_time_s=200))
    return out


def test_calibrated_preset_reduced_case():
    """The default preset at b = 1.0 m, seeds 0-3: N = 60 within ±8 % of Seyfried's 1.901 1/(m s) (a 4-seed
    mean; the 10-seed figures are printed by ``crowd-calibrate targets``), N = 20 inside the experiment's
    [1.77, 2.31] and not below N = 60 by more than the seeds' scatter, everyone out, no overlap beyond 1 mm."""
    n60 = _runs("calibrated", 1.0, 60, range(4))
    n20 = _runs("calibrated", 1.0, 20, range(4))
    assert all(r.complete and not r.stalled and r.min_gap_m > -1e-3 for r in n60 + n20)
    js60 = np.mean([r.specific_flow_per_m_s for r in n60])
    js20 = np.mean([r.specific_flow_per_m_s for r in n20])
    assert abs(js60 / 1.90114069 - 1.0) < 0.08
    assert 1.77 <= js20 <= 2.31
    assert js20 > 0.9 * js60


def test_capacity_criterion_separates_the_presets():
    """Stationary discharge rate of N = 120 over N = 60 at b = 1.0 m (seeds 0-1): a capacity for the
    calibrated preset (inside [0.95, 1.10]); the paper point's pressure-driven discharge grows with the
    crowd behind (above 1.10)."""
    def ratio(name):
        big, small = _runs(name, 1.0, 120, range(2)), _runs(name, 1.0, 60, range(2))
        assert all(r.complete for r in big + small)
        return (np.mean([r.stationary_specific_flow_per_m_s() for r in big])
                / np.mean([r.stationary_specific_flow_per_m_s() for r in small]))

    assert CAPACITY_RANGE[0] <= ratio("calibrated") <= CAPACITY_RANGE[1]
    assert ratio("paper") > CAPACITY_RANGE[1]
