"""The one-line notice at the first compilation of a crowd_env kernel, and silence for cached kernels."""
import io
import subprocess
import sys

import numba as nb
from numba.core import event

from crowd_env.compilation import MESSAGE, _FirstCompilation


def _compile_a_kernel(module: str):
    def f(x):
        return x + 1
    f.__module__ = module
    nb.njit(f)(1)


def test_the_first_crowd_env_compilation_prints_one_line_then_nothing():
    out = io.StringIO()
    listener = _FirstCompilation(out)
    event.register("numba:compile", listener)
    try:
        _compile_a_kernel("somebody_else.module")
        assert out.getvalue() == ""  # another package's kernel: nothing
        _compile_a_kernel("crowd_env.core.something")
        _compile_a_kernel("crowd_env.walking.other")
    finally:
        event.unregister("numba:compile", listener)
    assert out.getvalue() == MESSAGE + "\n"


def test_cached_kernels_say_nothing_and_the_notice_can_be_silenced(tmp_path):
    code = "from crowd_env.core.angles import direction_angles_rad; import numpy as np; direction_angles_rad(np.zeros((3, 2)))"
    first = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    again = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert MESSAGE not in again.stderr  # loaded from numba's cache: no compilation, no notice
    assert first.stderr.count(MESSAGE) <= 1
    quiet = subprocess.run([sys.executable, "-c", "import crowd_env.compilation as c; print(c.announce_compilation())"],
                           capture_output=True, text=True, check=True, env={"CROWD_ENV_QUIET": "1", "PATH": ""})
    assert quiet.stdout.strip() == "None"


def test_a_shared_numba_cache_dir_serves_a_second_process(tmp_path):
    """What docs/validation/calibration.md tells cluster users: NUMBA_CACHE_DIR at one folder, the first process
    compiles (and says so) and writes the kernels there, the next one loads them from it (and says nothing)."""
    import os

    code = "from crowd_env.core.angles import direction_angles_rad; import numpy as np; direction_angles_rad(np.zeros((3, 2)))"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba-cache"))
    env.pop("CROWD_ENV_QUIET", None)
    first = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
    assert MESSAGE in first.stderr  # an empty cache folder: compiled here
    assert any((tmp_path / "numba-cache").rglob("*.nbi"))
    again = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
    assert MESSAGE not in again.stderr
