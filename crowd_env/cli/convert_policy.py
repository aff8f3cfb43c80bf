"""Convert a trained model to a policy file (``.npz``), the format to share: arrays and JSON that load without
running any code, with the environment options the policy was trained with (observation layout, decision
interval, action bounds). An SB3 ``.zip`` holds pickles, which may run code when loaded; the conversion reads it
without unpickling anything (``crowd_env.experiments.training.conversion``)::

    crowd-convert-policy runs/ppo/model.zip --out runs/ppo/policy.npz     # env_config.json beside the model
    crowd-convert-policy runs/mappo --out runs/mappo/policy.npz           # a crowd-train-mappo run folder
    crowd-convert-policy my_model.zip --env-config my_env.json --out my_policy.npz

The policy file then goes wherever a policy does: ``crowd-evaluate --policies my_policy.npz``, ``crowd-video
rollout --policy my_policy.npz``, ``crowd-scorecard --policies my_policy.npz``, ``background_policy=``.
"""
from __future__ import annotations

import argparse
import json
import sys

from ..errors import CrowdEnvError
from ..experiments.training.conversion import convert_policy


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="crowd-convert-policy", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("model", help="an SB3 model (.zip: MlpPolicy, e.g. crowd-train-ppo's model.zip) or a "
                                  "crowd-train-mappo policy.pt or run folder")
    ap.add_argument("--out", required=True, help="the policy file to write (.npz)")
    ap.add_argument("--env-config", default=None, metavar="FILE",
                    help="JSON of the environment options the model was trained with (default: the env_config.json "
                         "beside the model, as the training commands write it)")
    return ap


def _env_config(path):
    """The JSON at ``path`` (None: None, the model's recorded options)."""
    if path is None:
        return None
    with open(path) as fh:
        return json.load(fh)


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    if not args.out.endswith(".npz"):
        raise SystemExit(f"error: --out must name a .npz file, got {args.out!r}")
    try:
        policy = convert_policy(args.model, args.out, env_config=_env_config(args.env_config))
    except (OSError, json.JSONDecodeError, CrowdEnvError) as exc:
        raise SystemExit(f"error: {exc}") from None
    bounds = f"[{policy.low.tolist()}, {policy.high.tolist()}]"
    print(f"wrote {args.out}: {policy.meta['algorithm']} policy, {policy.n_parameters} parameters, observations of "
          f"{policy.obs_dim} entries, actions in {bounds}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
