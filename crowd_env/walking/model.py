"""The model a preset names: the core's physics and the walking model's parameters, paired.

:class:`ModelParams` holds the core's :class:`~crowd_env.core.params.PhysicsParams` (the step and the Frémond
contacts) and the calibrated agent's :class:`~crowd_env.walking.agent.WalkingParams` (small frozen groups, each
checked beside the kernel that reads it). Every parameter keeps one flat name, the name it is given by everywhere a
model is written down (``ModelParams(social_strength_n=500)``, ``.replace(...)``, ``from_dict``, ``--param
NAME=VALUE``, the environment's ``params={...}``, the ``params`` of stored run configurations): a physics field by
its own name (``dt_s``, ``normal_dissipation_kg``, ``solver``, ...), a walking field ``field`` of the group
``group`` as ``<group>_<field>`` (``social_strength_n`` is ``walking.social.strength_n``, ``wall_social_range_m``
``walking.wall_social.range_m``, ``vision_rays`` ``walking.vision.rays``, ``ttc_horizon_s``
``walking.ttc.horizon_s``). A field added to a group is a model parameter at once, by that rule: nothing here
names one. Values are kept as given (an int stays an int, so that a stored configuration reads back to the same
dict); the kernels take :attr:`ModelParams.walking_bundle`, plain numbers resolved once.

The defaults are the paper's literal set (``ModelParams()``, the ``paper`` preset); the presets of
:mod:`crowd_env.walking.presets` are overrides by these names.
"""
from __future__ import annotations

import dataclasses
import operator
from dataclasses import dataclass, field

from crowd_env.errors import ParameterError, UnknownParameterError

from ..core.params import PhysicsParams
from .agent import WalkingParams

__all__ = ["ModelParams", "PhysicsParams", "WalkingParams", "model_parameter_names"]

_PHYSICS_NAMES = tuple(f.name for f in dataclasses.fields(PhysicsParams))
# flat name -> (group, field): a physics field by its name, a walking group's field as "<group>_<field>"
_WHERE = {name: (None, name) for name in _PHYSICS_NAMES}
for _group, _default in zip(WalkingParams._fields, WalkingParams()):
    for _field in type(_default)._fields:
        _name = f"{_group}_{_field}"
        if _name in _WHERE:  # two groups (or a group and the physics) claiming one name: refused at import
            raise ParameterError(f"model parameter {_name!r} named twice ({_WHERE[_name]} and {(_group, _field)})")
        _WHERE[_name] = (_group, _field)
_NAMES = tuple(_WHERE)


def model_parameter_names() -> tuple:
    """Every model parameter's flat name: the physics fields in their order, then each walking group's fields."""
    return _NAMES


def _unknown(names, what: str = "model parameter(s)") -> None:
    unknown = sorted(set(names) - set(_WHERE))
    if unknown:
        raise UnknownParameterError(f"unknown {what}: {unknown}; known: {sorted(_WHERE)}")


@dataclass(frozen=True, init=False, repr=False)
class ModelParams:
    """The core's :class:`~crowd_env.core.params.PhysicsParams` ``physics`` and the walking model's
    :class:`~crowd_env.walking.agent.WalkingParams` ``walking``, both checked; every parameter also by its flat name
    (module docstring): ``ModelParams(dt_s=0.005, social_strength_n=500.0)``, ``params.social_strength_n``,
    :meth:`replace`, :meth:`from_dict`, :meth:`to_dict`. Immutable, hashable, equal when both parts are equal.

    Collision (Eq. 7-8): ``normal_dissipation_kg`` K_n, ``tangential_dissipation_kg`` K_tg,
    ``link_dissipation_kg_per_m2`` K_v. Social repulsion (Eq. 16): ``social_strength_n`` A, ``social_range_m`` B,
    ``social_anisotropy`` λ (1 = isotropic), applied between pedestrians whose surface gap is below
    ``social_cutoff_m`` and from walls closer than that (``wall_social_strength_n``, ``wall_social_range_m``: the
    walls' own A and B, None: the pedestrians'). Vision (:mod:`crowd_env.walking.vision`, ``vision_*``) and the
    time-to-collision interaction (:mod:`crowd_env.walking.time_to_collision`, ``ttc_*``) are off by default.
    A simulator given these reads ``physics`` (:class:`~crowd_env.core.Simulator`) and the calibrated agent
    :attr:`walking_bundle`.
    """

    physics: PhysicsParams
    walking: WalkingParams
    walking_bundle: WalkingParams = field(compare=False)  # resolved once: what the kernels take

    def __init__(self, physics: PhysicsParams | None = None, walking: WalkingParams | None = None, **values):
        physics = PhysicsParams() if physics is None else physics
        walking = WalkingParams() if walking is None else walking
        if not isinstance(physics, PhysicsParams):
            raise ParameterError(f"physics must be a PhysicsParams, got {type(physics).__name__}")
        if not isinstance(walking, WalkingParams):
            raise ParameterError(f"walking must be a WalkingParams, got {type(walking).__name__}")
        extra = values.pop("extra", None)  # the earlier catch-all of unknown names: refused, each by its name
        if extra:
            raise UnknownParameterError(f"unknown model parameter(s): {sorted(extra)}; known: {sorted(_WHERE)}")
        if values:
            _unknown(values)
            physics_changes, groups = {}, {}
            for name, value in values.items():
                group, field = _WHERE[name]
                if group is None:
                    physics_changes[field] = value
                else:
                    groups.setdefault(group, {})[field] = value
            if physics_changes:
                physics = dataclasses.replace(physics, **physics_changes)
            if groups:
                walking = walking._replace(**{g: getattr(walking, g)._replace(**changes) for g, changes in groups.items()})
        walking.checked()
        object.__setattr__(self, "physics", physics)
        object.__setattr__(self, "walking", walking)
        object.__setattr__(self, "walking_bundle", walking.resolved())

    @classmethod
    def from_dict(cls, values: dict) -> "ModelParams":
        """Build from a mapping of flat names (:meth:`to_dict`'s), rejecting unknown keys by name."""
        _unknown(values)
        return cls(**values)

    def replace(self, **changes) -> "ModelParams":
        """A copy with some parameters changed, by their flat names (unknown names raise :class:`ParameterError`)."""
        _unknown(changes)
        return ModelParams(self.physics, self.walking, **changes)

    def to_dict(self) -> dict:
        """Every parameter by its flat name, the values as given (what a stored configuration holds)."""
        return {name: getattr(self, name) for name in _NAMES}

    @property
    def wall_strength_n(self) -> float:
        """The walls' A: ``wall_social_strength_n``, or the pedestrians' when None."""
        return self.walking_bundle.wall_social.strength_n

    @property
    def wall_range_m(self) -> float:
        """The walls' B: ``wall_social_range_m``, or the pedestrians' when None."""
        return self.walking_bundle.wall_social.range_m

    @property
    def interaction_reach_m(self) -> float:
        """How far beyond the bodies the walking model's forces reach, ``social_cutoff_m``: a periodic simulator
        must be longer than 2 (2 r_max + this) (:class:`~crowd_env.core.Simulator`)."""
        return float(self.walking.social.cutoff_m)

    def __reduce__(self):
        return ModelParams, (self.physics, self.walking)

    def __repr__(self) -> str:
        return f"ModelParams({', '.join(f'{name}={getattr(self, name)!r}' for name in _NAMES)})"


for _name, (_group, _field) in _WHERE.items():  # every flat name as a read-only attribute
    _get = operator.attrgetter(f"physics.{_field}" if _group is None else f"walking.{_group}.{_field}")
    setattr(ModelParams, _name, property(_get, doc=f"``{_name}`` (module docstring)."))
del _name, _group, _field, _get, _default
