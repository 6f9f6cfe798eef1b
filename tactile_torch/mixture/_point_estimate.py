"""The point estimate of a fitted :class:`PitmanYorGMM`: its partition and its components.

The partition is chosen from all saved partitions (:func:`choose_partition`, the minimiser of the
posterior expected loss of :mod:`._partition`); its components are posterior means given that
partition, from a short Gibbs run with the partition held fixed (:func:`partition_components`),
together with the Gaussians of the Monte Carlo prior predictive of a new component (novelty). Every
function works on whitened data unless it says otherwise; the estimator documents the model.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

# Sweeps of the fixed-partition run that gives the point estimate's components (first quarter discarded).
_FIXED_SWEEPS = 160
# Gaussians of the Monte Carlo prior predictive of a new component (novelty).
_NOVELTY_DRAWS = 64
# At most this many saved partitions (all chains) estimate the expected loss of the point estimate.
_POINT_ESTIMATE_SAMPLES = 200
# Above this many points the similarity matrix (n x n) is not formed for the search's starts.
_SIMILARITY_MAX_POINTS = 4000


def choose_partition(saved: np.ndarray, map_labels: np.ndarray, kind: str) -> tuple[np.ndarray, float]:
    """Return ``(labels, expected loss)`` of the point estimate ``kind`` ("vi", "binder" or "map").

    ``saved``: post-burn-in partitions of every chain (n_saved, n); the expected loss is estimated
    over at most ``_POINT_ESTIMATE_SAMPLES`` of them, evenly spaced. ``"map"`` reports the MAP
    sample's expected VI.
    """
    from ._partition import expected_loss, minimize_expected_loss, posterior_similarity

    n = saved.shape[1]
    similarity = posterior_similarity(saved) if n <= _SIMILARITY_MAX_POINTS else None
    saved = saved[
        np.unique(np.linspace(0, len(saved) - 1, min(len(saved), _POINT_ESTIMATE_SAMPLES)).astype(int))
    ]
    if kind == "map":
        return map_labels, expected_loss(map_labels, saved, "vi")
    return minimize_expected_loss(saved, kind, candidates=[map_labels], similarity=similarity)


def wishart_cholesky(rng: np.random.Generator, dof: float, scale_chol: np.ndarray) -> np.ndarray:
    """Lower Cholesky factor of a Wishart(dof, C C^T) draw (Bartlett), ``scale_chol`` = C."""
    D = scale_chol.shape[0]
    A = np.tril(rng.standard_normal((D, D)), -1)
    A[np.diag_indices(D)] = np.sqrt(rng.chisquare(dof - np.arange(D)))
    return scale_chol @ A


def new_component_gaussian(xi, GR, GW, beta, rng, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """One Gaussian of the Monte Carlo prior predictive of a new component (whitened): (mean, covariance).

    ``x | S ~ N(xi, c S^{-1} + R^{-1})`` with ``mu`` integrated out, ``S ~ Wishart(beta, (beta W)^{-1})``
    and ``c = scale`` (``1 + lambda`` with session effects: a window of a new session; else 1).
    With ``beta W = F F^T`` (``F = sqrt(beta) GW``) and ``A`` a Bartlett factor of ``Wishart(beta, I)``,
    ``S = F^{-T} A A^T F^{-1}``, so ``S^{-1} = M^T M`` with ``M = A^{-1} F^T``: no inverse of a
    possibly ill-conditioned ``W`` is formed.
    """
    D = xi.shape[0]
    A = wishart_cholesky(rng, beta, np.eye(D))
    # (scipy.linalg.solve_triangular took milliseconds per 3 x 3 call on a busy machine; numpy does not)
    M = np.linalg.solve(A, math.sqrt(beta) * GW.T)
    N = np.linalg.inv(GR)  # R^{-1} = N^T N
    return xi.copy(), scale * (M.T @ M) + N.T @ N


def new_session_terms(sc: np.ndarray) -> tuple[float, float]:
    """``(1 + lambda, omega)`` of a chain's scalars ``sc``: a window of a new session has covariance ``(1 + lambda) S^{-1} + omega I``.

    Its session's offset (``N(0, omega I)``) and its effect in the component (``N(0, lambda
    S^{-1})``) are unknown, so both are integrated out (whitened units); ``(1, 0)`` without sessions.
    """
    if sc[5] > 0.0:
        return 1.0 + float(sc[5]), float(sc[6])
    return 1.0, 0.0


def precision_cholesky(cov: np.ndarray) -> np.ndarray:
    """Upper ``U`` with ``U U^T`` = ``cov^{-1}`` (scikit-learn's ``precisions_cholesky_``)."""
    D = cov.shape[0]
    try:
        C = np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        level = float(np.trace(cov)) / D
        C = np.linalg.cholesky(cov + 1e-12 * max(level, 1e-300) * np.eye(D))
    return np.linalg.inv(C).T


class Components(NamedTuple):
    """The point estimate's mixture in the original coordinates (see the estimator's attributes)."""

    means: np.ndarray
    covariances: np.ndarray
    precisions_cholesky: np.ndarray
    weights: np.ndarray
    novelty_weight: float
    alpha: float
    discount: float
    novelty_means: np.ndarray
    novelty_precisions_cholesky: np.ndarray
    offsets: np.ndarray | None = None
    """Posterior means of the sessions' offsets (S, D), original coordinates; None without sessions."""


def partition_components(
    Xw, labels, map_state, cfg, rng, data_mean, data_scale, k_mean=10.0, *, same_features=True
) -> Components:
    """Return the components of the partition ``labels``: posterior means from a fixed-partition Gibbs run.

    With session effects (``map_state.sc[5] > 0``, the points' sessions in ``map_state.sess``) the
    covariances are those of a window of a *new* session, ``(1 + lambda) S^{-1} + omega I`` (its
    offset and effect integrated out, :func:`new_session_terms`), averaged over the run as lambda
    and omega are sampled; so are the novelty Gaussians.

    The run starts from the MAP sample's hyperparameters (``same_features``; otherwise, for
    features other than the chains', from the prior's centre: ``xi = 0``, ``R = W = I``, ``beta =
    D``, the partition prior's parameters kept) and uses the sampler's own component and
    hyperparameter updates (``cfg`` with ``allocate=False``), ``_FIXED_SWEEPS`` sweeps of which the
    last three quarters are averaged; no label switching can occur. ``_NOVELTY_DRAWS`` Gaussians of
    the prior predictive of a new component are drawn along the run. ``data_mean`` and
    ``data_scale`` map the whitened results back to the original coordinates.
    """
    from . import _gibbs as g

    n, D = Xw.shape
    K = int(labels.max()) + 1
    NO_NEIGHBOURS = np.zeros((n, 0), dtype=np.int64)  # no split-merge moves: the partition is fixed
    NO_SNAPSHOTS, NO_LABELS = np.zeros(0, dtype=np.int64), np.zeros((0, n), dtype=np.int32)
    st = g.new_state(labels, D, float(map_state.sc[0]), float(map_state.sc[1]), sessions=map_state.sess)
    if same_features:
        for name in ("sc", "xi", "R", "GR", "W", "GW"):  # lv is not used: the partition is fixed
            np.copyto(getattr(st, name), getattr(map_state, name))
    else:
        for k in (0, 1, 3, 4, 5, 6):  # alpha, d, zeta, gamma, lambda, omega; beta stays at D
            st.sc[k] = map_state.sc[k]
    fixed = cfg._replace(allocate=False, burn_in=_FIXED_SWEEPS)
    g.init_components(Xw, st, fixed.use_lik, rng)
    trace = np.zeros((_FIXED_SWEEPS, len(g.TRACE_NAMES)))
    kept = _FIXED_SWEEPS - _FIXED_SWEEPS // 4
    mus, covs, scs, novelty = np.zeros((K, D)), np.zeros((K, D, D)), np.zeros(st.sc.size), []
    offs = np.zeros_like(st.off)
    unused = g.ChainState(*(a.copy() for a in st))
    for s in range(_FIXED_SWEEPS):
        g.run_sweeps(
            Xw, st, fixed, rng, s, 1, trace, np.zeros(4, dtype=np.int64), unused, np.array([np.inf]),
            NO_NEIGHBOURS, NO_SNAPSHOTS, NO_LABELS,
        )  # fmt: skip
        if s < _FIXED_SWEEPS - kept:
            continue
        Linv = np.linalg.inv(st.L[:K])  # S^{-1} = L^{-T} L^{-1}
        scale, offset = new_session_terms(st.sc)
        mus += st.mu[:K]
        offs += st.off
        covs += scale * (np.swapaxes(Linv, 1, 2) @ Linv) + offset * np.eye(D)
        scs += st.sc
        if len(novelty) < _NOVELTY_DRAWS and (s % max(1, kept // _NOVELTY_DRAWS) == 0):
            xi, cov = new_component_gaussian(st.xi, st.GR, st.GW, st.sc[2], rng, scale)
            novelty.append((xi, cov + offset * np.eye(D)))
    mus /= kept
    covs /= kept
    scs /= kept
    alpha, d, gamma = float(scs[0]), float(scs[1]), float(scs[4])
    sizes = np.bincount(labels, minlength=K).astype(np.float64)
    weights = (sizes - d) / (n - d * K)
    if gamma > 0.0:
        from ._mfm import predictive_weights

        log_join, log_new = predictive_weights(n, sizes, alpha, d, gamma, k_mean)
        novelty_weight = math.exp(log_new)
        weights = np.exp(log_join) / np.exp(log_join).sum()
    else:
        novelty_weight = float((alpha + d * K) / (n + alpha))
    A, m = data_scale, data_mean
    covariances = A @ covs @ A.T
    return Components(
        means=m + mus @ A.T,
        covariances=covariances,
        precisions_cholesky=np.stack([precision_cholesky(c) for c in covariances]),
        weights=weights,
        novelty_weight=novelty_weight,
        alpha=alpha,
        discount=d,
        novelty_means=np.stack([m + A @ mu for mu, _ in novelty]),
        novelty_precisions_cholesky=np.stack([precision_cholesky(A @ c @ A.T) for _, c in novelty]),
        offsets=(offs / kept) @ A.T if st.sc[5] > 0.0 else None,
    )


def _whitening(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return (mean, lower Cholesky factor A of the data covariance) so that ``A^{-1}(x - mean)`` is white.

    Covariance with ddof=1, plus a ridge of 1e-9 of its mean variance so that collinear features
    still factorise; when the data have no spread at all (one point, or identical points) the
    scale is the identity.
    """
    mean = X.mean(axis=0)
    D = X.shape[1]
    cov = np.cov(X, rowvar=False, ddof=1).reshape(D, D) if X.shape[0] > 1 else np.zeros((D, D))
    level = float(np.trace(cov)) / D
    if not level > 0.0:
        return mean, np.eye(D)
    return mean, np.linalg.cholesky(cov + 1e-9 * level * np.eye(D))
