"""Timing shared by the benchmark scripts: the share of a run spent inside one method."""
from __future__ import annotations

import time


def time_calls(obj, name: str, clock: list) -> None:
    """Wrap ``obj.name`` (on this instance) so that each call adds its wall time in seconds to ``clock[0]``."""
    inner = getattr(obj, name)

    def timed(*args, **kwargs):
        t = time.perf_counter()
        out = inner(*args, **kwargs)
        clock[0] += time.perf_counter() - t
        return out

    setattr(obj, name, timed)
