"""Shared helpers of the whole test suite.

The test folders mirror the package (tests/core, tests/walking, tests/scenarios, tests/analysis,
tests/experiments, tests/envs, tests/baselines) and are packages (``__init__.py``), so test modules of the
same name in different folders do not clash and import the helpers of a conftest by its package name
(``from tests.conftest import DATA``). Folder-specific helpers live in that folder's conftest.py.
"""
import functools
import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]  # the repository root
DATA = ROOT / "tests" / "data"  # stored states and matrices of regressions


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
