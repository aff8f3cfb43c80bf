"""The one executor's ordered map (``run_all``): results in task order whatever order runs finish in, and a
failure reported with the task it belongs to, on the serial and the process backend."""
from __future__ import annotations

import time

import pytest

from crowd_env.errors import BackendError
from crowd_env.experiments.running.backends import make_backend, run_all


def _slow_square(task: dict) -> int:
    time.sleep(task["sleep_s"])
    if task["x"] < 0:
        raise ValueError(f"negative x {task['x']}")
    return task["x"] ** 2


@pytest.mark.parametrize("name", ["serial", "process"])
def test_run_all_keeps_task_order(name):
    # The first task sleeps longest, so on two workers it finishes last.
    tasks = [{"x": x, "sleep_s": s} for x, s in [(3, 0.4), (1, 0.0), (2, 0.1), (5, 0.0)]]
    with make_backend(name, jobs=2 if name == "process" else None) as backend:
        assert run_all(tasks, backend, _slow_square) == [9, 1, 4, 25]


def test_run_all_names_every_failed_task():
    tasks = [{"x": 2, "sleep_s": 0.0}, {"x": -1, "sleep_s": 0.0}, {"x": -7, "sleep_s": 0.0}]
    with pytest.raises(BackendError, match=r"2 of 3 runs failed") as err:
        run_all(tasks, make_backend("serial"), _slow_square)
    assert "negative x -1" in str(err.value) and "negative x -7" in str(err.value)


def test_run_all_refuses_one_task_object_passed_twice():
    task = {"x": 1, "sleep_s": 0.0}
    with pytest.raises(BackendError, match="distinct task objects"):
        run_all([task, task], make_backend("serial"), _slow_square)


def _blas_threads(task: dict) -> list:
    from threadpoolctl import threadpool_info

    return [lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"]


def test_process_workers_run_numpy_s_blas_on_one_thread():
    """crowd_env.threads: a pool of one worker per core with every worker's BLAS on every core oversubscribes
    them (a behaviour clone's forward pass 9 x slower); each worker gets one BLAS thread."""
    import numpy as np  # noqa: F401 (numpy's BLAS is loaded in this process, and so in the forked workers)

    with make_backend("process", jobs=2) as backend:
        counts = run_all([{"k": 0}, {"k": 1}], backend, _blas_threads)
    assert all(c and set(c) == {1} for c in counts), counts
