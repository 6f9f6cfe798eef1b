"""The mixture of finite mixtures' partition prior and the coarsened posterior's power (numpy only).

A mixture of finite mixtures (MFM; Miller & Harrison 2018) puts a prior ``p(k)`` on the number of
components and a symmetric ``Dirichlet(gamma, ..., gamma)`` on their weights. Its partition
distribution is ``V_n(t) prod_c gamma^(n_c)`` (``t`` blocks, ``gamma^(m)`` the rising factorial) with

    V_n(t) = sum_{k >= t} k_(t) / (gamma k)^(n) p(k)          (k_(t) the falling factorial)

so that its Gibbs sampler is the Chinese restaurant's with weights ``n_c + gamma`` (existing) and
``gamma V_n(t + 1) / V_n(t)`` (new): :mod:`tactile_torch.mixture._gibbs` runs it with ``d = -gamma``.
Unlike the Pitman-Yor process's, its posterior of the number of components is consistent when the
model holds. Our prior on ``k`` is geometric on ``{1, 2, ...}`` with mean ``k_mean``.

The coarsened posterior (Miller & Dunson 2018) raises the likelihood to ``zeta = a / (a + n)``:
the model then only has to fit the data up to a discrepancy of order ``1/a`` (a relative-entropy
neighbourhood), so that a few extra components no longer pay for small departures from
Gaussianity (session shifts, skewed features). It keeps the conditionals conjugate.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy.special import gammaln, logsumexp

# Blocks beyond this multiple of the k-means start (2 sqrt(n)), plus a margin, get no exact V_n(t):
# a new component there has weight exp(-700) (K is truncated far above anything a chain visits).
_T_CAP_FACTOR, _T_CAP_MARGIN = 4, 60
# Terms of the series of V_n(t) summed past k = t.
_K_SPAN = 4000


def log_prior_k(k: np.ndarray, k_mean: float) -> np.ndarray:
    """Return ``log p(k)`` of the geometric prior on {1, 2, ...} with mean ``k_mean``, same shape as ``k``."""
    p = 1.0 / k_mean
    if p >= 1.0:
        return np.where(k == 1, 0.0, -np.inf)
    return math.log(p) + (k - 1) * math.log1p(-p)


def log_v_at(n: float, gamma: float, k_mean: float, ts: np.ndarray) -> np.ndarray:
    """Return ``log V_n(t)`` for every ``t`` of ``ts`` (a log-sum-exp over ``k = t .. t + 4000``).

    ``n`` may be fractional (``zeta n`` under coarsening: ``(gamma k)^(n) = Gamma(gamma k + n) / Gamma(gamma k)``).
    The terms ``log(k_(t) / (gamma k)^(n) p(k)) = a(k) - log Gamma(k - t + 1)`` with
    ``a(k) = log Gamma(k + 1) - log (gamma k)^(n) + log p(k)`` are formed from one table of ``a``
    and one of ``log Gamma(m + 1)``, so that all ``t`` cost one pass of additions.
    """
    ts = np.asarray(ts, dtype=np.int64)
    flat = ts.ravel()
    out = np.empty(flat.shape, dtype=np.float64)
    if flat.size == 0:
        return out.reshape(ts.shape)
    first = np.maximum(flat, 1)  # the series starts at k = max(t, 1)
    k = np.arange(int(first.min()), int(first.max()) + _K_SPAN + 1, dtype=np.float64)
    a = gammaln(k + 1.0) - (gammaln(gamma * k + n) - gammaln(gamma * k)) + log_prior_k(k, k_mean)
    log_fact = gammaln(np.arange(int(first.max() - flat.min()) + _K_SPAN + 1, dtype=np.float64) + 1.0)
    offsets = np.arange(_K_SPAN + 1)
    for lo in range(0, flat.size, 256):  # blocks of t: at most 256 x 4001 terms at once
        t = flat[lo : lo + 256]
        start = first[lo : lo + 256]
        rows = (start - int(k[0]))[:, None] + offsets[None, :]
        terms = a[rows] - log_fact[(start - t)[:, None] + offsets[None, :]]
        top = terms.max(axis=1)
        out[lo : lo + 256] = top + np.log(np.exp(terms - top[:, None]).sum(axis=1))
    return out.reshape(ts.shape)


def components_given_clusters(n: float, gamma: float, k_mean: float, t: int, span: int = 200) -> np.ndarray:
    """Return ``P(K = k | T = t)`` for ``k = 0 .. t + span``: the number of components given ``t`` occupied clusters.

    In a mixture of finite mixtures the partition depends on K only through ``t``, so the
    posterior of K given the data is ``sum_t P(K | T = t) P(T = t | data)`` with
    ``P(K = k | T = t) = p(k) k_(t) / (gamma k)^(n) / V_n(t)`` for ``k >= t`` (Miller & Harrison
    2018, section 3.3): averaging it over the sampled ``t`` is the Rao-Blackwellised estimate of the
    posterior of K.
    """
    k = np.arange(max(t, 1), t + span + 1, dtype=np.float64)
    log_terms = (
        gammaln(k + 1.0)
        - gammaln(k - t + 1.0)
        - (gammaln(gamma * k + n) - gammaln(gamma * k))
        + log_prior_k(k, k_mean)
    )
    out = np.zeros(t + span + 1)
    out[max(t, 1) :] = np.exp(log_terms - logsumexp(log_terms))
    return out


def k_ceiling(n: int) -> int:
    """Return the largest number of blocks with an exact ``log V_n(t)`` (:func:`log_v`): ``4 * 2 sqrt(n) + 60``, at most ``n + 1``."""
    return min(n + 1, _T_CAP_FACTOR * math.ceil(2.0 * math.sqrt(max(n, 1))) + _T_CAP_MARGIN)


def log_v(n: int, gamma: float, k_mean: float) -> np.ndarray:
    """Return ``log V_n(t)`` for t = 0 .. n + 1, shape (n + 2,) (see the module docstring).

    Exact (:func:`log_v_at`) for ``t`` up to ``4 * 2 sqrt(n) + 60``; beyond, each further block
    costs ``700`` (a truncation of K far above any chain's reach).
    """
    t_cap = k_ceiling(n)
    out = np.empty(n + 2)
    out[: t_cap + 1] = log_v_at(n, gamma, k_mean, np.arange(t_cap + 1))
    if t_cap < n + 1:
        out[t_cap + 1 :] = out[t_cap] - 700.0 * np.arange(1, n + 1 - t_cap + 1)
    return out


def coarsening_power(a: float | None, n: int) -> float:
    """Return the power ``zeta = a / (a + n)`` of the likelihood (1 when ``a`` is None: no coarsening)."""
    if a is None:
        return 1.0
    return float(a) / (float(a) + n)


@functools.lru_cache(maxsize=4096)
def _log_v_step(n: int, gamma: float, k_mean: float, t: int) -> float:
    """``log V_n(t + 1) - log V_n(t)`` (memoised: a pure function of its arguments)."""
    lv = log_v_at(n, gamma, k_mean, np.array([t, t + 1]))
    return float(lv[1] - lv[0])


def predictive_weights(
    n: int, counts: np.ndarray, alpha: float, d: float, gamma: float, k_mean: float
) -> tuple[np.ndarray, float]:
    """Return (log P(a new point joins component j), log P(it opens a new one)), shapes (K,) and scalar.

    Pitman-Yor: ``(n_j - d) / (n + alpha)`` and ``(alpha + d K) / (n + alpha)``; mixture of finite
    mixtures (``gamma > 0``; ``d = -gamma``): ``n_j + gamma`` and ``gamma V_{n+1}(K + 1) / V_{n+1}(K)``,
    normalised.
    """
    K = counts.size
    if gamma <= 0.0:
        return np.log((counts - d) / (n + alpha)), math.log((alpha + d * K) / (n + alpha))
    log_new = math.log(gamma) + _log_v_step(n + 1, gamma, k_mean, K)
    log_join = np.log(counts + gamma)
    log_total = logsumexp(np.r_[log_join, log_new])
    return log_join - log_total, float(log_new - log_total)
