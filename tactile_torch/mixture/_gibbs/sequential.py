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
def _add_point(x, n, mean, scat):
    """Welford's update of a group's ``mean`` and ``scat`` (scatter about the mean) with ``x``; ``n`` after."""
    D = x.shape[0]
    for a in range(D):
        da = x[a] - mean[a]
        mean[a] += da / n
        for b in range(a + 1):
            scat[a, b] += da * (x[b] - mean[b])
            scat[b, a] = scat[a, b]


@njit(cache=True)
def _allocate_sequentially(X, Y, idx, ns, i, j, order, d, use_lik, draw, lab, rng, mA, sA, mB, sB):
    """Visit ``idx[order[t]]`` in turn; put each in part A (0) or B (1); return (log probability, nA, nB).

    With ``draw`` the parts are sampled; otherwise ``lab`` holds the labels whose probability is
    computed. ``Y`` holds the rows whitened by ``W`` (:func:`_whiten_rows`: the visited points,
    then i, then j). On return ``mA, sA, mB, sB`` are the parts' means and scatters in X's
    coordinates (i in A, j in B).
    """
    D = X.shape[1]
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
        la = math.log(nA - d)
        lb = math.log(nB - d)
        if use_lik:
            qa = 0.0
            qb = 0.0
            for a in range(D):
                qa += (Y[t, a] - yA[a]) ** 2
                qb += (Y[t, a] - yB[a]) ** 2
            fa = 1.0 + 1.0 / nA
            fb = 1.0 + 1.0 / nB
            la += -0.5 * D * math.log(fa) - 0.5 * qa / fa
            lb += -0.5 * D * math.log(fb) - 0.5 * qb / fb
        mx = max(la, lb)
        lz = mx + math.log(math.exp(la - mx) + math.exp(lb - mx))
        if draw:
            lab[t] = 0 if rng.random() < math.exp(la - lz) else 1
        if lab[t] == 0:
            logq += la - lz
            nA += 1
            for a in range(D):
                yA[a] += (Y[t, a] - yA[a]) / nA
            _add_point(X[k], nA, mA, sA)
        else:
            logq += lb - lz
            nB += 1
            for a in range(D):
                yB[a] += (Y[t, a] - yB[a]) / nB
            _add_point(X[k], nB, mB, sB)
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
def sequential_moves(n_moves, X, st, use_lik, rng, counters, nbr, near):
    """Run ``n_moves`` sequentially-allocated merge-split Metropolis-Hastings moves (see the module docstring)."""
    z, cnt, mu, L, ldet, sc, xi, R, GR, W, GW = (
        st.z, st.cnt, st.mu, st.L, st.ldet, st.sc, st.xi, st.R, st.GR, st.W, st.GW
    )  # fmt: skip
    n, D = X.shape
    if n < 2:
        return
    d, beta, zeta = sc[1], sc[2], sc[3]
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
    newA_mu, newB_mu, newC_mu = np.empty(D), np.empty(D), np.empty(D)
    newA_L, newB_L, newC_L = np.empty((D, D)), np.empty((D, D)), np.empty((D, D))
    # the likelihood off (prior only): the parameter steps see no data
    zero_m = np.zeros(D)
    zero_s = np.zeros((D, D))
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
        if use_lik:
            _whiten_rows(X, idx, ns, i, j, GW, Y)
        K = st.ist[0]
        u = rng.random()
        if ci == cj:
            counters[SPLIT_PROPOSED] += 1
            logq, nA, nB = _allocate_sequentially(
                X, Y, idx, ns, i, j, order, d, use_lik, True, lab, rng, mA, sA, mB, sB
            )
            nC = _pool(nA, mA, sA, nB, mB, sB, mC, sC)
            if use_lik:
                qA, ldA = component_step(
                    nA, mA, sA, mA, beta, W, R, Rxi, True, newA_mu, newA_L, 0.0, zeta, rng
                )
                qB, ldB = component_step(
                    nB, mB, sB, mB, beta, W, R, Rxi, True, newB_mu, newB_L, 0.0, zeta, rng
                )
                q_rev, _ = component_step(
                    nC, mC, sC, mC, beta, W, R, Rxi, False, mu[ci].copy(), L[ci].copy(), ldet[ci], zeta, rng
                )
            else:
                qA, ldA = component_step(
                    0, zero_m, zero_s, zero_m, beta, W, R, Rxi, True, newA_mu, newA_L, 0.0, 1.0, rng
                )
                qB, ldB = component_step(
                    0, zero_m, zero_s, zero_m, beta, W, R, Rxi, True, newB_mu, newB_L, 0.0, 1.0, rng
                )
                q_rev, _ = component_step(
                    0,
                    zero_m,
                    zero_s,
                    zero_m,
                    beta,
                    W,
                    R,
                    Rxi,
                    False,
                    mu[ci].copy(),
                    L[ci].copy(),
                    ldet[ci],
                    1.0,
                    rng,
                )
            log_ratio = (
                log_new_weight(sc, st.lv, K)
                + math.lgamma(nA - d)
                + math.lgamma(nB - d)
                - math.lgamma(1.0 - d)
                - math.lgamma(nC - d)
                + base_logpdf(newA_mu, newA_L, ldA, beta, W, ldet_w, xi, GR)
                + base_logpdf(newB_mu, newB_L, ldB, beta, W, ldet_w, xi, GR)
                - base_logpdf(mu[ci], L[ci], ldet[ci], beta, W, ldet_w, xi, GR)
                + q_rev
                - logq
                - qA
                - qB
            )
            if use_lik:
                log_ratio += (
                    group_loglik(nA, mA, sA, newA_mu, newA_L, ldA, zeta)
                    + group_loglik(nB, mB, sB, newB_mu, newB_L, ldB, zeta)
                    - group_loglik(nC, mC, sC, mu[ci], L[ci], ldet[ci], zeta)
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
            counters[MERGE_PROPOSED] += 1
            for t in range(ns):
                lab[t] = 0 if z[idx[t]] == ci else 1
            logq_rev, nA, nB = _allocate_sequentially(
                X, Y, idx, ns, i, j, order, d, use_lik, False, lab, rng, mA, sA, mB, sB
            )
            nC = _pool(nA, mA, sA, nB, mB, sB, mC, sC)
            if use_lik:
                qC, ldC = component_step(
                    nC, mC, sC, mC, beta, W, R, Rxi, True, newC_mu, newC_L, 0.0, zeta, rng
                )
                qA, _ = component_step(
                    nA, mA, sA, mA, beta, W, R, Rxi, False, mu[ci].copy(), L[ci].copy(), ldet[ci], zeta, rng
                )
                qB, _ = component_step(
                    nB, mB, sB, mB, beta, W, R, Rxi, False, mu[cj].copy(), L[cj].copy(), ldet[cj], zeta, rng
                )
            else:
                qC, ldC = component_step(
                    0, zero_m, zero_s, zero_m, beta, W, R, Rxi, True, newC_mu, newC_L, 0.0, 1.0, rng
                )
                qA, _ = component_step(
                    0,
                    zero_m,
                    zero_s,
                    zero_m,
                    beta,
                    W,
                    R,
                    Rxi,
                    False,
                    mu[ci].copy(),
                    L[ci].copy(),
                    ldet[ci],
                    1.0,
                    rng,
                )
                qB, _ = component_step(
                    0,
                    zero_m,
                    zero_s,
                    zero_m,
                    beta,
                    W,
                    R,
                    Rxi,
                    False,
                    mu[cj].copy(),
                    L[cj].copy(),
                    ldet[cj],
                    1.0,
                    rng,
                )
            log_ratio = (
                -log_new_weight(sc, st.lv, K - 1)
                + math.lgamma(1.0 - d)
                + math.lgamma(nC - d)
                - math.lgamma(nA - d)
                - math.lgamma(nB - d)
                + base_logpdf(newC_mu, newC_L, ldC, beta, W, ldet_w, xi, GR)
                - base_logpdf(mu[ci], L[ci], ldet[ci], beta, W, ldet_w, xi, GR)
                - base_logpdf(mu[cj], L[cj], ldet[cj], beta, W, ldet_w, xi, GR)
                + logq_rev
                + qA
                + qB
                - qC
            )
            if use_lik:
                log_ratio += (
                    group_loglik(nC, mC, sC, newC_mu, newC_L, ldC, zeta)
                    - group_loglik(nA, mA, sA, mu[ci], L[ci], ldet[ci], zeta)
                    - group_loglik(nB, mB, sB, mu[cj], L[cj], ldet[cj], zeta)
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
