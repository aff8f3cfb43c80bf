"""Where runs execute: Ray (local on all cores or a running cluster), a process pool, or serially.

One executor for every sweep of bottleneck runs (Kabalan et al. 2016, Section 4): the reproduction, the
calibration and the generalisation. All backends expose ``imap_unordered(fn, tasks)`` yielding
``(task, ok, result_or_error_text)`` as each run finishes, so the caller can save it at once;
:func:`execute` does that into a :class:`~crowd_env.experiments.running.store.RunStore` with a tqdm bar (ETA).
Ray: ``ray.init()`` starts a local instance on all cores (``num_cpus`` to limit it); with ``address``
(``host:port`` of a head node, ``ray://host:port`` for Ray Client, or ``auto``) it joins a running
cluster through the same code path. Cluster nodes need ``crowd_env`` installed (same version). An
unreachable address fails within ``connect_timeout_s`` (Ray's own connect would retry for minutes).
"""
from __future__ import annotations

from crowd_env.errors import BackendError

import os
import re
import socket
import sys
import tempfile
import threading
import traceback
from contextlib import contextmanager
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

from ...compilation import compiling
from ...core.checks import check_integer
from ...threads import limit_worker_threads
from .warmup import warm_up

__all__ = ["BACKENDS", "BackendError", "SerialBackend", "ProcessBackend", "RayBackend", "check_reachable",
           "make_backend", "DeferredBackend", "join_ray", "ray_join_error", "execute", "kept_alive", "failure_report", "run_all"]

BACKENDS = ("ray", "process", "serial")


def _error_text(exc: BaseException) -> str:
    return "".join(traceback.format_exception_only(type(exc), exc)).strip()


class SerialBackend:
    """Runs in this process, one after another (tests, debugging)."""

    n_workers = 1
    _warmed = True  # a pool sets it False: its workers share a cold start before their first runs

    def _warm_up_once(self, tasks: list) -> None:
        """Before the first runs of a pool (``_warmed`` False): :func:`~.warmup.warm_up` on its workers
        (``self._map``)."""
        if tasks and not self._warmed:
            self._warmed = True
            warm_up(self._map, self.n_workers)

    def imap_unordered(self, fn, tasks):
        for task in tasks:
            try:
                yield task, True, fn(task)
            except Exception as exc:  # a failed run is reported, the sweep goes on
                yield task, False, _error_text(exc)

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class ProcessBackend(SerialBackend):
    """A local process pool of ``jobs`` workers. On a cold numba cache the workers first compile the compiled
    rollout's kernels between them, one part each (:func:`~crowd_env.experiments.running.warmup.warm_up`),
    instead of each compiling all of them at its first run."""

    def __init__(self, jobs: int | None = None):
        self.n_workers = int(jobs or os.cpu_count() or 1)
        if self.n_workers < 1:
            raise BackendError(f"jobs must be >= 1, got {jobs!r}")
        # one BLAS thread per worker: the pool spreads the work over the cores (crowd_env.threads)
        self._pool = ProcessPoolExecutor(max_workers=self.n_workers, initializer=limit_worker_threads)
        self._warmed = False

    def imap_unordered(self, fn, tasks):
        tasks = list(tasks)
        self._warm_up_once(tasks)
        pending = {}
        it = iter(tasks)
        try:
            for task in it:
                pending[self._pool.submit(fn, task)] = task
                if len(pending) >= 2 * self.n_workers:
                    break
            while pending:
                done, _ = wait(pending, return_when=FIRST_COMPLETED)
                for fut in done:
                    task = pending.pop(fut)
                    exc = fut.exception()
                    yield (task, False, _error_text(exc)) if exc else (task, True, fut.result())
                    nxt = next(it, None)
                    if nxt is not None:
                        pending[self._pool.submit(fn, nxt)] = nxt
        finally:
            for fut in pending:
                fut.cancel()

    def _map(self, fn, items) -> list:
        """``fn(item)`` for every item on the workers at once; the results once all are done."""
        return [fut.result() for fut in [self._pool.submit(fn, item) for item in items]]

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)


def _in_one_thread(fn, task):
    """A Ray task: ``fn(task)`` with one BLAS thread (:func:`crowd_env.threads.limit_worker_threads`)."""
    limit_worker_threads()
    return fn(task)


def check_reachable(address: str, timeout_s: float = 5.0) -> None:
    """Fail fast when ``host:port`` (or ``ray://host:port``) accepts no TCP connection within ``timeout_s``."""
    if address == "auto":
        return
    hostport = address.split("://", 1)[1] if "://" in address else address
    host, sep, port = hostport.rpartition(":")
    if not sep or not host or not port.isdigit():
        raise BackendError(f"Ray address must be 'host:port', 'ray://host:port' or 'auto', got {address!r}")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout_s):
            pass
    except OSError as exc:
        raise BackendError(f"cannot reach the Ray cluster at {address!r} within {timeout_s:g} s ({exc}); "
                               f"is the head node running ('ray start --head') and the port open?") from None


RAY_CLUSTER_DOCS = "docs/validation/calibration.md, 'Token authentication'"
_RAY_LOG_LINE = re.compile(r"^\[[^\]]*\] [\w./-]+\.cc:\d+: (?P<message>.+)$", re.M)


@contextmanager
def _stderr_into(file):
    """File descriptor 2 (where Ray's C++ core logs) into ``file`` while the block runs."""
    sys.stderr.flush()
    saved = os.dup(2)
    os.dup2(file.fileno(), 2)
    try:
        yield
    finally:
        sys.stderr.flush()
        os.dup2(saved, 2)
        os.close(saved)


def ray_join_error(address: str, exc: BaseException, log: str) -> str:
    """The message of a failed join of the Ray cluster at ``address``: Ray's exception, then Ray's own reason (the
    last line its core logged while connecting, e.g. 'Unauthenticated: ... Authentication token is missing or
    incorrect'; Ray's exception only says 'Failed to connect'), and for a token the way to join such a cluster."""
    lines = [m.group("message").strip() for m in _RAY_LOG_LINE.finditer(log)]
    reason = f"; Ray: {lines[-1]}" if lines else ""
    text = f"{exc}{reason}"
    hint = ""
    if re.search(r"unauthenticated|auth_?token|authentication", text, re.I):
        hint = ("; the cluster uses token authentication: join it with RAY_AUTH_MODE=token set here and the cluster's "
                f"token in ~/.ray/auth_token, RAY_AUTH_TOKEN_PATH or RAY_AUTH_TOKEN ({RAY_CLUSTER_DOCS})")
    return f"cannot join the Ray cluster at {address!r}: {text}{hint}"


def join_ray(ray, address: str, **kwargs) -> None:
    """``ray.init(address=address, **kwargs)``, Ray's core logging of the attempt held back: on success it is
    written to standard error as it would have been; on failure :class:`BackendError` says why
    (:func:`ray_join_error`) instead of Ray's many identical retry lines."""
    with tempfile.TemporaryFile() as log:
        with _stderr_into(log):
            try:
                ray.init(address=address, **kwargs)
                error = None
            except (ConnectionError, RuntimeError, ValueError, ray.exceptions.RayError) as exc:
                error = exc
        log.seek(0)
        text = log.read().decode("utf-8", "replace")
    if error is not None:
        raise BackendError(ray_join_error(address, error, text)) from None
    sys.stderr.write(text)


class RayBackend(SerialBackend):
    """Ray tasks, one per run (``num_cpus=1`` each), at most ``2 × cluster CPUs`` in flight.

    ``address=None``: local instance (``ray.init(num_cpus=num_cpus)``); otherwise joins that cluster.
    Shuts Ray down on close only if it started it. A local instance on a cold numba cache first compiles the
    compiled rollout's kernels in its workers, one part each, as :class:`ProcessBackend` does (a cluster's nodes
    have caches of their own: ``docs/validation/calibration.md``).
    """

    def __init__(self, address: str | None = None, num_cpus: int | None = None, connect_timeout_s: float = 5.0):
        try:
            import ray
        except ImportError:
            raise BackendError("the Ray backend needs ray: pip install 'crowd_env[distributed]' "
                                   "(or use --backend process)") from None
        self._ray = ray
        self._started = False
        if not ray.is_initialized():
            kwargs = {"include_dashboard": False, "log_to_driver": False}
            if address is None:
                kwargs["num_cpus"] = num_cpus
                try:
                    ray.init(**kwargs)
                except (ConnectionError, RuntimeError, ValueError, ray.exceptions.RayError) as exc:
                    raise BackendError(f"cannot start Ray: {exc}") from None
            else:
                check_reachable(address, connect_timeout_s)
                join_ray(ray, address, **kwargs)
            self._started = True
        self.n_workers = max(1, int(ray.cluster_resources().get("CPU", 1)))
        self._remote = None  # the one Ray remote function, _in_one_thread, made on first use
        # a local instance shares this machine's numba cache: its workers share a cold start's compilation
        self._warmed = address is not None

    def _map(self, fn, items) -> list:
        """``fn(item)`` for every item as Ray tasks at once; the results once all are done."""
        return self._ray.get([self._remote.remote(fn, item) for item in items])

    def imap_unordered(self, fn, tasks):
        ray = self._ray
        if self._remote is None:
            self._remote = ray.remote(num_cpus=1, max_retries=1)(_in_one_thread)
        remote = self._remote
        tasks = list(tasks)
        self._warm_up_once(tasks)
        it = iter(tasks)
        pending = {}
        try:
            for task in it:
                pending[remote.remote(fn, task)] = task
                if len(pending) >= 2 * self.n_workers:
                    break
            while pending:
                done, _ = ray.wait(list(pending), num_returns=1, timeout=0.5)  # timeout: Ctrl-C stays responsive
                if not done:
                    continue
                ref = done[0]
                task = pending.pop(ref)
                try:
                    yield task, True, ray.get(ref)
                except ray.exceptions.RayError as exc:
                    cause = getattr(exc, "cause", None)
                    yield task, False, _error_text(cause if isinstance(cause, BaseException) else exc)
                nxt = next(it, None)
                if nxt is not None:
                    pending[remote.remote(fn, nxt)] = nxt
        finally:
            for ref in pending:
                ray.cancel(ref, force=True)

    def close(self) -> None:
        if self._started and self._ray.is_initialized():
            self._ray.shutdown()
        self._started = False


class DeferredBackend:
    """A backend made by ``factory()`` when it is first asked to run something, not before: a command opens it
    around work that checks its plan first (tasks built, folders checked), so that an impossible plan is refused
    before Ray starts or a pool forks. Closes the backend if it was made."""

    def __init__(self, factory):
        self._factory = factory
        self._backend = None

    @property
    def backend(self):
        """The backend, made now if it was not yet."""
        if self._backend is None:
            self._backend = self._factory()
        return self._backend

    @property
    def started(self) -> bool:
        return self._backend is not None

    @property
    def n_workers(self) -> int:
        return self.backend.n_workers

    def imap_unordered(self, fn, tasks):
        return self.backend.imap_unordered(fn, tasks)

    def close(self) -> None:
        if self._backend is not None:
            self._backend.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def make_backend(name: str = "ray", *, address: str | None = None, jobs: int | None = None,
                 connect_timeout_s: float = 5.0):
    """Backend by name: ``ray`` (default), ``process`` or ``serial``."""
    if name not in BACKENDS:
        raise BackendError(f"unknown backend {name!r}; choose one of {BACKENDS}")
    if address is not None and name != "ray":
        raise BackendError(f"--address needs the ray backend, not {name!r}")
    if jobs is not None:
        check_integer("jobs", jobs, error=BackendError, minimum=1, whole_floats=True)
    if name == "ray":
        return RayBackend(address, jobs, connect_timeout_s)
    if name == "process":
        return ProcessBackend(jobs)
    return SerialBackend()


@contextmanager
def kept_alive(bar, desc: str, every_s: float = 1.0):
    """While the block runs, a thread redraws the tqdm ``bar`` every ``every_s`` seconds, so that its elapsed time
    moves while no run finishes (a cold start compiles for a minute or more before the first one does), with
    "compiling numba kernels" after ``desc`` while this process compiles or waits for its workers to
    (:func:`crowd_env.compilation.compiling`)."""
    stop = threading.Event()

    def tick():
        shown = desc
        while not stop.wait(every_s):
            now = f"{desc} (compiling numba kernels)" if compiling() else desc
            if now != shown:
                shown = now
                bar.set_description_str(now, refresh=False)
            bar.refresh()

    thread = threading.Thread(target=tick, name="progress-bar", daemon=True)
    thread.start()
    try:
        yield bar
    finally:
        stop.set()
        thread.join()
        bar.set_description_str(desc, refresh=False)


def execute(tasks: list, store, backend, run_fn, desc: str = "runs", leave: bool = True) -> int:
    """Run the tasks of ``tasks`` not yet in their store, saving each as it finishes; returns the number of
    failures (logged to ``OUT/errors.jsonl``; they are retried by the next call; :func:`failure_report` says why).
    The progress bar stays alive while nothing finishes (:func:`kept_alive`).

    ``store``: a :class:`~crowd_env.experiments.running.store.RunStore`, or ``store(task) -> RunStore`` when the
    tasks go to several folders (one per configuration, e.g. per geometry).
    """
    from tqdm import tqdm

    store_of = store if callable(store) else (lambda task: store)
    todo = [store_of(t).prepare(t) for t in tasks if not store_of(t).done(t)]
    # Largest groups first, so that the last runs to finish are short ones (load balance).
    todo.sort(key=lambda t: -t["n_pedestrians"])
    failures = 0
    with tqdm(total=len(tasks), initial=len(tasks) - len(todo), desc=desc, unit="run", file=sys.stderr,
              leave=leave, dynamic_ncols=True) as bar, kept_alive(bar, desc):
        for task, ok, value in backend.imap_unordered(run_fn, todo):
            if ok:
                store_of(task).save(task, value)
            else:
                failures += 1
                store_of(task).log_error(task, value)
                bar.set_postfix(failed=failures)
            bar.update()
    return failures


REASONS_SHOWN = 3  # distinct reasons a failure report quotes


def _own_error(text: str) -> bool:
    """Whether a logged error (``"module.Class: message"``, :func:`_error_text`) is one of crowd_env's own
    (:mod:`crowd_env.errors`): the run's input refused, or its computation failed. Runs are seeded, so such a run
    fails the same way again; an error of another kind may come from the machine (a killed worker, memory, disk)."""
    return text.startswith("crowd_env.errors.")


def _reason(text: str) -> str:
    """A logged error on one line: its class without the module (``ScenarioError: ...``), its first line only."""
    lines = text.strip().splitlines() or [""]
    first = re.sub(r"^[A-Za-z_][\w.]*\.(?=\w+: )", "", lines[0])
    return first + (" [...]" if len(lines) > 1 else "")


def failure_report(tasks: list, store) -> str:
    """What a sweep says when runs of ``tasks`` failed (those not in their store after :func:`execute`): how many,
    each distinct reason (the error logged last for the run in ``OUT/errors.jsonl``, its class without its module)
    with the first run that gave it and how many did, whether a rerun can help (:func:`_own_error`) and where the
    log is. ``store`` as for :func:`execute`."""
    store_of = store if callable(store) else (lambda task: store)
    logged, logs, reasons = {}, set(), {}
    failed = [t for t in tasks if not store_of(t).done(t)]
    for task in failed:
        s = store_of(task)
        if id(s) not in logged:
            logged[id(s)] = s.logged_errors()
        key = s.key(task)
        text = logged[id(s)].get(key)
        if text is not None:
            logs.add(str(s.errors_path))
        reasons.setdefault(text or "no error logged for it", []).append(key)
    shown = [f"{keys[0]}{f' and {len(keys) - 1} more' if len(keys) > 1 else ''}: {_reason(text)}"
             for text, keys in list(reasons.items())[:REASONS_SHOWN]]
    if len(reasons) > REASONS_SHOWN:
        shown.append(f"{len(reasons) - REASONS_SHOWN} other reason(s)")
    own = [_own_error(text) for text in reasons]
    if all(own):
        advice = ("a rerun fails the same way (crowd_env refused these runs, and runs are seeded): change what the "
                  "error names")
    elif not any(own):
        advice = "a rerun retries them and can help if the cause was the machine (a killed worker, memory, disk)"
    else:
        advice = ("a rerun retries them: those failing with crowd_env's own errors fail the same way again (change "
                  "what the error names), the others can pass if the cause was the machine")
    where = f" (every failure: {', '.join(sorted(logs))})" if logs else ""
    return f"{len(failed)} of {len(tasks)} run(s) failed: {'; '.join(shown)}; {advice}{where}"


def run_all(tasks: list, backend, run_fn) -> list:
    """``run_fn`` of every task on ``backend``, the results in the order of ``tasks`` (for studies whose
    runs are not stored one by one). A failed run raises :class:`BackendError` naming every failed task
    and its error, after the others have finished."""
    tasks = list(tasks)
    slot = {id(t): i for i, t in enumerate(tasks)}
    if len(slot) != len(tasks):
        raise BackendError("run_all needs distinct task objects (the same object was passed twice)")
    results = [None] * len(tasks)
    failed = []
    for task, ok, value in backend.imap_unordered(run_fn, tasks):
        if ok:
            results[slot[id(task)]] = value
        else:
            failed.append(f"{task!r}: {value}")
    if failed:
        raise BackendError(f"{len(failed)} of {len(tasks)} runs failed:\n" + "\n".join(failed))
    return results
