"""Session effects integrated out: per-(component, session) statistics, a group's effective statistics, lambda.

With sessions, a point of session s in component j is ``x = mu_j + b_(s,j) + e`` with
``b_(s,j) ~ N(0, lambda S_j^{-1})`` and ``e ~ N(0, S_j^{-1})`` (``S_j`` the precision). Given
``(mu_j, S_j, lambda)`` the ``n_s`` points of one (component, session) group are jointly Gaussian
with row covariance ``A_s = I + lambda 1 1^T`` and column covariance ``S_j^{-1}`` (matrix normal), so
the effects integrate out in closed form:

    log p(X_s | mu, S, lambda) = n_s (log|S|/2 - D/2 log 2 pi) - D/2 log(1 + lambda n_s)
                                 - 1/2 tr(S Q_s),   Q_s = sum_i r_i r_i^T - lambda / (1 + lambda n_s) r_s r_s^T

with ``r_i = x_i - mu`` and ``r_s`` their sum (``A_s^{-1} = I - lambda / (1 + lambda n_s) 1 1^T``,
``|A_s| = 1 + lambda n_s``). Summed over the sessions of a component this is a Gaussian likelihood in
``(mu, S)`` with *effective* statistics (:func:`effective_stats`): weight ``e_s = n_s / (1 + lambda
n_s)`` per session mean, so that ``S | mu`` stays Wishart (degrees of freedom ``+ n``) and ``mu | S``
normal (precision ``R + E S``, ``E = sum_s e_s``). A point's predictive given the ``n_s`` other
points of its group (sum ``t_s``) is ``N(mu + f (t_s - n_s mu), c S^{-1})`` with ``f = lambda / (1 +
lambda n_s)`` and ``c = 1 + f`` (``allocate``'s packed table); a point of a session the component has no
point of: ``N(mu, (1 + lambda) S^{-1})``. With ``lambda = 0`` everything reduces to the plain model.

The prior of lambda: the intra-group correlation ``lambda / (1 + lambda)`` is uniform on (0, 1), i.e.
``log lambda`` is standard logistic; lambda is slice-sampled on the log scale (:func:`update_lambda`).

**Session offsets.** A session also moves *every* component by its offset ``c_s ~ N(0, omega I)``
(whitened units: a re-mounted sensor's gain moves the log-amplitude features of every surface
alike): ``x = mu_j + c_s + b_(s,j) + e``. The kernels see ``x - c_s`` (:func:`offset_data`); given
the partition, the components and lambda, ``c_s`` is normal with precision ``I / omega + sum_j
e_(s,j) S_j`` and mean ``precision^{-1} sum_j e_(s,j) S_j (mean_(s,j) - mu_j)`` (the effects ``b``
still integrated out), and ``omega`` has a half-Cauchy(0, 1) prior on its square root (Gelman
2006), slice-sampled on ``log omega`` (:func:`update_offsets`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .densities import _normal_draw_prec
from .linalg import LOG2PI, NEG_INF, _cholesky, _solve_chol

# log lambda is kept within these bounds (the logistic prior puts mass e^-30 beyond them).
_LOG_LAMBDA_BOUND = 30.0


@njit(cache=True)
def n_sessions(sess):
    """Number of sessions ``S = max(sess) + 1`` (1 for no points)."""
    S = 1
    for i in range(sess.shape[0]):
        if sess[i] + 1 > S:
            S = sess[i] + 1
    return S


@njit(cache=True)
def session_table(X, z, sess, pos, K, nts, sts):
    """Per active component position ``t < K`` and session ``s``: count ``nts[t, s]`` and sum ``sts[t, s]`` of its points."""
    n, D = X.shape
    nts[:K] = 0
    sts[:K] = 0.0
    for i in range(n):
        t = pos[z[i]]
        s = sess[i]
        nts[t, s] += 1
        for a in range(D):
            sts[t, s, a] += X[i, a]


@njit(cache=True)
def group_quadratics(X, st, K):
    """Return ``(ms, qs, P)``: count ``m`` and ``(mean - mu_j)^T S_j (mean - mu_j)`` of each of the ``P`` non-empty (component, session) groups.

    ``X``: the data the components see (offsets removed); the groups of the ``K`` active components.
    """
    D = X.shape[1]
    S = n_sessions(st.sess)
    nts = np.zeros((K, S), dtype=np.int64)
    sts = np.zeros((K, S, D))
    session_table(X, st.z, st.sess, st.pos, K, nts, sts)
    ms = np.empty(K * S)
    qs = np.empty(K * S)
    dev = np.empty(D)
    P = 0
    for t in range(K):
        j = st.act[t]
        for s in range(S):
            m = nts[t, s]
            if m == 0:
                continue
            for a in range(D):
                dev[a] = sts[t, s, a] / m - st.mu[j, a]
            q = 0.0
            for e in range(D):
                v = 0.0
                for a in range(e, D):
                    v += st.L[j, a, e] * dev[a]
                q += v * v
            ms[P] = m
            qs[P] = q
            P += 1
    return ms, qs, P


@njit(cache=True)
def effective_stats(n, mean, scat, ns, sums, lam, mean_e, scat_e):
    """Return ``(E, pen)`` of a group and write its effective mean and scatter into ``mean_e``, ``scat_e``.

    ``n`` points with ``mean`` and ``scat`` (scatter about the mean); ``ns`` (S,) and ``sums`` (S, D)
    their counts and sums per session. With ``e_s = n_s / (1 + lam n_s)``, ``E = sum_s e_s``,
    ``d_s`` the session mean minus ``mean`` and ``delta = sum_s e_s d_s / E``::

        mean_e = mean + delta
        scat_e = scat - sum_s (n_s - e_s) d_s d_s^T - E delta delta^T
               = sum_s scatter_s + sum_s e_s (mean_s - mean_e)(mean_s - mean_e)^T
        pen    = sum_s log(1 + lam n_s)

    so that the group's log likelihood is ``n (log|S|/2 - D/2 log 2 pi) - 1/2 (tr(S scat_e) +
    E (mean_e - mu)^T S (mean_e - mu)) - D/2 pen`` (module docstring).
    """
    D = mean.shape[0]
    S = ns.shape[0]
    for a in range(D):
        mean_e[a] = 0.0
        for b in range(D):
            scat_e[a, b] = scat[a, b]
    E = 0.0
    pen = 0.0
    dev = np.empty(D)
    for s in range(S):
        m = ns[s]
        if m == 0:
            continue
        e = m / (1.0 + lam * m)
        E += e
        pen += math.log1p(lam * m)
        w = m - e
        for a in range(D):
            dev[a] = sums[s, a] / m - mean[a]
            mean_e[a] += e * dev[a]
        for a in range(D):
            for b in range(D):
                scat_e[a, b] -= w * dev[a] * dev[b]
    for a in range(D):
        mean_e[a] /= E
    for a in range(D):
        for b in range(D):
            scat_e[a, b] -= E * mean_e[a] * mean_e[b]
    for a in range(D):
        mean_e[a] += mean[a]
    return E, pen


@njit(cache=True)
def _lambda_logp(u, ms, qs, P, D):
    """Log conditional density of ``u = log lambda`` given the groups' counts ``ms`` and ``qs`` (see :func:`update_lambda`)."""
    if u > _LOG_LAMBDA_BOUND or u < -_LOG_LAMBDA_BOUND:
        return NEG_INF
    lam = math.exp(u)
    out = u - 2.0 * math.log1p(lam)  # standard logistic prior on log lambda
    for p in range(P):
        m = ms[p]
        out += -0.5 * D * math.log1p(lam * m) + 0.5 * lam * m * m / (1.0 + lam * m) * qs[p]
    return out


@njit(cache=True)
def update_lambda(lam, ms, qs, P, D, rng):
    """Return lambda after one slice-sampling update of ``log lambda`` (Neal 2003, stepping out, width 1).

    ``ms[p]``, ``qs[p]`` for the ``P`` non-empty (component, session) groups: the count and
    ``(mean_s - mu)^T S (mean_s - mu)``. The conditional of lambda given the partition and the
    components is ``p(lambda) prod_groups (1 + lambda m)^(-D/2) exp(lambda m^2 q / (2 (1 + lambda m)))``.
    """
    x0 = math.log(lam)
    f0 = _lambda_logp(x0, ms, qs, P, D)
    v = rng.random()
    logy = f0 + math.log(v) if v > 0.0 else NEG_INF
    left = x0 - rng.random()
    right = left + 1.0
    for _ in range(100):
        if left <= -_LOG_LAMBDA_BOUND or _lambda_logp(left, ms, qs, P, D) <= logy:
            break
        left -= 1.0
    for _ in range(100):
        if right >= _LOG_LAMBDA_BOUND or _lambda_logp(right, ms, qs, P, D) <= logy:
            break
        right += 1.0
    for _ in range(200):
        x1 = left + (right - left) * rng.random()
        if _lambda_logp(x1, ms, qs, P, D) > logy:
            return math.exp(x1)
        if x1 < x0:
            left = x1
        else:
            right = x1
    return lam


@njit(cache=True)
def log_prior_lambda(lam):
    """Log prior density of lambda (``lambda / (1 + lambda) ~ U(0, 1)``): ``-2 log(1 + lambda)``."""
    return -2.0 * math.log1p(lam)


@njit(cache=True)
def offset_data(X, st):
    """``X`` minus the offset of every point's session, ``X[i] - off[sess[i]]`` (a new array)."""
    n, D = X.shape
    out = np.empty((n, D))
    for i in range(n):
        s = st.sess[i]
        for a in range(D):
            out[i, a] = X[i, a] - st.off[s, a]
    return out


@njit(cache=True)
def _omega_logp(u, ss, m):
    """Log conditional density of ``u = log omega`` given ``ss = sum_s |c_s|^2`` of ``m`` offset coordinates."""
    if u > _LOG_LAMBDA_BOUND or u < -_LOG_LAMBDA_BOUND:
        return NEG_INF
    w = math.exp(u)
    # half-Cauchy(0, 1) on sqrt(omega), as a density of log omega: -log(1 + omega) + u / 2
    return -math.log1p(w) + 0.5 * u - 0.5 * m * u - 0.5 * ss / w


@njit(cache=True)
def update_offsets(X, st, rng, use_lik):
    """Gibbs update of every session's offset ``c_s`` (``st.off``), then a slice update of omega (``sc[6]``).

    ``X``: the data *without* the offsets removed. See the module docstring for the conditionals
    (with the likelihood off, the offsets' prior).
    """
    D = X.shape[1]
    K = st.ist[0]
    S = st.off.shape[0]
    lam, omega = st.sc[5], st.sc[6]
    nts = np.zeros((K, S), dtype=np.int64)
    sts = np.zeros((K, S, D))
    session_table(X, st.z, st.sess, st.pos, K, nts, sts)
    P = np.empty((D, D))
    h = np.empty(D)
    G = np.empty((D, D))
    m = np.empty(D)
    dev = np.empty(D)
    Sj = np.empty((D, D))
    for s in range(S):
        for a in range(D):
            h[a] = 0.0
            for b in range(D):
                P[a, b] = (1.0 / omega) if a == b else 0.0
        for t in range(K):
            c = nts[t, s]
            if c == 0 or not use_lik:
                continue
            j = st.act[t]
            e = c / (1.0 + lam * c)
            for a in range(D):
                for b in range(a + 1):
                    v = 0.0
                    for k in range(b + 1):
                        v += st.L[j, a, k] * st.L[j, b, k]
                    Sj[a, b] = v
                    Sj[b, a] = v
                dev[a] = sts[t, s, a] / c - st.mu[j, a]
            for a in range(D):
                for b in range(D):
                    P[a, b] += e * Sj[a, b]
                    h[a] += e * Sj[a, b] * dev[b]
        _cholesky(P, G)
        _solve_chol(G, h, m)
        _normal_draw_prec(rng, m, G, st.off[s])
    ss = 0.0
    for s in range(S):
        for a in range(D):
            ss += st.off[s, a] * st.off[s, a]
    x0 = math.log(omega)
    f0 = _omega_logp(x0, ss, S * D)
    v = rng.random()
    logy = f0 + math.log(v) if v > 0.0 else NEG_INF
    left = x0 - rng.random()
    right = left + 1.0
    for _ in range(100):
        if left <= -_LOG_LAMBDA_BOUND or _omega_logp(left, ss, S * D) <= logy:
            break
        left -= 1.0
    for _ in range(100):
        if right >= _LOG_LAMBDA_BOUND or _omega_logp(right, ss, S * D) <= logy:
            break
        right += 1.0
    for _ in range(200):
        x1 = left + (right - left) * rng.random()
        if _omega_logp(x1, ss, S * D) > logy:
            st.sc[6] = math.exp(x1)
            return
        if x1 < x0:
            left = x1
        else:
            right = x1


@njit(cache=True)
def log_prior_offsets(off, omega):
    """Log prior density of the offsets ``N(0, omega I)`` and of omega (half-Cauchy on its square root)."""
    S, D = off.shape
    ss = 0.0
    for s in range(S):
        for a in range(D):
            ss += off[s, a] * off[s, a]
    # p(omega) = 1 / (pi sqrt(omega) (1 + omega)) for sqrt(omega) ~ half-Cauchy(0, 1)
    return (
        -0.5 * S * D * (LOG2PI + math.log(omega))
        - 0.5 * ss / omega
        - math.log(math.pi)
        - 0.5 * math.log(omega)
        - math.log1p(omega)
    )
