"""Command-line options shared by the commands: the Seyfried geometry and navigation flags and the model
configuration they describe (``crowd-bottleneck``, ``crowd-calibrate``), ``KEY=VALUE`` lists (``--param``,
``--scenario-option``), the default policy resolver (``crowd-evaluate``, ``crowd-train-ppo``, ``crowd-video``)
and the problem a policy runs on (the configuration recorded beside a saved model, ``--scenario``,
``--scenario-option``, ``--controlled``, ``--frame-skip``, ``--max-time``: :func:`policy_run_setup`, one
function for ``crowd-evaluate`` and ``crowd-video rollout``)."""
from __future__ import annotations

import json
import os

from ..walking.model import ModelParams
from ..errors import OptionError
from ..walking.presets import DEFAULT_PRESET, get_preset
from ..experiments.validation.bottleneck import GEOMETRY_OPTIONS, bottleneck_config, model_params
from ..experiments.validation.calibration.tasks import body_clearance_m
from ..experiments.running.evaluation import (DEFAULT_POLICY_RESOLVER, ScenarioSpec, episode_setup,
                                              recorded_env_config)

__all__ = ["add_geometry_arguments", "model_params_from_args", "navigation_clearance_from_args", "radius_from_args",
           "config_of",
           "DEFAULT_POLICY_RESOLVER", "key_values", "policy_env_options", "MODEL_ENV_KEYS", "PICKLED_MODELS_NOTE",
           "policy_run_setup", "DEFAULT_SCENARIO"]

# Said wherever a command takes a saved model (the --help of crowd-evaluate, crowd-video, crowd-scorecard).
PICKLED_MODELS_NOTE = ("SB3 .zip models and crowd-train-rllib run folders are pickles, which run code when loaded: load "
                       "them only from sources you trust; share a policy as .npz (crowd-convert-policy), which holds "
                       "data only, as does crowd-train-mappo's policy.pt")
DEFAULT_SCENARIO = "seyfried_bottleneck"



def add_key_values(group, flag: str, help: str, *, metavar: str = "NAME=VALUE") -> None:
    """A ``NAME=VALUE ...`` option (read with :func:`key_values`): given once with several items or repeated, every
    item counts (``--param a=1 --param b=2`` is ``--param a=1 b=2``); a repeat never replaces the items before it."""
    group.add_argument(flag, nargs="+", action="extend", default=[], metavar=metavar, help=f"{help} (repeatable)")


def json_or_text(value: str):
    """A command-line value read as JSON when it is JSON (numbers, true, false, null, lists, ...), else kept as text."""
    try:
        return json.loads(value)
    except json.JSONDecodeError:
        return value


def key_values(items, usage: str, *, parse=json_or_text) -> dict:
    """``["k=v", ...]`` → ``{k: v}``, each v read by ``parse`` (default :func:`json_or_text`); an item without ``=``
    or without a name raises :class:`~crowd_env.errors.OptionError` ``f"{usage}, got {item!r}"``, and so does a name
    given twice (which value was meant, the command cannot know). Every command's NAME=VALUE items go through here."""
    out = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise OptionError(f"{usage}, got {item!r}")
        if key in out:
            raise OptionError(f"{usage.split()[0]}: {key!r} is given twice ({out[key]!r} and {value!r}); give it once")
        out[key] = parse(value)
    return out


MODEL_ENV_KEYS = ("n_neighbors", "n_rays", "frame_skip", "heading_target", "params")


def policy_env_options(model_path=None, frame_skip=None, controlled="all") -> dict:
    """Environment options of a policy run: the :data:`MODEL_ENV_KEYS` of the ``env_config.json`` beside the
    saved model ``model_path`` (when there is one; the observation layout and decision interval it was
    trained with), ``frame_skip`` when given (wins), and ``controlled`` ("all", or JSON such as a count, a
    fraction or a list of ids, or comma-separated ids)."""
    out = {}
    if model_path:
        cfg_path = os.path.join(os.path.dirname(os.path.abspath(model_path)), "env_config.json")
        if os.path.exists(cfg_path):
            with open(cfg_path) as fh:
                cfg = json.load(fh)
            out.update({key: cfg[key] for key in MODEL_ENV_KEYS if key in cfg})
    if frame_skip is not None:
        out["frame_skip"] = frame_skip
    if controlled != "all":
        try:
            controlled = json.loads(controlled)
        except json.JSONDecodeError:
            controlled = controlled.split(",")
    out["controlled"] = controlled
    return out


def policy_run_setup(model=None, *, scenario=None, scenario_option=(), widths=None, max_time=None, controlled=None,
                     frame_skip=None, use_recorded: bool = True, default_max_time_s: float) -> tuple:
    """``(scenarios, env_options, max_time_s, source)`` of the episodes a policy runs on, as ``crowd-evaluate`` and
    ``crowd-video rollout`` take them: with a saved ``model`` (a path; ``use_recorded``) whose ``env_config.json``
    exists, the configuration recorded there (scenario and its options, observation options, decision interval, its
    episode length) with the flags given explicitly on top (``scenario`` another than the recorded one starts from
    its own default options); otherwise the defaults (:data:`DEFAULT_SCENARIO`, every pedestrian controlled,
    ``default_max_time_s``) with the flags on top. ``widths``: one scenario per bottleneck width (``width_m``).
    ``source`` says which configuration, and which flags overrode it, for the printout. A malformed
    ``scenario_option`` raises :class:`~crowd_env.errors.OptionError`."""
    options = key_values(scenario_option, "--scenario-option needs key=value")
    recorded, path = recorded_env_config(model) if model and use_recorded else (None, None)
    if recorded is not None:
        spec, env_options, recorded_max_time = episode_setup(recorded)
        name = spec.scenario if scenario in (None, spec.scenario) else scenario
        base = dict(spec.scenario_options or {}) if name == spec.scenario else {}
        flags = [f for f, given in (("--scenario", name != spec.scenario), ("--scenario-option", bool(options)),
                                    ("--widths", bool(widths)), ("--max-time", max_time is not None),
                                    ("--controlled", controlled is not None),
                                    ("--frame-skip", frame_skip is not None)) if given]
        source = f"recorded with the model: {path}" + (f", overridden by {' '.join(flags)}" if flags else "")
        if frame_skip is not None:
            env_options["frame_skip"] = frame_skip
        if controlled is not None:
            env_options["controlled"] = policy_env_options(controlled=controlled)["controlled"]
        if max_time is None:
            max_time = default_max_time_s if recorded_max_time is None else recorded_max_time
    else:
        name, base = scenario or DEFAULT_SCENARIO, {}
        env_options = policy_env_options(model, frame_skip, controlled or "all")
        max_time = default_max_time_s if max_time is None else max_time
        source = ("the command's defaults and flags" + (" (--no-recorded-config)" if model and not use_recorded else
                                                        f" (no env_config.json beside {model})" if model else ""))
    options = {**base, **options}
    if widths:
        scenarios = [ScenarioSpec(name, {**options, "width_m": w}) for w in widths]
    else:
        scenarios = [ScenarioSpec(name, options or None)]
    return scenarios, env_options, max_time, source


def add_geometry_arguments(group, clearance_help: str, wall_slowdown_where: str = "the bottleneck's field") -> None:
    """The scenario's geometry and navigation options."""
    for flag, (_, default) in GEOMETRY_OPTIONS.items():
        if flag == "radius":  # the preset's body (Preset.radius_m), resolved with the preset in config_of
            group.add_argument("--radius", type=float, default=None, dest="radius",
                               help=f"every pedestrian's radius (m; default the preset's: {default} unless it calibrated "
                                    "its body)")
            continue
        group.add_argument(f"--{flag.replace('_', '-')}", type=float, default=default, dest=flag,
                           help=f"default {default}")
    group.add_argument("--navigation-clearance", type=float, default=None, dest="navigation_clearance",
                       help=clearance_help)
    add_wall_slowdown_argument(group, wall_slowdown_where)


def add_wall_slowdown_argument(group, where: str) -> None:
    """``--navigation-wall-slowdown DIST FACTOR`` (``args.navigation_wall_slowdown``: None or two floats) in the
    navigation fields ``where`` names."""
    group.add_argument("--navigation-wall-slowdown", type=float, nargs=2, default=None, metavar=("DIST", "FACTOR"),
                       dest="navigation_wall_slowdown",
                       help="slower wavefront speed near walls, an option the paper describes with Eq. 11 but does not "
                            "use: V is multiplied by FACTOR in (0, 1] within DIST m of a wall, so that desired "
                            f"directions keep away from walls, in {where}; default off (V = 1 everywhere, as in the "
                            "paper)")


def model_params_from_args(args) -> ModelParams:
    """The preset's model (``--preset``) with the explicit flags (``--A``, ``--B``, ..., ``--param``) on top."""
    changes = {}
    for name in ("social_strength_n", "social_range_m", "social_anisotropy", "normal_dissipation_kg"):
        if getattr(args, name) is not None:
            changes[name] = getattr(args, name)
    changes.update(key_values(args.param, "--param expects NAME=VALUE"))
    if args.no_social:
        changes["social_forces"] = False
    if args.no_rotation:
        changes["rotation"] = False
    return model_params(getattr(args, "preset", DEFAULT_PRESET), changes)


def navigation_clearance_from_args(args) -> float:
    """--navigation-clearance if given, else the preset's; where the preset's field is its body's configuration space
    (clearance = its radius) and ``--radius`` gives another body, that body's (clearance = --radius), as
    :func:`~crowd_env.experiments.validation.calibration.tasks.body_clearance_m` (the rule of ``with_body``) moves it for crowd-virtual-experiments and
    the calibration's free radius; a point field (clearance 0) stays one."""
    value = getattr(args, "navigation_clearance", None)
    if value is not None:
        return float(value)
    preset = get_preset(getattr(args, "preset", DEFAULT_PRESET))
    radius = getattr(args, "radius", None)
    if radius is None:
        return float(preset.navigation_clearance_m)
    return body_clearance_m(preset.navigation_clearance_m, preset.radius_m, radius)


def radius_from_args(args) -> float:
    """--radius if given, else the preset's body (:attr:`~crowd_env.walking.presets.Preset.radius_m`)."""
    value = getattr(args, "radius", None)
    return float(get_preset(getattr(args, "preset", DEFAULT_PRESET)).radius_m if value is None else value)


def config_of(args, params: ModelParams) -> dict:
    """The configuration of the runs the flags describe
    (:func:`~crowd_env.experiments.validation.bottleneck.bottleneck_config`)."""
    return bottleneck_config(params, navigation_clearance_m=navigation_clearance_from_args(args),
                             max_time_s=args.max_time,
                             navigation_wall_slowdown=getattr(args, "navigation_wall_slowdown", None),
                             stall_window_s=getattr(args, "stall_window", None),
                             stall_speed_m_s=getattr(args, "stall_speed", None),
                             **{opt: radius_from_args(args) if flag == "radius" else getattr(args, flag)
                                for flag, (opt, _) in GEOMETRY_OPTIONS.items()})
