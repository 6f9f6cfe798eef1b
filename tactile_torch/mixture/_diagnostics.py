"""Convergence diagnostics of several chains: rank-normalised split R-hat and effective sample sizes.

Vehtari, Gelman, Simpson, Carpenter & Bürkner (2021), "Rank-normalization, folding, and
localization: an improved R-hat for assessing convergence of MCMC", Bayesian Analysis 16(2). The
computations follow ArviZ's (``arviz_stats`` 0.8, ``rhat(method="rank")``, ``ess(method="bulk")``,
``ess(method="tail", prob=(0.05, 0.95))``) step by step, so that the numbers are the ones ArviZ
users know; ``tests/mixture/test_mixture.py`` checks them against values computed with ArviZ. Ties (the
number of clusters K is an integer) get average ranks, as in ArviZ.
"""

from __future__ import annotations

import numpy as np
from scipy.fft import next_fast_len
from scipy.special import ndtri

RHAT_THRESHOLD = 1.01
"""R-hat above this value signals chains that have not mixed (Vehtari et al. 2021)."""


def _as_chains(draws: object) -> np.ndarray:
    arr = np.asarray(draws, dtype=np.float64)
    if arr.ndim == 1:
        arr = arr[None]
    if arr.ndim != 2:
        raise ValueError(f"draws must have shape (n_chains, n_draws), got {arr.shape}")
    return arr


def _split_chains(x: np.ndarray) -> np.ndarray:
    half = x.shape[1] // 2
    return np.vstack((x[:, :half], x[:, -half:]))


def _average_ranks(x: np.ndarray) -> np.ndarray:
    """Ranks 1 .. size of the flattened ``x``, ties given their average rank (``scipy.stats.rankdata``)."""
    flat = x.ravel()
    rank = np.empty(flat.size)
    rank[np.argsort(flat, kind="stable")] = np.arange(1, flat.size + 1)
    _, inverse, counts = np.unique(flat, return_inverse=True, return_counts=True)
    return (np.bincount(inverse, weights=rank) / counts)[inverse].reshape(x.shape)


def _z_scale(x: np.ndarray) -> np.ndarray:
    return ndtri((_average_ranks(x) - 3 / 8) / (x.size - 2 * 3 / 8 + 1))


def _rhat(x: np.ndarray) -> float:
    n = x.shape[1]
    between = n * np.var(x.mean(axis=1), ddof=1)
    within = np.mean(np.var(x, axis=1, ddof=1))
    with np.errstate(divide="ignore", invalid="ignore"):  # within = 0: inf (chains stuck apart)
        return float(np.sqrt((between / within + n - 1) / n))


def _autocov(x: np.ndarray) -> np.ndarray:
    n = x.shape[1]
    m = next_fast_len(2 * n)
    x = x - x.mean(axis=1, keepdims=True)
    f = np.fft.rfft(x, n=m, axis=1)
    f *= np.conjugate(f)
    return np.fft.irfft(f, n=m, axis=1)[:, :n] / n


def _ess(x: np.ndarray) -> float:
    """ESS of (n_chains, n_draws) draws by Geyer's initial monotone sequence (ArviZ's ``_ess``)."""
    if np.max(x) - np.min(x) < np.finfo(float).resolution:
        return float(x.size)
    n_chain, n_draw = x.shape
    acov = _autocov(x)
    mean_var = np.mean(acov[:, 0]) * n_draw / (n_draw - 1.0)
    var_plus = mean_var * (n_draw - 1.0) / n_draw
    if n_chain > 1:
        var_plus += np.var(x.mean(axis=1), ddof=1)
    rho = np.zeros(n_draw)
    even = 1.0
    rho[0] = even
    odd = 1.0 - (mean_var - np.mean(acov[:, 1])) / var_plus
    rho[1] = odd
    t = 1
    while t < n_draw - 3 and even + odd > 0.0:
        even = 1.0 - (mean_var - np.mean(acov[:, t + 1])) / var_plus
        odd = 1.0 - (mean_var - np.mean(acov[:, t + 2])) / var_plus
        if even + odd >= 0:
            rho[t + 1] = even
            rho[t + 2] = odd
        t += 2
    max_t = t - 2
    if even > 0:
        rho[max_t + 1] = even
    t = 1
    while t <= max_t - 2:
        if rho[t + 1] + rho[t + 2] > rho[t - 1] + rho[t]:
            rho[t + 1] = (rho[t - 1] + rho[t]) / 2.0
            rho[t + 2] = rho[t + 1]
        t += 2
    size = n_chain * n_draw
    tau = -1.0 + 2.0 * np.sum(rho[: max_t + 1]) + np.sum(rho[max_t + 1 : max_t + 2])
    tau = max(tau, 1 / np.log10(size))
    return float(np.nan if np.isnan(rho).any() else size / tau)


def rhat(draws: object) -> float:
    """Return the rank-normalised split R-hat of draws of shape (n_chains, n_draws).

    The larger of the bulk R-hat (split chains, rank-normalised) and the tail R-hat (the same on
    values folded about the median); ``nan`` with fewer than 2 chains or 4 draws. When every draw of
    every chain is the same value (K constant, for instance) the chains agree exactly and the result
    is 1.0 (ArviZ returns ``nan`` there: 0/0).

    Parameters
    ----------
    draws : array-like of shape (n_chains, n_draws), or (n_draws,) for one chain
        A scalar quantity's draws (K, a log-likelihood), one row per chain.

    Returns
    -------
    float
        >= 1 in practice; above 1.01 flags chains that disagree. ``nan`` as above, or for a NaN/inf
        draw.

    Raises
    ------
    ValueError
        If ``draws`` is not 1-D or 2-D, or not convertible to float (numpy's message).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> round(rhat(rng.normal(size=(4, 500))), 2)
    1.0
    """
    x = _as_chains(draws)
    if x.shape[0] < 2 or x.shape[1] < 4 or not np.isfinite(x).all():
        return float("nan")
    if np.ptp(x) == 0.0:
        return 1.0
    split = _split_chains(x)
    bulk = _rhat(_z_scale(split))
    tail = _rhat(_z_scale(np.abs(split - np.median(split))))
    return max(bulk, tail)


def ess_bulk(draws: object) -> float:
    """Return the bulk effective sample size of draws (n_chains, n_draws): ESS of rank-normalised split chains.

    Parameters
    ----------
    draws : array-like of shape (n_chains, n_draws), or (n_draws,) for one chain
        A scalar quantity's draws (K, a log-likelihood), one row per chain.

    Returns
    -------
    float
        About ``n_chains * n_draws`` for independent draws, less for autocorrelated ones; ``nan``
        with fewer than 4 draws or a NaN/inf draw.

    Raises
    ------
    ValueError
        If ``draws`` is not 1-D or 2-D, or not convertible to float (numpy's message).

    Examples
    --------
    >>> ess_bulk(np.random.default_rng(0).normal(size=(4, 500))) > 1500  # 2000 independent draws
    True
    """
    x = _as_chains(draws)
    if x.shape[1] < 4 or not np.isfinite(x).all():
        return float("nan")
    return _ess(_z_scale(_split_chains(x)))


def ess_tail(draws: object, prob: tuple[float, float] = (0.05, 0.95)) -> float:
    """Return the tail effective sample size: the smaller ESS of the indicators ``x <= q`` at the 5 % and 95 % quantiles.

    Parameters
    ----------
    draws : array-like of shape (n_chains, n_draws), or (n_draws,) for one chain
        A scalar quantity's draws (K, a log-likelihood), one row per chain.
    prob : (float, float)
        The two quantiles.

    Returns
    -------
    float
        ``nan`` with fewer than 4 draws or a NaN/inf draw.

    Raises
    ------
    ValueError
        If ``draws`` is not 1-D or 2-D, or not convertible to float (numpy's message).

    Examples
    --------
    >>> ess_tail(np.random.default_rng(0).normal(size=(4, 500))) > 1500  # 2000 independent draws
    True
    """
    x = _as_chains(draws)
    if x.shape[1] < 4 or not np.isfinite(x).all():
        return float("nan")
    return min(_ess(_split_chains((x <= np.quantile(x, p)).astype(np.float64))) for p in prob)


def convergence_table(chains: dict[str, np.ndarray]) -> list[dict[str, object]]:
    """Return one row per quantity: R-hat, bulk and tail ESS, and whether R-hat exceeds 1.01."""
    rows = []
    for name, draws in chains.items():
        r = rhat(draws)
        rows.append(
            {
                "quantity": name,
                "R-hat": r,
                "ESS bulk": ess_bulk(draws),
                "ESS tail": ess_tail(draws),
                "converged": bool(np.isfinite(r) and r <= RHAT_THRESHOLD),
            }
        )
    return rows


ESS_TARGET = 400.0
"""Bulk ESS of K that ``n_iter="auto"`` runs to (with R-hat below :data:`RHAT_THRESHOLD`)."""


def budget_warning(model, auto: bool) -> str | None:
    """Return the warning of a fitted :class:`~tactile_torch.mixture.PitmanYorGMM`, or None when there is none.

    ``n_iter="auto"``: only when a budget ran out before the targets held, or the run stopped early
    because it could not reach them (``stop_reason_``: the evidence and the next step); it gives
    the diagnostics that missed their target and names the budget to raise. A fixed ``n_iter``: when an R-hat is
    above the threshold (the chains disagree); it suggests ``n_iter="auto"``.
    """
    n_iter = model.n_iter_
    rows = [r for r in model.convergence_ if np.isfinite(r["R-hat"])]
    if auto:
        if model.stopped_by_ == "converged":
            return None
        if model.stop_reason_:  # stopped early: the evidence, in one line
            return f"PitmanYorGMM: stopped after {n_iter} sweeps per chain: {model.stop_reason_}"
        missed = [f"{r['quantity']} {r['R-hat']:.3f}" for r in rows if not r["converged"]]
        ess = next(float(r["ESS bulk"]) for r in model.convergence_ if r["quantity"] == "K")
        what = f"R-hat {', '.join(missed) or 'below ' + str(RHAT_THRESHOLD)}, bulk ESS of K {ess:.0f}"
        budget = model.stopped_by_
        limit = model.max_iter if budget == "max_iter" else model.max_seconds
        return (
            f"PitmanYorGMM: R-hat > {RHAT_THRESHOLD} or ESS of K < {ESS_TARGET:.0f} ({what}) after {n_iter} "
            f"sweeps per chain, when the budget {budget} ran out (now {limit:g}); for the convergence "
            f"targets (R-hat < {RHAT_THRESHOLD}, ESS >= {ESS_TARGET:.0f}) raise it, e.g. {budget}={2 * limit:g}"
        )
    bad = [f"{r['quantity']} {r['R-hat']:.3f}" for r in rows if not r["converged"]]
    if not bad:
        return None
    return (
        f"PitmanYorGMM: R-hat > {RHAT_THRESHOLD} ({', '.join(bad)}) after {n_iter} sweeps per chain: the "
        "chains disagree; pass n_iter='auto' (runs until converged) or more sweeps than n_iter"
    )
