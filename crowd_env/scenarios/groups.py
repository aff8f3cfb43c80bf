"""Hand-holding groups in the Seyfried bottleneck crowd (Kabalan et al. 2016, Eq. 2 and Section 2.2).

The crowd is the one of :func:`~crowd_env.scenarios.bottleneck.seyfried_bottleneck`; then ``n_pairs``
pairs and ``n_triples`` triples are formed from neighbouring pedestrians, moved side by side across
their desired direction e_d (a row with ``hand_gap_m`` between shoulders; :func:`form_groups`), and
joined by hand links: the shoulders facing each other (Eq. 2, held by the at-a-distance deformation
velocity with K_v = ``ModelParams.link_dissipation_kg_per_m2``). A triple's middle member holds both
others. ``metadata["groups"]`` lists the members of each group.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from .checks import check_count
from .placement import form_groups
from .registry import register_scenario, scenario_options
from .scenario import ScenarioError
from .bottleneck import seyfried_bottleneck

__all__ = ["bottleneck_groups"]


@register_scenario("bottleneck_groups")
def bottleneck_groups(width_m: float = 1.2, n_pedestrians: int = 40, seed: int | None = 0, n_pairs: int = 4,
                      n_triples: int = 2, hand_gap_m: float = 0.05, **bottleneck_options):
    """The Seyfried bottleneck (``width_m``, ``n_pedestrians``, any other of its options) with hand-holding
    pairs and triples mixed into the crowd. Raises :class:`ScenarioError` naming the problem (unknown
    option, more group members than pedestrians, no room to put a group side by side)."""
    known = set(scenario_options("seyfried_bottleneck")) - {"width_m", "n_pedestrians", "seed"}
    unknown = sorted(set(bottleneck_options) - known)
    if unknown:
        raise ScenarioError(f"unknown option(s) {unknown} for scenario 'bottleneck_groups'; known: "
                            f"{sorted(known | {'width_m', 'n_pedestrians', 'seed', 'n_pairs', 'n_triples', 'hand_gap_m'})}")
    n_pairs = check_count("n_pairs", n_pairs, 0)
    n_triples = check_count("n_triples", n_triples, 0)
    base = seyfried_bottleneck(width_m=width_m, n_pedestrians=n_pedestrians, seed=seed, **bottleneck_options)
    sizes = [3] * n_triples + [2] * n_pairs
    if sum(sizes) > base.n_pedestrians:
        raise ScenarioError(f"{n_pairs} pairs and {n_triples} triples need {sum(sizes)} pedestrians, but the crowd has "
                            f"{base.n_pedestrians}")
    rng = _group_rng(seed)
    radius = base.pedestrian_params["radius_m"]
    position, groups, links = form_groups(base.position_m, sizes, radius, base.spawn_area, rng,
                                          walking_direction=base.navigation().direction, gap_m=hand_gap_m)
    metadata = {**base.metadata, "n_pairs": n_pairs, "n_triples": n_triples, "hand_gap_m": float(hand_gap_m),
                "groups": [g.tolist() for g in groups]}
    return dataclasses.replace(base, position_m=position, heading_rad=None, links=links if links.size else None,
                               link_offsets_m=None, name="bottleneck_groups", metadata=metadata)


def _group_rng(seed):
    """The RNG choosing the groups: independent of the placement's stream, reproducible from ``seed``."""
    return np.random.default_rng(None if seed is None else [int(seed), 1])
