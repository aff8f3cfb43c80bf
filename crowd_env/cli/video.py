"""Write an MP4 or GIF of a rollout of any policy on any scenario, or of a saved trajectory file.

    crowd-video rollout --policy baseline --scenario-option n_pedestrians=20 --controlled 5 --out runs/video/b.mp4
    crowd-video rollout --policy runs/ppo/model.zip --controlled 5 --out runs/video/ppo.gif --fps 10
    crowd-video trajectory out/run.txt --out out/run.mp4 --learned 0 3

rollout: one episode of the evaluation harness (as crowd-evaluate runs it: the same policy names,
import paths module:attribute, saved models, scenarios, --scenario-option, --controlled and seed). A saved
model (.zip) runs on the configuration recorded beside it (env_config.json: its scenario and options, the
observation options, the decision interval and the episode length), as crowd-evaluate --model does; flags given
explicitly override it, --no-recorded-config ignores it, and the command prints which configuration it films.
trajectory: a trajectory file in PedPy's text format (crowd_env's export, e.g.
crowd-bottleneck --trajectories) with its geometry JSON, by default <stem>.geometry.json beside <stem>.txt (where the
export writes it; --geometry otherwise). Trajectory files hold no radii (--radius), no learned/background
split (--learned) and no percussions.

Frames: learned pedestrians blue, background grey, each heading a line from the centre to the rim,
contact percussions (rollouts) as lines between touching pedestrians or to the wall, wider and redder
with the normal percussion of the steps since the previous frame (darkest from --percussion-scale on).

Time: a frame every --every environment steps (rollout) or file frames (trajectory), i.e. every
EVERY x step simulated seconds (step: the environment's decision interval, frame_skip x 0.01 s, or
1 / the file's frame rate). Frames per second follow simulated time: without --fps the video plays in
real time (fps = 1 / (EVERY x step)); --fps alone takes a frame every 1/FPS simulated seconds (which must
be a whole number of steps); with both, the video plays FPS x EVERY x step times real time; with neither,
real time at the largest rate up to 25 fps. The extension picks the format: .mp4 (needs imageio-ffmpeg)
or .gif (pillow; fps must divide 100); both come with pip install 'crowd_env[video]'.
"""
from __future__ import annotations

import argparse
import os
import sys

from ..errors import CrowdEnvError
from ..experiments.output.video import record_rollout, record_trajectory_file
from ..experiments.running.evaluation import describe_setup
from .options import add_key_values, DEFAULT_POLICY_RESOLVER, DEFAULT_SCENARIO, PICKLED_MODELS_NOTE, policy_run_setup

DEFAULT_MAX_TIME_S = 30.0


def _timing(ap) -> None:
    ap.add_argument("--out", required=True, metavar="PATH", help="the video file: PATH.mp4 or PATH.gif")
    ap.add_argument("--fps", type=float, default=None,
                    help="video frames per second (default: real time, 1 / (EVERY x step), at most 25 without "
                         "--every); alone, one frame every 1/FPS simulated seconds (real time)")
    ap.add_argument("--every", type=int, default=None, metavar="K",
                    help="frame stride: a frame every K environment steps / file frames (default: from --fps)")


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="crowd-video", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="source", required=True, metavar="{rollout,trajectory}")
    ro = sub.add_parser("rollout", help="one episode of a policy on a scenario", description=__doc__,
                        formatter_class=argparse.RawDescriptionHelpFormatter)
    ro.add_argument("--policy", default="baseline",
                    help="a name the resolver knows (baseline, random, zero), a policy file (.npz), a saved SB3 "
                         "model (.zip; its env_config.json sets the observation layout) or an import path "
                         f"module:attribute. {PICKLED_MODELS_NOTE}")
    ro.add_argument("--policy-resolver", default=DEFAULT_POLICY_RESOLVER, metavar="MODULE:FUNCTION",
                    help=f"resolve(spec, name=None) -> policy for names and models (default {DEFAULT_POLICY_RESOLVER})")
    ro.add_argument("--no-recorded-config", action="store_true",
                    help="ignore the env_config.json beside a saved --policy model (default: film it on that problem)")
    ro.add_argument("--scenario", default=None,
                    help=f"a registered scenario name (default: the model's env_config.json, else {DEFAULT_SCENARIO})")
    add_key_values(ro, "--scenario-option", metavar="KEY=VALUE",
                   help="scenario option (JSON values) on top of the recorded or default ones, e.g. "
                        "n_pedestrians=20")
    ro.add_argument("--seed", type=int, default=0)
    ro.add_argument("--controlled", default=None, help="'all', a count, a fraction or comma-separated ids: the "
                    "pedestrians the policy drives (blue); the others follow the background policy (grey) "
                    "(default: recorded, else all)")
    ro.add_argument("--frame-skip", type=int, default=None, help="decision interval in simulator steps "
                    "(default: the model's env_config.json, else 1)")
    ro.add_argument("--max-time", type=float, default=None,
                    help=f"simulated seconds at most (default: the model's recorded episode length, else "
                         f"{DEFAULT_MAX_TIME_S:g})")
    ro.add_argument("--percussion-scale", type=float, default=20.0, metavar="KG_M_S",
                    help="percussion (kg m/s) from which contact lines are widest and darkest (default 20)")
    _timing(ro)
    tr = sub.add_parser("trajectory", help="a saved trajectory file (PedPy text format) with its geometry",
                        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    tr.add_argument("trajectory", help="trajectory file (.txt, PedPy's format, e.g. written by crowd_env's export)")
    tr.add_argument("--geometry", default=None, metavar="JSON",
                    help="geometry file (crowd_env's geometry JSON; default <stem>.geometry.json beside <stem>.txt)")
    tr.add_argument("--learned", type=int, nargs="*", default=[], metavar="ID",
                    help="pedestrian ids to draw as learned (blue); the others are grey")
    tr.add_argument("--radius", type=float, default=None, metavar="M",
                    help="radius of every pedestrian (files hold none; default 0.23 m)")
    tr.add_argument("--max-time", type=float, default=None, help="simulated seconds after the first frame at most")
    _timing(tr)
    return ap


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    try:
        if args.source == "rollout":
            (spec,), env_options, max_time, source = policy_run_setup(
                args.policy if args.policy.endswith(".zip") else None, scenario=args.scenario,
                scenario_option=args.scenario_option, max_time=args.max_time, controlled=args.controlled,
                frame_skip=args.frame_skip, use_recorded=not args.no_recorded_config,
                default_max_time_s=DEFAULT_MAX_TIME_S)
            print(f"video configuration: {source}\n  {describe_setup([spec], env_options, max_time)}; seed {args.seed}")
            metrics, info = record_rollout(args.policy, args.out, spec, args.seed, env_options=env_options,
                                           max_time_s=max_time, fps=args.fps,
                                           every=args.every, resolver=args.policy_resolver,
                                           percussion_scale_kg_m_s=args.percussion_scale)
            print(f"{metrics.policy} on {metrics.scenario}, seed {metrics.seed}: {metrics.simulated_time_s:.2f} s "
                  f"simulated, {metrics.n_evacuated}/{metrics.n_pedestrians} evacuated, "
                  f"{metrics.n_percussions} percussions")
        else:
            info = record_trajectory_file(args.trajectory, args.out, geometry=args.geometry, fps=args.fps,
                                          every=args.every, max_time_s=args.max_time, radius_m=args.radius,
                                          learned_ids=args.learned)
    except CrowdEnvError as exc:
        raise SystemExit(f"error: {exc}") from None
    print(f"wrote {info.path}: {info.n_frames} frames of {info.size[0]}x{info.size[1]} px at {info.fps:g} fps, "
          f"one per {info.frame_interval_s:g} s simulated (x{info.speed:g} real time)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
