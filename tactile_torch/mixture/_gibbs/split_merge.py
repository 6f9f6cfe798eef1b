"""Split-merge moves of Jain & Neal (2007) for non-conjugate mixtures (restricted Gibbs sampling).

Two points ``i != j`` are drawn (``i`` uniformly; ``j`` with probability ``near`` uniformly among the
k nearest neighbours of ``i``, otherwise uniformly among the other points); if they share a component
a split is proposed, otherwise a merge of their two components. The probability ``q(i, j)`` of the
pair enters the Metropolis-Hastings ratio as ``q(i, j) / q(i, j) = 1``: the reverse of a split
proposed from ``(i, j)`` is the merge proposed from the same ordered pair, and ``q`` depends on the
data only (never on the partition), so the move stays exact with near pairs as with uniform ones.
Near pairs make merges of adjacent components (the ones the posterior hesitates over) frequent,
where uniform pairs mostly propose merges of far-apart components that are always rejected. See :class:`tactile_torch.mixture.PitmanYorGMM` for the launch states
and the acceptance ratio.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .conditionals import base_logpdf, component_step
from .densities import log_new_weight
from .linalg import LOG2PI, _logdet_chol, _quad_chol
from .state import activate, deactivate, pop_free

# Indices of the counters of split-merge moves.
SPLIT_PROPOSED, SPLIT_ACCEPTED, MERGE_PROPOSED, MERGE_ACCEPTED = 0, 1, 2, 3


@njit(cache=True)
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


@njit(cache=True)
def _group_loglik(X, anchors, idx, ns, lab, want, mu, L, ldet, zeta):
    """Log likelihood (to the power ``zeta``) of ``anchors`` and the ``idx[t]`` with ``lab[t] == want``."""
    D = X.shape[1]
    norm = 0.5 * ldet - 0.5 * D * LOG2PI
    out = 0.0
    for a_ in range(anchors.shape[0]):
        out += norm - 0.5 * _quad_chol(L, X[anchors[a_]], mu)
    for t in range(ns):
        if want < 0 or lab[t] == want:
            out += norm - 0.5 * _quad_chol(L, X[idx[t]], mu)
    return zeta * out


@njit(cache=True)
def _restricted_scan(X, i, j, idx, ns, lab, target, muA, LA, ldA, muB, LB, ldB, d, zeta, use_lik, draw, rng):
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
    normA = 0.5 * ldA - 0.5 * D * LOG2PI
    normB = 0.5 * ldB - 0.5 * D * LOG2PI
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
            la += zeta * (normA - 0.5 * _quad_chol(LA, X[k], muA))
            lb += zeta * (normB - 0.5 * _quad_chol(LB, X[k], muB))
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


@njit(cache=True)
def _part_step(X, anchor, idx, ns, lab, want, mu0, sc, R, Rxi, W, use_lik, draw, mu, L, ldet_in, rng):
    """:func:`component_step` for the part of a split holding ``anchor`` and the ``idx`` labelled ``want``.

    Returns (number of points of the part, log density of the move, log|S|).
    """
    D = X.shape[1]
    mean = np.empty(D)
    scat = np.empty((D, D))
    n = _group_stats(X, anchor, idx, ns, lab, want, mean, scat)
    logq, ldet = component_step(
        n if use_lik else 0,
        n if use_lik else 0,
        mean,
        scat,
        mu0,
        sc[2],
        W,
        R,
        Rxi,
        draw,
        mu,
        L,
        ldet_in,
        sc[3],
        rng,
    )
    return n, logq, ldet


@njit(cache=True)
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
                X, i, j, idx, ns, lab, lab, muA, LA, ldA, muB, LB, ldB, sc[1], sc[3], use_lik, True, rng
            )
        ldA = _part_step(
            X, anchA, idx, ns, lab, 0, muA.copy(), sc, R, Rxi, W, use_lik, True, muA, LA, 0.0, rng
        )[2]
        ldB = _part_step(
            X, anchB, idx, ns, lab, 1, muB.copy(), sc, R, Rxi, W, use_lik, True, muB, LB, 0.0, rng
        )[2]
    return ldA, ldB


@njit(cache=True)
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
        component_step(nM, nM, mean, scat, mu0.copy(), sc[2], W, R, Rxi, True, mu0, Ltmp, 0.0, sc[3], rng)
    return nM, mean, scat


@njit(cache=True)
def split_merge_moves(n_moves, X, st, n_launch, use_lik, rng, counters, nbr, near):
    """Run ``n_moves`` split-merge Metropolis-Hastings moves (Jain & Neal 2007, non-conjugate version).

    ``nbr`` (n, k): nearest neighbours of each point; ``near``: share of pairs drawn among them.
    """
    z, cnt, mu, L, ldet, sc, xi, R, GR, W, GW = (
        st.z, st.cnt, st.mu, st.L, st.ldet, st.sc, st.xi, st.R, st.GR, st.W, st.GW
    )  # fmt: skip
    n, D = X.shape
    if n < 2:
        return
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
        idx = np.empty(n, dtype=np.int64)
        ns = 0
        for k in range(n):
            if k != i and k != j and (z[k] == ci or z[k] == cj):
                idx[ns] = k
                ns += 1
        lab = np.empty(ns, dtype=np.int64)
        d, beta, zeta = sc[1], sc[2], sc[3]
        K = st.ist[0]
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
                X, i, j, idx, ns, lab, lab, muA, LA, ldA, muB, LB, ldB, d, zeta, use_lik, True, rng
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
                nM,
                nM,
                meanM,
                scatM,
                muM0,
                beta,
                W,
                R,
                Rxi,
                False,
                mu[ci].copy(),
                L[ci].copy(),
                ldet[ci],
                zeta,
                rng,
            )
            nC = nA + nB
            log_ratio = (
                log_new_weight(sc, st.lv, K)
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
                    _group_loglik(X, anchA, idx, ns, lab, 0, newA_mu, newA_L, newA_ld, zeta)
                    + _group_loglik(X, anchB, idx, ns, lab, 1, newB_mu, newB_L, newB_ld, zeta)
                    - _group_loglik(X, anchM, idx, ns, lab, -1, mu[ci], L[ci], ldet[ci], zeta)
                )
            if u > 0.0 and math.log(u) < log_ratio:
                counters[SPLIT_ACCEPTED] += 1
                jb = pop_free(st)
                activate(jb, st)
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
                nM, nM, meanM, scatM, muM0, beta, W, R, Rxi, True, newM_mu, newM_L, 0.0, zeta, rng
            )
            # reverse: the split launch's final scan landing on the current labels and parameters
            target = np.empty(ns, dtype=np.int64)
            for t in range(ns):
                target[t] = 0 if z[idx[t]] == ci else 1
            logq_rev = _restricted_scan(
                X, i, j, idx, ns, lab, target, muA, LA, ldA, muB, LB, ldB, d, zeta, use_lik, False, rng
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
                -log_new_weight(sc, st.lv, K - 1)
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
                    _group_loglik(X, anchM, idx, ns, lab, -1, newM_mu, newM_L, newM_ld, zeta)
                    - _group_loglik(X, anchA, idx, ns, lab, 0, mu[ci], L[ci], ldet[ci], zeta)
                    - _group_loglik(X, anchB, idx, ns, lab, 1, mu[cj], L[cj], ldet[cj], zeta)
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
                deactivate(cj, st)
