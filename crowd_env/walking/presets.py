"""Named configurations of the model: the social force's parameters, the body and the navigation field.

A preset pairs the core's physics with the walking model's parameters: a set of
:class:`~crowd_env.walking.model.ModelParams` overrides (by their flat names) plus the clearance of the
eikonal field (Eq. 11-13): 0 solves it for points, as the paper does; the pedestrians' radius solves
it in the configuration space of the disk centres (walls inflated by r), so e_d never points into a
wall or at a corner a centre cannot reach. The reproduction (``crowd-bottleneck``), the calibration,
the generalisation command and the RL environment take their model from :data:`DEFAULT_PRESET`
unless told otherwise; ``ModelParams()`` itself stays the paper's literal parameter set.

- ``calibrated`` (default): calibrated against every figure the Seyfried et al. (2009) experiment
  measured at once (:mod:`crowd_env.experiments.validation.calibration.objective`: the N = 60 flows, N = 20/40, the stationary
  speed and densities, the capacity criterion N = 120 vs 60), ``crowd-calibrate optimize --objective
  targets --preset recalibrated --free A B lambda``. Eq. 16 with the anisotropy λ inside the
  paper's range 0 < λ < 1, between pedestrians only (walls act through the Frémond contacts alone,
  as in the paper), configuration-space field.
- ``paper``: the published validation point A = 790 N, B = 0.08 m (Section 4.1.3), λ = 1 (isotropic,
  outside Eq. 16's stated range; the paper never sets it), the literal point field and walls
  repelling like pedestrians. For the literal reproduction of Section 4.
- ``vision``: ``calibrated`` plus vision (:mod:`crowd_env.walking.vision`, an addition to the paper: a speed
  rule from the free distance and a choice of direction among a fan, after Moussaïd et al. 2011 and Tordeux et
  al. 2016), T = 1 s, l = 0.2 m, ±75° in 11 rays, κ = 0.5 and the right of way (a neighbour farther from the
  exit never blocks), set by hand from probes (docs/validation/fundamental_diagram.md): it has a fundamental
  diagram (corridor and single file within about 0.17 m/s of the experiments) but its bottleneck flows are about
  a third too low. Not calibrated, not the default.
- ``recalibrated``: the paper's ε_T calibration (Eq. 23-24, N = 60 flows only) redone for the
  configuration-space field without wall repulsion: A = 1150 N, B = 0.2 m, λ = 1.
- ``joint``: calibrated on every shipped experiment as it was run at once (``crowd-calibrate optimize --objective
  virtual --preset calibrated --free A B lambda radius --weight single_file=0 headway_fit=0``: Seyfried's
  bottleneck and the nine Jülich corridor runs with their entrances and exits,
  :mod:`crowd_env.experiments.validation.virtual_experiments`), the body's radius freed: A = 223 N, B = 0.332 m,
  λ = 0.476, r = 0.214 m, configuration-space field of that body, no wall social force. A longer, weaker social
  range keeps queues apart and a slimmer body passes the 0.70 m exit the default wedges in; the single file is
  not met (weights 0: no point of this family meets it). Not the default (docs/validation/virtual_experiments.md
  says what it meets and misses).
- ``shoulders``: bodies of three circles 0.46 m across and 0.25 m deep (``body_depth_m``, a median man's chest
  depth; :mod:`crowd_env.core.body`) that turn their shoulders at an aperture narrower than 1.3 shoulder widths
  (``shoulder_turn_critical_ratio``, Warren & Whang's ratio; :mod:`crowd_env.walking.shoulder_turn`), Kabalan's
  radius; only the social force calibrated, on every shipped experiment as run at once (``crowd-calibrate
  optimize --objective virtual --preset calibrated --param body_depth_m=0.25 --param
  shoulder_turn_critical_ratio=1.3 --free A B lambda --weight single_file=0 headway_fit=0``): A = 304.0 N,
  B = 0.0807 m, λ = 0.0679, configuration-space field, no wall social force. Passes the 0.70 m exit without a
  clog and the narrow doors off their axis as people do; the narrow entrances, the queues' density, the wide runs
  and the single file are not met. Not the default (docs/validation/virtual_experiments.md).
"""
from __future__ import annotations

from dataclasses import dataclass, field

from crowd_env.errors import ParameterError

from ..core.params import PedestrianDefaults
from .model import ModelParams

__all__ = ["DEFAULT_PRESET", "PRESETS", "Preset", "get_preset"]

_RADIUS_M = PedestrianDefaults().radius_m


@dataclass(frozen=True)
class Preset:
    """``model``: ModelParams overrides; ``navigation_clearance_m``: clearance of the eikonal field; ``radius_m``: every
    pedestrian's radius, the body the model was calibrated with (Kabalan's Table 2 unless the preset calibrated it):
    the environment and the commands that run a preset give it to every scenario whose factory takes ``radius_m``
    and whose options set none (:func:`crowd_env.scenarios.registry.body_options`)."""

    name: str
    model: dict = field(default_factory=dict)
    navigation_clearance_m: float = 0.0
    summary: str = ""
    radius_m: float = _RADIUS_M

    @property
    def body_radius_m(self) -> float | None:
        """The preset's radius when it differs from Kabalan's Table 2, else None: what scenario options must carry
        for this preset (None: the factories' own default, the same body)."""
        return None if self.radius_m == _RADIUS_M else float(self.radius_m)

    def params(self, **changes) -> ModelParams:
        """ModelParams of this preset, with ``changes`` on top (unknown names raise ParameterError)."""
        return ModelParams().replace(**{**self.model, **changes})


PRESETS = {
    "calibrated": Preset("calibrated", {"social_strength_n": 331.5, "social_range_m": 0.04111, "social_anisotropy": 0.1093,
                                        "wall_social_strength_n": 0.0}, _RADIUS_M,
                         "all of Seyfried 2009's figures at once; λ in (0, 1); configuration-space field; "
                         "no wall social force"),
    "paper": Preset("paper", {}, 0.0, "Kabalan Section 4.1.3: A = 790 N, B = 0.08 m, λ = 1, point field, walls "
                                      "repel like pedestrians"),
    "vision": Preset("vision", {"social_strength_n": 331.5, "social_range_m": 0.04111, "social_anisotropy": 0.1093,
                                "wall_social_strength_n": 0.0, "vision_time_gap_s": 1.0, "vision_jam_gap_m": 0.2,
                                "vision_half_angle_rad": 1.309, "vision_rays": 11, "vision_body_scale": 0.5,
                                "vision_right_of_way": True},
                     _RADIUS_M, "calibrated + vision (T = 1 s, l = 0.2 m, ±75°, 11 rays, κ = 0.5, right of way), "
                                "chosen by hand from probes: corridor and single file within about 0.17 m/s, "
                                "bottleneck flows about a third too low; not calibrated"),
    "recalibrated": Preset("recalibrated", {"social_strength_n": 1150.0, "social_range_m": 0.2,
                                            "wall_social_strength_n": 0.0}, _RADIUS_M,
                           "ε_T of N = 60 only, configuration-space field, no wall social force, λ = 1"),
    "joint": Preset("joint", {"social_strength_n": 223.0, "social_range_m": 0.332, "social_anisotropy": 0.476,
                              "wall_social_strength_n": 0.0}, 0.214,
                    "Seyfried 2009 and the nine Jülich corridor runs as run, at once (--objective virtual); "
                    "a calibrated body, r = 0.214 m; single file unmet", radius_m=0.214),
    "shoulders": Preset("shoulders", {"social_strength_n": 304.0, "social_range_m": 0.0807, "social_anisotropy": 0.0679,
                                      "wall_social_strength_n": 0.0, "body_depth_m": 0.25,
                                      "shoulder_turn_critical_ratio": 1.3}, _RADIUS_M,
                        "bodies of three circles 0.25 m deep that turn their shoulders at narrow apertures "
                        "(Warren & Whang's 1.3); the social force calibrated on every shipped experiment as run at "
                        "once (--objective virtual); single file unmet"),
}
DEFAULT_PRESET = "calibrated"


def get_preset(name: str) -> Preset:
    """The preset called ``name``; an unknown name raises :class:`ParameterError` listing the known ones."""
    try:
        return PRESETS[name]
    except (KeyError, TypeError):
        raise ParameterError(f"unknown preset {name!r}; choose one of {sorted(PRESETS)}") from None
