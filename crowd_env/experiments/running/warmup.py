"""A cold start shared by the workers: each compiles one part of the compiled rollout's kernels.

The first run on a machine spends most of its time compiling (numba, ``cache=True``): the compiled rollout
(:func:`~crowd_env.experiments.running.rollout.rollout_steps`) compiles each kernel it calls (the impact stage,
the dense projection, the walking model's step, ...) before its own body. A pool of two worker processes that
both start a run on a cold cache compiles every one of them twice, side by side. :func:`warm_up` instead gives
each worker one part of the rollout's callees (:data:`~crowd_env.experiments.running.compile_plan.PARTS`: two
parts of about equal compile time, with the signatures the rollout calls them with) and waits for both; the runs
then find every callee in numba's cache and compile only the rollout's own body. When the rollout is already
cached it does nothing.

The plan is generated from a measured cold compilation (``python benchmarks/compile_profile.py --write-plan``);
``tests/experiments/running/test_warmup.py`` fails when it no longer names what the rollout compiles. A stale
plan costs time, never a result: a kernel it misses is compiled where the rollout needs it, as without it.
Figures: ``docs/performance.md`` (cold start).
"""
from __future__ import annotations

import warnings

from numba.core import types

from crowd_env.errors import InputError
from ...compilation import announce_compilation

__all__ = ["rollout_is_cached", "compile_part", "warm_up", "type_source", "tuple_source"]


def rollout_is_cached() -> bool:
    """Whether numba's cache holds a compiled rollout for the current source (then nothing needs warming)."""
    from .rollout import rollout_steps

    try:
        return bool(rollout_steps._cache._cache_file._load_index())
    except (AttributeError, OSError, EOFError, ValueError):  # numba's cache internals moved, or a torn index
        return False


def compile_part(k: int) -> int:
    """In a worker: compile (or load from numba's cache) every kernel of part ``k`` of the plan for its planned
    signatures. Returns how many signatures it served. A signature the kernel no longer accepts (a stale plan)
    warns and is skipped: the rollout then compiles that kernel itself."""
    from .compile_plan import PARTS

    done = 0
    for kernel, signatures in PARTS[k]:
        for sig in signatures:
            try:
                kernel.compile(sig)
            except Exception as exc:  # numba's typing errors have no common base; the run goes on without it
                warnings.warn(f"compile plan out of date: {kernel.py_func.__module__}.{kernel.__name__}{sig} "
                              f"({type(exc).__name__}); regenerate it with "
                              "'python benchmarks/compile_profile.py --write-plan'", RuntimeWarning, stacklevel=2)
                continue
            done += 1
    return done


def warm_up(map_parts, n_workers: int) -> bool:
    """Before a pool's first runs: when the rollout is not cached and the pool has two workers or more, say so on
    one line (:func:`crowd_env.compilation.notice`: the compiled rollout) and compile the plan's parts in the workers
    at once, :func:`crowd_env.compilation.compiling` true meanwhile. ``map_parts(fn, items)`` runs ``fn(item)`` for
    every item on the pool's workers in parallel and returns when all are done (the process pool's futures, Ray's
    tasks). Returns whether it warmed."""
    if n_workers < 2 or rollout_is_cached():
        return False
    from .compile_plan import PARTS

    listener = announce_compilation()
    if listener is None:
        map_parts(compile_part, range(len(PARTS)))
        return True
    # said here, before the workers fork: they inherit that it was
    listener.say("crowd_env.experiments.running.rollout", "rollout_steps")
    with listener.in_workers():  # a sweep's progress bar says that kernels compile meanwhile
        map_parts(compile_part, range(len(PARTS)))
    return True


def type_source(t) -> str:
    """A numba type as the Python expression the plan module writes (in the names of :mod:`numba.core.types`
    and the bundles' classes): ``Array(float64, 2, 'C')``, ``UniTuple(float64, 4)``, ``Bodies`` named tuples...
    Raises :class:`~crowd_env.errors.InputError` for a type it cannot write."""
    if isinstance(t, types.Array):
        extra = (", readonly=True" if not t.mutable else "") + ("" if t.aligned else ", aligned=False")
        return f"Array({type_source(t.dtype)}, {t.ndim}, {t.layout!r}{extra})"
    if isinstance(t, types.Boolean):
        return "boolean"
    if isinstance(t, (types.Integer, types.Float)):
        return t.name
    if isinstance(t, types.NamedUniTuple):
        return f"NamedUniTuple({type_source(t.dtype)}, {t.count}, {t.instance_class.__name__})"
    if isinstance(t, types.NamedTuple):
        return f"NamedTuple({tuple_source(t.types)}, {t.instance_class.__name__})"
    if isinstance(t, types.UniTuple):
        return f"UniTuple({type_source(t.dtype)}, {t.count})"
    if isinstance(t, types.Tuple):
        return f"Tuple({tuple_source(t.types)})"
    raise InputError(f"type_source: no source form for the numba type {t!r}")


def tuple_source(items) -> str:
    """A tuple of numba types (a signature) as a Python tuple expression of their :func:`type_source`."""
    return f"({', '.join(type_source(x) for x in items)}{',' if len(items) == 1 else ''})"
