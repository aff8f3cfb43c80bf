"""The one executor's ordered map (``run_all``): results in task order whatever order runs finish in, and a
failure reported with the task it belongs to, on the serial and the process backend."""
from __future__ import annotations

import os
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


def _fails_by_seed(task: dict) -> dict:
    """A run that fails by its seed: 0 with crowd_env's own error, 1 with the machine's (memory), else passes."""
    from crowd_env.errors import ScenarioError

    if task["seed"] == 0:
        raise ScenarioError(f"{task['n_pedestrians']} pedestrians cannot be placed")
    if task["seed"] == 1:
        raise MemoryError("out of memory")
    return {"n_pedestrians": task["n_pedestrians"], "complete": True}


@pytest.mark.parametrize("seeds, says", [
    ([0, 2], r"^1 of 2 run\(s\) failed: b1\.000_n9_s0: ScenarioError: 9 pedestrians cannot be placed; a rerun fails "
             r"the same way \(crowd_env refused these runs, and runs are seeded\): change what the error names "
             r"\(every failure: .*errors\.jsonl\)$"),
    ([1, 2], r"^1 of 2 run\(s\) failed: b1\.000_n9_s1: MemoryError: out of memory; a rerun retries them and can help "
             r"if the cause was the machine"),
    ([0, 1, 2], r"^2 of 3 run\(s\) failed: b1\.000_n9_s0: ScenarioError: .*; b1\.000_n9_s1: MemoryError: .*; a rerun "
                r"retries them: those failing with crowd_env's own errors fail the same way again"),
])
def test_a_failure_report_gives_each_reason_and_whether_a_rerun_can_help(tmp_path, seeds, says):
    """Regression (issue 52): a sweep whose runs failed said only '1 run(s) failed (see errors.jsonl); rerun to retry
    them', also where the reason (a density that cannot be placed, too many steps) makes every rerun fail alike."""
    from crowd_env.experiments.running.backends import execute, failure_report
    from crowd_env.experiments.running.store import RunStore

    store = RunStore(tmp_path, {"kind": "test"})
    tasks = [{"width_m": 1.0, "n_pedestrians": 9, "seed": s} for s in seeds]
    with make_backend("serial") as backend:
        failed = execute(tasks, store, backend, _fails_by_seed, leave=False)
    assert failed == len([s for s in seeds if s < 2])
    import re
    assert re.search(says, failure_report(tasks, store)), failure_report(tasks, store)


def test_a_failure_report_counts_runs_of_one_reason_and_shows_at_most_three_reasons(tmp_path):
    from crowd_env.experiments.running.backends import failure_report
    from crowd_env.experiments.running.store import RunStore

    store = RunStore(tmp_path, {"kind": "test"})
    tasks = [{"width_m": 1.0, "n_pedestrians": n, "seed": s} for n in (5, 6, 7, 8) for s in (0, 1)]
    for t in tasks:
        store.log_error(t, f"crowd_env.errors.InputError: N = {t['n_pedestrians']}\nsecond line")
    text = failure_report(tasks, store)
    assert text.startswith("8 of 8 run(s) failed: b1.000_n5_s0 and 1 more: InputError: N = 5 [...]; "
                           "b1.000_n6_s0 and 1 more: InputError: N = 6 [...]; b1.000_n7_s0 and 1 more: ")
    assert "; 1 other reason(s); a rerun fails the same way" in text and "\n" not in text


def _run_while_kernels_compile(task: dict) -> dict:
    """A run of 2.5 s during which this process waits for kernels to compile (as a pool's warm-up does)."""
    from contextlib import nullcontext

    from crowd_env.compilation import announce_compilation

    listener = announce_compilation()
    with listener.in_workers() if listener is not None else nullcontext():
        time.sleep(2.5)
    return {"n_pedestrians": task["n_pedestrians"], "complete": True}


def test_the_progress_bar_stays_alive_and_says_so_while_kernels_compile(tmp_path, capsys):
    """Regression (issue 52): the main job's cold run showed its bar frozen at 0/10 for 113 s while it compiled.
    The bar is now redrawn every second (its elapsed time moves) and says when kernels compile."""
    from crowd_env.compilation import announce_compilation
    from crowd_env.experiments.running.backends import execute
    from crowd_env.experiments.running.store import RunStore

    store = RunStore(tmp_path, {"kind": "test"})
    with make_backend("serial") as backend:
        execute([{"width_m": 1.0, "n_pedestrians": 3, "seed": 0}], store, backend, _run_while_kernels_compile,
                desc="slow runs")
    frames = capsys.readouterr().err.split("\r")
    waiting = [f for f in frames if "0/1" in f]
    assert any("00:01" in f for f in waiting) and any("00:02" in f for f in waiting), waiting
    if announce_compilation() is not None:
        assert any(f.startswith("slow runs (compiling numba kernels)") for f in waiting), waiting
    assert frames[-1].startswith("slow runs: 100%")  # the plain description again at the end


_RAY_REFUSED = ("[2026-12-06 20:52:56,359 W 14926 14926] gcs_client.cc:210: Failed to get cluster ID from GCS server: "
                "Unauthenticated: RPC error: InvalidAuthToken: Authentication token is missing or incorrect\n")


class _FakeRay:
    """What RayBackend uses of ray, joining a cluster that refuses this client's (missing) token as Ray 2.60 does:
    its core logs the reason on file descriptor 2 at every retry and ray.init raises 'Failed to connect'."""

    class exceptions:
        class RayError(Exception):
            pass

    def __init__(self, refuse: bool):
        self.refuse, self.initialized = refuse, False

    def is_initialized(self):
        return self.initialized

    def init(self, **kwargs):
        for _ in range(3):
            os.write(2, _RAY_REFUSED.encode() if self.refuse else b"Connected to Ray cluster.\n")
        if self.refuse:
            raise ConnectionError("Failed to connect to Ray cluster at 192.0.2.2:6391")
        self.initialized = True

    def cluster_resources(self):
        return {"CPU": 3.0}

    def shutdown(self):
        self.initialized = False


def test_a_refused_ray_join_carries_ray_s_reason_and_the_way_to_join(monkeypatch, capfd):
    """Regression (issue 52): joining a cluster that uses token authentication ('ray start --head', Ray 2.60) failed
    with 'cannot start or join Ray ... Failed to connect', Ray's reason only in its log lines. The error now carries
    the reason and says how to join such a cluster (RAY_AUTH_MODE=token); a join that works still shows Ray's lines."""
    import socket
    import sys

    from crowd_env.experiments.running.backends import RAY_CLUSTER_DOCS, RayBackend

    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen()
        address = f"127.0.0.1:{server.getsockname()[1]}"
        monkeypatch.setitem(sys.modules, "ray", _FakeRay(refuse=True))
        with pytest.raises(BackendError) as info:
            RayBackend(address=address)
        monkeypatch.setitem(sys.modules, "ray", _FakeRay(refuse=False))
        with RayBackend(address=address) as backend:
            assert backend.n_workers == 3
    assert str(info.value) == (
        f"cannot join the Ray cluster at {address!r}: Failed to connect to Ray cluster at 192.0.2.2:6391; Ray: Failed "
        "to get cluster ID from GCS server: Unauthenticated: RPC error: InvalidAuthToken: Authentication token is "
        "missing or incorrect; the cluster uses token authentication: join it with RAY_AUTH_MODE=token set here and "
        f"the cluster's token in ~/.ray/auth_token, RAY_AUTH_TOKEN_PATH or RAY_AUTH_TOKEN ({RAY_CLUSTER_DOCS})")
    err = capfd.readouterr().err
    assert "Unauthenticated" not in err and err.count("Connected to Ray cluster.") == 3
    from pathlib import Path

    page, section = RAY_CLUSTER_DOCS.split(", ")
    text = (Path(__file__).resolve().parents[3] / page).read_text()
    assert f"- {section.strip(chr(39))}:" in text and "set `RAY_AUTH_MODE=token` in the" in text
