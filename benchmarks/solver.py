"""Per-solve time of the production Frémond solver against the cvxpy reference.

Clusters of 2, 10, 60 and 200 pedestrians in dense random packings (hexagonal patches where every
lattice neighbour touches, a wall under the lowest row; K_n = 1e5 kg as in Table 2, random
velocities), all solved in one run:

* ``solve_rows``: the compiled dense solver (numba, timed after a warm-up call);
* ``solve_rows_sparse``: the sparse pivoting solver the simulator uses for clusters beyond
  ``MAX_DENSE_ROWS`` / ``MAX_DENSE_BODIES`` (Python + SuperLU);
* ``solve_rows_cvxpy``: the reference, the primal of Eq. 7 rebuilt by cvxpy for every solve.

Prints the times, the production/reference ratio (target: ≥ 50× up to 60 pedestrians; the median
and range of the ratios of ``--rounds`` interleaved rounds) and the largest velocity difference to the
reference.

    python benchmarks/solver.py [--sizes 2 10 60 200] [--ktg 0] [--seed 0] [--rounds 5]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from crowd_env.core.contacts import NORMAL
from crowd_env.core.solvers.impact import MAX_DENSE_BODIES, MAX_DENSE_ROWS, solve_rows
from crowd_env.core.solvers.reference import random_cluster, solve_rows_cvxpy
from crowd_env.core.solvers.sparse_qp import solve_rows_sparse


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
    ap.add_argument("--rounds", type=int, default=5,
                    help="interleaved rounds (production, sparse, cvxpy timed in turn): the machine's speed "
                         "drifts by 10-20 %% over a minute, so each ratio comes from one round and the "
                         "median and range over rounds are printed")
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    print(f"{'N':>5} {'rows':>5} {'normal':>6} | {'solve_rows ms':>13} {'sparse ms':>9} {'cvxpy ms':>9} | "
          f"{'cvxpy/prod median':>17} {'(range)':>13} | {'max |Δv| m/s':>12}  production path")
    for n in args.sizes:
        cl = random_cluster(n, rng, k_tg=args.ktg)
        rows = cl["rows"]
        md, vm = cl["mass_diag"], cl["v_minus"]
        zero = np.zeros_like(vm)
        n_normal = int((rows[5] == NORMAL).sum())
        dense_path = n_normal <= MAX_DENSE_ROWS and n <= MAX_DENSE_BODIES
        t_dense, t_sparse, t_ref, ratios = [], [], [], []
        for _ in range(args.rounds):
            td, _, (v_dense, _, st) = timed(lambda: solve_rows(md, *rows, vm, zero), min_time=0.1)
            ts, _, (v_sparse, _, st2) = timed(lambda: solve_rows_sparse(md, *rows, vm), min_time=0.1)
            tr, _, (v_ref, _) = timed(lambda: solve_rows_cvxpy(md, *rows, vm), min_time=0.2, max_reps=5)
            t_dense.append(td), t_sparse.append(ts), t_ref.append(tr)
            ratios.append(tr / (td if dense_path else ts))
        err = max(np.abs(v_dense - v_ref).max(), np.abs(v_sparse - v_ref).max())
        print(f"{n:5d} {rows[0].size:5d} {n_normal:6d} | {np.median(t_dense) * 1e3:13.3f} {np.median(t_sparse) * 1e3:9.2f} "
              f"{np.median(t_ref) * 1e3:9.1f} | {np.median(ratios):16.0f}x {min(ratios):6.0f}-{max(ratios):.0f}x | "
              f"{err:12.1e}  {'dense (numba)' if dense_path else 'sparse (SuperLU)'}")
        assert st == 0 and st2 == 0
    print(f"times: medians over {args.rounds} interleaved rounds of best-of-repeated calls, single process; the "
          "reference rebuilds its cvxpy problem per solve")


if __name__ == "__main__":
    main()
