"""One sweep's allocation and component updates: Neal's (2000) algorithm 8, then every component's (S, mu)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .conditionals import _draw_mean, _draw_precision_given_point, component_step, group_loglik
from .densities import log_new_weight, wishart_draw
from .linalg import LOG2PI, LOGPI, NEG_INF, _quad_rows, _scale_factor, _tril_inverse
from .sessions import effective_stats, group_quadratics, n_sessions, session_table, update_lambda
from .state import activate, deactivate, pop_free

# Log weights this far below the largest are skipped: exp(-50) < 2e-22, which added to a total >= 1
# changes no bit of a float64.
_NEGLIGIBLE = 50.0


@njit(cache=True)
def _categorical_first(lw, k, first, u):
    """Index in ``0 .. k-1`` drawn with probabilities proportional to ``exp(lw[:k])``, by inverse CDF from ``u``.

    The cumulative sum starts with ``first`` (then the others in order), so that a caller that has
    established ``u * total < exp(lw[first])`` from a bound on the total already knows the answer
    (``first < 0``: plain order). Weights more than ``_NEGLIGIBLE`` below the largest are skipped.
    """
    mx = lw[0]
    for t in range(1, k):
        if lw[t] > mx:
            mx = lw[t]
    total = 0.0
    for t in range(k):
        v = lw[t] - mx
        lw[t] = math.exp(v) if v > -_NEGLIGIBLE else 0.0
        total += lw[t]
    target = u * total
    acc = 0.0
    if first >= 0:
        acc = lw[first]
        if target < acc:
            return first
    for t in range(k):
        if t == first:
            continue
        acc += lw[t]
        if target < acc:
            return t
    for t in range(k - 1, -1, -1):  # rounding: the last category with positive weight
        if lw[t] > 0.0:
            return t
    return k - 1


# Rows of the packed component table of :func:`allocate`, one column per component position (structure of
# arrays, so that one point's weights under every component are computed in vectorised loops): then the
# predictive mean m (D rows), b = L^T m (D rows) and L's lower triangle column by column.
_LNORM, _HZ, _MU = 0, 1, 2


@njit(cache=True)
def _pack_column(L, mu, ldet, j, zeta, half, lam, ns, sums, packed, s, t):
    """Write component ``j``'s terms of the point update, for points of session ``s``, into column ``t`` of ``packed[s]``.

    The predictive of a point is ``N(m, c S_j^{-1})`` (to the power ``zeta``): without session
    effects (``lam = 0``) ``m = mu_j``, ``c = 1``; with them, given the ``ns`` other points of the
    session in ``j`` (sum ``sums``), ``m = mu_j + f (sums - ns mu_j)``, ``c = 1 + f``, ``f = lam / (1 +
    lam ns)`` (:mod:`.sessions`). Written: ``_LNORM``: ``zeta (log|S_j|/2 - D/2 log 2 pi
    - D/2 log c)``, ``_HZ``: ``zeta / (2c)``, then ``m``, ``b = L_j^T m`` (``|L_j^T (x - m)|^2 =
    |L_j^T x - b|^2``) and the lower triangle of ``L_j``, column by column.
    """
    D = mu.shape[1]
    f = lam / (1.0 + lam * ns)
    c = 1.0 + f
    for a in range(D):
        packed[s, _MU + a, t] = mu[j, a] + f * (sums[a] - ns * mu[j, a])
    packed[s, _LNORM, t] = zeta * (0.5 * ldet[j] - half - 0.5 * D * math.log(c))
    packed[s, _HZ, t] = 0.5 * zeta / c
    o = _MU + 2 * D
    for e in range(D):
        v = 0.0
        for a in range(e, D):
            v += L[j, a, e] * packed[s, _MU + a, t]
            packed[s, o, t] = L[j, a, e]
            o += 1
        packed[s, _MU + D + e, t] = v


@njit(cache=True)
def _likelihoods(packed, s, K, x, D, q, u, out):
    """``out[t] = log N(x | m_t, c_t S_t^{-1})`` (to the power zeta) for every position ``t < K``, from ``packed[s]``.

    ``_LNORM - _HZ |L^T x - b|^2``, one row of the table at a time over every component (loops
    over contiguous memory that the compiler vectorises); ``q``, ``u``: work arrays of length >= K.
    """
    for t in range(K):
        q[t] = 0.0
    o = _MU + 2 * D
    for e in range(D):
        for t in range(K):
            u[t] = -packed[s, _MU + D + e, t]
        for a in range(e, D):
            xa = x[a]
            for t in range(K):
                u[t] += packed[s, o, t] * xa
            o += 1
        for t in range(K):
            q[t] += u[t] * u[t]
    for t in range(K):
        out[t] = packed[s, _LNORM, t] - packed[s, _HZ, t] * q[t]


@njit(cache=True)
def _undo_removal(packed, s, own, saved, nts, sts, x, lam):
    """Put a point of session ``s`` back into its component at position ``own`` (its removal undone; the count aside)."""
    if lam > 0.0:
        for r in range(saved.shape[0]):
            packed[s, r, own] = saved[r]
        nts[own, s] += 1
        for a in range(x.shape[0]):
            sts[own, s, a] += x[a]


@njit(cache=True)
def _move_position(src, dst, S, packed, lcnt, nts, sts, lam):
    """Copy everything :func:`allocate` keeps per component position from ``src`` to ``dst``."""
    for s in range(S):
        for r in range(packed.shape[1]):
            packed[s, r, dst] = packed[s, r, src]
    lcnt[dst] = lcnt[src]
    if lam > 0.0:
        for s in range(S):
            nts[dst, s] = nts[src, s]
            for a in range(sts.shape[2]):
                sts[dst, s, a] = sts[src, s, a]


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

    **Cost.** The components' terms are packed one column per component (and one table per
    session), so a point's likelihoods under all K components come from a few vectorised loops
    (:func:`_likelihoods`); ``log(n - d)`` comes from a table. The draw is by inverse CDF from one
    uniform ``u`` with the point's own component first: the normaliser is at most ``exp(w_own) (1 +
    (K - 1 + m) exp(M - w_own))``, ``M`` the largest other weight or the auxiliaries' Student-t
    peak, so when ``u`` times that bound is below ``exp(w_own)`` the inverse CDF picks the own
    component whatever the other weights are, and the point stays at the price of one
    exponential. Otherwise the auxiliaries' weights are computed too, every weight within
    ``exp(-50)`` of the largest exponentiated (smaller ones change no bit of the float64 sum), and
    the same ``u`` picks the component: the exact Gibbs draw either way.

    Mixture of finite mixtures (``sc[4] = gamma > 0``): the weights are ``n_j + gamma`` and
    ``gamma V_n(K + 1) / V_n(K) / m`` (:func:`log_new_weight`). Coarsened posterior (``sc[3] = zeta
    < 1``): every likelihood is raised to ``zeta``; the auxiliaries' integrated likelihood then is
    ``pi^(-zeta D/2) Gamma_D((beta + zeta)/2) / Gamma_D(beta/2) |V|^(zeta/2) (1 + zeta q)^(-(beta + zeta)/2)``
    with ``V = (beta W)^{-1}`` and ``q = (x - mu)^T V (x - mu)`` (the Student-t above when zeta = 1).
    Session effects (``sc[5] = lambda > 0``, :mod:`.sessions`): a point's likelihood under component
    j is its predictive given the other points of its session in j, ``N(m_(j,s), c_(j,s) S_j^{-1})``;
    under an auxiliary ``N(mu, (1 + lambda) S^{-1})``, so its Student-t has ``q / (1 + lambda)`` and
    the factor ``(1 + lambda)^(-D/2)``, and the opened component's precision is drawn from
    ``S | mu, x_i`` with that covariance.
    """
    z, cnt, mu, L, ldet, act, pos, ist, sc, xi, GR, W, sess = (
        st.z, st.cnt, st.mu, st.L, st.ldet, st.act, st.pos, st.ist, st.sc, st.xi, st.GR, st.W, st.sess
    )  # fmt: skip
    n, D = X.shape
    cap = n + 1
    half = 0.5 * D * LOG2PI
    d, beta, zeta, lam = sc[1], sc[2], sc[3], sc[5]
    S = n_sessions(sess) if lam > 0.0 else 1
    rows = _MU + 2 * D + D * (D + 1) // 2
    packed = np.empty((S, rows, cap))
    nts = np.zeros((cap if lam > 0.0 else 0, S), dtype=np.int64)
    sts = np.zeros((cap if lam > 0.0 else 0, S, D))
    ltab = np.empty(cap)  # log(k - d)
    ltab[0] = NEG_INF
    for k in range(1, cap):
        ltab[k] = math.log(k - d)
    lcnt = np.empty(cap)  # log(n_t - d) by position
    x = np.zeros(D)
    K = ist[0]
    if lam > 0.0:
        session_table(X, z, sess, pos, K, nts, sts)
    for t in range(K):
        j = act[t]
        lcnt[t] = ltab[cnt[j]]
        for s in range(S):
            if lam > 0.0:
                _pack_column(L, mu, ldet, j, zeta, half, lam, nts[t, s], sts[t, s], packed, s, t)
            else:
                _pack_column(L, mu, ldet, j, zeta, half, 0.0, 0, x, packed, s, t)
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
    c0 = 1.0 + lam  # an auxiliary (no point in any session): covariance (1 + lambda) S^{-1}
    t_norm -= 0.5 * zeta * D * math.log(c0)
    amu = np.empty((m, D))
    lw = np.empty(cap + m)
    q = np.empty(cap)
    u_work = np.empty(cap)
    saved = np.empty(rows)
    for i in range(n):
        if i % refresh == 0:
            for k in range(m):
                _draw_mean(rng, xi, FR, amu, k)
        for a in range(D):
            x[a] = X[i, a]
        s = sess[i] if lam > 0.0 else 0
        c = z[i]
        cnt[c] -= 1
        own = -1
        if cnt[c] == 0:
            p = pos[c]
            deactivate(c, st)  # the last active component moves to position p: so does its column
            if p < ist[0]:
                _move_position(ist[0], p, S, packed, lcnt, nts, sts, lam)
            k0 = min(int(rng.random() * m), m - 1) if refresh > 1 else 0
            for a in range(D):
                amu[k0, a] = mu[c, a]
        else:
            own = pos[c]
            if lam > 0.0:
                for r in range(rows):
                    saved[r] = packed[s, r, own]
                nts[own, s] -= 1
                for a in range(D):
                    sts[own, s, a] -= x[a]
                _pack_column(L, mu, ldet, c, zeta, half, lam, nts[own, s], sts[own, s], packed, s, own)
        K = ist[0]
        lnew = (log_new_weight(sc, st.lv, K) if K > 0 else 0.0) - logm
        aux_top = lnew + t_norm if use_lik else lnew  # the auxiliaries' weights are at most this
        if use_lik:
            _likelihoods(packed, s, K, x, D, q, u_work, lw)
            for t in range(K):
                lw[t] += lcnt[t]
        else:
            for t in range(K):
                lw[t] = lcnt[t]
        u = rng.random()
        if own >= 0:
            # the own component's weight has one point less; the fast path bounds the others'
            lw[own] += ltab[cnt[c]] - lcnt[own]
            w_own = lw[own]
            lw[own] = NEG_INF
            top = aux_top
            for t in range(K):
                top = max(top, lw[t])
            lw[own] = w_own
            if u * (1.0 + (K - 1 + m) * math.exp(min(top - w_own, 700.0))) < 1.0:
                cnt[c] += 1  # stays: undo the removal
                _undo_removal(packed, s, own, saved, nts, sts, x, lam)
                continue
            lcnt[own] = ltab[cnt[c]]
        top = NEG_INF
        for t in range(K):
            top = max(top, lw[t])
        if use_lik and aux_top < top - _NEGLIGIBLE:
            for k in range(m):  # the Student-t peaks at q = 0: every auxiliary is negligible
                lw[K + k] = NEG_INF
        else:
            for k in range(m):
                if use_lik:
                    qa = _quad_rows(CW3, 0, amu, k, X, i) / c0
                    lw[K + k] = lnew + t_norm - t_pow * math.log1p(zeta * qa)
                else:
                    lw[K + k] = lnew
        t = _categorical_first(lw, K + m, own, u)
        if t == own:  # stays after all: undo the removal
            cnt[c] += 1
            lcnt[own] = ltab[cnt[c]]
            _undo_removal(packed, s, own, saved, nts, sts, x, lam)
        elif t < K:
            j = act[t]
            z[i] = j
            cnt[j] += 1
            lcnt[t] = ltab[cnt[j]]
            if lam > 0.0:
                nts[t, s] += 1
                for a in range(D):
                    sts[t, s, a] += x[a]
                _pack_column(L, mu, ldet, j, zeta, half, lam, nts[t, s], sts[t, s], packed, s, t)
        else:
            k = t - K
            j = pop_free(st)
            mu[j] = amu[k]
            if use_lik:
                ldet[j] = _draw_precision_given_point(rng, X[i], amu[k], beta, W, zeta, c0, L[j])
            else:
                ldet[j] = wishart_draw(rng, CW, ldet_v0, beta, L[j])
            activate(j, st)
            z[i] = j
            cnt[j] = 1
            lcnt[K] = ltab[1]
            if lam > 0.0:
                for s2 in range(S):
                    nts[K, s2] = 0
                    for a in range(D):
                        sts[K, s2, a] = 0.0
                nts[K, s] = 1
                for a in range(D):
                    sts[K, s, a] = x[a]
            for s2 in range(S):
                if lam > 0.0:
                    _pack_column(L, mu, ldet, j, zeta, half, lam, nts[K, s2], sts[K, s2], packed, s2, K)
                else:
                    _pack_column(L, mu, ldet, j, zeta, half, 0.0, 0, x, packed, s2, K)
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
def component_terms(X, st, K, means, scats, me, se, Es, pens):
    """Each active component's statistics for :func:`component_step`: ``me``, ``se``, ``Es`` and ``pens`` by position.

    ``means``, ``scats``: the plain ones (:func:`_component_stats`). Without session effects they are
    copied and ``Es`` is the count; with them (``sc[5] > 0``) the effective statistics of
    :func:`~.sessions.effective_stats` (``pens``: ``D/2 sum_s log(1 + lambda n_s)``).
    """
    D = X.shape[1]
    lam = st.sc[5]
    if lam > 0.0:
        S = n_sessions(st.sess)
        nts = np.zeros((K, S), dtype=np.int64)
        sts = np.zeros((K, S, D))
        session_table(X, st.z, st.sess, st.pos, K, nts, sts)
    for t in range(K):
        n = st.cnt[st.act[t]]
        if lam > 0.0:
            E, pen = effective_stats(n, means[t], scats[t], nts[t], sts[t], lam, me[t], se[t])
            Es[t] = E
            pens[t] = 0.5 * D * pen
        else:
            me[t] = means[t]
            se[t] = scats[t]
            Es[t] = n
            pens[t] = 0.0


@njit(cache=True)
def _update_lambda_given_components(X, st, K, rng):
    """Slice update of lambda (``sc[5]``) given the partition and the components (:func:`~.sessions.update_lambda`)."""
    ms, qs, P = group_quadratics(X, st, K)
    st.sc[5] = update_lambda(st.sc[5], ms, qs, P, X.shape[1], rng)


@njit(cache=True)
def update_components(X, st, use_lik, rng, fit_lambda):
    """Gibbs update of every component: ``S_j | mu_j`` then ``mu_j | S_j`` (see :func:`component_step`).

    With session effects (``sc[5] > 0``) the components see their effective statistics, then
    lambda is updated when ``fit_lambda`` (given the likelihood off: from its prior).
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
    me = np.empty((K, D))
    se = np.empty((K, D, D))
    Es = np.empty(K)
    pens = np.empty(K)
    Rxi = np.zeros(D)
    for a in range(D):
        for b in range(D):
            Rxi[a] += R[a, b] * xi[b]
    zero_mean = np.zeros(D)
    zero_scat = np.zeros((D, D))
    if use_lik:
        _component_stats(X, z, st.pos, K, cnt, act, means, scats)
        component_terms(X, st, K, means, scats, me, se, Es, pens)
    for t in range(K):
        j = act[t]
        if use_lik:
            _, ldet[j] = component_step(
                cnt[j],
                Es[t],
                me[t],
                se[t],
                mu[j].copy(),
                sc[2],
                W,
                R,
                Rxi,
                True,
                mu[j],
                L[j],
                0.0,
                sc[3],
                rng,
            )
        else:
            _, ldet[j] = component_step(
                0, 0.0, zero_mean, zero_scat, mu[j].copy(), sc[2], W, R, Rxi, True, mu[j], L[j], 0.0, 1.0, rng
            )
    if sc[5] > 0.0 and fit_lambda:
        if use_lik:
            _update_lambda_given_components(X, st, K, rng)
            component_terms(X, st, K, means, scats, me, se, Es, pens)  # at the new lambda
        else:
            st.sc[5] = update_lambda(sc[5], Es, pens, 0, D, rng)  # no groups: its prior
    loglik = 0.0
    if use_lik:
        for t in range(K):
            j = act[t]
            loglik += group_loglik(cnt[j], Es[t], me[t], se[t], mu[j], L[j], ldet[j], sc[3]) - pens[t]
    return loglik
