"""A reward grounded in walking: the metabolic energy of a pedestrian, and the least-effort reward.

People walk at about 1.3 m/s because that speed minimises the metabolic energy per metre. Guy, Chhugani,
Curtis, Dubey, Lin & Manocha (2010, "PLEdestrians: a least-effort approach to crowd simulation", SCA
2010), from Whittle's gait data, write the metabolic rate per kg of a walker at speed v as

    Ė / m = e_s + e_w v²,   e_s = 2.23 J/(kg s),   e_w = 1.26 J s/(kg m²),

so the energy per metre, e_s / v + e_w v, is least at v* = √(e_s / e_w) ≈ 1.33 m/s, where it costs
c* = 2 √(e_s e_w) ≈ 3.35 J/(kg m), the minimum cost of transport.

:class:`MetabolicEffort` (``metabolic_effort``) is −(e_s + e_w v̄²) Δt per step in J/kg, v̄² the mean of the
squared speeds at the step's start and end (the trapezoid rule over the step). The least-effort reward
(:data:`LEAST_EFFORT_TERMS`) adds it to the existing terms, all in J/kg:

    r = c* ΔT − (e_s + e_w v̄²) Δt − 0.01 c* P + c* [exit]

Progress along the travel-time field is valued at c* per metre: a metre is worth what it costs at best.
With that one weight the optimum speed is v* whatever the task: per metre of a walk to an exit, the net
reward c* − e_s / v − e_w v is largest (zero) at v*; per second of a walk that never ends (a periodic
corridor, a fixed horizon), c* v − e_s − e_w v² is largest (zero) at v* too, and standing still costs e_s.
The progress term is a potential-based shaping (Φ = −c* T; Ng, Harada & Russell 1999), so it speeds up
learning without changing which walk is best to the exit. The contact percussion P (kg m/s) and the exit
bonus keep the default reward's proportions: an impact of 20 kg m/s costs what 0.2 m of walking at best
does, and leaving is worth one such metre. ``tests/envs/test_least_effort.py`` checks the optimum speed
of this reward in both settings.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from crowd_env.errors import InputError

from ...core.checks import check_number
from .base import METABOLIC_EFFORT, RewardTerm

__all__ = ["E_S_J_KG_S", "E_W_J_S_KG_M2", "PREFERRED_SPEED_M_S", "COST_OF_TRANSPORT_J_KG_M", "MetabolicEffort",
           "LEAST_EFFORT_TERMS"]

E_S_J_KG_S = 2.23  # e_s: the resting part of the walking metabolic rate, J/(kg s) (Guy et al. 2010, Whittle)
E_W_J_S_KG_M2 = 1.26  # e_w: the speed part, J s/(kg m²)
PREFERRED_SPEED_M_S = math.sqrt(E_S_J_KG_S / E_W_J_S_KG_M2)  # v* = √(e_s / e_w) ≈ 1.330 m/s
COST_OF_TRANSPORT_J_KG_M = 2.0 * math.sqrt(E_S_J_KG_S * E_W_J_S_KG_M2)  # c* = 2 √(e_s e_w) ≈ 3.352 J/(kg m)


@dataclass(frozen=True)
class MetabolicEffort(RewardTerm):
    """``metabolic_effort``: −(e_s + e_w v̄²) Δt, the metabolic energy per kg spent walking this step (J/kg),
    v̄² = (v_start² + v_end²) / 2; ``e_s_j_kg_s`` and ``e_w_j_s_kg_m2`` default to Guy et al.'s (2010) values."""

    weight: float = 1.0
    e_s_j_kg_s: float = E_S_J_KG_S
    e_w_j_s_kg_m2: float = E_W_J_S_KG_M2

    name = "metabolic_effort"
    kind = METABOLIC_EFFORT  # its value, computed in compiled code: crowd_env.envs.rewards.base._sum_terms

    def __post_init__(self):
        super().__post_init__()
        check_number("MetabolicEffort.e_s_j_kg_s", self.e_s_j_kg_s, error=InputError, minimum=0.0)
        check_number("MetabolicEffort.e_w_j_s_kg_m2", self.e_w_j_s_kg_m2, error=InputError, minimum=0.0)

    @property
    def constants(self) -> tuple:
        return float(self.e_s_j_kg_s), float(self.e_w_j_s_kg_m2)


# The least-effort reward, term -> weight (the environment's reward_terms="least_effort" is this).
LEAST_EFFORT_TERMS = {"progress": COST_OF_TRANSPORT_J_KG_M, "metabolic_effort": 1.0,
                      "contact_percussion": 0.01 * COST_OF_TRANSPORT_J_KG_M, "exit": COST_OF_TRANSPORT_J_KG_M}
