"""Shared helpers of the whole test suite.

The test folders mirror the package (tests/core, tests/walking, tests/scenarios, tests/analysis,
tests/experiments, tests/envs, tests/baselines) and are packages (``__init__.py``), so test modules of the
same name in different folders do not clash and import the helpers of a conftest by its package name
(``from tests.conftest import DATA``). Folder-specific helpers live in that folder's conftest.py.
"""
import functools
import importlib.util
import os
import shutil
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]  # the repository root
DATA = ROOT / "tests" / "data"  # stored states and matrices of regressions


_KEY_FOLDER = []  # the temporary folder of the session's signing key, when pytest_configure made one


def pytest_configure(config):
    """The signing key of checkpoints (crowd_env.files.secret_path) in a temporary folder of this session, not in
    the account's own data folder; the commands the tests start in other processes inherit it."""
    if not os.environ.get("CROWD_ENV_SECRET_FILE"):
        _KEY_FOLDER.append(tempfile.mkdtemp(prefix="crowd_env_key_"))
        os.environ["CROWD_ENV_SECRET_FILE"] = os.path.join(_KEY_FOLDER[0], "secret.key")


def pytest_unconfigure(config):
    for folder in _KEY_FOLDER:
        shutil.rmtree(folder, ignore_errors=True)


def pytest_sessionstart(session):
    """On a cold numba cache (a fresh clone): the compiled rollout's kernels compiled in two processes at once
    before the first test, as the README's main job shares them between its workers
    (:func:`crowd_env.experiments.running.warmup.warm_up`); the first test to run a rollout would otherwise compile
    them all on one core (about 60 s). Nothing when the rollout is cached; a stale plan costs time, never a result."""
    from crowd_env.experiments.running.warmup import warm_up

    with ProcessPoolExecutor(max_workers=2) as pool:  # its processes start at the first task: none when cached
        warm_up(lambda fn, items: list(pool.map(fn, items)), 2)


class CodeRunningPayload:
    """An object whose unpickling creates the file ``flag``: a stand-in for the code a crafted pickle runs (the
    file-loading tests plant it and check that ``flag`` never appears)."""

    def __init__(self, flag):
        self.flag = str(flag)

    def __reduce__(self):
        return (open, (self.flag, "w"))


def plant_in_sb3_archive(path, flag, part: str = "data") -> None:
    """Rewrite the SB3 archive ``path`` with a :class:`CodeRunningPayload` in ``part``: ``"data"`` as its pickled
    policy class (which SB3's loader unpickles), ``"policy.pth"`` as a weight of its state dict."""
    import base64
    import io
    import json
    import pickle
    import zipfile

    import torch

    with zipfile.ZipFile(path) as z:
        parts = {name: z.read(name) for name in z.namelist()}
    if part == "data":
        data = json.loads(parts["data"])
        data["policy_class"][":serialized:"] = base64.b64encode(pickle.dumps(CodeRunningPayload(flag))).decode()
        parts["data"] = json.dumps(data).encode()
    else:
        buffer = io.BytesIO()
        torch.save({"mlp_extractor.policy_net.0.weight": CodeRunningPayload(flag)}, buffer)
        parts[part] = buffer.getvalue()
    with zipfile.ZipFile(path, "w") as z:
        for name, blob in parts.items():
            z.writestr(name, blob)


def load_script(name):
    """The thin entry point ``scripts/<name>.py`` imported as a module (to call its ``main``)."""
    spec = importlib.util.spec_from_file_location(f"_script_{name}", ROOT / "scripts" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def room_geometry():
    """A 6 m x 4 m room with an exit strip x in [5.5, 6] m along its right end."""
    from shapely.geometry import box

    from crowd_env.core.geometry import Geometry

    return Geometry(box(0, 0, 6, 4), exits=[box(5.5, 0, 6, 4)], name="room")


@functools.lru_cache(maxsize=None)
def _seyfried_2009():
    from crowd_env.analysis.experiment import seyfried_2009

    return seyfried_2009()


def exp_js(b):
    """Seyfried et al. 2009's specific flow J_s (1/(m s)) at bottleneck width ``b`` (m) for N = 60."""
    exp = _seyfried_2009()
    return float(exp.specific_flow_per_m_s[exp.lookup(b, 60)[0]])
