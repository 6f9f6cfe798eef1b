"""The model's conditionals: one component's (S, mu) given its points, the base measure, new components."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .densities import _normal_draw_prec, normal_logpdf, wishart_draw, wishart_logpdf
from .linalg import (
    LOG2PI,
    _cholesky,
    _gram,
    _scale_factor,
    _solve_chol,
    _trace_prod_chol,
)


@njit(cache=True)
def component_step(n, ne, mean, scat, mu0, beta, W, R, Rxi, draw, mu, L, ldet_in, zeta, rng):
    """One Gibbs update of a component's (S, mu) given its data; return (log density of the move, log|S|).

    ``S | mu0 ~ Wishart(beta + n, (beta W + sum_i (x_i - mu0)(x_i - mu0)^T)^{-1})`` then
    ``mu | S ~ N(Lambda^{-1}(R xi + S sum_i x_i), Lambda^{-1})`` with ``Lambda = R + n S``; under
    the coarsened posterior (likelihood to the power ``zeta``) every ``n`` and every sum over the
    points is multiplied by ``zeta`` (conjugacy is kept). The data
    enter through ``n``, their ``mean`` and their scatter ``scat`` about the mean (``n = 0``: the
    prior). ``ne``: the count that weighs the mean (``n`` itself, or with session effects the
    effective count ``E`` of :func:`~.sessions.effective_stats`, with ``mean`` and ``scat`` the
    effective ones; ``n`` still adds the degrees of freedom). With ``draw`` the new (mu, L) are drawn
    into ``mu``/``L``; without, the density of moving to the given ``mu``/``L`` (with ``log|S| =
    ldet_in``) is evaluated. The log density is the transition density used by the split-merge
    proposals.
    """
    D = mean.shape[0]
    P = np.empty((D, D))
    for a in range(D):
        da = mean[a] - mu0[a]
        for b in range(D):
            P[a, b] = beta * W[a, b]
            if n > 0:  # n = 0: no data, whatever mean/scat hold
                P[a, b] += zeta * (scat[a, b] + ne * da * (mean[b] - mu0[b]))
    C = np.empty((D, D))
    ldet_p = _scale_factor(P, C)
    nz = zeta * n
    nez = zeta * ne
    nu = beta + nz
    if draw:
        ldet_s = wishart_draw(rng, C, -ldet_p, nu, L)
    else:
        ldet_s = ldet_in
    logq = wishart_logpdf(L, ldet_s, nu, P, ldet_p)
    S = _gram(L, np.empty((D, D)))
    lam = np.empty((D, D))
    h = np.empty(D)
    for a in range(D):
        s = Rxi[a]
        for b in range(D):
            lam[a, b] = R[a, b] + nez * S[a, b]
            if n > 0:
                s += nez * S[a, b] * mean[b]
        h[a] = s
    G = np.empty((D, D))
    _cholesky(lam, G)
    m = np.empty(D)
    _solve_chol(G, h, m)
    if draw:
        _normal_draw_prec(rng, m, G, mu)
    logq += normal_logpdf(mu, m, G)
    return logq, ldet_s


@njit(cache=True)
def base_logpdf(mu, L, ldet, beta, W, ldet_w, xi, GR):
    """Log density of a component's (mu, S) under the base measure G0 = N(xi, R^{-1}) x Wishart(beta, (beta W)^{-1})."""
    D = mu.shape[0]
    return normal_logpdf(mu, xi, GR) + wishart_logpdf(L, ldet, beta, beta * W, D * math.log(beta) + ldet_w)


@njit(cache=True)
def _draw_mean(rng, xi, FR, Mu, k):
    """Draw a component mean from N(xi, R^{-1}) into row ``k`` of ``Mu`` (``FR FR^T = R^{-1}``)."""
    D = xi.shape[0]
    for a in range(D):
        Mu[k, a] = xi[a]
    for b in range(D):
        e = rng.standard_normal()
        for a in range(D):
            Mu[k, a] += FR[a, b] * e


@njit(cache=True)
def _draw_precision_given_point(rng, x, mu, beta, W, zeta, c, L):
    """Draw ``S | mu, x ~ Wishart(beta + zeta, (beta W + zeta / c (x - mu)(x - mu)^T)^{-1})`` into ``L``; return log|S|.

    ``x ~ N(mu, c S^{-1})`` to the power ``zeta`` (``c = 1 + lambda``: a point whose session effect
    is integrated out; 1 without sessions).
    """
    D = x.shape[0]
    P = np.empty((D, D))
    f = zeta / c
    for a in range(D):
        for b in range(D):
            P[a, b] = beta * W[a, b] + f * ((x[a] - mu[a]) * (x[b] - mu[b]))
    C = np.empty((D, D))
    ldet_p = _scale_factor(P, C)
    return wishart_draw(rng, C, -ldet_p, beta + zeta, L)


@njit(cache=True)
def group_loglik(n, ne, mean, scat, mu, L, ldet, zeta):
    """``zeta sum_k log N(x_k | mu, S^{-1})`` of ``n`` points with this ``mean`` and ``scat`` (scatter about it), ``S = L L^T``.

    ``sum_k (x_k - mu)^T S (x_k - mu) = tr(S scat) + n (mean - mu)^T S (mean - mu)``: the points
    enter through their sufficient statistics only. ``ne``: the count of the mean term (``n``, or
    with session effects the effective count, ``mean`` and ``scat`` then the effective ones: the
    caller subtracts ``D/2 pen``, :func:`~.sessions.effective_stats`).
    """
    D = mean.shape[0]
    q = 0.0
    for e in range(D):
        v = 0.0
        for a in range(e, D):
            v += L[a, e] * (mean[a] - mu[a])
        q += v * v
    return zeta * (n * (0.5 * ldet - 0.5 * D * LOG2PI) - 0.5 * (_trace_prod_chol(scat, L) + ne * q))
