"""One sweep's allocation and component updates: Neal's (2000) algorithm 8, then every component's (S, mu)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .conditionals import _draw_mean, _draw_precision_given_point, component_step, group_loglik
from .densities import log_new_weight, wishart_draw
from .linalg import LOG2PI, LOGPI, NEG_INF, _quad_rows, _scale_factor, _tril_inverse
from .state import activate, deactivate, pop_free

# Log weights this far below the largest are skipped: exp(-50) < 2e-22, which added to a total >= 1
# changes no bit of a float64.
_NEGLIGIBLE = 50.0


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
        if v > -_NEGLIGIBLE:
            total += math.exp(v)
        lw[t] = total
    u = rng.random() * total
    for t in range(k):
        if u < lw[t]:
            return t
    return k - 1


# Columns of a row of the packed component table of :func:`allocate` (then mu, b = L^T mu, and L's lower
# triangle column by column).
_BASE, _BOUND, _LNORM, _MU = 0, 1, 2, 3


@njit(cache=True)
def _min_eigenvalue_bound(L, j):
    """Return ``1 / |L_j^{-1}|_F^2 = 1 / tr(S_j^{-1})``, a lower bound on the smallest eigenvalue of ``S_j = L_j L_j^T``.

    0 (no bound) when a diagonal entry of ``L_j`` has underflowed to 0 or the sum overflows.
    """
    D = L.shape[1]
    for e in range(D):
        if not L[j, e, e] > 0.0:
            return 0.0
    inv = np.zeros((D, D))
    for e in range(D):
        inv[e, e] = 1.0 / L[j, e, e]
        for r in range(e + 1, D):
            s = 0.0
            for k in range(e, r):
                s += L[j, r, k] * inv[k, e]
            inv[r, e] = -s / L[j, r, r]
    f = 0.0
    for e in range(D):
        for a in range(e, D):
            f += inv[a, e] * inv[a, e]
    return 1.0 / f if f > 0.0 and math.isfinite(f) else 0.0


@njit(cache=True)
def _pack_component(L, mu, ldet, cnt, j, d, zeta, half, row):
    """Write component ``j``'s terms of the point update into ``row`` (see :func:`allocate`).

    ``row[_LNORM] = zeta (log|S_j|/2 - D/2 log 2 pi)``, ``row[_BASE] = log(n_j - d) + row[_LNORM]``,
    ``row[_BOUND] = zeta / 2 / |L_j^{-1}|_F^2`` (``1 / |L^{-1}|_F^2`` is a lower bound on the
    smallest eigenvalue of ``S_j``, so that ``zeta/2 (x - mu_j)^T S_j (x - mu_j) >= row[_BOUND]
    |x - mu_j|^2``), then ``mu_j``, ``b_j = L_j^T mu_j`` (``|L_j^T (x - mu_j)|^2 = |L_j^T x -
    b_j|^2``) and the lower triangle of ``L_j``, column by column.
    """
    D = mu.shape[1]
    row[_LNORM] = zeta * (0.5 * ldet[j] - half)
    row[_BASE] = math.log(cnt[j] - d) + row[_LNORM]
    row[_BOUND] = 0.5 * zeta * _min_eigenvalue_bound(L, j)
    o = _MU + 2 * D
    for e in range(D):
        row[_MU + e] = mu[j, e]
        v = 0.0
        for a in range(e, D):
            v += L[j, a, e] * mu[j, a]
            row[o] = L[j, a, e]
            o += 1
        row[_MU + D + e] = v


@njit(cache=True)
def _point_weight(packed, t, x, hz, D, use_lik):
    """Log weight of the component in row ``t`` of ``packed`` for the point ``x`` (see :func:`allocate`).

    ``log(n - d) + zeta log N(x | mu, S^{-1})``, with ``(x - mu)^T S (x - mu) = |L^T x - b|^2``
    written out (a call of a helper here costs more than the arithmetic); ``log(n - d)`` alone with
    the likelihood off.
    """
    if not use_lik:
        return packed[t, _BASE] - packed[t, _LNORM]
    q = 0.0
    o = _MU + 2 * D
    for e in range(D):
        u = -packed[t, _MU + D + e]
        for a in range(e, D):
            u += packed[t, o] * x[a]
            o += 1
        q += u * u
    return packed[t, _BASE] - hz * q


@njit(cache=True)
def allocate(X, st, m, use_lik, rng, refresh):
    """Neal (2000) algorithm 8 over every point, with the Pitman-Yor weights.

    Existing component j: ``(n_j^{-i} - d) N(x_i | mu_j, S_j^{-1})``; each of the ``m`` auxiliary
    components: ``(alpha + d K^{-i}) / m`` times its likelihood. The auxiliary *means* are drawn
    from N(xi, R^{-1}) afresh every ``refresh`` points (1: before every point, as in algorithm 8)
    and reused in between (Favaro & Teh 2013, "ReUse"): one that a point opens is replaced by a
    fresh draw, and when a point leaves a component of its own, that component's mean replaces an
    auxiliary chosen uniformly. Given the partition, the auxiliaries not chosen by a point are still
    independent draws from the prior (the point's choice depends on them only through its own
    likelihood, which does not involve them once the point joined an existing component), so reuse
    leaves the same posterior invariant. The auxiliaries' *precisions* are integrated out: given its
    mean, an auxiliary's likelihood is the multivariate Student-t ``t_{beta-D+1}(x_i; mu, beta W /
    (beta - D + 1))``, and a new component draws its precision from ``S | mu, x_i`` (conjugate) when
    it is opened: a partially collapsed Gibbs update of (z_i, S_new).

    The components' terms are packed one row per component in the order of ``act`` (one pass over
    contiguous memory per point). A component whose weight is provably below ``exp(-50)`` of the
    largest one so far (from the bound ``(x - mu)^T S (x - mu) >= lam_min(S) |x - mu|^2``) is
    skipped, as is every auxiliary when the Student-t's peak is: such a weight changes no bit of the
    float64 sum of the weights.

    Mixture of finite mixtures (``sc[4] = gamma > 0``): the weights are ``n_j + gamma`` and
    ``gamma V_n(K + 1) / V_n(K) / m`` (:func:`log_new_weight`). Coarsened posterior (``sc[3] = zeta
    < 1``): every likelihood is raised to ``zeta``; the auxiliaries' integrated likelihood then is
    ``pi^(-zeta D/2) Gamma_D((beta + zeta)/2) / Gamma_D(beta/2) |V|^(zeta/2) (1 + zeta q)^(-(beta + zeta)/2)``
    with ``V = (beta W)^{-1}`` and ``q = (x - mu)^T V (x - mu)`` (the Student-t above when zeta = 1).
    """
    z, cnt, mu, L, ldet, act, pos, ist, sc, xi, GR, W = (
        st.z, st.cnt, st.mu, st.L, st.ldet, st.act, st.pos, st.ist, st.sc, st.xi, st.GR, st.W
    )  # fmt: skip
    n, D = X.shape
    half = 0.5 * D * LOG2PI
    d, beta, zeta = sc[1], sc[2], sc[3]
    hz = 0.5 * zeta
    width = _MU + 2 * D + D * (D + 1) // 2
    packed = np.empty((n + 1, width))
    for t in range(ist[0]):
        _pack_component(L, mu, ldet, cnt, act[t], d, zeta, half, packed[t])
    # FR = GR^{-T} (upper): FR FR^T = R^{-1}; CW CW^T = V0 = (beta W)^{-1}
    FR = np.ascontiguousarray(_tril_inverse(GR).T)
    CW = np.empty((D, D))
    ldet_v0 = -_scale_factor(beta * W, CW)
    CW3 = CW.reshape((1, D, D))
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
    x = np.empty(D)
    for i in range(n):
        if i % refresh == 0:
            for k in range(m):
                _draw_mean(rng, xi, FR, amu, k)
        for a in range(D):
            x[a] = X[i, a]
        c = z[i]
        cnt[c] -= 1
        if cnt[c] == 0:
            p = pos[c]
            deactivate(c, st)  # the last active component moves to position p: so does its row
            if p < ist[0]:
                packed[p] = packed[ist[0]]
            k0 = min(int(rng.random() * m), m - 1) if refresh > 1 else 0
            for a in range(D):
                amu[k0, a] = mu[c, a]
        else:
            row = packed[pos[c]]
            row[_BASE] = math.log(cnt[c] - d) + row[_LNORM]
        K = ist[0]
        # the point's own component first (when it still has points): usually the largest weight,
        # which lets the bound below skip most of the others
        own = pos[c] if cnt[c] > 0 else -1
        if own >= 0:
            lw[own] = _point_weight(packed, own, x, hz, D, use_lik)
        top = lw[own] if own >= 0 else NEG_INF
        for t in range(K):
            if t == own:
                continue
            if use_lik:
                # a bound first: |x - mu_j|^2 costs D products, the quadratic form D(D+1)/2
                r2 = 0.0
                for a in range(D):
                    r2 += (x[a] - packed[t, _MU + a]) ** 2
                if packed[t, _BASE] - packed[t, _BOUND] * r2 < top - _NEGLIGIBLE:
                    lw[t] = NEG_INF
                    continue
            v = _point_weight(packed, t, x, hz, D, use_lik)
            lw[t] = v
            if v > top:
                top = v
        lnew = (log_new_weight(sc, st.lv, K) if K > 0 else 0.0) - logm
        if use_lik and lnew + t_norm < top - _NEGLIGIBLE:
            # the Student-t peaks at q = 0: every auxiliary is negligible
            for k in range(m):
                lw[K + k] = NEG_INF
        else:
            for k in range(m):
                if use_lik:
                    lw[K + k] = lnew + t_norm - t_pow * math.log1p(zeta * _quad_rows(CW3, 0, amu, k, X, i))
                else:
                    lw[K + k] = lnew
        t = _categorical(rng, lw, K + m)
        if t < K:
            j = act[t]
            z[i] = j
            cnt[j] += 1
            row = packed[t]
            row[_BASE] = math.log(cnt[j] - d) + row[_LNORM]
        else:
            k = t - K
            j = pop_free(st)
            mu[j] = amu[k]
            if use_lik:
                ldet[j] = _draw_precision_given_point(rng, X[i], amu[k], beta, W, zeta, L[j])
            else:
                ldet[j] = wishart_draw(rng, CW, ldet_v0, beta, L[j])
            activate(j, st)
            z[i] = j
            cnt[j] = 1
            _pack_component(L, mu, ldet, cnt, j, d, zeta, half, packed[K])
            if refresh > 1:  # the auxiliary became a component: a fresh one takes its place
                _draw_mean(rng, xi, FR, amu, k)


@njit(cache=True)
def _component_stats(X, z, pos, K, cnt, act, means, scats):
    """Per active component, at its position ``pos[j]`` in ``act``: mean and scatter about the mean of its points.

    Two passes over the points, for stability; ``means`` (>= K, D) and ``scats`` (>= K, D, D).
    """
    n, D = X.shape
    for t in range(K):
        means[t] = 0.0
        scats[t] = 0.0
    for i in range(n):
        t = pos[z[i]]
        for a in range(D):
            means[t, a] += X[i, a]
    for t in range(K):
        means[t] /= cnt[act[t]]
    for i in range(n):
        t = pos[z[i]]
        for a in range(D):
            da = X[i, a] - means[t, a]
            for b in range(a + 1):
                scats[t, a, b] += da * (X[i, b] - means[t, b])
    for t in range(K):
        for a in range(D):
            for b in range(a):
                scats[t, b, a] = scats[t, a, b]


@njit(cache=True)
def update_components(X, st, use_lik, rng):
    """Gibbs update of every component: ``S_j | mu_j`` then ``mu_j | S_j`` (see :func:`component_step`).

    Returns the log likelihood of the data under the updated components (to the power ``zeta``; 0
    with the likelihood off), from each component's count, mean and scatter.
    """
    z, cnt, mu, L, ldet, act, ist, sc, xi, R, W = (
        st.z, st.cnt, st.mu, st.L, st.ldet, st.act, st.ist, st.sc, st.xi, st.R, st.W
    )  # fmt: skip
    K = ist[0]
    D = mu.shape[1]
    means = np.empty((K, D))
    scats = np.empty((K, D, D))
    Rxi = np.zeros(D)
    for a in range(D):
        for b in range(D):
            Rxi[a] += R[a, b] * xi[b]
    _component_stats(X, z, st.pos, K, cnt, act, means, scats)
    zero_mean = np.zeros(D)
    zero_scat = np.zeros((D, D))
    loglik = 0.0
    for t in range(K):
        j = act[t]
        if use_lik:
            _, ldet[j] = component_step(
                cnt[j], means[t], scats[t], mu[j].copy(), sc[2], W, R, Rxi, True, mu[j], L[j], 0.0, sc[3], rng
            )
            loglik += group_loglik(cnt[j], means[t], scats[t], mu[j], L[j], ldet[j], sc[3])
        else:
            _, ldet[j] = component_step(
                0, zero_mean, zero_scat, mu[j].copy(), sc[2], W, R, Rxi, True, mu[j], L[j], 0.0, 1.0, rng
            )
    return loglik
