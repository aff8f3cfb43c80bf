"""Say so when numba compiles crowd_env's kernels: the first run on a machine spends up to a minute compiling.

The kernels are compiled on first use and cached (``cache=True``) in the ``__pycache__`` folders beside the
modules, so only the first run on a machine (or after a kernel changed) pays for it: measured on this project's
2-core machine, a first bottleneck run compiles for about 60 s of one core (process CPU time,
``benchmarks/compile_profile.py``), nearly all of it the compiled rollout
(``experiments.running.rollout.rollout_steps``, with the core's step, the fused step and the impact solvers),
and takes 1 s once cached; the README's main job, whose two worker processes share the compilation
(:mod:`crowd_env.experiments.running.warmup`), about 52 s cold (``benchmarks/cold_start.py``). Without a word that
looks like a hang, so :func:`announce_compilation` prints one line to standard error at the first compilation of a
crowd_env kernel in a process, and nothing when every kernel comes from the cache. ``CROWD_ENV_QUIET=1`` silences
it. Workers on other machines (a Ray cluster) compile their own copies unless the package's folders are shared;
point ``NUMBA_CACHE_DIR`` at a shared folder to share them.
"""
from __future__ import annotations

import os
import sys

from numba.core import event

__all__ = ["MESSAGE", "announce_compilation"]

MESSAGE = ("crowd_env: compiling its numerical kernels (the first run on this machine only: up to a minute; "
           "cached afterwards in crowd_env's __pycache__ folders)")


class _FirstCompilation(event.Listener):
    """Prints :data:`MESSAGE` at the first numba compilation of a crowd_env function, then stays quiet."""

    def __init__(self, stream=None):
        self.stream = stream
        self.said = False

    def on_start(self, ev) -> None:
        if self.said:
            return
        dispatcher = ev.data.get("dispatcher") if isinstance(ev.data, dict) else None
        module = getattr(getattr(dispatcher, "py_func", None), "__module__", "") or ""
        if module.split(".")[0] == "crowd_env":
            self.say()

    def say(self) -> None:
        """Print :data:`MESSAGE` unless it was printed already (a process pool says it before its workers
        compile: :func:`crowd_env.experiments.running.warmup.warm_up`)."""
        if not self.said:
            self.said = True
            print(MESSAGE, file=self.stream or sys.stderr, flush=True)

    def on_end(self, ev) -> None:
        pass


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
