"""One thread per worker for the numerical libraries of a pool's worker processes.

numpy's BLAS (OpenBLAS in numpy's wheels) starts as many threads as the machine has cores in *every*
process. A pool of one worker per core then runs cores × cores BLAS threads, and OpenBLAS's threads
spin while they wait: measured on this project's 2-core machine with two scorecard workers busy, a
behaviour clone's forward pass (121 pedestrians, two hidden layers of 128) took 5.4 ms instead of
0.6 ms, and one fundamental-diagram run 18.5 s of CPU instead of 2.7 s. The pools of this package
(:mod:`crowd_env.experiments.running.backends`' process pool and Ray tasks, the vector environment's
workers) call :func:`limit_worker_threads` in each worker, where the work is already spread over the
processes.
"""
from __future__ import annotations

import os

__all__ = ["WORKER_THREAD_VARIABLES", "limit_worker_threads"]

# read by OpenBLAS, MKL and OpenMP when they load (so also by libraries a worker imports later)
WORKER_THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def limit_worker_threads() -> None:
    """Set the thread variables to 1 for libraries loaded from now on, and limit the ones already loaded
    (numpy's BLAS inherited by a forked worker) to one thread through ``threadpoolctl``."""
    for name in WORKER_THREAD_VARIABLES:
        os.environ[name] = "1"
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=1)
