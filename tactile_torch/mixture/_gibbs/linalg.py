"""Small dense linear algebra on D x D matrices for the Gibbs kernels, and the numba types they share.

D is small (3 in the study): plain loops beat the overhead of a LAPACK call. The entry kernels of the
package (:func:`tactile_torch.mixture._gibbs.chain.run_sweeps`, ``init_components``) are compiled eagerly for
the exact types below and cached on disk; the helpers here and in the sibling modules carry no
signature and are compiled into them, so that importing the package loads a handful of cache
entries instead of one per helper (what made the start-up slow).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit, types

f8, i8, b1, void = types.float64, types.int64, types.boolean, types.void
A1, A2, A3 = (types.Array(types.float64, k, "C") for k in (1, 2, 3))
I1 = types.Array(types.int64, 1, "C")
I2 = types.Array(types.int64, 2, "C")
J2 = types.Array(types.int32, 2, "C")
RNG = numba.typeof(np.random.default_rng(0))

LOG2PI = math.log(2.0 * math.pi)
LOGPI = math.log(math.pi)
LOG2 = math.log(2.0)
NEG_INF = -np.inf


@njit(cache=True)
def _cholesky(A, G):
    """Lower Cholesky factor of SPD ``A`` into ``G``; adds a growing ridge if ``A`` is not numerically PD."""
    D = A.shape[0]
    ridge = 0.0
    scale = 0.0
    for a in range(D):
        scale = max(scale, abs(A[a, a]))
    if scale == 0.0 or not math.isfinite(scale):
        scale = 1.0
    for _attempt in range(60):
        ok = True
        for a in range(D):
            for b in range(a + 1):
                s = A[a, b]
                if a == b:
                    s += ridge
                for c in range(b):
                    s -= G[a, c] * G[b, c]
                if a == b:
                    if not (s > 0.0) or not math.isfinite(s):
                        ok = False
                        break
                    G[a, a] = math.sqrt(s)
                else:
                    G[a, b] = s / G[b, b]
            if not ok:
                break
            for b in range(a + 1, D):
                G[a, b] = 0.0
        if ok:
            return
        ridge = scale * 1e-14 if ridge == 0.0 else ridge * 10.0


@njit(cache=True)
def _logdet_chol(G):
    s = 0.0
    for a in range(G.shape[0]):
        s += math.log(G[a, a])
    return 2.0 * s


@njit(cache=True)
def _tril_inverse(G):
    """Inverse of a lower-triangular matrix (lower), by forward substitution column by column."""
    D = G.shape[0]
    Ginv = np.zeros((D, D))
    for c in range(D):
        Ginv[c, c] = 1.0 / G[c, c]
        for r in range(c + 1, D):
            s = 0.0
            for k in range(c, r):
                s += G[r, k] * Ginv[k, c]
            Ginv[r, c] = -s / G[r, r]
    return Ginv


@njit(cache=True)
def _scale_factor(P, C):
    """Write into ``C`` a lower-triangular factor with ``C C^T = P^{-1}``; return ``log|P|``.

    Uses the Cholesky factor of the row/column-reversed matrix: if ``J P J = G G^T`` then
    ``P^{-1} = (J G^{-T} J)(J G^{-T} J)^T`` and ``J G^{-T} J`` is lower triangular. No explicit
    inverse of ``P`` is formed, so an ill-conditioned ``P`` loses no more than its Cholesky factor.
    """
    D = P.shape[0]
    F = np.empty((D, D))
    for a in range(D):
        for b in range(D):
            F[a, b] = P[D - 1 - a, D - 1 - b]
    G = np.empty((D, D))
    _cholesky(F, G)
    Ginv = _tril_inverse(G)
    for a in range(D):
        for b in range(D):
            C[a, b] = Ginv[D - 1 - b, D - 1 - a] if a >= b else 0.0
    return _logdet_chol(G)


@njit(cache=True)
def _solve_chol(G, h, out):
    """``out = (G G^T)^{-1} h`` for lower ``G``."""
    D = G.shape[0]
    for a in range(D):
        s = h[a]
        for b in range(a):
            s -= G[a, b] * out[b]
        out[a] = s / G[a, a]
    for a in range(D - 1, -1, -1):
        s = out[a]
        for b in range(a + 1, D):
            s -= G[b, a] * out[b]
        out[a] = s / G[a, a]


@njit(cache=True)
def _quad_chol(L, x, mu):
    """``(x - mu)^T L L^T (x - mu)`` for lower ``L``."""
    D = L.shape[0]
    q = 0.0
    for c in range(D):
        v = 0.0
        for a in range(c, D):
            v += L[a, c] * (x[a] - mu[a])
        q += v * v
    return q


@njit(cache=True)
def _quad_rows(Ls, jl, Mu, jm, X, i):
    """``_quad_chol(Ls[jl], X[i], Mu[jm])`` without making array views (each view costs two atomic
    reference-count updates, which dominated the per-point loop)."""
    D = X.shape[1]
    q = 0.0
    for c in range(D):
        v = 0.0
        for a in range(c, D):
            v += Ls[jl, a, c] * (X[i, a] - Mu[jm, a])
        q += v * v
    return q


@njit(cache=True)
def _gram(L, S):
    """``S = L L^T``."""
    D = L.shape[0]
    for a in range(D):
        for b in range(a + 1):
            s = 0.0
            for c in range(b + 1):
                s += L[a, c] * L[b, c]
            S[a, b] = s
            S[b, a] = s
    return S


@njit(cache=True)
def _trace_prod_chol(P, L):
    """``tr(P L L^T)`` for symmetric ``P`` and lower ``L``."""
    D = L.shape[0]
    tr = 0.0
    for c in range(D):
        for a in range(c, D):
            row = 0.0
            for b in range(c, D):
                row += P[a, b] * L[b, c]
            tr += L[a, c] * row
    return tr
