"""Say so when numba compiles crowd_env's kernels, and what for: a cold start can spend a minute or more compiling.

The kernels are compiled on first use and cached (``cache=True``) in the ``__pycache__`` folders beside the
modules (in ``NUMBA_CACHE_DIR`` when it is set), so each part of crowd_env pays for it once on a machine (or after
a kernel changed): the simulation step, the walking model, the environment's observations, the compiled rollout of
the scenario runs each compile on their first use, which is why a first environment, a first corridor, a first
vector environment and a first bottleneck run each compile something. The compiled rollout
(``experiments.running.rollout.rollout_steps``, with the core's step, the fused step and the impact solvers) takes
about 60 s of one core (process CPU time, ``benchmarks/compile_profile.py``); the README's main job, whose two
worker processes share it (:mod:`crowd_env.experiments.running.warmup`), took 48-59 s cold on 2 idle cores, 117 s
on 2 cores busy with other work (load average 2.6-5.2), and 6 s once cached; a first environment (made, reset,
stepped once; the simulation core's step, the walking model, the observations) 51-60 s cold in two runs at load
averages of 2.4-5.1 and 1.7 s cached (``docs/performance.md``, "Cold start").

Without a word that looks like a hang, so :func:`announce_compilation` prints one line to standard error when a
compilation of one of crowd_env's kernels is still running after :data:`NOTICE_DELAY_S` (:data:`MESSAGE`, the part
of crowd_env and the kernel; the first line of a process also says why and for how long), once per kernel, and
nothing when the kernels come from the cache or compile in a moment. :func:`compiling` says whether this process
is compiling numba kernels now (a sweep's progress bar shows it: :func:`crowd_env.experiments.running.backends.
execute`). ``CROWD_ENV_QUIET=1`` silences the notice. Workers on other machines (a Ray cluster) compile their own
copies unless the package's folders are shared; point ``NUMBA_CACHE_DIR`` at a shared folder to share them.
"""
from __future__ import annotations

import os
import sys
import threading
from contextlib import contextmanager

from numba.core import event

__all__ = ["MESSAGE", "NOTICE_DELAY_S", "PARTS", "announce_compilation", "compiling", "notice", "part_of"]

MESSAGE = "crowd_env: numba is compiling"  # the start of every notice
NOTICE_DELAY_S = 1.0  # a compilation still running after this long is announced; shorter ones say nothing

# The parts of crowd_env that compile kernels, by the package of the kernel that starts a compilation.
PARTS = {
    "crowd_env.experiments": "the compiled rollout of scenario runs (crowd-bottleneck, sweeps, calibration)",
    "crowd_env.envs": "the RL environment's observations",
    "crowd_env.walking": "the walking model",
    "crowd_env.core": "the simulation core",
    "crowd_env.analysis": "the measurements",
    "crowd_env.scenarios": "the scenarios",
}


def part_of(module: str) -> str:
    """The package of :data:`PARTS` a module belongs to (``crowd_env.core.step`` -> ``crowd_env.core``)."""
    return ".".join(module.split(".")[:2])


def notice(module: str, kernel: str, first: bool = True) -> str:
    """The line said when ``module.kernel`` compiles: which part of crowd_env and which kernel, and, for the first
    notice of a process (``first``), why and for how long."""
    part = PARTS.get(part_of(module), part_of(module))
    line = f"{MESSAGE} {part}: {module}.{kernel}"
    if not first:
        return line
    return (f"{line}. Each part of crowd_env (the simulation core, the walking model, the environment's observations, "
            "the rollout of scenario runs) compiles on its first use on this machine, up to about a minute of one "
            "core each (longer on a busy machine), then loads from the cache in crowd_env's __pycache__ folders")


class _FirstCompilation(event.Listener):
    """Prints :func:`notice` when a compilation started by a crowd_env kernel (not one nested inside another) is
    still running after ``delay_s`` seconds, once per kernel in the process (short compilations say nothing), and
    counts the compilations in progress (:func:`compiling`)."""

    def __init__(self, stream=None, delay_s: float = NOTICE_DELAY_S):
        self.stream = stream
        self.delay_s = delay_s
        self.said = set()  # the kernels announced, "module.name"
        self.depth = 0  # compilations in progress, nested ones included
        self.elsewhere = 0  # compilations this process waits for in its workers (a pool's warm-up)
        self._timer = None

    def on_start(self, ev) -> None:
        self.depth += 1
        if self.depth > 1:
            return
        dispatcher = ev.data.get("dispatcher") if isinstance(ev.data, dict) else None
        func = getattr(dispatcher, "py_func", None)
        module = getattr(func, "__module__", "") or ""
        if module.split(".")[0] != "crowd_env":
            return
        name = getattr(func, "__name__", "")
        if self.delay_s <= 0:
            self.say(module, name)
            return
        self._timer = threading.Timer(self.delay_s, self.say, (module, name))
        self._timer.daemon = True
        self._timer.start()

    def on_end(self, ev) -> None:
        self.depth = max(0, self.depth - 1)
        if self.depth == 0 and self._timer is not None:
            self._timer.cancel()
            self._timer = None

    def say(self, module: str, kernel: str) -> None:
        """Print the :func:`notice` of ``module.kernel`` unless it was printed already in this process (a process
        pool says it before its workers compile: :func:`crowd_env.experiments.running.warmup.warm_up`)."""
        key = f"{module}.{kernel}"
        if key not in self.said:
            print(notice(module, kernel, first=not self.said), file=self.stream or sys.stderr, flush=True)
            self.said.add(key)

    @contextmanager
    def in_workers(self):
        """While the block runs, :func:`compiling` is true: this process waits for kernels its workers compile."""
        self.elsewhere += 1
        try:
            yield
        finally:
            self.elsewhere -= 1


_LISTENER = None


def announce_compilation(stream=None) -> _FirstCompilation | None:
    """Register the one-line notice (once per process; not when ``CROWD_ENV_QUIET`` is set to 1). Returns the
    listener (None when silenced)."""
    global _LISTENER
    if os.environ.get("CROWD_ENV_QUIET", "") == "1":
        return None
    if _LISTENER is None:
        _LISTENER = _FirstCompilation(stream)
        event.register("numba:compile", _LISTENER)
    return _LISTENER


def compiling() -> bool:
    """Whether this process is compiling numba kernels now, or waiting for its workers to compile crowd_env's
    (False when the notice is silenced: nothing listens)."""
    return _LISTENER is not None and (_LISTENER.depth > 0 or _LISTENER.elsewhere > 0)
