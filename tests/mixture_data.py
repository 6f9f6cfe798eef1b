"""Data and settings shared by the mixture tests."""

from __future__ import annotations

import math

import numpy as np

PYP = {"model": "pyp", "coarsen": None}
"""The study's Pitman-Yor mixture (the estimator's default model is the mixture of finite mixtures)."""


def blobs(n_clusters=28, per=50, dim=3, spread=0.3, box=20.0, seed=0):
    """Well-separated Gaussian clusters (the study's 28 surfaces x 50 windows in PCA-3 space)."""
    rng = np.random.default_rng(seed)
    centers = rng.uniform(-box, box, size=(n_clusters, dim))
    while True:  # keep the centres at least 3 units apart so that the clusters are well separated
        d = np.linalg.norm(centers[:, None] - centers[None], axis=-1) + np.eye(n_clusters) * 1e9
        if d.min() > 3.0:
            break
        centers[np.argmin(d.min(1))] = rng.uniform(-box, box, size=dim)
    X = np.concatenate([rng.normal(c, spread, size=(per, dim)) for c in centers])
    return X, np.repeat(np.arange(n_clusters), per)


def batch_se(x, n_batches=40):
    """Batch-means standard error of the mean of a chain's trace (autocorrelation accounted for)."""
    b = np.asarray(x, dtype=np.float64)[: len(x) // n_batches * n_batches].reshape(n_batches, -1).mean(1)
    return b.std(ddof=1) / math.sqrt(n_batches)


def set_partitions(n):
    """Every set partition of n items as a restricted growth string (labels 0 .. K-1)."""
    z = [0] * n

    def rec(i, k):
        if i == n:
            yield list(z)
            return
        for c in range(k + 1):
            z[i] = c
            yield from rec(i + 1, max(k, c + 1))

    yield from rec(1, 1) if n > 1 else iter([[0]])


def exact_mfm_prior_k(n, gamma, k_mean):
    """P(K) of the MFM partition prior by enumerating every set partition of n items."""
    from scipy.special import gammaln

    from tactile_torch.mixture._mfm import log_v

    lv = log_v(n, gamma, k_mean)
    p = np.zeros(n + 1)
    for z in set_partitions(n):
        counts = np.bincount(z)
        t = counts.size
        p[t] += math.exp(lv[t] + (gammaln(counts + gamma) - gammaln(gamma)).sum())
    return p / p.sum()


def assert_samples_prior_of_k(model, exact, mean_slack=0.0):
    """The chain's K samples match the exact prior ``exact`` (P(K = 0..n)), and both moves were exercised.

    The mean of K within 4 batch-means standard errors (+ ``mean_slack``); every frequency within 4.5
    (with a floor for values rarely seen).
    """
    ks = model.n_clusters_samples_
    n = len(exact) - 1
    assert abs(ks.mean() - (np.arange(n + 1) * exact).sum()) < 4 * batch_se(ks) + mean_slack
    for k in range(1, n + 1):
        ind = (ks == k).astype(float)
        se = max(batch_se(ind), math.sqrt(exact[k] * (1 - exact[k]) / len(ks)), 1e-3)
        assert abs(ind.mean() - exact[k]) < 4.5 * se, (k, ind.mean(), exact[k])
    st = model.split_merge_stats_
    assert st["split_accepted"] > 100 and st["merge_accepted"] > 100
