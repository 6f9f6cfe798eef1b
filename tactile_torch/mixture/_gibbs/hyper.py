"""Gibbs and slice-sampling updates of the hyperparameters xi, R, W, beta, alpha and d."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .densities import _lmvgamma, _normal_draw_prec, log_eppf, wishart_draw
from .linalg import (
    NEG_INF,
    _cholesky,
    _gram,
    _logdet_chol,
    _scale_factor,
    _solve_chol,
    _trace_prod_chol,
)

_WHICH_BETA, _WHICH_ALPHA, _WHICH_D = 0, 1, 2


@njit(cache=True)
def _hyper_logp(which, x, D, K, n, cnt, act, alpha, d, sum_ldet, sum_tr, ldet_w):
    """Log conditional density of one hyperparameter on its sampling scale.

    beta: on ``u = log(beta - D + 1)`` (prior term includes the Jacobian); alpha: on ``v = log(alpha)``;
    d: on d itself (uniform prior).
    """
    if which == _WHICH_BETA:
        if x > 700.0:
            return NEG_INF
        e = math.exp(x)
        beta = D - 1.0 + e
        if not (beta > D - 1.0):
            return NEG_INF
        out = -0.5 * x - 0.5 * D / e
        out += K * (0.5 * beta * D * math.log(0.5 * beta) + 0.5 * beta * ldet_w - _lmvgamma(0.5 * beta, D))
        out += 0.5 * (beta - D - 1.0) * sum_ldet - 0.5 * beta * sum_tr
        return out
    if which == _WHICH_ALPHA:
        if x > 700.0 or x < -700.0:
            return NEG_INF
        return -0.5 * x - 0.5 * math.exp(-x) + log_eppf(cnt, act, K, n, math.exp(x), d)
    # which == _WHICH_D
    if not (x < 1.0) or x < 0.0:
        return NEG_INF
    return log_eppf(cnt, act, K, n, alpha, x)


@njit(cache=True)
def _slice(rng, which, x0, width, lo, hi, D, K, n, cnt, act, alpha, d, sum_ldet, sum_tr, ldet_w):
    """One univariate slice-sampling update of ``x0`` within (lo, hi) (``width`` <= 0: no stepping out)."""
    f0 = _hyper_logp(which, x0, D, K, n, cnt, act, alpha, d, sum_ldet, sum_tr, ldet_w)
    u = rng.random()
    logy = f0 + math.log(u) if u > 0.0 else NEG_INF
    if width > 0.0:
        left = x0 - width * rng.random()
        right = left + width
        for _ in range(100):
            if (
                left <= lo
                or _hyper_logp(which, left, D, K, n, cnt, act, alpha, d, sum_ldet, sum_tr, ldet_w) <= logy
            ):
                break
            left -= width
        for _ in range(100):
            if (
                right >= hi
                or _hyper_logp(which, right, D, K, n, cnt, act, alpha, d, sum_ldet, sum_tr, ldet_w) <= logy
            ):
                break
            right += width
        left = max(left, lo)
        right = min(right, hi)
    else:
        left, right = lo, hi
    for _ in range(200):
        x1 = left + (right - left) * rng.random()
        if x1 > lo and x1 < hi:
            if _hyper_logp(which, x1, D, K, n, cnt, act, alpha, d, sum_ldet, sum_tr, ldet_w) > logy:
                return x1
        if x1 < x0:
            left = x1
        else:
            right = x1
    return x0


@njit(cache=True)
def _min_eig_at_least(W, w_min):
    """Whether ``W - w_min I`` is positive definite (plain Cholesky, no ridge)."""
    D = W.shape[0]
    G = np.zeros((D, D))
    for a in range(D):
        for b in range(a + 1):
            s = W[a, b] - (w_min if a == b else 0.0)
            for c in range(b):
                s -= G[a, c] * G[b, c]
            if a == b:
                if not (s > 0.0):
                    return False
                G[a, a] = math.sqrt(s)
            else:
                G[a, b] = s / G[b, b]
    return True


@njit(cache=True)
def update_hyper(st, n, fit_alpha, fit_d, d_low, w_min, rng):
    """Gibbs updates of xi, R, W, then slice updates of beta, alpha and d (whitened data: priors use I)."""
    mu, L, ldet, act, ist, cnt, sc = st.mu, st.L, st.ldet, st.act, st.ist, st.cnt, st.sc
    xi, R, GR, W, GW = st.xi, st.R, st.GR, st.W, st.GW
    K = ist[0]
    D = xi.shape[0]
    # xi | mu, R ~ N(Lam^{-1} R sum_k mu_k, Lam^{-1}),  Lam = I + K R   (prior N(0, I))
    lam = np.empty((D, D))
    h = np.zeros(D)
    for a in range(D):
        for b in range(D):
            lam[a, b] = K * R[a, b] + (1.0 if a == b else 0.0)
            for t in range(K):
                h[a] += R[a, b] * mu[act[t], b]
    G = np.empty((D, D))
    _cholesky(lam, G)
    m = np.empty(D)
    _solve_chol(G, h, m)
    _normal_draw_prec(rng, m, G, xi)
    # R | mu, xi ~ Wishart(D + K, (D I + sum_k (mu_k - xi)(mu_k - xi)^T)^{-1})   (prior Wishart(D, (D I)^{-1}))
    P = np.zeros((D, D))
    for a in range(D):
        P[a, a] = D
    for t in range(K):
        j = act[t]
        for a in range(D):
            for b in range(D):
                P[a, b] += (mu[j, a] - xi[a]) * (mu[j, b] - xi[b])
    C = np.empty((D, D))
    ldet_p = _scale_factor(P, C)
    wishart_draw(rng, C, -ldet_p, D + K, GR)
    _gram(GR, R)
    # W | S, beta ~ Wishart(D + K beta, (D I + beta sum_k S_k)^{-1}), truncated to W >= w_min I: the
    # untruncated conditional is an independence proposal, accepted iff it lies in the support.
    beta = sc[2]
    S = np.empty((D, D))
    P[:] = 0.0
    for a in range(D):
        P[a, a] = D
    for t in range(K):
        _gram(L[act[t]], S)
        for a in range(D):
            for b in range(D):
                P[a, b] += beta * S[a, b]
    ldet_p = _scale_factor(P, C)
    GWnew = np.empty((D, D))
    wishart_draw(rng, C, -ldet_p, D + K * beta, GWnew)
    Wnew = _gram(GWnew, np.empty((D, D)))
    if _min_eig_at_least(Wnew, w_min):
        W[:] = Wnew
        GW[:] = GWnew
    # beta | S, W (slice sampling on u = log(beta - D + 1))
    ldet_w = _logdet_chol(GW)
    sum_ldet = 0.0
    sum_tr = 0.0
    for t in range(K):
        j = act[t]
        sum_ldet += ldet[j]
        sum_tr += _trace_prod_chol(W, L[j])
    u = _slice(
        rng, _WHICH_BETA, math.log(beta - D + 1.0), 1.0, -np.inf, np.inf,
        D, K, n, cnt, act, sc[0], sc[1], sum_ldet, sum_tr, ldet_w,
    )  # fmt: skip
    sc[2] = D - 1.0 + math.exp(u)
    # alpha, d | partition (Pitman-Yor EPPF)
    if fit_alpha:
        v = _slice(
            rng,
            _WHICH_ALPHA,
            math.log(sc[0]),
            1.0,
            -np.inf,
            np.inf,
            D,
            K,
            n,
            cnt,
            act,
            sc[0],
            sc[1],
            0.0,
            0.0,
            0.0,
        )
        sc[0] = math.exp(v)
    if fit_d:
        sc[1] = _slice(rng, _WHICH_D, sc[1], 0.0, d_low, 1.0, D, K, n, cnt, act, sc[0], sc[1], 0.0, 0.0, 0.0)
