"""Shared linear algebra of the solvers: small compiled dense and envelope Cholesky kernels.

Used by the dense impact (:mod:`~crowd_env.core.solvers.impact`, H = M + Bᵀ K B of Kabalan 2016,
Eq. 7), the pivoting LCP (:mod:`~crowd_env.core.solvers.pivoting`) and the Newton-type projections
(:mod:`~crowd_env.core.solvers.large_projection`). Not LAPACK: the systems are small or banded, and
OpenBLAS threads competing on a loaded machine made LAPACK calls far slower than these loops. Inner
products run over *unsigned* offsets (:func:`dot_range`): with signed indices numba keeps its
negative-index wraparound test inside the loop and LLVM does not vectorise it.
The dense kernels use no fast-math flags that change rounding (``SAME_ROUNDING_FASTMATH``); four
interleaved partial sums vectorise without reassociation. ``test_fused_and_staged_steps_agree_bitwise``
checks that they round the same wherever they are compiled (the fused step inlines them into one
function, the staged step calls them one by one). The envelope kernels serve only the large-jam
projection, which runs in the staged step alone: they are compiled with full fast-math, which lets
LLVM vectorise their short inner products (``benchmarks/scaling.py`` measures the projection stage;
the factors agree with rounding-preserving builds to about 1e-14 relative).
"""
from __future__ import annotations

from crowd_env.errors import NotPositiveDefiniteError

import numba as nb
import numpy as np


# Fast-math flags that change no rounding of finite arithmetic (no reassociation, reciprocal or FMA
# contraction): LLVM may re-optimise a kernel once inlined into the fused step, and with rounding-changing
# flags it may vectorise it differently there than in the staged step (the two must stay bitwise equal).
SAME_ROUNDING_FASTMATH = {"nnan", "ninf", "nsz"}


@nb.njit(cache=True, fastmath=SAME_ROUNDING_FASTMATH, inline="always")
def dot_range(a, ia, b, ib, n):
    """Σ_{t < n} a[ia + t] · b[ib + t] for 1-D arrays (offsets ≥ 0; n ≤ 0 gives 0).

    Four interleaved partial sums combined in a fixed order; inlined, so it rounds as its caller is
    compiled: callers that must round the same wherever they are compiled (the dense kernels) use
    ``SAME_ROUNDING_FASTMATH`` or no fast-math (reassociation would let LLVM round differently in
    different callers)."""
    if n <= 0:
        return 0.0
    ua = nb.uint64(ia)
    ub = nb.uint64(ib)
    un = nb.uint64(n)
    n4 = un & ~nb.uint64(3)
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    s3 = 0.0
    t = nb.uint64(0)
    while t < n4:
        s0 += a[ua + t] * b[ub + t]
        s1 += a[ua + t + 1] * b[ub + t + 1]
        s2 += a[ua + t + 2] * b[ub + t + 2]
        s3 += a[ua + t + 3] * b[ub + t + 3]
        t += nb.uint64(4)
    while t < un:
        s0 += a[ua + t] * b[ub + t]
        t += nb.uint64(1)
    return (s0 + s1) + (s2 + s3)


@nb.njit(cache=True, fastmath=SAME_ROUNDING_FASTMATH, inline="always")
def sub_scaled(y, iy, a, ia, alpha, n):
    """y[iy + t] −= alpha · a[ia + t] for t < n (offsets ≥ 0; n ≤ 0 does nothing)."""
    if n <= 0:
        return
    uy = nb.uint64(iy)
    ua = nb.uint64(ia)
    for t in range(nb.uint64(n)):
        y[uy + t] -= alpha * a[ua + t]


@nb.njit(cache=True, fastmath=SAME_ROUNDING_FASTMATH)
def profile_cholesky(A, first):
    """Lower Cholesky factor of the SPD matrix A whose row i has no nonzero left of column
    ``first[i]`` (the factor keeps that envelope). Raises on a non-positive pivot.

    Up-looking, one row and column at a time, on dense rows (the impact solver's dense systems,
    at most 3 × ``MAX_DENSE_BODIES`` rows; the sparse path takes larger ones)."""
    n = A.shape[0]
    L = np.zeros((n, n))
    for i in range(n):
        fi = first[i]
        Li = L[i]
        for j in range(fi, i):
            Lj = L[j]
            k0 = max(fi, first[j])
            Li[j] = (A[i, j] - dot_range(Li, k0, Lj, k0, j - k0)) / Lj[j]
        s = A[i, i] - dot_range(Li, fi, Li, fi, i - fi)
        if not s > 0.0:
            raise NotPositiveDefiniteError("matrix is not positive definite")
        Li[i] = np.sqrt(s)
    return L


@nb.njit(cache=True)
def cholesky(A):
    """Lower Cholesky factor of the dense SPD matrix A. Raises on a non-positive pivot."""
    return profile_cholesky(A, np.zeros(A.shape[0], np.int64))


@nb.njit(cache=True, fastmath=SAME_ROUNDING_FASTMATH, inline="always")
def dot_2x2(a, ia0, ia1, b, ib0, ib1, n):
    """The four inner products Σ_{t < n} a[ia_r + t] · b[ib_c + t] (r, c ∈ {0, 1}) in one pass:
    ``(s00, s01, s10, s11)``. Offsets ≥ 0, n ≤ 0 gives zeros. One accumulator per product, in order
    (the four chains are independent, so no reassociation is needed to keep the FPU busy)."""
    s00 = 0.0
    s01 = 0.0
    s10 = 0.0
    s11 = 0.0
    if n <= 0:
        return s00, s01, s10, s11
    ua0 = nb.uint64(ia0)
    ua1 = nb.uint64(ia1)
    ub0 = nb.uint64(ib0)
    ub1 = nb.uint64(ib1)
    for t in range(nb.uint64(n)):
        x0 = a[ua0 + t]
        x1 = a[ua1 + t]
        y0 = b[ub0 + t]
        y1 = b[ub1 + t]
        s00 += x0 * y0
        s01 += x0 * y1
        s10 += x1 * y0
        s11 += x1 * y1
    return s00, s01, s10, s11


@nb.njit(cache=True, fastmath=True)
def envelope_cholesky(env, off, first):
    """In-place Cholesky of an SPD matrix in envelope storage: row i holds columns first[i] … i at
    env[off[i] : off[i + 1]] (A[i, j] = env[off[i] + j − first[i]]). Raises on a non-positive pivot.

    Up-looking (row by row), in 2×2 blocks wherever two consecutive rows start at the same column
    (the x and y velocity of one body always do): rows i, i + 1 against columns j, j + 1 take the four
    inner products in one pass over the shared prefix, which halves the loads and runs four
    independent chains (the inner products are short, about ten terms in the door jams of
    ``benchmarks/scaling.py``, so loads and loop overhead dominate them). Multiplies by reciprocal
    pivots rather than dividing."""
    nd = first.shape[0]
    inv_pivot = np.empty(nd)
    i = 0
    while i < nd:
        fi = first[i]
        oi = off[i] - fi  # env[oi + j] = L[i, j]
        pair = i + 1 < nd and first[i + 1] == fi
        oi1 = off[i + 1] - fi if pair else oi  # row i + 1 (row i again when unpaired: results unused)
        j = fi
        while j < i:
            fj = first[j]
            oj = off[j] - fj
            k0 = max(fi, fj)
            if j + 1 < i and first[j + 1] == fj:  # columns j, j + 1 together
                oj1 = off[j + 1] - fj
                s00, s01, s10, s11 = dot_2x2(env, oi + k0, oi1 + k0, env, oj + k0, oj1 + k0, j - k0)
                l_j1_j = env[oj1 + j]
                l_i_j = (env[oi + j] - s00) * inv_pivot[j]
                env[oi + j] = l_i_j
                env[oi + j + 1] = (env[oi + j + 1] - s01 - l_i_j * l_j1_j) * inv_pivot[j + 1]
                if pair:
                    l_i1_j = (env[oi1 + j] - s10) * inv_pivot[j]
                    env[oi1 + j] = l_i1_j
                    env[oi1 + j + 1] = (env[oi1 + j + 1] - s11 - l_i1_j * l_j1_j) * inv_pivot[j + 1]
                j += 2
            else:
                env[oi + j] = (env[oi + j] - dot_range(env, oi + k0, env, oj + k0, j - k0)) * inv_pivot[j]
                if pair:
                    env[oi1 + j] = (env[oi1 + j] - dot_range(env, oi1 + k0, env, oj + k0, j - k0)) * inv_pivot[j]
                j += 1
        last = i + 1 if pair else i
        for r in range(i, last + 1):  # the pair's own triangle: L[i + 1, i], then the pivots
            orr = off[r] - fi
            if r > i:
                env[orr + i] = (env[orr + i] - dot_range(env, orr + fi, env, oi + fi, i - fi)) * inv_pivot[i]
            s = env[orr + r] - dot_range(env, orr + fi, env, orr + fi, r - fi)
            if not s > 0.0:
                raise NotPositiveDefiniteError("Newton matrix is not positive definite")
            env[orr + r] = np.sqrt(s)
            inv_pivot[r] = 1.0 / env[orr + r]
        i = last + 1


@nb.njit(cache=True, fastmath=True)
def envelope_solve(env, off, first, x):
    """x ← (L Lᵀ)⁻¹ x in place with the factor of :func:`envelope_cholesky`."""
    nd = first.shape[0]
    for i in range(nd):
        oi = off[i] - first[i]
        x[i] = (x[i] - dot_range(env, oi + first[i], x, first[i], i - first[i])) / env[oi + i]
    for i in range(nd - 1, -1, -1):
        oi = off[i] - first[i]
        x[i] /= env[oi + i]
        sub_scaled(x, first[i], env, oi + first[i], x[i], i - first[i])


@nb.njit(cache=True, fastmath=SAME_ROUNDING_FASTMATH)
def cholesky_solve(L, b):
    """x solving (L Lᵀ) x = b (1-D) with the dense lower factor L: :func:`envelope_solve` on dense
    rows, kept as its own loop for the same reason as :func:`profile_cholesky` (a wrapper would add a
    call per solve inside the pivoting loop)."""
    n = L.shape[0]
    x = b.copy()
    for i in range(n):
        x[i] = (x[i] - dot_range(L[i], 0, x, 0, i)) / L[i, i]
    for i in range(n - 1, -1, -1):
        x[i] /= L[i, i]
        sub_scaled(x, 0, L[i], 0, x[i], i)
    return x
