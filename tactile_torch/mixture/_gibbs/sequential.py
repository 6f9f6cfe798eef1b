"""Sequentially-allocated merge-split moves (Dahl & Newcomb 2022), adapted to the conditionally conjugate model.

Two points ``i != j`` are drawn as for the restricted-Gibbs moves of :mod:`.split_merge` (``i``
uniformly; ``j`` with probability ``near`` among the k nearest neighbours of ``i``, otherwise
uniformly); the other points of their components are visited once, in a uniformly random order.

*Split* (``i`` and ``j`` share a component): each visited point joins part A (holding ``i``) or
part B (holding ``j``) with probability proportional to ``(n_part - d)`` times a Gaussian
predictive density of it given the points already in that part: mean of those points, covariance
``W (1 + 1 / n_part)`` (``W`` the mean covariance of a component under the prior, an input of the
move that the move does not change). Each part then draws its parameters by one Gibbs step of
:func:`~.conditionals.component_step` started at its points' mean (``S | mu = mean``, then
``mu | S``). *Merge* (different components): the union draws its parameters the same way.

The Metropolis-Hastings ratio is exact: the sequential allocation's probability of a given split is
a product of the per-point probabilities, computable for the proposed split and, for a merge, for
the split that the merge undoes (same pair, same visiting order: the order is drawn independently
of the state, so it is an auxiliary variable shared by a move and its reverse); the parameter
proposals' densities are :func:`component_step`'s. The pair's probability depends on the data only
and cancels. Likelihoods enter through each part's count, mean and scatter (sufficient statistics),
so a move costs one pass over the points of the two components plus a few D x D factorisations,
where a restricted-Gibbs move costs ``n_launch + 2`` passes and ``2 n_launch + 6`` parameter steps.

Dahl, D. B. & Newcomb, S. (2022). Sequentially allocated merge-split samplers for conjugate Bayesian
nonparametric models. Journal of Statistical Computation and Simulation 92(7), 1487-1511.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .conditionals import base_logpdf, component_step, group_loglik
from .densities import log_new_weight
from .linalg import _logdet_chol
from .sessions import effective_stats, n_sessions
from .split_merge import MERGE_ACCEPTED, MERGE_PROPOSED, SPLIT_ACCEPTED, SPLIT_PROPOSED
from .state import activate, deactivate, pop_free


@njit(cache=True)
def _whiten_rows(X, idx, ns, i, j, GW, Y):
    """``Y[t] = GW^{-1} X[idx[t]]`` for t < ns, then ``Y[ns] = GW^{-1} X[i]``, ``Y[ns + 1] = GW^{-1} X[j]``."""
    D = X.shape[1]
    for t in range(ns + 2):
        k = idx[t] if t < ns else (i if t == ns else j)
        for a in range(D):
            s = X[k, a]
            for b in range(a):
                s -= GW[a, b] * Y[t, b]
            Y[t, a] = s / GW[a, a]


@njit(cache=True)
def _add_point(X, k, n, mean, scat):
    """Welford's update of a group's ``mean`` and ``scat`` (scatter about the mean) with ``X[k]``; ``n`` after."""
    D = X.shape[1]
    for a in range(D):
        da = X[k, a] - mean[a]
        mean[a] += da / n
        for b in range(a + 1):
            scat[a, b] += da * (X[k, b] - mean[b])
            scat[b, a] = scat[a, b]


@njit(cache=True)
def _tables(n, d, D, ltab, lfac, hq):
    """``ltab[k] = log(k - d)``, ``lfac[k] = -D/2 log(1 + 1/k)`` and ``hq[k] = 1 / (2 (1 + 1/k))`` for k = 1 .. n."""
    for k in range(1, n + 1):
        ltab[k] = math.log(k - d)
        lfac[k] = -0.5 * D * math.log1p(1.0 / k)
        hq[k] = 0.5 * k / (k + 1.0)


@njit(cache=True)
def _allocate_sequentially(
    X, Y, idx, ns, i, j, order, tabs, use_lik, draw, lab, rng, mA, sA, mB, sB, sess, lam, part_sums
):
    """Visit ``idx[order[t]]`` in turn; put each in part A (0) or B (1); return (log probability, nA, nB).

    With ``draw`` the parts are sampled; otherwise ``lab`` holds the labels whose probability is
    computed. ``Y`` holds the rows whitened by ``W`` (:func:`_whiten_rows`: the visited points,
    then i, then j); ``tabs = (ltab, lfac, hq)`` of :func:`_tables`. On return ``mA, sA, mB, sB``
    are the parts' means and scatters in X's coordinates (i in A, j in B). A point joins A with
    probability ``1 / (1 + exp(lb - la))``: one exponential and one logarithm per point.

    With session effects (``lam > 0``; ``sess`` the points' sessions) the part's predictive of a
    point of session s follows the model's (:mod:`.sessions`): mean ``m + f (t_s - n_s m)``, covariance
    ``(1 + 1/n + f) W`` with ``f = lam / (1 + lam n_s)``, ``n_s`` and ``t_s`` the part's points of
    session s so far and their sum (``part_sums``: (2, S, D + 1) work array, whitened sums and
    counts); so that a surface seen on several days is not proposed split along its days.
    """
    ltab, lfac, hq = tabs
    D = X.shape[1]
    if lam > 0.0:
        part_sums[:] = 0.0
        for a in range(D):
            part_sums[0, sess[i], a] = Y[ns, a]
            part_sums[1, sess[j], a] = Y[ns + 1, a]
        part_sums[0, sess[i], D] = 1.0
        part_sums[1, sess[j], D] = 1.0
    yA = np.empty(D)
    yB = np.empty(D)
    for a in range(D):
        yA[a] = Y[ns, a]
        yB[a] = Y[ns + 1, a]
        mA[a] = X[i, a]
        mB[a] = X[j, a]
    sA[:] = 0.0
    sB[:] = 0.0
    nA = 1
    nB = 1
    logq = 0.0
    for u in range(ns):
        t = order[u]
        k = idx[t]
        la = ltab[nA]
        lb = ltab[nB]
        if use_lik and lam > 0.0:
            s = sess[k]
            cA = part_sums[0, s, D]
            cB = part_sums[1, s, D]
            fA = lam / (1.0 + lam * cA)
            fB = lam / (1.0 + lam * cB)
            qa = 0.0
            qb = 0.0
            for a in range(D):
                qa += (Y[t, a] - yA[a] - fA * (part_sums[0, s, a] - cA * yA[a])) ** 2
                qb += (Y[t, a] - yB[a] - fB * (part_sums[1, s, a] - cB * yB[a])) ** 2
            vA = 1.0 + 1.0 / nA + fA
            vB = 1.0 + 1.0 / nB + fB
            la += -0.5 * D * math.log(vA) - 0.5 * qa / vA
            lb += -0.5 * D * math.log(vB) - 0.5 * qb / vB
        elif use_lik:
            qa = 0.0
            qb = 0.0
            for a in range(D):
                qa += (Y[t, a] - yA[a]) ** 2
                qb += (Y[t, a] - yB[a]) ** 2
            la += lfac[nA] - hq[nA] * qa
            lb += lfac[nB] - hq[nB] * qb
        v = lb - la  # P(A) = 1 / (1 + e^v); log(1 + e^v) computed stably
        e = math.exp(-abs(v))
        softplus = max(v, 0.0) + math.log1p(e)
        if draw:
            p_a = (e if v > 0.0 else 1.0) / (1.0 + e)
            lab[t] = 0 if rng.random() < p_a else 1
        if lam > 0.0:
            part = lab[t]
            s = sess[k]
            for a in range(D):
                part_sums[part, s, a] += Y[t, a]
            part_sums[part, s, D] += 1.0
        if lab[t] == 0:
            logq -= softplus
            nA += 1
            for a in range(D):
                yA[a] += (Y[t, a] - yA[a]) / nA
            _add_point(X, k, nA, mA, sA)
        else:
            logq += v - softplus
            nB += 1
            for a in range(D):
                yB[a] += (Y[t, a] - yB[a]) / nB
            _add_point(X, k, nB, mB, sB)
    return logq, nA, nB


@njit(cache=True)
def _pool(nA, mA, sA, nB, mB, sB, mC, sC):
    """Mean and scatter of the union of two groups (Chan et al.'s pairwise formula); return its count."""
    D = mA.shape[0]
    nC = nA + nB
    for a in range(D):
        mC[a] = (nA * mA[a] + nB * mB[a]) / nC
    w = nA * nB / nC
    for a in range(D):
        for b in range(D):
            sC[a, b] = sA[a, b] + sB[a, b] + w * (mA[a] - mB[a]) * (mA[b] - mB[b])
    return nC


@njit(cache=True)
def _group_by_session(order, idx, ns, sess, S, rng, rank, start, work):
    """Reorder ``order[:ns]`` (a uniform shuffle) session by session, the sessions in a uniformly random order.

    Within a session the shuffled order is kept (a stable counting sort). The visiting order still
    depends on the data's sessions and the random draws only, never on the partition, so a move and
    its reverse share it; visiting a session's points together lets a part's predictive of the
    session sharpen after its first points there (:func:`_allocate_sequentially`).
    """
    for s in range(S):
        rank[s] = s
    for s in range(S - 1, 0, -1):
        r = min(int(rng.random() * (s + 1)), s)
        rank[s], rank[r] = rank[r], rank[s]
    start[:] = 0
    for t in range(ns):
        start[rank[sess[idx[order[t]]]] + 1] += 1
    for s in range(S):
        start[s + 1] += start[s]
    for t in range(ns):
        g = rank[sess[idx[order[t]]]]
        work[start[g]] = order[t]
        start[g] += 1
    for t in range(ns):
        order[t] = work[t]


@njit(cache=True)
def _session_sums(X, sess, idx, ns, i, j, lab, nsA, suA, nsB, suB):
    """Per-session counts and sums of part A (``i`` and the ``idx`` labelled 0) and part B (``j`` and those labelled 1)."""
    D = X.shape[1]
    nsA[:] = 0
    nsB[:] = 0
    suA[:] = 0.0
    suB[:] = 0.0
    for t in range(ns + 2):
        k = idx[t] if t < ns else (i if t == ns else j)
        part_a = lab[t] == 0 if t < ns else t == ns
        s = sess[k]
        if part_a:
            nsA[s] += 1
            for a in range(D):
                suA[s, a] += X[k, a]
        else:
            nsB[s] += 1
            for a in range(D):
                suB[s, a] += X[k, a]


@njit(cache=True)
def _part_terms(n, mean, scat, ns, sums, lam, use_lik, mean_e, scat_e):
    """``(n, E, D/2 pen)`` of a part for :func:`component_step` and its likelihood; effective stats in ``mean_e``, ``scat_e``.

    Without the likelihood: no data (``n = E = 0``, zero statistics); without session effects the
    plain statistics (``E = n``, no penalty); with them :func:`~.sessions.effective_stats`.
    """
    D = mean.shape[0]
    if not use_lik:
        mean_e[:] = 0.0
        scat_e[:] = 0.0
        return 0, 0.0, 0.0
    if lam > 0.0:
        E, pen = effective_stats(n, mean, scat, ns, sums, lam, mean_e, scat_e)
        return n, E, 0.5 * D * pen
    mean_e[:] = mean
    scat_e[:] = scat
    return n, float(n), 0.0


@njit(cache=True)
def sequential_moves(n_moves, X, st, use_lik, rng, counters, nbr, near):
    """Run ``n_moves`` sequentially-allocated merge-split Metropolis-Hastings moves (see the module docstring).

    With session effects (``sc[5] = lambda > 0``) the parts' likelihoods and parameter steps use
    their effective statistics (:func:`~.sessions.effective_stats`); the sequential allocation,
    a proposal, stays the plain one.
    """
    z, cnt, mu, L, ldet, sc, xi, R, GR, W, GW, sess = (
        st.z, st.cnt, st.mu, st.L, st.ldet, st.sc, st.xi, st.R, st.GR, st.W, st.GW, st.sess
    )  # fmt: skip
    n, D = X.shape
    if n < 2:
        return
    d, beta, lam = sc[1], sc[2], sc[5]
    zeta = sc[3] if use_lik else 1.0
    S = n_sessions(sess) if lam > 0.0 else 1
    Rxi = np.empty(D)
    for a in range(D):
        s = 0.0
        for b in range(D):
            s += R[a, b] * xi[b]
        Rxi[a] = s
    ldet_w = _logdet_chol(GW)
    idx = np.empty(n, dtype=np.int64)
    order = np.empty(n, dtype=np.int64)
    lab = np.empty(n, dtype=np.int64)
    Y = np.empty((n + 2, D))
    mA, mB, mC = np.empty(D), np.empty(D), np.empty(D)
    sA, sB, sC = np.empty((D, D)), np.empty((D, D)), np.empty((D, D))
    eA, eB, eC = np.empty(D), np.empty(D), np.empty(D)  # effective means
    tA, tB, tC = np.empty((D, D)), np.empty((D, D)), np.empty((D, D))  # effective scatters
    nsA, nsB, nsC = np.zeros(S, dtype=np.int64), np.zeros(S, dtype=np.int64), np.zeros(S, dtype=np.int64)
    suA, suB, suC = np.zeros((S, D)), np.zeros((S, D)), np.zeros((S, D))
    newA_mu, newB_mu, newC_mu = np.empty(D), np.empty(D), np.empty(D)
    newA_L, newB_L, newC_L = np.empty((D, D)), np.empty((D, D)), np.empty((D, D))
    tabs = (np.empty(n + 1), np.empty(n + 1), np.empty(n + 1))
    part_sums = np.zeros((2, S, D + 1))
    session_rank = np.empty(S, dtype=np.int64)
    session_start = np.empty(S + 1, dtype=np.int64)
    shuffled = np.empty(n, dtype=np.int64)
    _tables(n, d, D, *tabs)
    for _move in range(n_moves):
        i = min(int(rng.random() * n), n - 1)
        if near > 0.0 and nbr.shape[1] > 0 and rng.random() < near:
            j = nbr[i, min(int(rng.random() * nbr.shape[1]), nbr.shape[1] - 1)]
        else:
            j = min(int(rng.random() * (n - 1)), n - 2)
            if j >= i:
                j += 1
        ci = z[i]
        cj = z[j]
        ns = 0
        for k in range(n):
            if k != i and k != j and (z[k] == ci or z[k] == cj):
                idx[ns] = k
                ns += 1
        for t in range(ns):  # a uniformly random visiting order (Fisher-Yates)
            order[t] = t
        for t in range(ns - 1, 0, -1):
            r = min(int(rng.random() * (t + 1)), t)
            order[t], order[r] = order[r], order[t]
        if lam > 0.0 and use_lik:
            _group_by_session(order, idx, ns, sess, S, rng, session_rank, session_start, shuffled)
        if use_lik:
            _whiten_rows(X, idx, ns, i, j, GW, Y)
        K = st.ist[0]
        u = rng.random()
        split = ci == cj
        if split:
            counters[SPLIT_PROPOSED] += 1
        else:
            counters[MERGE_PROPOSED] += 1
            for t in range(ns):
                lab[t] = 0 if z[idx[t]] == ci else 1
        # the split proposed (or, for a merge, the one it undoes): its log probability and the parts
        logq_split, nA, nB = _allocate_sequentially(
            X, Y, idx, ns, i, j, order, tabs, use_lik, split, lab, rng, mA, sA, mB, sB, sess, lam, part_sums
        )
        nC = _pool(nA, mA, sA, nB, mB, sB, mC, sC)
        if lam > 0.0 and use_lik:
            _session_sums(X, sess, idx, ns, i, j, lab, nsA, suA, nsB, suB)
            for s in range(S):
                nsC[s] = nsA[s] + nsB[s]
                for a in range(D):
                    suC[s, a] = suA[s, a] + suB[s, a]
        pA, EA, penA = _part_terms(nA, mA, sA, nsA, suA, lam, use_lik, eA, tA)
        pB, EB, penB = _part_terms(nB, mB, sB, nsB, suB, lam, use_lik, eB, tB)
        pC, EC, penC = _part_terms(nC, mC, sC, nsC, suC, lam, use_lik, eC, tC)
        # log [p(split state) / p(merged state)] of the partition prior (the others cancel)
        log_prior = (
            log_new_weight(sc, st.lv, K if split else K - 1)
            + math.lgamma(nA - d)
            + math.lgamma(nB - d)
            - math.lgamma(1.0 - d)
            - math.lgamma(nC - d)
        )
        if split:
            qA, ldA = component_step(
                pA, EA, eA, tA, eA, beta, W, R, Rxi, True, newA_mu, newA_L, 0.0, zeta, rng
            )
            qB, ldB = component_step(
                pB, EB, eB, tB, eB, beta, W, R, Rxi, True, newB_mu, newB_L, 0.0, zeta, rng
            )
            q_merge, _ = component_step(
                pC, EC, eC, tC, eC, beta, W, R, Rxi, False, mu[ci].copy(), L[ci].copy(), ldet[ci], zeta, rng
            )
            log_ratio = (
                log_prior
                + base_logpdf(newA_mu, newA_L, ldA, beta, W, ldet_w, xi, GR)
                + base_logpdf(newB_mu, newB_L, ldB, beta, W, ldet_w, xi, GR)
                - base_logpdf(mu[ci], L[ci], ldet[ci], beta, W, ldet_w, xi, GR)
                + q_merge
                - logq_split
                - qA
                - qB
            )
            if use_lik:
                log_ratio += (
                    group_loglik(nA, EA, eA, tA, newA_mu, newA_L, ldA, zeta)
                    + group_loglik(nB, EB, eB, tB, newB_mu, newB_L, ldB, zeta)
                    - group_loglik(nC, EC, eC, tC, mu[ci], L[ci], ldet[ci], zeta)
                    - penA
                    - penB
                    + penC
                )
            if u > 0.0 and math.log(u) < log_ratio:
                counters[SPLIT_ACCEPTED] += 1
                jb = pop_free(st)
                activate(jb, st)
                mu[ci] = newA_mu
                L[ci] = newA_L
                ldet[ci] = ldA
                mu[jb] = newB_mu
                L[jb] = newB_L
                ldet[jb] = ldB
                z[j] = jb
                for t in range(ns):
                    if lab[t] == 1:
                        z[idx[t]] = jb
                cnt[ci] = nA
                cnt[jb] = nB
        else:
            qC, ldC = component_step(
                pC, EC, eC, tC, eC, beta, W, R, Rxi, True, newC_mu, newC_L, 0.0, zeta, rng
            )
            qA, _ = component_step(
                pA, EA, eA, tA, eA, beta, W, R, Rxi, False, mu[ci].copy(), L[ci].copy(), ldet[ci], zeta, rng
            )
            qB, _ = component_step(
                pB, EB, eB, tB, eB, beta, W, R, Rxi, False, mu[cj].copy(), L[cj].copy(), ldet[cj], zeta, rng
            )
            log_ratio = (
                -log_prior
                + base_logpdf(newC_mu, newC_L, ldC, beta, W, ldet_w, xi, GR)
                - base_logpdf(mu[ci], L[ci], ldet[ci], beta, W, ldet_w, xi, GR)
                - base_logpdf(mu[cj], L[cj], ldet[cj], beta, W, ldet_w, xi, GR)
                + logq_split
                + qA
                + qB
                - qC
            )
            if use_lik:
                log_ratio += (
                    group_loglik(nC, EC, eC, tC, newC_mu, newC_L, ldC, zeta)
                    - group_loglik(nA, EA, eA, tA, mu[ci], L[ci], ldet[ci], zeta)
                    - group_loglik(nB, EB, eB, tB, mu[cj], L[cj], ldet[cj], zeta)
                    - penC
                    + penA
                    + penB
                )
            if u > 0.0 and math.log(u) < log_ratio:
                counters[MERGE_ACCEPTED] += 1
                mu[ci] = newC_mu
                L[ci] = newC_L
                ldet[ci] = ldC
                z[j] = ci
                for t in range(ns):
                    z[idx[t]] = ci
                cnt[ci] = nC
                cnt[cj] = 0
                deactivate(cj, st)
