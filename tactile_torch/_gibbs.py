"""Compiled (numba) kernels of the Pitman-Yor Gaussian-mixture Gibbs sampler of :mod:`tactile_torch.mixture`.

Everything here works on *whitened* data (see :class:`tactile_torch.mixture.PitmanYorGMM`), in float64,
and trusts its caller. The model and every parameterisation are documented in
``PitmanYorGMM``; this module only says how the numbers are laid out.

State of the chain (``cap = n + 1`` component slots; active slots listed in ``act[:ist[0]]``):

- ``z[i]``: slot of point ``i``; ``cnt[j]``: number of points in slot ``j``;
- ``mu[j]`` component mean, ``L[j]`` lower Cholesky factor of its *precision* ``S_j = L_j L_j^T``,
  ``ldet[j] = log|S_j|`` (kept from the log-domain draw, so that it stays finite when a factor underflows);
- ``pos[j]`` position of slot ``j`` in ``act`` (-1 if free); ``fre[:ist[1]]`` stack of free slots;
- ``sc = [alpha, d, beta]``; ``xi`` (D,), ``R``, ``W`` (D, D) and ``GR``/``GW`` their lower Cholesky factors.

The per-point update costs O((K + m) D^2): component likelihoods come from the cached factors
(one triangular mat-vec each), and the weights ``log(n_j - d)`` and ``log|S_j|/2`` are cached per
component and refreshed only when a count or a parameter changes. The random numbers come from the
``numpy.random.Generator`` passed in (numba draws from its bit generator), so a seeded run is
reproducible and shares no global state.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit, types

# Every kernel is compiled once, for the exact types below (and cached on disk), rather than once per
# combination of argument types met at its call sites (numba specialises on literal arguments),
# which multiplied the compile time.
f8, i8, b1, void = types.float64, types.int64, types.boolean, types.void
A1, A2, A3 = (types.Array(types.float64, k, "C") for k in (1, 2, 3))
I1 = types.Array(types.int64, 1, "C")
S2 = types.Array(types.int32, 2, "C")
RNG = numba.typeof(np.random.default_rng(0))
UniTuple, Tuple = types.UniTuple, types.Tuple

_LOG2PI = math.log(2.0 * math.pi)
_LOGPI = math.log(math.pi)
_LOG2 = math.log(2.0)
# Floor of a log chi-square draw: keeps a Bartlett factor (and so log|S|) finite when a tiny-shape
# gamma variate underflows; it binds with probability below 1e-300 per draw.
_LOG_DRAW_FLOOR = -1400.0
_NEG_INF = -np.inf

# Indices of the counters of split-merge moves.
SPLIT_PROPOSED, SPLIT_ACCEPTED, MERGE_PROPOSED, MERGE_ACCEPTED = 0, 1, 2, 3


# --------------------------------------------------------------------------------------------------
# small dense linear algebra on D x D matrices (D is small; plain loops beat LAPACK call overhead)
# --------------------------------------------------------------------------------------------------
@njit(void(A2, A2), cache=True)
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


@njit(f8(A2), cache=True)
def _logdet_chol(G):
    s = 0.0
    for a in range(G.shape[0]):
        s += math.log(G[a, a])
    return 2.0 * s


@njit(A2(A2), cache=True)
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


@njit(f8(A2, A2), cache=True)
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


@njit(void(A2, A1, A1), cache=True)
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


@njit(f8(A2, A1, A1), cache=True)
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


@njit(f8(A3, i8, A2, i8, A2, i8), cache=True)
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


@njit(A2(A2, A2), cache=True)
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


@njit(f8(A2, A2), cache=True)
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


# --------------------------------------------------------------------------------------------------
# densities and draws
# --------------------------------------------------------------------------------------------------
@njit(f8(f8, i8), cache=True)
def _lmvgamma(a, D):
    """Log of the multivariate gamma function Gamma_D(a)."""
    out = 0.25 * D * (D - 1) * _LOGPI
    for i in range(D):
        out += math.lgamma(a - 0.5 * i)
    return out


@njit(f8(A2, f8, f8, A2, f8), cache=True)
def wishart_logpdf(L, ldet_s, nu, P, ldet_p):
    """Log density of ``S = L L^T`` under Wishart(nu, V) with *inverse* scale ``P = V^{-1}``.

    ``log W(S; nu, V) = (nu-D-1)/2 log|S| - tr(V^{-1} S)/2 - nu D/2 log 2 - nu/2 log|V| - log Gamma_D(nu/2)``
    (mean ``nu V``), as ``scipy.stats.wishart(df=nu, scale=V)``.
    """
    D = L.shape[0]
    return (
        0.5 * (nu - D - 1.0) * ldet_s
        - 0.5 * _trace_prod_chol(P, L)
        - 0.5 * nu * D * _LOG2
        + 0.5 * nu * ldet_p
        - _lmvgamma(0.5 * nu, D)
    )


@njit(f8(A1, A1, A2), cache=True)
def normal_logpdf(x, m, G):
    """Log density of ``x`` under N(m, Lambda^{-1}) with precision ``Lambda = G G^T`` (lower ``G``)."""
    D = G.shape[0]
    return 0.5 * _logdet_chol(G) - 0.5 * D * _LOG2PI - 0.5 * _quad_chol(G, x, m)


@njit(f8(RNG, f8), cache=True)
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


@njit(f8(RNG, A2, f8, f8, A2), cache=True)
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
        lchi = _LOG2 + _log_gamma_draw(rng, 0.5 * (nu - a))
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


@njit(void(RNG, A1, A2, A1), cache=True)
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


# --------------------------------------------------------------------------------------------------
# the model's conditionals
# --------------------------------------------------------------------------------------------------
@njit(UniTuple(f8, 2)(i8, A1, A2, A1, f8, A2, A2, A1, b1, A1, A2, f8, RNG), cache=True)
def component_step(n, mean, scat, mu0, beta, W, R, Rxi, draw, mu, L, ldet_in, rng):
    """One Gibbs update of a component's (S, mu) given its data; return (log density of the move, log|S|).

    ``S | mu0 ~ Wishart(beta + n, (beta W + sum_i (x_i - mu0)(x_i - mu0)^T)^{-1})`` then
    ``mu | S ~ N(Lambda^{-1}(R xi + S sum_i x_i), Lambda^{-1})`` with ``Lambda = R + n S``. The data
    enter through ``n``, their ``mean`` and their scatter ``scat`` about the mean (``n = 0``: the
    prior). With ``draw`` the new (mu, L) are drawn into ``mu``/``L``; without, the density of
    moving to the given ``mu``/``L`` (with ``log|S| = ldet_in``) is evaluated. The log density is the
    transition density used by the split-merge proposals.
    """
    D = mean.shape[0]
    P = np.empty((D, D))
    for a in range(D):
        da = mean[a] - mu0[a]
        for b in range(D):
            P[a, b] = beta * W[a, b]
            if n > 0:  # n = 0: no data, whatever mean/scat hold
                P[a, b] += scat[a, b] + n * da * (mean[b] - mu0[b])
    C = np.empty((D, D))
    ldet_p = _scale_factor(P, C)
    nu = beta + n
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
            lam[a, b] = R[a, b] + n * S[a, b]
            if n > 0:
                s += n * S[a, b] * mean[b]
        h[a] = s
    G = np.empty((D, D))
    _cholesky(lam, G)
    m = np.empty(D)
    _solve_chol(G, h, m)
    if draw:
        _normal_draw_prec(rng, m, G, mu)
    logq += normal_logpdf(mu, m, G)
    return logq, ldet_s


@njit(f8(A1, A2, f8, f8, A2, f8, A1, A2), cache=True)
def base_logpdf(mu, L, ldet, beta, W, ldet_w, xi, GR):
    """Log density of a component's (mu, S) under the base measure G0 = N(xi, R^{-1}) x Wishart(beta, (beta W)^{-1})."""
    D = mu.shape[0]
    return normal_logpdf(mu, xi, GR) + wishart_logpdf(L, ldet, beta, beta * W, D * math.log(beta) + ldet_w)


@njit(void(RNG, A1, A2, A2, i8), cache=True)
def _draw_mean(rng, xi, FR, Mu, k):
    """Draw a component mean from N(xi, R^{-1}) into row ``k`` of ``Mu`` (``FR FR^T = R^{-1}``)."""
    D = xi.shape[0]
    for a in range(D):
        Mu[k, a] = xi[a]
    for b in range(D):
        e = rng.standard_normal()
        for a in range(D):
            Mu[k, a] += FR[a, b] * e


@njit(f8(RNG, A1, A1, f8, A2, A2), cache=True)
def _draw_precision_given_point(rng, x, mu, beta, W, L):
    """Draw ``S | mu, x ~ Wishart(beta + 1, (beta W + (x - mu)(x - mu)^T)^{-1})`` into ``L``; return log|S|."""
    D = x.shape[0]
    P = np.empty((D, D))
    for a in range(D):
        for b in range(D):
            P[a, b] = beta * W[a, b] + (x[a] - mu[a]) * (x[b] - mu[b])
    C = np.empty((D, D))
    ldet_p = _scale_factor(P, C)
    return wishart_draw(rng, C, -ldet_p, beta + 1.0, L)


@njit(f8(I1, I1, i8, i8, f8, f8), cache=True)
def log_eppf(cnt, act, K, n, alpha, d):
    """Log exchangeable partition probability of the Pitman-Yor (Chinese restaurant) prior.

    ``prod_{k=1}^{K-1}(alpha + k d) / (alpha + 1)_{n-1} * prod_j (1 - d)_{n_j - 1}``, ``(x)_m`` the
    rising factorial; ``d = 0`` gives the Dirichlet process.
    """
    out = math.lgamma(alpha + 1.0) - math.lgamma(alpha + n)
    for k in range(1, K):
        v = alpha + k * d
        if v <= 0.0:
            return _NEG_INF
        out += math.log(v)
    l1d = math.lgamma(1.0 - d)
    for t in range(K):
        out += math.lgamma(cnt[act[t]] - d) - l1d
    return out


@njit(f8(f8, i8), cache=True)
def _log_prior_beta(beta, D):
    # 1/(beta - D + 1) ~ Gamma(shape 1/2, rate D/2), as a density in beta.
    g = 1.0 / (beta - D + 1.0)
    return 0.5 * math.log(0.5 * D) - math.lgamma(0.5) - 0.5 * math.log(g) - 0.5 * D * g + 2.0 * math.log(g)


@njit(f8(f8), cache=True)
def _log_prior_alpha(alpha):
    # 1/alpha ~ Gamma(shape 1/2, rate 1/2), as a density in alpha.
    g = 1.0 / alpha
    return 0.5 * math.log(0.5) - math.lgamma(0.5) - 0.5 * math.log(g) - 0.5 * g + 2.0 * math.log(g)


# --------------------------------------------------------------------------------------------------
# slice sampling of beta, alpha and d (Neal 2003, stepping out and shrinkage)
# --------------------------------------------------------------------------------------------------
_WHICH_BETA, _WHICH_ALPHA, _WHICH_D = 0, 1, 2


@njit(f8(i8, f8, i8, i8, i8, I1, I1, f8, f8, f8, f8, f8), cache=True)
def _hyper_logp(which, x, D, K, n, cnt, act, alpha, d, sum_ldet, sum_tr, ldet_w):
    """Log conditional density of one hyperparameter on its sampling scale.

    beta: on ``u = log(beta - D + 1)`` (prior term includes the Jacobian); alpha: on ``v = log(alpha)``;
    d: on d itself (uniform prior).
    """
    if which == _WHICH_BETA:
        if x > 700.0:
            return _NEG_INF
        e = math.exp(x)
        beta = D - 1.0 + e
        if not (beta > D - 1.0):
            return _NEG_INF
        out = -0.5 * x - 0.5 * D / e
        out += K * (0.5 * beta * D * math.log(0.5 * beta) + 0.5 * beta * ldet_w - _lmvgamma(0.5 * beta, D))
        out += 0.5 * (beta - D - 1.0) * sum_ldet - 0.5 * beta * sum_tr
        return out
    if which == _WHICH_ALPHA:
        if x > 700.0 or x < -700.0:
            return _NEG_INF
        return -0.5 * x - 0.5 * math.exp(-x) + log_eppf(cnt, act, K, n, math.exp(x), d)
    # which == _WHICH_D
    if not (x < 1.0) or x < 0.0:
        return _NEG_INF
    return log_eppf(cnt, act, K, n, alpha, x)


@njit(f8(RNG, i8, f8, f8, f8, f8, i8, i8, i8, I1, I1, f8, f8, f8, f8, f8), cache=True)
def _slice(rng, which, x0, width, lo, hi, D, K, n, cnt, act, alpha, d, sum_ldet, sum_tr, ldet_w):
    """One univariate slice-sampling update of ``x0`` within (lo, hi) (``width`` <= 0: no stepping out)."""
    f0 = _hyper_logp(which, x0, D, K, n, cnt, act, alpha, d, sum_ldet, sum_tr, ldet_w)
    u = rng.random()
    logy = f0 + math.log(u) if u > 0.0 else _NEG_INF
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


# --------------------------------------------------------------------------------------------------
# bookkeeping of component slots
# --------------------------------------------------------------------------------------------------
@njit(void(i8, I1, I1, I1), cache=True)
def _activate(j, act, pos, ist):
    act[ist[0]] = j
    pos[j] = ist[0]
    ist[0] += 1


@njit(void(i8, I1, I1, I1, I1), cache=True)
def _deactivate(j, act, pos, ist, fre):
    p = pos[j]
    last = act[ist[0] - 1]
    act[p] = last
    pos[last] = p
    pos[j] = -1
    ist[0] -= 1
    fre[ist[1]] = j
    ist[1] += 1


@njit(i8(I1, I1), cache=True)
def _pop_free(fre, ist):
    ist[1] -= 1
    return fre[ist[1]]


@njit(i8(RNG, A1, i8), cache=True)
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


# --------------------------------------------------------------------------------------------------
# one sweep: Neal's algorithm 8, then the component and hyperparameter updates
# --------------------------------------------------------------------------------------------------
@njit(void(A2, I1, I1, A2, A3, A1, I1, I1, I1, I1, A1, A1, A2, A2, i8, b1, RNG), cache=True)
def allocate(X, z, cnt, mu, L, ldet, act, pos, fre, ist, sc, xi, GR, W, m, use_lik, rng):
    """Neal (2000) algorithm 8 over every point, with the Pitman-Yor weights.

    Existing component j: ``(n_j^{-i} - d) N(x_i | mu_j, S_j^{-1})``; each of the ``m`` auxiliary
    components: ``(alpha + d K^{-i}) / m`` times its likelihood. Auxiliary means are drawn from
    N(xi, R^{-1}) (a point alone in its component hands that component's mean to the first
    auxiliary); their precisions are integrated out: given its mean, an auxiliary's likelihood is the
    multivariate Student-t ``t_{beta-D+1}(x_i; mu, beta W / (beta - D + 1))``, and a new component
    draws its precision from ``S | mu, x_i`` (conjugate) when it is opened. This partially
    collapsed form of algorithm 8 leaves the same posterior invariant and needs no Wishart draw per
    auxiliary.
    """
    cap = cnt.shape[0]
    D = X.shape[1]
    half = 0.5 * D * _LOG2PI
    # cached per component: log(n_j - d) and log|S_j|/2 - D/2 log(2 pi)
    lcnt = np.zeros(cap)
    lnorm = np.zeros(cap)
    for t in range(ist[0]):
        j = act[t]
        lcnt[j] = math.log(cnt[j] - sc[1])
        lnorm[j] = 0.5 * ldet[j] - half
    # FR = GR^{-T} (upper): FR FR^T = R^{-1}; CW CW^T = V0 = (beta W)^{-1}
    FR = np.ascontiguousarray(_tril_inverse(GR).T)
    CW = np.empty((D, D))
    ldet_v0 = -_scale_factor(sc[2] * W, CW)
    CW3 = CW.reshape((1, D, D))
    n, D = X.shape
    alpha, d, beta = sc[0], sc[1], sc[2]
    half = 0.5 * D * _LOG2PI
    logm = math.log(m)
    # log Student-t normaliser: lgamma((beta+1)/2) - lgamma((beta-D+1)/2) - D/2 log(pi) + log|V|/2
    t_norm = (
        math.lgamma(0.5 * (beta + 1.0))
        - math.lgamma(0.5 * (beta - D + 1.0))
        - 0.5 * D * _LOGPI
        + 0.5 * ldet_v0
    )
    t_pow = 0.5 * (beta + 1.0)
    amu = np.empty((m, D))
    lw = np.empty(n + m + 1)
    dev = np.empty(D)
    for i in range(n):
        c = z[i]
        cnt[c] -= 1
        first = 0
        if cnt[c] == 0:
            _deactivate(c, act, pos, ist, fre)
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
                lw[t] = lcnt[j] + lnorm[j] - 0.5 * q
            else:
                lw[t] = lcnt[j]
        lnew = (math.log(alpha + d * K) if K > 0 else 0.0) - logm
        for k in range(m):
            if use_lik:
                lw[K + k] = lnew + t_norm - t_pow * math.log1p(_quad_rows(CW3, 0, amu, k, X, i))
            else:
                lw[K + k] = lnew
        t = _categorical(rng, lw, K + m)
        if t < K:
            j = act[t]
        else:
            k = t - K
            j = _pop_free(fre, ist)
            mu[j] = amu[k]
            if use_lik:
                ldet[j] = _draw_precision_given_point(rng, X[i], amu[k], beta, W, L[j])
            else:
                ldet[j] = wishart_draw(rng, CW, ldet_v0, beta, L[j])
            lnorm[j] = 0.5 * ldet[j] - half
            cnt[j] = 0
            _activate(j, act, pos, ist)
        z[i] = j
        cnt[j] += 1
        lcnt[j] = math.log(cnt[j] - d)


@njit(void(A2, I1, I1, I1, i8, A2, A3), cache=True)
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


@njit(void(A2, I1, I1, A2, A3, A1, I1, I1, A1, A1, A2, A2, b1, RNG), cache=True)
def update_components(X, z, cnt, mu, L, ldet, act, ist, sc, xi, R, W, use_lik, rng):
    """Gibbs update of every component: ``S_j | mu_j`` then ``mu_j | S_j`` (see :func:`component_step`)."""
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
                cnt[j], means[j], scats[j], mu[j].copy(), sc[2], W, R, Rxi, True, mu[j], L[j], 0.0, rng
            )
        else:
            _, ldet[j] = component_step(
                0, zero_mean, zero_scat, mu[j].copy(), sc[2], W, R, Rxi, True, mu[j], L[j], 0.0, rng
            )


@njit(b1(A2, f8), cache=True)
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


@njit(void(A2, A3, A1, I1, I1, i8, I1, A1, A1, A2, A2, A2, A2, b1, b1, f8, f8, RNG), cache=True)
def update_hyper(mu, L, ldet, act, ist, n, cnt, sc, xi, R, GR, W, GW, fit_alpha, fit_d, d_low, w_min, rng):
    """Gibbs updates of xi, R, W, then slice updates of beta, alpha and d (whitened data: priors use I)."""
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


# --------------------------------------------------------------------------------------------------
# split-merge moves (Jain & Neal 2007, non-conjugate restricted Gibbs sampling)
# --------------------------------------------------------------------------------------------------
@njit(i8(A2, I1, I1, i8, I1, i8, A1, A2), cache=True)
def _group_stats(X, anchors, idx, ns, lab, want, mean, scat):
    """Count, mean and scatter of ``anchors`` plus the ``idx[t]`` with ``lab[t] == want`` (want < 0: all)."""
    D = X.shape[1]
    mean[:] = 0.0
    scat[:] = 0.0
    cnt = 0
    for a_ in range(anchors.shape[0]):
        k = anchors[a_]
        for a in range(D):
            mean[a] += X[k, a]
        cnt += 1
    for t in range(ns):
        if want < 0 or lab[t] == want:
            k = idx[t]
            for a in range(D):
                mean[a] += X[k, a]
            cnt += 1
    for a in range(D):
        mean[a] /= cnt
    for a_ in range(anchors.shape[0] + ns):
        if a_ < anchors.shape[0]:
            k = anchors[a_]
        else:
            t = a_ - anchors.shape[0]
            if not (want < 0 or lab[t] == want):
                continue
            k = idx[t]
        for a in range(D):
            da = X[k, a] - mean[a]
            for b in range(D):
                scat[a, b] += da * (X[k, b] - mean[b])
    return cnt


@njit(f8(A2, I1, I1, i8, I1, i8, A1, A2, f8), cache=True)
def _group_loglik(X, anchors, idx, ns, lab, want, mu, L, ldet):
    D = X.shape[1]
    norm = 0.5 * ldet - 0.5 * D * _LOG2PI
    out = 0.0
    for a_ in range(anchors.shape[0]):
        out += norm - 0.5 * _quad_chol(L, X[anchors[a_]], mu)
    for t in range(ns):
        if want < 0 or lab[t] == want:
            out += norm - 0.5 * _quad_chol(L, X[idx[t]], mu)
    return out


@njit(f8(A2, i8, i8, I1, i8, I1, I1, A1, A2, f8, A1, A2, f8, f8, b1, b1, RNG), cache=True)
def _restricted_scan(X, i, j, idx, ns, lab, target, muA, LA, ldA, muB, LB, ldB, d, use_lik, draw, rng):
    """Restricted Gibbs scan of the labels of ``idx`` between component A (holds i) and B (holds j).

    With ``draw`` the labels are sampled; otherwise they are set to ``target``. Returns the log
    probability of the labels so produced (the proposal probability of Jain & Neal).
    """
    D = X.shape[1]
    nA = 1
    nB = 1
    for t in range(ns):
        if lab[t] == 0:
            nA += 1
        else:
            nB += 1
    normA = 0.5 * ldA - 0.5 * D * _LOG2PI
    normB = 0.5 * ldB - 0.5 * D * _LOG2PI
    logq = 0.0
    for t in range(ns):
        k = idx[t]
        if lab[t] == 0:
            nA -= 1
        else:
            nB -= 1
        la = math.log(nA - d)
        lb = math.log(nB - d)
        if use_lik:
            la += normA - 0.5 * _quad_chol(LA, X[k], muA)
            lb += normB - 0.5 * _quad_chol(LB, X[k], muB)
        mx = max(la, lb)
        lz = mx + math.log(math.exp(la - mx) + math.exp(lb - mx))
        if draw:
            new = 0 if rng.random() < math.exp(la - lz) else 1
        else:
            new = target[t]
        logq += (la if new == 0 else lb) - lz
        lab[t] = new
        if new == 0:
            nA += 1
        else:
            nB += 1
    return logq


@njit(Tuple((i8, f8, f8))(A2, I1, I1, i8, I1, i8, A1, A1, A2, A1, A2, b1, b1, A1, A2, f8, RNG), cache=True)
def _part_step(X, anchor, idx, ns, lab, want, mu0, sc, R, Rxi, W, use_lik, draw, mu, L, ldet_in, rng):
    """:func:`component_step` for the part of a split holding ``anchor`` and the ``idx`` labelled ``want``.

    Returns (number of points of the part, log density of the move, log|S|).
    """
    D = X.shape[1]
    mean = np.empty(D)
    scat = np.empty((D, D))
    n = _group_stats(X, anchor, idx, ns, lab, want, mean, scat)
    logq, ldet = component_step(
        n if use_lik else 0, mean, scat, mu0, sc[2], W, R, Rxi, draw, mu, L, ldet_in, rng
    )
    return n, logq, ldet


@njit(UniTuple(f8, 2)(A2, i8, i8, I1, i8, I1, A1, A2, A1, A2, i8, A1, A2, A1, A2, b1, RNG), cache=True)
def _split_launch(X, i, j, idx, ns, lab, muA, LA, muB, LB, n_launch, sc, R, Rxi, W, use_lik, rng):
    """Launch state of a split: labels by nearest of x_i / x_j, then ``n_launch`` restricted Gibbs scans.

    It depends on the data of the points involved only, never on their current labels, as the
    validity of the Metropolis-Hastings ratio requires. Returns (log|S_A|, log|S_B|).
    """
    D = X.shape[1]
    for t in range(ns):
        k = idx[t]
        di = 0.0
        dj = 0.0
        for a in range(D):
            di += (X[k, a] - X[i, a]) ** 2
            dj += (X[k, a] - X[j, a]) ** 2
        lab[t] = 0 if di <= dj else 1
    muA[:] = X[i]
    muB[:] = X[j]
    anchA = np.array([i])
    anchB = np.array([j])
    ldA = 0.0
    ldB = 0.0
    for it in range(n_launch + 1):
        if it > 0:
            _restricted_scan(
                X, i, j, idx, ns, lab, lab, muA, LA, ldA, muB, LB, ldB, sc[1], use_lik, True, rng
            )
        ldA = _part_step(
            X, anchA, idx, ns, lab, 0, muA.copy(), sc, R, Rxi, W, use_lik, True, muA, LA, 0.0, rng
        )[2]
        ldB = _part_step(
            X, anchB, idx, ns, lab, 1, muB.copy(), sc, R, Rxi, W, use_lik, True, muB, LB, 0.0, rng
        )[2]
    return ldA, ldB


@njit(Tuple((i8, A1, A2))(A2, i8, i8, I1, i8, I1, A1, i8, A1, A2, A1, A2, b1, RNG), cache=True)
def _merge_launch(X, i, j, idx, ns, lab, mu0, n_launch, sc, R, Rxi, W, use_lik, rng):
    """Launch state of a merge: ``n_launch + 1`` parameter updates of one component holding every point."""
    D = X.shape[1]
    mean = np.empty(D)
    scat = np.empty((D, D))
    nM = _group_stats(X, np.array([i, j]), idx, ns, lab, -1, mean, scat)
    if not use_lik:
        nM = 0
        mean[:] = 0.0
        scat[:] = 0.0
    mu0[:] = mean if use_lik else X[i]
    Ltmp = np.empty((D, D))
    for _ in range(n_launch + 1):
        component_step(nM, mean, scat, mu0.copy(), sc[2], W, R, Rxi, True, mu0, Ltmp, 0.0, rng)
    return nM, mean, scat


@njit(void(i8, A2, I1, I1, A2, A3, A1, I1, I1, I1, I1, A1, A1, A2, A2, A2, A2, i8, b1, RNG, I1), cache=True)
def split_merge_moves(
    n_moves,
    X,
    z,
    cnt,
    mu,
    L,
    ldet,
    act,
    pos,
    fre,
    ist,
    sc,
    xi,
    R,
    GR,
    W,
    GW,
    n_launch,
    use_lik,
    rng,
    counters,
):
    """Run ``n_moves`` split-merge Metropolis-Hastings moves (Jain & Neal 2007, non-conjugate version)."""
    n, D = X.shape
    if n < 2:
        return
    for _move in range(n_moves):
        i = min(int(rng.random() * n), n - 1)
        j = min(int(rng.random() * (n - 1)), n - 2)
        if j >= i:
            j += 1
        ci = z[i]
        cj = z[j]
        idx = np.empty(n, dtype=np.int64)
        ns = 0
        for k in range(n):
            if k != i and k != j and (z[k] == ci or z[k] == cj):
                idx[ns] = k
                ns += 1
        lab = np.empty(ns, dtype=np.int64)
        alpha, d, beta = sc[0], sc[1], sc[2]
        K = ist[0]
        Rxi = np.empty(D)
        for a in range(D):
            s = 0.0
            for b in range(D):
                s += R[a, b] * xi[b]
            Rxi[a] = s
        ldet_w = _logdet_chol(GW)
        anchA = np.array([i])
        anchB = np.array([j])
        anchM = np.array([i, j])
        # launch states, built the same way whichever move is proposed
        muA = np.empty(D)
        LA = np.empty((D, D))
        muB = np.empty(D)
        LB = np.empty((D, D))
        ldA, ldB = _split_launch(
            X, i, j, idx, ns, lab, muA, LA, muB, LB, n_launch, sc, R, Rxi, W, use_lik, rng
        )
        muM0 = np.empty(D)
        nM, meanM, scatM = _merge_launch(X, i, j, idx, ns, lab, muM0, n_launch, sc, R, Rxi, W, use_lik, rng)
        u = rng.random()
        if ci == cj:
            counters[SPLIT_PROPOSED] += 1
            # forward: final restricted scan from the split launch, then a parameter update of each part
            logq = _restricted_scan(
                X, i, j, idx, ns, lab, lab, muA, LA, ldA, muB, LB, ldB, d, use_lik, True, rng
            )
            newA_mu, newB_mu = np.empty(D), np.empty(D)
            newA_L, newB_L = np.empty((D, D)), np.empty((D, D))
            nA, qA, newA_ld = _part_step(
                X, anchA, idx, ns, lab, 0, muA, sc, R, Rxi, W, use_lik, True, newA_mu, newA_L, 0.0, rng
            )
            nB, qB, newB_ld = _part_step(
                X, anchB, idx, ns, lab, 1, muB, sc, R, Rxi, W, use_lik, True, newB_mu, newB_L, 0.0, rng
            )
            logq += qA + qB
            # reverse: the merge launch's final update landing on the current parameters
            logq_rev, _ = component_step(
                nM, meanM, scatM, muM0, beta, W, R, Rxi, False, mu[ci].copy(), L[ci].copy(), ldet[ci], rng
            )
            nC = nA + nB
            log_ratio = (
                math.log(alpha + d * K)
                + math.lgamma(nA - d)
                + math.lgamma(nB - d)
                - math.lgamma(1.0 - d)
                - math.lgamma(nC - d)
                + base_logpdf(newA_mu, newA_L, newA_ld, beta, W, ldet_w, xi, GR)
                + base_logpdf(newB_mu, newB_L, newB_ld, beta, W, ldet_w, xi, GR)
                - base_logpdf(mu[ci], L[ci], ldet[ci], beta, W, ldet_w, xi, GR)
                + logq_rev
                - logq
            )
            if use_lik:
                log_ratio += (
                    _group_loglik(X, anchA, idx, ns, lab, 0, newA_mu, newA_L, newA_ld)
                    + _group_loglik(X, anchB, idx, ns, lab, 1, newB_mu, newB_L, newB_ld)
                    - _group_loglik(X, anchM, idx, ns, lab, -1, mu[ci], L[ci], ldet[ci])
                )
            if u > 0.0 and math.log(u) < log_ratio:
                counters[SPLIT_ACCEPTED] += 1
                jb = _pop_free(fre, ist)
                _activate(jb, act, pos, ist)
                mu[ci] = newA_mu
                L[ci] = newA_L
                ldet[ci] = newA_ld
                mu[jb] = newB_mu
                L[jb] = newB_L
                ldet[jb] = newB_ld
                z[j] = jb
                for t in range(ns):
                    if lab[t] == 1:
                        z[idx[t]] = jb
                cnt[ci] = nA
                cnt[jb] = nB
        else:
            counters[MERGE_PROPOSED] += 1
            newM_mu = np.empty(D)
            newM_L = np.empty((D, D))
            logq, newM_ld = component_step(
                nM, meanM, scatM, muM0, beta, W, R, Rxi, True, newM_mu, newM_L, 0.0, rng
            )
            # reverse: the split launch's final scan landing on the current labels and parameters
            target = np.empty(ns, dtype=np.int64)
            for t in range(ns):
                target[t] = 0 if z[idx[t]] == ci else 1
            logq_rev = _restricted_scan(
                X, i, j, idx, ns, lab, target, muA, LA, ldA, muB, LB, ldB, d, use_lik, False, rng
            )
            nA, qA, _ = _part_step(
                X, anchA, idx, ns, lab, 0, muA, sc, R, Rxi, W, use_lik, False, mu[ci].copy(), L[ci].copy(), ldet[ci], rng
            )  # fmt: skip
            nB, qB, _ = _part_step(
                X, anchB, idx, ns, lab, 1, muB, sc, R, Rxi, W, use_lik, False, mu[cj].copy(), L[cj].copy(), ldet[cj], rng
            )  # fmt: skip
            logq_rev += qA + qB
            nC = nA + nB
            log_ratio = (
                -math.log(alpha + d * (K - 1))
                + math.lgamma(1.0 - d)
                + math.lgamma(nC - d)
                - math.lgamma(nA - d)
                - math.lgamma(nB - d)
                + base_logpdf(newM_mu, newM_L, newM_ld, beta, W, ldet_w, xi, GR)
                - base_logpdf(mu[ci], L[ci], ldet[ci], beta, W, ldet_w, xi, GR)
                - base_logpdf(mu[cj], L[cj], ldet[cj], beta, W, ldet_w, xi, GR)
                + logq_rev
                - logq
            )
            if use_lik:
                log_ratio += (
                    _group_loglik(X, anchM, idx, ns, lab, -1, newM_mu, newM_L, newM_ld)
                    - _group_loglik(X, anchA, idx, ns, lab, 0, mu[ci], L[ci], ldet[ci])
                    - _group_loglik(X, anchB, idx, ns, lab, 1, mu[cj], L[cj], ldet[cj])
                )
            if u > 0.0 and math.log(u) < log_ratio:
                counters[MERGE_ACCEPTED] += 1
                mu[ci] = newM_mu
                L[ci] = newM_L
                ldet[ci] = newM_ld
                z[j] = ci
                for t in range(ns):
                    z[idx[t]] = ci
                cnt[ci] = nC
                cnt[cj] = 0
                _deactivate(cj, act, pos, ist, fre)


# --------------------------------------------------------------------------------------------------
# log joint density (for the MAP sample) and the driver
# --------------------------------------------------------------------------------------------------
@njit(f8(A2, I1, I1, A2, A3, A1, I1, I1, A1, A1, A2, A2, A2, A2, b1), cache=True)
def log_joint(X, z, cnt, mu, L, ldet, act, ist, sc, xi, R, GR, W, GW, use_lik):
    """Unnormalised log density of the whole state (labels, components, hyperparameters) given X."""
    n, D = X.shape
    K = ist[0]
    alpha, d, beta = sc[0], sc[1], sc[2]
    out = 0.0
    if use_lik:
        half = 0.5 * D * _LOG2PI
        for i in range(n):
            j = z[i]
            out += 0.5 * ldet[j] - half - 0.5 * _quad_chol(L[j], X[i], mu[j])
    out += log_eppf(cnt, act, K, n, alpha, d)
    ldet_w = _logdet_chol(GW)
    for t in range(K):
        j = act[t]
        out += base_logpdf(mu[j], L[j], ldet[j], beta, W, ldet_w, xi, GR)
    eye_d = np.zeros((D, D))
    for a in range(D):
        eye_d[a, a] = D
    xx = 0.0
    for a in range(D):
        xx += xi[a] * xi[a]
    out += -0.5 * D * _LOG2PI - 0.5 * xx
    out += wishart_logpdf(GR, _logdet_chol(GR), D, eye_d, D * math.log(D))
    out += wishart_logpdf(GW, ldet_w, D, eye_d, D * math.log(D))
    out += _log_prior_beta(beta, D)
    if alpha > 0.0:
        out += _log_prior_alpha(alpha)
    return out
