"""One sweep's allocation and component updates: Neal's (2000) algorithm 8, then every component's (S, mu)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .conditionals import _draw_mean, _draw_precision_given_point, component_step
from .densities import log_new_weight, wishart_draw
from .linalg import LOG2PI, LOGPI, _quad_rows, _scale_factor, _tril_inverse
from .state import activate, deactivate, pop_free


@njit(cache=True)
def _categorical(rng, lw, k):
    """Index drawn with probabilities proportional to ``exp(lw[:k])``."""
    mx = lw[0]
    for t in range(1, k):
        if lw[t] > mx:
            mx = lw[t]
    total = 0.0
    for t in range(k):
        v = lw[t] - mx
        # exp(-50) < 2e-22: adding it to a total >= 1 changes no bit of a float64, so skip the exp
        if v > -50.0:
            total += math.exp(v)
        lw[t] = total
    u = rng.random() * total
    for t in range(k):
        if u < lw[t]:
            return t
    return k - 1


@njit(cache=True)
def allocate(X, st, m, use_lik, rng):
    """Neal (2000) algorithm 8 over every point, with the Pitman-Yor weights.

    Existing component j: ``(n_j^{-i} - d) N(x_i | mu_j, S_j^{-1})``; each of the ``m`` auxiliary
    components: ``(alpha + d K^{-i}) / m`` times its likelihood. Auxiliary means are drawn from
    N(xi, R^{-1}) (a point alone in its component hands that component's mean to the first
    auxiliary); their precisions are integrated out: given its mean, an auxiliary's likelihood is the
    multivariate Student-t ``t_{beta-D+1}(x_i; mu, beta W / (beta - D + 1))``, and a new component
    draws its precision from ``S | mu, x_i`` (conjugate) when it is opened. This partially
    collapsed form of algorithm 8 leaves the same posterior invariant and needs no Wishart draw per
    auxiliary.

    Mixture of finite mixtures (``sc[4] = gamma > 0``): the weights are ``n_j + gamma`` and
    ``gamma V_n(K + 1) / V_n(K) / m`` (:func:`log_new_weight`). Coarsened posterior (``sc[3] = zeta
    < 1``): every likelihood is raised to ``zeta``; the auxiliaries' integrated likelihood then is
    ``pi^(-zeta D/2) Gamma_D((beta + zeta)/2) / Gamma_D(beta/2) |V|^(zeta/2) (1 + zeta q)^(-(beta + zeta)/2)``
    with ``V = (beta W)^{-1}`` and ``q = (x - mu)^T V (x - mu)`` (the Student-t above when zeta = 1).
    """
    z, cnt, mu, L, ldet, act, ist, sc, xi, GR, W = (
        st.z, st.cnt, st.mu, st.L, st.ldet, st.act, st.ist, st.sc, st.xi, st.GR, st.W
    )  # fmt: skip
    cap = cnt.shape[0]
    D = X.shape[1]
    half = 0.5 * D * LOG2PI
    zeta = sc[3]
    hz = 0.5 * zeta
    # cached per component: log(n_j - d) and zeta (log|S_j|/2 - D/2 log(2 pi))
    lcnt = np.zeros(cap)
    lnorm = np.zeros(cap)
    for t in range(ist[0]):
        j = act[t]
        lcnt[j] = math.log(cnt[j] - sc[1])
        lnorm[j] = zeta * (0.5 * ldet[j] - half)
    # FR = GR^{-T} (upper): FR FR^T = R^{-1}; CW CW^T = V0 = (beta W)^{-1}
    FR = np.ascontiguousarray(_tril_inverse(GR).T)
    CW = np.empty((D, D))
    ldet_v0 = -_scale_factor(sc[2] * W, CW)
    CW3 = CW.reshape((1, D, D))
    n, D = X.shape
    d, beta = sc[1], sc[2]
    half = 0.5 * D * LOG2PI
    logm = math.log(m)
    # log Student-t normaliser: lgamma((beta+1)/2) - lgamma((beta-D+1)/2) - D/2 log(pi) + log|V|/2
    if zeta == 1.0:
        t_norm = (
            math.lgamma(0.5 * (beta + 1.0))
            - math.lgamma(0.5 * (beta - D + 1.0))
            - 0.5 * D * LOGPI
            + 0.5 * ldet_v0
        )
    else:
        t_norm = -0.5 * zeta * D * LOGPI + 0.5 * zeta * ldet_v0
        for a in range(D):
            t_norm += math.lgamma(0.5 * (beta + zeta - a)) - math.lgamma(0.5 * (beta - a))
    t_pow = 0.5 * (beta + zeta)
    amu = np.empty((m, D))
    lw = np.empty(n + m + 1)
    dev = np.empty(D)
    for i in range(n):
        c = z[i]
        cnt[c] -= 1
        first = 0
        if cnt[c] == 0:
            deactivate(c, st)
            amu[0] = mu[c]
            first = 1
        else:
            lcnt[c] = math.log(cnt[c] - d)
        for k in range(first, m):
            _draw_mean(rng, xi, FR, amu, k)
        K = ist[0]
        for t in range(K):
            j = act[t]
            if use_lik:
                # (x - mu_j)^T S_j (x - mu_j) = |L_j^T (x - mu_j)|^2, written out: a call here costs
                # more than the arithmetic
                for a in range(D):
                    dev[a] = X[i, a] - mu[j, a]
                q = 0.0
                for c in range(D):
                    v = 0.0
                    for a in range(c, D):
                        v += L[j, a, c] * dev[a]
                    q += v * v
                lw[t] = lcnt[j] + lnorm[j] - hz * q
            else:
                lw[t] = lcnt[j]
        lnew = (log_new_weight(sc, st.lv, K) if K > 0 else 0.0) - logm
        for k in range(m):
            if use_lik:
                lw[K + k] = lnew + t_norm - t_pow * math.log1p(zeta * _quad_rows(CW3, 0, amu, k, X, i))
            else:
                lw[K + k] = lnew
        t = _categorical(rng, lw, K + m)
        if t < K:
            j = act[t]
        else:
            k = t - K
            j = pop_free(st)
            mu[j] = amu[k]
            if use_lik:
                ldet[j] = _draw_precision_given_point(rng, X[i], amu[k], beta, W, zeta, L[j])
            else:
                ldet[j] = wishart_draw(rng, CW, ldet_v0, beta, L[j])
            lnorm[j] = zeta * (0.5 * ldet[j] - half)
            cnt[j] = 0
            activate(j, st)
        z[i] = j
        cnt[j] += 1
        lcnt[j] = math.log(cnt[j] - d)


@njit(cache=True)
def _component_stats(X, z, cnt, act, K, means, scats):
    """Per active slot: mean and scatter about the mean of its points (two passes, for stability)."""
    n, D = X.shape
    for t in range(K):
        j = act[t]
        means[j] = 0.0
        scats[j] = 0.0
    for i in range(n):
        j = z[i]
        for a in range(D):
            means[j, a] += X[i, a]
    for t in range(K):
        j = act[t]
        means[j] /= cnt[j]
    for i in range(n):
        j = z[i]
        for a in range(D):
            da = X[i, a] - means[j, a]
            for b in range(a + 1):
                scats[j, a, b] += da * (X[i, b] - means[j, b])
    for t in range(K):
        j = act[t]
        for a in range(D):
            for b in range(a):
                scats[j, b, a] = scats[j, a, b]


@njit(cache=True)
def update_components(X, st, use_lik, rng):
    """Gibbs update of every component: ``S_j | mu_j`` then ``mu_j | S_j`` (see :func:`component_step`)."""
    z, cnt, mu, L, ldet, act, ist, sc, xi, R, W = (
        st.z, st.cnt, st.mu, st.L, st.ldet, st.act, st.ist, st.sc, st.xi, st.R, st.W
    )  # fmt: skip
    K = ist[0]
    cap, D = mu.shape
    means = np.zeros((cap, D))
    scats = np.zeros((cap, D, D))
    Rxi = np.zeros(D)
    for a in range(D):
        for b in range(D):
            Rxi[a] += R[a, b] * xi[b]
    _component_stats(X, z, cnt, act, K, means, scats)
    zero_mean = np.zeros(D)
    zero_scat = np.zeros((D, D))
    for t in range(K):
        j = act[t]
        if use_lik:
            _, ldet[j] = component_step(
                cnt[j], means[j], scats[j], mu[j].copy(), sc[2], W, R, Rxi, True, mu[j], L[j], 0.0, sc[3], rng
            )
        else:
            _, ldet[j] = component_step(
                0, zero_mean, zero_scat, mu[j].copy(), sc[2], W, R, Rxi, True, mu[j], L[j], 0.0, 1.0, rng
            )
