"""Desired walking speeds by age (Weidmann 1993, as RiMEA 4.1.1 prescribes them for its test 7).

``WEIDMANN_SPEEDS_BY_AGE_M_S``: age (years) -> (v_min, v_max) of the walking speed on the flat, the
band RiMEA 4.1.1's figure 3 draws from Weidmann's data, as transcribed for test 7 by JuPedSim's
verification suite (``PedestrianDynamics/jupedsim-web-community``,
``scripts/scenario_builders/rimea07_demographic.py``). The band narrows to a single value at 60 and 70
years in that transcription. ``RIMEA_ADULTS``: the 50 adults of test 7 (age -> count). Use
:func:`desired_speeds_for_ages` to give a scenario's pedestrians these speeds
(``pedestrian_params={"desired_speed_m_s": ...}``), in the RiMEA tests and in any scenario or RL
environment.
"""
from __future__ import annotations

import numpy as np

from crowd_env.errors import ScenarioError

__all__ = ["WEIDMANN_SPEEDS_BY_AGE_M_S", "RIMEA_ADULTS", "desired_speeds_for_ages", "ages_of_population"]

WEIDMANN_SPEEDS_BY_AGE_M_S = {20: (1.60, 1.64), 30: (1.52, 1.56), 40: (1.46, 1.50), 50: (1.39, 1.43),
                              60: (1.27, 1.27), 70: (1.07, 1.07)}
RIMEA_ADULTS = {20: 10, 30: 10, 40: 10, 50: 10, 60: 5, 70: 5}  # RiMEA test 7: 50 adults


def ages_of_population(counts: dict) -> np.ndarray:
    """(N,) ages from ``{age: count}`` (e.g. :data:`RIMEA_ADULTS`), in the order of the dict."""
    ages = []
    for age, count in counts.items():
        if int(count) != count or count < 0:
            raise ScenarioError(f"the count of age {age} must be a whole number >= 0, got {count!r}")
        ages += [age] * int(count)
    return np.array(ages, dtype=np.float64)


def desired_speeds_for_ages(ages_years, rng: np.random.Generator, table: dict | None = None) -> np.ndarray:
    """(N,) desired speeds: each pedestrian's drawn uniformly from the (v_min, v_max) band of its age in
    ``table`` (default :data:`WEIDMANN_SPEEDS_BY_AGE_M_S`). An age the table does not list raises
    :class:`~crowd_env.errors.ScenarioError` naming it (no interpolation, nothing silently rounded)."""
    table = WEIDMANN_SPEEDS_BY_AGE_M_S if table is None else table
    ages = np.asarray(ages_years, dtype=np.float64).reshape(-1)
    unknown = sorted({float(a) for a in ages} - {float(k) for k in table})
    if unknown:
        raise ScenarioError(f"no speed band for age(s) {unknown}; the table lists {sorted(table)}")
    lo = np.array([table[int(a)][0] for a in ages])
    hi = np.array([table[int(a)][1] for a in ages])
    return lo + (hi - lo) * rng.random(ages.shape[0])
