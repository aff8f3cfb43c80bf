"""A file is data: loading a policy or a run never runs code from it.

Every format crowd_env reads a shared policy or a kept run from is planted with a code-running pickle
(:class:`tests.conftest.CodeRunningPayload`: unpickling it creates a flag file); each load must raise a clear
error naming the file and leave no flag. A scan of the source (``crowd_env/``, ``baselines/``, ``scripts/``,
``benchmarks/``) finds every call that could unpickle a file outside :data:`ALLOWED`, each entry with the reason it
is safe. Elsewhere: an SB3 archive read by the converter (``tests/experiments/training/test_conversion.py``), SB3
and RLlib training checkpoints (``test_ppo.py``, ``test_rllib.py``), a run checkpoint signed under another key
(``test_checkpoint.py``) and the signed files themselves (``test_files.py``).
"""
from __future__ import annotations

import ast
import json
import os
import pickle
from pathlib import Path

import numpy as np
import pytest

from crowd_env.errors import CrowdEnvError, UntrustedFileError
from tests.conftest import CodeRunningPayload, load_script

ROOT = Path(__file__).resolve().parents[1]
SCANNED = ("crowd_env", "baselines", "scripts", "benchmarks")

# The calls that may unpickle, by (file, call), and why each is safe.
ALLOWED = {
    ("crowd_env/envs/vector.py", "import cloudpickle"):
        "the vector environment's copies and replies cross the pipes of its own worker processes, never a file",
    ("crowd_env/envs/vector.py", "cloudpickle.loads"): "the same: bytes this process or its own workers pickled",
    ("crowd_env/experiments/running/runner.py", "pickle.loads"):
        "read_checkpoint: only after read_signed checked the HMAC under this account's key",
    ("crowd_env/experiments/training/ppo.py", "VecNormalize.load"):
        "resuming: only after check_checkpoint checked the digest under this account's key",
    ("crowd_env/experiments/training/ppo.py", "PPO.load"): "the same",
    ("crowd_env/experiments/training/rllib.py", "restore_from_path"): "the same, for RLlib's checkpoints",
    ("crowd_env/experiments/training/rllib.py", "from_checkpoint"):
        "load_policy of an RLlib run folder the user passes: documented as pickles to load from trusted sources only",
    ("baselines/reference_policies.py", "PPO.load"):
        "SB3Policy of a .zip the user passes: documented (docstring, docs, --help) as pickles to load from trusted "
        "sources only; crowd-convert-policy makes the .npz to share",
}
_UNPICKLING_MODULES = {"pickle", "_pickle", "cloudpickle", "dill", "joblib", "marshal", "shelve"}
_LIBRARY_LOADERS = {"from_checkpoint", "restore_from_path", "read_pickle"}


def _unpickling_calls(tree: ast.AST):
    """``(line, what)`` of every place in ``tree`` that may unpickle: an import of a pickling module other than
    ``pickle`` itself (which also pickles), a load through one, ``torch.load`` without ``weights_only=True``, any
    call with ``allow_pickle`` other than False, a class's ``.load`` (SB3's ``PPO.load``, ``VecNormalize.load``)
    and RLlib's / pandas' loaders."""
    for node in ast.walk(tree):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            names = [node.module or ""] if isinstance(node, ast.ImportFrom) else [a.name for a in node.names]
            for name in names:
                if name.split(".")[0] in _UNPICKLING_MODULES - {"pickle"}:
                    yield node.lineno, f"import {name}"
            continue
        if not isinstance(node, ast.Call):
            continue
        f = node.func
        owner = f.value.id if isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) else None
        attr = f.attr if isinstance(f, ast.Attribute) else None
        keywords = {k.arg: k.value for k in node.keywords}
        if owner in _UNPICKLING_MODULES and attr in ("load", "loads", "Unpickler", "open"):
            yield node.lineno, f"{owner}.{attr}"
        elif owner == "torch" and attr == "load":
            safe = keywords.get("weights_only")
            if not (isinstance(safe, ast.Constant) and safe.value is True):
                yield node.lineno, "torch.load without weights_only=True"
        elif "allow_pickle" in keywords and not (isinstance(keywords["allow_pickle"], ast.Constant)
                                                 and keywords["allow_pickle"].value is False):
            yield node.lineno, "allow_pickle=True"
        elif attr == "load" and owner and owner[0].isupper():
            yield node.lineno, f"{owner}.load"
        elif attr in _LIBRARY_LOADERS:
            yield node.lineno, attr


def _found() -> list:
    out = []
    for top in SCANNED:
        for path in sorted((ROOT / top).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            for line, what in _unpickling_calls(ast.parse(path.read_text(encoding="utf-8"))):
                out.append((rel, line, what))
    return out


def test_nothing_unpickles_a_file_outside_the_allowed_places():
    found = _found()
    stray = [f"{rel}:{line}: {what}" for rel, line, what in found if (rel, what) not in ALLOWED]
    assert not stray, "calls that may unpickle (run code from) a file; load data only, or add to ALLOWED with the " \
                      "reason it is safe:\n" + "\n".join(stray)
    unused = set(ALLOWED) - {(rel, what) for rel, _, what in found}
    assert not unused, f"ALLOWED names places that no longer unpickle: {sorted(unused)}"


def test_the_scan_finds_each_kind_of_unpickling_call():
    source = "\n".join([
        "import cloudpickle", "from dill import loads", "pickle.load(fh)", "pickle.loads(b)", "torch.load(p)",
        "torch.load(p, weights_only=False)", "np.load(p, allow_pickle=True)", "PPO.load(p)",
        "RLModule.from_checkpoint(p)", "algo.restore_from_path(p)",
        # safe: not reported
        "import pickle", "pickle.dumps(x)", "torch.load(p, weights_only=True)", "np.load(p, allow_pickle=False)",
        "json.load(fh)", "store.load(task)"])
    found = [what for _, what in sorted(_unpickling_calls(ast.parse(source)))]
    assert found == ["import cloudpickle", "import dill", "pickle.load", "pickle.loads", "torch.load without "
                     "weights_only=True", "torch.load without weights_only=True", "allow_pickle=True", "PPO.load",
                     "from_checkpoint", "restore_from_path"]


def test_the_commands_that_take_a_saved_model_say_it_may_run_code():
    from crowd_env.cli import evaluate, video
    from crowd_env.cli.options import PICKLED_MODELS_NOTE

    rollout = video.build_parser()._subparsers._group_actions[0].choices["rollout"]
    for parser in (evaluate.build_parser(), rollout):
        assert "".join(PICKLED_MODELS_NOTE.split()) in "".join(parser.format_help().split()), parser.prog  # rewrapped
    assert "pickles, which run code when loaded" in PICKLED_MODELS_NOTE


# --- each format, planted ------------------------------------------------------------------------------------
TINY = {"scenario": "polygon", "controlled": "all", "frame_skip": 10, "max_steps": 20,
        "scenario_options": {"walkable_area": [[0, 0], [1.6, 0], [1.6, 2.0], [0, 2.0]],
                             "exits": [[[1.6, 0.0], [1.6, 2.0]]], "n_pedestrians": 3,
                             "spawn_area": [[0.8, 0], [1.6, 0], [1.6, 2.0], [0.8, 2.0]]}}


def _mappo_policy(tmp_path, flag):
    """The file of issue 54: a .pt that looks like a MAPPO policy. Loaded by marl.load_policy, by the policy
    resolver of the commands and by crowd-evaluate."""
    pytest.importorskip("torchrl")
    import torch

    from baselines.reference_policies import as_policy
    from crowd_env.experiments.training import marl

    path = str(tmp_path / "evil_policy.pt")
    torch.save({"format": "x", "evil": CodeRunningPayload(flag)}, path)
    yield lambda: marl.load_policy(path), r"evil_policy.pt holds a reference to \w*\.open, not only the numbers"
    yield lambda: as_policy(path), "evil_policy.pt holds a reference to"
    yield (lambda: load_script("evaluate").main(["--policies", path, "--seeds", "0", "--out", str(tmp_path / "e")]),
           "error: .*evil_policy.pt holds a reference to")


def _mappo_checkpoint(tmp_path, flag):
    """A planted checkpoint in a crowd-train-mappo folder, resumed."""
    pytest.importorskip("torchrl")
    import torch

    from baselines.reference_policies import as_policy
    from crowd_env.experiments.training import marl

    out = tmp_path / "mappo"
    (out / "checkpoints").mkdir(parents=True)
    torch.save({"algorithm": "mappo", "actor": CodeRunningPayload(flag)}, out / "checkpoints" / "mappo_200_frames.pt")
    (out / "checkpoints" / "index.json").write_text(json.dumps(
        {"checkpoints": [{"timesteps": 200, "model": "mappo_200_frames.pt", "algorithm": "mappo"}]}))
    yield (lambda: marl.train(TINY, 400, str(out), algorithm="mappo", resolve=as_policy, resume=True,
                              frames_per_batch=200, eval_seeds=(5,), progress=lambda *a: None),
           "mappo_200_frames.pt holds a reference to")


def _run_checkpoint(tmp_path, flag):
    """A plain pickle planted as a run's checkpoint (a shared run folder, or a checkpoint from before they were
    signed), resumed by run_scenario."""
    from crowd_env.experiments.running.runner import RunCheckpoint, run_scenario
    from crowd_env.scenarios import make_scenario
    from crowd_env.walking.agent import SocialForceAgent

    path = tmp_path / "run.checkpoint.pkl"
    path.write_bytes(pickle.dumps({"key": "a", "sim": CodeRunningPayload(flag)}))
    sc = make_scenario("seyfried_bottleneck", width_m=1.0, n_pedestrians=4, seed=0)
    yield (lambda: run_scenario(sc, SocialForceAgent(sc.navigation()), max_time_s=1.0,
                                checkpoint=RunCheckpoint(str(path), key="a")),
           r"run.checkpoint.pkl is not a file crowd_env signed.*delete it to start that run afresh")


def _object_array_npz(path, flag, meta):
    np.savez(path, meta=np.array(json.dumps(meta)), frame=np.array([CodeRunningPayload(flag)], dtype=object),
             w0=np.array([CodeRunningPayload(flag)], dtype=object))


def _policy_file(tmp_path, flag):
    """A policy file (.npz) with a pickled object array, loaded by path and as a background policy."""
    from baselines.reference_policies import as_policy
    from crowd_env.envs import crowd_v0
    from crowd_env.envs.policy_files import POLICY_FILE_FORMAT, load_policy_file

    path = str(tmp_path / "evil.npz")
    _object_array_npz(path, flag, {"format": POLICY_FILE_FORMAT, "activation": "tanh", "output": "linear",
                                   "n_layers": 1})
    yield lambda: load_policy_file(path), "evil.npz is not a crowd_env policy file: Object arrays cannot be loaded"
    yield lambda: as_policy(path), "evil.npz is not a crowd_env policy file"
    yield lambda: crowd_v0.parallel_env(background_policy=path), "evil.npz is not a crowd_env policy file"


def _rimea_run(tmp_path, flag):
    """A run kept by crowd-rimea (.npz) with a pickled object array, read back by --resume."""
    from crowd_env.experiments.validation.rimea.suite import load_run

    path = str(tmp_path / "rimea_1_crowd_env.npz")
    _object_array_npz(path, flag, {"settings": {}})
    yield lambda: load_run(path, {}), r"rimea_1_crowd_env.npz is not a run kept by crowd-rimea \(ValueError: Object"


@pytest.mark.parametrize("planted", [_mappo_policy, _mappo_checkpoint, _run_checkpoint, _policy_file, _rimea_run])
def test_a_planted_payload_never_runs(tmp_path, planted):
    flag = tmp_path / "ran.flag"
    for load, message in planted(tmp_path, flag):
        with pytest.raises((CrowdEnvError, SystemExit), match=message) as info:
            load()
        assert not flag.exists(), f"{planted.__name__}: the payload ran"
        if planted in (_mappo_policy, _mappo_checkpoint, _run_checkpoint) and info.type is not SystemExit:
            assert info.type is UntrustedFileError
    assert os.listdir(tmp_path)  # the planted files were there
