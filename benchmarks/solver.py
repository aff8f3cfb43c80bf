"""Per-solve time of the production Frémond solver against the cvxpy reference.

Clusters of 2, 10, 60 and 200 pedestrians in dense random packings (hexagonal patches where every
lattice neighbour touches, a wall under the lowest row; K_n = 1e5 kg as in Table 2, random
velocities), all solved in one run:

* ``solve_rows``: the compiled dense solver (numba, timed after a warm-up call);
* ``solve_rows_sparse``: the sparse pivoting solver the simulator uses for clusters beyond
  ``MAX_DENSE_ROWS`` / ``MAX_DENSE_BODIES`` (Python + SuperLU);
* ``solve_rows_cvxpy``: the reference, the primal of Eq. 7 rebuilt by cvxpy for every solve.

Prints the times, the production/reference ratio (target: ≥ 50× up to 60 pedestrians) and the
largest velocity difference to the reference.

    python benchmarks/solver.py [--sizes 2 10 60 200] [--ktg 0] [--seed 0]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from crowd_env.core.collision import MAX_DENSE_BODIES, MAX_DENSE_ROWS, solve_rows, solve_rows_sparse
from crowd_env.core.contacts import NORMAL
from crowd_env.core.reference import random_cluster, solve_rows_cvxpy


def timed(fn, min_time=0.3, max_reps=2000):
    """Best-of-batches mean time per call (s) of ``fn()``; at least one call."""
    fn()
    reps, total, best = 0, 0.0, float("inf")
    while total < min_time and reps < max_reps:
        t0 = time.perf_counter()
        out = fn()
        dt = time.perf_counter() - t0
        total += dt
        reps += 1
        best = min(best, dt)
    return best, total / reps, out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[2, 10, 60, 200])
    ap.add_argument("--ktg", type=float, default=0.0, help="K_tg (kg); > 0 adds tangent rows")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    print(f"{'N':>5} {'rows':>5} {'normal':>6} | {'solve_rows ms':>13} {'sparse ms':>9} {'cvxpy ms':>9} | "
          f"{'cvxpy/dense':>11} {'cvxpy/prod':>10} | {'max |Δv| m/s':>12}  production path")
    for n in args.sizes:
        cl = random_cluster(n, rng, k_tg=args.ktg)
        rows = cl["rows"]
        md, vm = cl["mass_diag"], cl["v_minus"]
        zero = np.zeros_like(vm)
        n_normal = int((rows[5] == NORMAL).sum())
        t_dense, _, (v_dense, _, st) = timed(lambda: solve_rows(md, *rows, vm, zero))
        t_sparse, _, (v_sparse, _, st2) = timed(lambda: solve_rows_sparse(md, *rows, vm))
        t_ref, _, (v_ref, _) = timed(lambda: solve_rows_cvxpy(md, *rows, vm), min_time=1.0, max_reps=20)
        dense_path = n_normal <= MAX_DENSE_ROWS and n <= MAX_DENSE_BODIES
        t_prod = t_dense if dense_path else t_sparse
        err = max(np.abs(v_dense - v_ref).max(), np.abs(v_sparse - v_ref).max())
        print(f"{n:5d} {rows[0].size:5d} {n_normal:6d} | {t_dense * 1e3:13.3f} {t_sparse * 1e3:9.2f} "
              f"{t_ref * 1e3:9.1f} | {t_ref / t_dense:10.0f}x {t_ref / t_prod:9.0f}x | {err:12.1e}  "
              f"{'dense (numba)' if dense_path else 'sparse (SuperLU)'}")
        assert st == 0 and st2 == 0
    print("times: best of repeated calls, single process; the reference rebuilds its cvxpy problem per solve")


if __name__ == "__main__":
    main()
