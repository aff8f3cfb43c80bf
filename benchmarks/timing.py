"""Timing shared by the benchmark scripts: the share of a run spent inside one method."""
from __future__ import annotations

import time


def time_calls(obj, name: str, clock: list, timer=time.perf_counter) -> None:
    """Wrap ``obj.name`` (on this instance) so that each call adds its time in seconds to ``clock[0]``: wall time,
    or what ``timer`` counts (``time.thread_time``: this thread's CPU time)."""
    inner = getattr(obj, name)

    def timed(*args, **kwargs):
        t = timer()
        out = inner(*args, **kwargs)
        clock[0] += timer() - t
        return out

    setattr(obj, name, timed)
