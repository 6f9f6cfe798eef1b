"""Log densities and random draws of the model's distributions (Wishart, normal, Pitman-Yor EPPF, priors)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .linalg import (
    LOG2,
    LOG2PI,
    LOGPI,
    NEG_INF,
    _logdet_chol,
    _quad_chol,
    _trace_prod_chol,
)

# Floor of a log chi-square draw: keeps a Bartlett factor (and so log|S|) finite when a tiny-shape
# gamma variate underflows; it binds with probability below 1e-300 per draw.
_LOG_DRAW_FLOOR = -1400.0


@njit(cache=True)
def _lmvgamma(a, D):
    """Log of the multivariate gamma function Gamma_D(a)."""
    out = 0.25 * D * (D - 1) * LOGPI
    for i in range(D):
        out += math.lgamma(a - 0.5 * i)
    return out


@njit(cache=True)
def wishart_logpdf(L, ldet_s, nu, P, ldet_p):
    """Log density of ``S = L L^T`` under Wishart(nu, V) with *inverse* scale ``P = V^{-1}``.

    ``log W(S; nu, V) = (nu-D-1)/2 log|S| - tr(V^{-1} S)/2 - nu D/2 log 2 - nu/2 log|V| - log Gamma_D(nu/2)``
    (mean ``nu V``), as ``scipy.stats.wishart(df=nu, scale=V)``.
    """
    D = L.shape[0]
    return (
        0.5 * (nu - D - 1.0) * ldet_s
        - 0.5 * _trace_prod_chol(P, L)
        - 0.5 * nu * D * LOG2
        + 0.5 * nu * ldet_p
        - _lmvgamma(0.5 * nu, D)
    )


@njit(cache=True)
def normal_logpdf(x, m, G):
    """Log density of ``x`` under N(m, Lambda^{-1}) with precision ``Lambda = G G^T`` (lower ``G``)."""
    D = G.shape[0]
    return 0.5 * _logdet_chol(G) - 0.5 * D * LOG2PI - 0.5 * _quad_chol(G, x, m)


@njit(cache=True)
def _log_gamma_draw(rng, shape):
    """Log of a Gamma(shape, 1) variate, computed so that small shapes do not underflow to log(0)."""
    if shape >= 1.0:
        g = rng.standard_gamma(shape)
        return math.log(g) if g > 0.0 else _LOG_DRAW_FLOOR
    # Gamma(a) = Gamma(a + 1) * U^(1/a), in the log domain.
    g = rng.standard_gamma(shape + 1.0)
    u = rng.random()
    if u <= 0.0 or g <= 0.0:
        return _LOG_DRAW_FLOOR
    return max(math.log(g) + math.log(u) / shape, _LOG_DRAW_FLOOR)


@njit(cache=True)
def wishart_draw(rng, C, ldet_v, nu, L):
    """Draw ``S ~ Wishart(nu, V)`` with ``V = C C^T`` (lower ``C``); write its lower Cholesky factor in ``L``.

    Bartlett decomposition: ``S = (C A)(C A)^T`` with ``A`` lower, ``A_aa^2 ~ chi2(nu - a)``,
    ``A_ab ~ N(0, 1)`` below the diagonal; ``C A`` is lower with a positive diagonal, so it *is* the
    Cholesky factor of ``S``. Returns ``log|S| = log|V| + sum_a log chi2_a``, from the log-domain draws.
    """
    D = C.shape[0]
    A = np.zeros((D, D))
    ldet = ldet_v
    for a in range(D):
        lchi = LOG2 + _log_gamma_draw(rng, 0.5 * (nu - a))
        A[a, a] = math.exp(0.5 * lchi)
        ldet += lchi
        for b in range(a):
            A[a, b] = rng.standard_normal()
    for a in range(D):
        for b in range(D):
            s = 0.0
            for c in range(b, a + 1):
                s += C[a, c] * A[c, b]
            L[a, b] = s
    return ldet


@njit(cache=True)
def _normal_draw_prec(rng, m, G, out):
    """``out ~ N(m, (G G^T)^{-1})``: ``m + G^{-T} eps``."""
    D = G.shape[0]
    eps = np.empty(D)
    for a in range(D):
        eps[a] = rng.standard_normal()
    for a in range(D - 1, -1, -1):
        s = eps[a]
        for b in range(a + 1, D):
            s -= G[b, a] * eps[b]
        eps[a] = s / G[a, a]
    for a in range(D):
        out[a] = m[a] + eps[a]


@njit(cache=True)
def log_eppf(cnt, act, K, n, alpha, d):
    """Log exchangeable partition probability of the Pitman-Yor (Chinese restaurant) prior.

    ``prod_{k=1}^{K-1}(alpha + k d) / (alpha + 1)_{n-1} * prod_j (1 - d)_{n_j - 1}``, ``(x)_m`` the
    rising factorial; ``d = 0`` gives the Dirichlet process.
    """
    out = math.lgamma(alpha + 1.0) - math.lgamma(alpha + n)
    for k in range(1, K):
        v = alpha + k * d
        if v <= 0.0:
            return NEG_INF
        out += math.log(v)
    l1d = math.lgamma(1.0 - d)
    for t in range(K):
        out += math.lgamma(cnt[act[t]] - d) - l1d
    return out


@njit(cache=True)
def log_eppf_mfm(cnt, act, K, gamma, lv):
    """Log partition probability of the mixture of finite mixtures (Miller & Harrison 2018, eq. 3.2).

    ``V_n(K) prod_j gamma^(n_j)`` with ``gamma^(m)`` the rising factorial and ``lv[K] = log V_n(K)``.
    """
    out = lv[K]
    lg = math.lgamma(gamma)
    for t in range(K):
        out += math.lgamma(cnt[act[t]] + gamma) - lg
    return out


@njit(cache=True)
def log_new_weight(sc, lv, t):
    """Log weight of a new component when ``t`` components hold the other points (Gibbs conditional).

    Pitman-Yor: ``log(alpha + d t)``; mixture of finite mixtures (``sc[4] = gamma > 0``):
    ``log(gamma V_n(t + 1) / V_n(t))`` (Miller & Harrison 2018, eq. 3.6). The weight of an existing
    component is ``n_j - d`` in both (``d = -gamma`` for the mixture of finite mixtures).
    """
    if sc[4] > 0.0:
        return math.log(sc[4]) + lv[t + 1] - lv[t]
    return math.log(sc[0] + sc[1] * t)


@njit(cache=True)
def _log_prior_beta(beta, D):
    # 1/(beta - D + 1) ~ Gamma(shape 1/2, rate D/2), as a density in beta.
    g = 1.0 / (beta - D + 1.0)
    return 0.5 * math.log(0.5 * D) - math.lgamma(0.5) - 0.5 * math.log(g) - 0.5 * D * g + 2.0 * math.log(g)


@njit(cache=True)
def _log_prior_alpha(alpha):
    # 1/alpha ~ Gamma(shape 1/2, rate 1/2), as a density in alpha.
    g = 1.0 / alpha
    return 0.5 * math.log(0.5) - math.lgamma(0.5) - 0.5 * math.log(g) - 0.5 * g + 2.0 * math.log(g)
