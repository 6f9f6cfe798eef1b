"""Prediction of a fitted :class:`PitmanYorGMM`: the posterior predictive over saved samples, and the point estimate's.

For a new point, each saved partition gives the probability of joining each of its components
(weight ``n_j - d``) or a new one (weight ``alpha + d K``, the new component's prior predictive
density by Monte Carlo); the components are mapped onto the point estimate's clusters by the share
of each component's training points in each cluster, and the result is averaged over the samples
(:func:`posterior_predictive`). :func:`point_scores` computes the same from the point estimate's
components alone, as the exported graph does.
"""

from __future__ import annotations

import math

import numpy as np

from ._mfm import predictive_weights
from ._point_estimate import new_component_gaussian, new_session_terms, precision_cholesky

# At most this many saved partitions per chain enter the posterior predictive of predict/predict_proba.
_PREDICTIVE_SAMPLES = 50
_LOG_2PI = math.log(2.0 * math.pi)


# Log densities below this (a point ~1e154 standard deviations away, whose squared distance
# overflows) are reported as this value: finite, and below every representable density.
LOG_FLOOR = -np.finfo(np.float64).max


def _quadratic(y: np.ndarray) -> np.ndarray:
    """``sum(y**2, axis=-1)`` without overflow to inf: the result saturates at the largest float."""
    with np.errstate(over="ignore"):
        q = np.einsum("...e,...e->...", y, y)
    return np.minimum(q, np.finfo(np.float64).max)


def log_gauss(Z: np.ndarray, mu: np.ndarray, L: np.ndarray, ldet: np.ndarray) -> np.ndarray:
    """(n, C) ``log N(z | mu_c, (L_c L_c^T)^{-1})`` for whitened rows and components (``ldet = log|L L^T|``).

    Finite for finite input: values below ``LOG_FLOOR`` are clipped to it.
    """
    with np.errstate(over="ignore", invalid="ignore"):
        y = np.einsum("nd,cde->nce", Z, L) - np.einsum("cd,cde->ce", mu, L)[None]
    y = np.nan_to_num(
        y, nan=np.finfo(np.float64).max, posinf=np.finfo(np.float64).max, neginf=-np.finfo(np.float64).max
    )
    out = 0.5 * ldet - 0.5 * Z.shape[1] * _LOG_2PI - 0.5 * _quadratic(y)
    return np.maximum(out, LOG_FLOOR)


def log_gauss_upper(X: np.ndarray, means: np.ndarray, U: np.ndarray) -> np.ndarray:
    """(n, K) ``log N(x | mean_k, (U_k U_k^T)^{-1})`` (the formula of :func:`gaussian_mixture_scores`), clipped like :func:`log_gauss`."""
    with np.errstate(over="ignore", invalid="ignore"):
        y = np.einsum("nd,kde->nke", X, U) - np.einsum("kd,kde->ke", means, U)[None]
    y = np.nan_to_num(
        y, nan=np.finfo(np.float64).max, posinf=np.finfo(np.float64).max, neginf=-np.finfo(np.float64).max
    )
    log_det = np.log(np.abs(np.diagonal(U, axis1=1, axis2=2))).sum(axis=1)
    return np.maximum(log_det - 0.5 * X.shape[1] * _LOG_2PI - 0.5 * _quadratic(y), LOG_FLOOR)


def pack_predictive(runs, n, labels, rng, k_mean: float = 10.0) -> dict:
    """Pack the components of (at most ``_PREDICTIVE_SAMPLES`` per chain) saved sweeps for prediction.

    With session effects a new point is taken to come from a new session: every component's
    covariance is ``(1 + lambda) S^{-1} + omega I`` (the session's offset and effect integrated out).

    ``runs``: the chains' saved samples (after the burn-in, each with its sweep's partition);
    ``labels``: the point estimate, onto whose clusters every
    sample's components are mapped. One Gaussian of the new component's prior predictive is drawn
    per sample from ``rng``.
    """
    K = int(labels.max()) + 1
    D = runs[0]["samples"][0]["mu"].shape[1]
    mus, Ls, ldets, logw, share, owner, new_mu, new_prec, new_ldet, new_logw = ([] for _ in range(10))
    for run in runs:
        pick = np.unique(
            np.linspace(0, len(run["samples"]) - 1, min(_PREDICTIVE_SAMPLES, len(run["samples"]))).astype(int)
        )
        for k in pick:
            smp = run["samples"][k]
            alpha, d, beta, _, gamma = smp["sc"][:5]
            Ks = smp["cnt"].size
            log_join, log_new = predictive_weights(n, smp["cnt"], alpha, d, gamma, k_mean)
            s = len(new_logw)
            # a new point is of a new session: its offset and effect integrated out (new_session_terms)
            scale, offset = new_session_terms(smp["sc"])
            mus.append(smp["mu"])
            if offset > 0.0:
                Linv = np.linalg.inv(smp["L"])
                cov = scale * (np.swapaxes(Linv, 1, 2) @ Linv) + offset * np.eye(D)
                Lc = np.linalg.cholesky(np.linalg.inv(cov))  # lower, L L^T = precision
                Ls.append(Lc)
                ldets.append(2.0 * np.log(np.diagonal(Lc, axis1=1, axis2=2)).sum(axis=1))
            else:
                Ls.append(smp["L"])
                ldets.append(smp["ldet"])
            logw.append(log_join)
            table = np.zeros((Ks, K))
            np.add.at(table, (smp["labels"], labels), 1.0)
            share.append(table / table.sum(axis=1, keepdims=True))
            owner.append(np.full(Ks, s))
            xi, cov = new_component_gaussian(smp["xi"], smp["GR"], smp["GW"], beta, rng, scale)
            U = precision_cholesky(cov + offset * np.eye(D))  # upper, U U^T = cov^{-1}
            new_mu.append(xi)
            new_prec.append(U)
            new_ldet.append(2.0 * np.log(np.abs(np.diag(U))).sum())
            new_logw.append(log_new)
    return {
        "mu": np.concatenate(mus).reshape(-1, D),
        "L": np.concatenate(Ls).reshape(-1, D, D),
        "ldet": np.concatenate(ldets),
        "logw": np.concatenate(logw),
        "share": np.concatenate(share),
        "owner": np.concatenate(owner),
        "new_mu": np.stack(new_mu),
        "new_L": np.stack(new_prec),
        "new_ldet": np.array(new_ldet),
        "new_logw": np.array(new_logw),
    }


def posterior_predictive(Z: np.ndarray, p: dict, K: int) -> tuple[np.ndarray, np.ndarray]:
    """(n, K) log probability of joining each point-estimate cluster and (n,) of a new component, averaged over samples.

    ``Z``: whitened rows; ``p``: :func:`pack_predictive`'s output. Every step is in log space (a
    point far from every component gets finite log probabilities, never 0/0). Samples are processed
    in blocks of about 2e6 numbers.
    """
    from scipy.special import logsumexp

    S = p["new_logw"].size
    n = Z.shape[0]
    log_joint = np.full((n, K), -np.inf)
    log_new = np.full(n, -np.inf)
    starts = np.flatnonzero(np.r_[True, p["owner"][1:] != p["owner"][:-1]])
    bounds = np.r_[starts, p["owner"].size]
    step = max(1, int(2e6 // max(1, n * (bounds[-1] / S) * Z.shape[1])))
    for s0 in range(0, S, step):
        s1 = min(S, s0 + step)
        lo, hi = bounds[s0], bounds[s1]
        comp = p["logw"][lo:hi] + log_gauss(Z, p["mu"][lo:hi], p["L"][lo:hi], p["ldet"][lo:hi])
        fresh = p["new_logw"][s0:s1] + log_gauss(
            Z, p["new_mu"][s0:s1], p["new_L"][s0:s1], p["new_ldet"][s0:s1]
        )
        seg = starts[s0:s1] - lo
        owner = p["owner"][lo:hi] - s0
        # per sample: log of its normaliser (its components and its new component)
        top = np.maximum(np.maximum.reduceat(comp, seg, axis=1), fresh)
        log_total = top + np.log(
            np.add.reduceat(np.exp(comp - top[:, owner]), seg, axis=1) + np.exp(fresh - top)
        )
        comp_norm = comp - log_total[:, owner]  # log P(component | x) within its sample
        log_new = np.logaddexp(log_new, logsumexp(fresh - log_total, axis=1))
        # log sum_c P(c | x) share[c, k], with the largest term factored out (exact in log space)
        m = comp_norm.max(axis=1, keepdims=True)
        with np.errstate(divide="ignore"):  # a cluster no component of the block maps to: log 0
            block = np.log(np.exp(comp_norm - m) @ p["share"][lo:hi]) + m
        log_joint = np.logaddexp(log_joint, block)
    return log_joint - math.log(S), log_new - math.log(S)


def point_scores(X: np.ndarray, c) -> tuple[np.ndarray, np.ndarray]:
    """(n, K) ``log P(join k) + log N(x | k)`` and (n,) ``log P(new) + log p_new(x)``, original coordinates.

    ``c``: the point estimate's components (:class:`._point_estimate.Components` or the fitted
    estimator's attributes of the same names).
    """
    known = log_gauss_upper(X, c.means, c.precisions_cholesky)
    known += np.log(c.weights * (1 - c.novelty_weight))
    new = log_gauss_upper(X, c.novelty_means, c.novelty_precisions_cholesky)
    M = c.novelty_means.shape[0]
    return known, np.logaddexp.reduce(new, axis=1) - math.log(M) + math.log(c.novelty_weight)


def normalise(known: np.ndarray, new: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Log probabilities from the log scores of :func:`point_scores`: (n, K) per cluster and (n,) new."""
    total = np.logaddexp(np.logaddexp.reduce(known, axis=1), new)
    return known - total[:, None], new - total
