"""The one-line notice at the first compilation of a crowd_env kernel, and silence for cached kernels."""
import io
import subprocess
import sys

import numba as nb
import pytest
from numba.core import event

from crowd_env.compilation import MESSAGE, _FirstCompilation, notice


# a subprocess's notice at the first moment of a compilation (the tiny kernels below compile faster than the delay)
_AT_ONCE = "import numpy as np; import crowd_env.compilation as c; c.announce_compilation().delay_s = 0; "


def _kernel(module: str, name: str = "f", callee=None):
    """A numba kernel (compiled at its first call) whose function claims to live in ``module``."""
    def f(x):
        return x + 1

    def g(x):
        return callee(x) + 1

    fn = g if callee is not None else f
    fn.__module__, fn.__name__ = module, name
    return nb.njit(fn)


def _compile_a_kernel(module: str, name: str = "f", callee=None):
    kernel = _kernel(module, name, callee)
    kernel(1)
    return kernel


def test_each_kernel_that_compiles_says_what_it_compiles_once():
    """Regression (issue 52): 'compiling its numerical kernels (the first run on this machine only: up to a
    minute)' appeared eight times, in every first use of another part (environment, corridor, vector environment,
    training, sweep, ...), never saying what compiled. A compilation started by a crowd_env kernel now names the
    part and the kernel, once per kernel, the first line of a process saying why and for how long; a kernel
    compiled inside another's compilation says nothing of its own."""
    out = io.StringIO()
    listener = _FirstCompilation(out, delay_s=0.0)
    event.register("numba:compile", listener)
    try:
        _compile_a_kernel("somebody_else.module")
        assert out.getvalue() == ""  # another package's kernel: nothing
        _compile_a_kernel("crowd_env.core.something", "first_core_kernel")
        _compile_a_kernel("crowd_env.core.something", "first_core_kernel")  # another function of the same name
        inner = _kernel("crowd_env.walking.inner", "inner")  # compiled inside outer's compilation
        _compile_a_kernel("crowd_env.envs.observations.x", "outer", callee=inner)
        assert listener.depth == 0 and inner.signatures
    finally:
        event.unregister("numba:compile", listener)
    lines = out.getvalue().splitlines()
    assert lines == [notice("crowd_env.core.something", "first_core_kernel"),
                     notice("crowd_env.envs.observations.x", "outer", first=False)]
    assert lines[0].startswith(f"{MESSAGE} the simulation core: crowd_env.core.something.first_core_kernel. Each part "
                               "of crowd_env (") and "up to about a minute of one core each" in lines[0]
    assert lines[1] == f"{MESSAGE} the RL environment's observations: crowd_env.envs.observations.x.outer"
    assert "first run on this machine only" not in out.getvalue()


def test_a_compilation_shorter_than_the_delay_says_nothing():
    out = io.StringIO()
    listener = _FirstCompilation(out, delay_s=60.0)
    event.register("numba:compile", listener)
    try:
        _compile_a_kernel("crowd_env.core.quick", "quick")
    finally:
        event.unregister("numba:compile", listener)
    assert out.getvalue() == "" and listener._timer is None


def test_compiling_is_true_while_a_kernel_compiles_or_workers_compile():
    import crowd_env.compilation as compilation

    listener = compilation.announce_compilation()
    if listener is None:
        pytest.skip("CROWD_ENV_QUIET=1: nothing listens")
    seen = []

    def spy(x):
        seen.append(compilation.compiling())
        return x

    class Spy(event.Listener):  # registered after the notice's listener: it sees its count
        def on_start(self, ev):
            spy(None)

        def on_end(self, ev):
            pass

    probe = Spy()
    event.register("numba:compile", probe)
    try:
        _compile_a_kernel("somebody_else.probe")
    finally:
        event.unregister("numba:compile", probe)
    assert seen == [True] and not compilation.compiling()
    with listener.in_workers():
        assert compilation.compiling()
    assert not compilation.compiling()


def test_cached_kernels_say_nothing_and_the_notice_can_be_silenced(tmp_path):
    code = _AT_ONCE + "from crowd_env.core.angles import direction_angles_rad; direction_angles_rad(np.zeros((3, 2)))"
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

    code = _AT_ONCE + "from crowd_env.core.angles import direction_angles_rad; direction_angles_rad(np.zeros((3, 2)))"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba-cache"))
    env.pop("CROWD_ENV_QUIET", None)
    first = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
    assert MESSAGE in first.stderr  # an empty cache folder: compiled here
    assert any((tmp_path / "numba-cache").rglob("*.nbi"))
    again = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
    assert MESSAGE not in again.stderr
