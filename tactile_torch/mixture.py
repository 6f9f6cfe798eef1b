"""Pitman-Yor process mixture of Gaussians, fitted by Gibbs sampling: how many surfaces, and which is which.

:class:`PitmanYorGMM` is the unsupervised half of method 2 (DESIGN.md): an infinite Gaussian mixture
(Rasmussen 2000) with a Pitman-Yor prior on the partition, sampled with Neal's (2000) algorithm 8
plus split-merge moves (Jain & Neal 2007) so that the chain finds the number of components from any
start. The inner loop is compiled with numba (:mod:`tactile_torch._gibbs`): 10,000 sweeps over the
study's 1,400 windows take seconds rather than hours.

:func:`baseline_clusterings` runs the study's scikit-learn baselines; :func:`gaussian_mixture_scores`
and :class:`GaussianMixtureClassifier` evaluate a fitted mixture with torch ops (exportable to ONNX).
"""

from __future__ import annotations

import math
import numbers
import time
from collections.abc import Mapping

import numpy as np
import torch
from scipy.linalg import solve_triangular
from sklearn.base import BaseEstimator, ClusterMixin

from ._checks import RandomState, as_feature_matrix, numpy_rng

__all__ = [
    "GaussianMixtureClassifier",
    "PitmanYorGMM",
    "baseline_clusterings",
    "gaussian_mixture_scores",
    "pitman_yor_prior_k",
]

# Floor on the eigenvalues of the hyperparameter W (whitened units; see the class docstring).
W_FLOOR = 1e-10
# Columns of the per-sweep trace.
_TRACE_NAMES = ("n_clusters", "alpha", "discount", "beta", "log_posterior")


_as_features = as_feature_matrix


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


def pitman_yor_prior_k(n: int, alpha: float, discount: float) -> np.ndarray:
    """Return the prior distribution of the number of clusters K of n points under a Pitman-Yor prior.

    Chinese-restaurant recursion: customer ``m + 1`` opens a new table with probability
    ``(alpha + K d) / (alpha + m)``. Entry ``k`` of the result (length ``n + 1``) is ``P(K = k)``.

    Examples
    --------
    >>> p = pitman_yor_prior_k(3, 1.0, 0.0)  # DP, alpha = 1: P(K=1) = 1/3, P(K=3) = 1/6
    >>> [round(float(v), 4) for v in p]
    [0.0, 0.3333, 0.5, 0.1667]
    """
    if not (0.0 <= discount < 1.0) or not alpha > -discount:
        raise ValueError(
            f"need 0 <= discount < 1 and alpha > -discount, got alpha={alpha}, discount={discount}"
        )
    p = np.zeros(n + 1)
    p[1] = 1.0
    k = np.arange(n + 1)
    for m in range(1, n):
        new = np.zeros(n + 1)
        new[1:] = p[:-1] * (alpha + k[:-1] * discount) / (alpha + m)
        p = p * (m - k * discount) / (alpha + m) + new
    return p


def _check_choice(value: object, name: str, lo: float, hi: float, *, lo_open: bool, hi_open: bool) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
        raise TypeError(f"{name} must be a finite real number or None, got {value!r}")
    ok_lo = value > lo if lo_open else value >= lo
    ok_hi = value < hi if hi_open else value <= hi
    if not (ok_lo and ok_hi):
        interval = f"{'(' if lo_open else '['}{lo}, {hi}{')' if hi_open else ']'}"
        raise ValueError(f"{name} must lie in {interval}, got {value!r}")
    return float(value)


def _check_int(value: object, name: str, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name} must be an integer, got {value!r}")
    if value < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {value!r}")
    return int(value)


class PitmanYorGMM(ClusterMixin, BaseEstimator):
    """Pitman-Yor process mixture of Gaussians (infinite GMM) fitted by Gibbs sampling.

    **Model.** Data are first whitened: ``z = A^{-1}(x - m)`` with ``m`` the data mean and
    ``A A^T`` the data covariance (ddof=1; see *Degenerate data*). On whitened data the model is
    Rasmussen's (2000) infinite Gaussian mixture in its multivariate, conditionally conjugate form
    (Görür & Rasmussen 2010) with a Pitman-Yor prior on the partition::

        partition          ~ PY(alpha, d)                  (Chinese restaurant; d = 0: Dirichlet process)
        z_i | component j  ~ N(mu_j, S_j^{-1})             (S_j: precision)
        mu_j               ~ N(xi, R^{-1})
        S_j                ~ Wishart(beta, (beta W)^{-1})  (so E[S_j] = W^{-1})
        xi ~ N(0, I),  R ~ Wishart(D, I/D),  W ~ Wishart(D, I/D) restricted to W >= 1e-10 I
        1/(beta - D + 1) ~ Gamma(shape 1/2, rate D/2),  1/alpha ~ Gamma(shape 1/2, rate 1/2),  d ~ U(0, 1)

    ``Wishart(nu, V)`` has scale matrix ``V`` and mean ``nu V`` (``scipy.stats.wishart(df=nu,
    scale=V)``); ``Gamma(shape, rate)`` has mean shape/rate. On whitened data ``N(0, I)``,
    ``Wishart(D, I/D)`` are exactly Rasmussen's data-dependent hyperpriors ``N(mu_y, Sigma_y)``,
    ``Wishart(D, (D Sigma_y)^{-1})`` and ``Wishart(D, Sigma_y / D)`` stated in the original
    coordinates (DESIGN.md writes the latter ``Sigma ~ W(D, I/D)``). The gamma priors are
    Rasmussen's ``G(1, 1/D)`` and ``G(1, 1)`` in his (shape ``a/2``, mean ``b``) convention, which
    for D = 1 reduce to his univariate ``beta^{-1} ~ G(1, 1)``. The floor on ``W`` (a truncation
    of its prior, sampled exactly: see below) only matters for degenerate data, where the
    untruncated posterior is improper.

    **Sampler.** Each sweep: ``n_split_merge`` split-merge Metropolis-Hastings moves; Neal's (2000)
    algorithm 8 over every point with ``m = n_aux`` auxiliary components (weight ``n_j - d`` for an
    existing component, ``(alpha + d K)/m`` for each auxiliary, auxiliaries drawn from the base
    measure except that a point alone in its component hands it its parameters); a Gibbs update of
    every component's ``S_j | mu_j`` (Wishart) then ``mu_j | S_j`` (normal); Gibbs updates of
    ``xi``, ``R`` and ``W`` (the truncated ``W`` by an independence Metropolis step whose proposal is
    the untruncated conditional, accepted iff it satisfies the floor), and slice-sampling updates
    (Neal 2003) of ``log(beta - D + 1)``, ``log(alpha)`` and ``d`` from their conditionals, the
    latter two through the Pitman-Yor exchangeable partition probability function, with the
    Jacobians of the log transforms. Hyperparameters given as numbers are kept fixed.

    The split-merge moves are Jain & Neal's (2007) restricted-Gibbs moves for non-conjugate
    mixtures: two points ``i != j`` are drawn uniformly; if they share a component a split is
    proposed, otherwise a merge of their two components. The launch state of the split puts every
    other point of the two components with the nearer of ``x_i``, ``x_j`` (data only, never the
    current labels, so the launch is the same for a split and for the reverse of a merge) and then
    alternates ``n_launch`` restricted Gibbs scans of labels and parameters; the merge launch
    updates one component's parameters ``n_launch + 1`` times. The proposal is one more restricted
    scan (labels, then parameters) from the launch state; the acceptance probability has the exact
    proposal densities of both directions, the Pitman-Yor prior ratio
    ``(alpha + d K) Gamma(n_A - d) Gamma(n_B - d) / (Gamma(1 - d) Gamma(n_A + n_B - d))``, the
    base-measure densities and the likelihoods. Single-site Gibbs alone splits a merged cluster only
    by rare luck (it must empty it point by point); these moves do it in one step.

    **Outputs.** The *MAP sample* is the post-burn-in sweep with the largest unnormalised log
    joint density of every sampled variable (labels, component parameters, hyperparameters) on the
    whitened data. ``labels_``, ``means_``, ``covariances_``, ``weights_``, :meth:`predict`,
    :meth:`predict_proba` and :meth:`score_samples` all come from it (not averaged over samples:
    labels are not identifiable across samples). The posterior over the number of components comes
    from all post-burn-in sweeps.

    Parameters
    ----------
    alpha : float or None, default None
        Pitman-Yor concentration. ``None``: sampled, prior ``1/alpha ~ Gamma(1/2, 1/2)``. A number
        keeps it fixed; it must exceed ``-discount`` (or ``-1`` when the discount is sampled, whose
        support then becomes ``(max(0, -alpha), 1)``).
    discount : float or None, default None
        Pitman-Yor discount ``d`` in ``[0, 1)``. ``None``: sampled, prior ``U(0, 1)``; ``0`` gives the
        Dirichlet process.
    n_iter : int, default 2000
        Number of sweeps, burn-in included.
    burn_in : int, default 500
        Sweeps discarded from the posterior summaries and the MAP search (``0 <= burn_in < n_iter``).
    n_aux : int, default 5
        Number ``m`` of auxiliary components of algorithm 8.
    init : {"kmeans", "one"}, int or array-like of shape (n,), default "kmeans"
        Starting partition: k-means (scikit-learn, seeded from ``random_state``) with a generous
        ``ceil(2 sqrt(n))`` clusters (at most n); an int sets that number of k-means clusters;
        ``"one"`` puts every point in one component; an array gives the labels. The chain reaches
        the posterior from any of them: single-site moves merge excess clusters, split-merge moves
        split merged ones.
    n_split_merge : int, default 5
        Split-merge moves per sweep (0 disables them, leaving plain algorithm 8).
    n_launch : int, default 3
        Intermediate restricted Gibbs scans of the split-merge launch states.
    thin : int or None, default None
        Keep the labels of every ``thin``-th sweep (burn-in included) in ``labels_samples_``.
        ``None``: about 200 snapshots. Scalar traces are kept for every sweep.
    prior_only : bool, default False
        Ignore the data (likelihood switched off): the chain then samples the prior, which checks
        the sampler against the known prior distribution of K (a diagnostic; predictions are
        meaningless).
    random_state : int, numpy.random.Generator, torch.Generator or None
        Seed of every random choice (k-means start and the chain). Same seed, same result.
    progress : bool, default True
        Show a tqdm progress bar when the run lasts more than a second.

    Attributes
    ----------
    labels_ : ndarray of shape (n,)
        Component of every training point in the MAP sample, numbered 0 … K-1 by decreasing size.
    n_clusters_ : int
        Number of components K of the MAP sample.
    means_, covariances_ : ndarray of shape (K, D), (K, D, D)
        MAP components in the original coordinates.
    precisions_cholesky_ : ndarray of shape (K, D, D)
        Upper-triangular ``U_k`` with precision ``U_k U_k^T`` (scikit-learn's convention):
        ``log N(x) = sum(log diag U_k) - D/2 log(2 pi) - |(x - mean_k) @ U_k|^2 / 2``.
    weights_ : ndarray of shape (K,)
        ``(n_k - d) / (n - d K)``: the Pitman-Yor predictive probability that a new point joins
        component k, given that it joins an existing one (used by :meth:`predict`).
    alpha_, discount_ : float
        Their values in the MAP sample.
    n_clusters_samples_, alpha_samples_, discount_samples_, beta_samples_, log_posterior_samples_ : ndarray
        Post-burn-in values, one per sweep.
    trace_ : dict of ndarray
        The same quantities for every sweep, burn-in included (keys ``n_clusters``, ``alpha``,
        ``discount``, ``beta``, ``log_posterior``).
    labels_samples_ : ndarray of shape (n_saved, n)
        Labels at the sweeps ``labels_sweeps_`` (component ids are arbitrary per sweep).
    map_sweep_ : int
        Sweep index of the MAP sample.
    split_merge_stats_ : dict
        Proposed and accepted split and merge moves.
    data_mean_, data_scale_ : ndarray of shape (D,), (D, D)
        Whitening ``z = data_scale_^{-1} (x - data_mean_)`` (``data_scale_`` lower triangular).
    n_features_in_, n_iter_ : int
    fit_seconds_, sweep_seconds_ : float
        Wall time of ``fit`` and of one sweep (mean; excluding compilation and start-up).

    Notes
    -----
    *Degenerate data.* One point or identical points have no covariance: the whitening scale is
    then the identity. When every component holds coincident points (identical points, or a
    constant feature) the untruncated posterior is improper (the precision can grow without
    bound); the floor on ``W`` keeps the chain finite. A single point gives K = 1. D = 1 works.

    References
    ----------
    C. E. Rasmussen, "The infinite Gaussian mixture model", NIPS 12, 2000.
    D. Görür, C. E. Rasmussen, "Dirichlet process Gaussian mixture models: choice of the base
    distribution", J. Computer Science and Technology 25(4), 2010.
    R. M. Neal, "Markov chain sampling methods for Dirichlet process mixture models", JCGS 9, 2000.
    S. Jain, R. M. Neal, "Splitting and merging components of a nonconjugate Dirichlet process
    mixture model", Bayesian Analysis 2(3), 2007.
    J. Pitman, M. Yor, "The two-parameter Poisson-Dirichlet distribution ...", Ann. Probab. 25, 1997.
    R. M. Neal, "Slice sampling", Ann. Statist. 31, 2003.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> X = np.concatenate([rng.normal(c, 0.1, size=(30, 2)) for c in (0, 3, 6)])
    >>> model = PitmanYorGMM(n_iter=200, burn_in=50, random_state=0, progress=False).fit(X)
    >>> model.n_clusters_
    3
    """

    def __init__(
        self,
        alpha: float | None = None,
        discount: float | None = None,
        n_iter: int = 2000,
        burn_in: int = 500,
        n_aux: int = 5,
        init: str | int | np.ndarray = "kmeans",
        n_split_merge: int = 5,
        n_launch: int = 3,
        thin: int | None = None,
        prior_only: bool = False,
        random_state: RandomState = None,
        progress: bool = True,
    ) -> None:
        self.alpha = alpha
        self.discount = discount
        self.n_iter = n_iter
        self.burn_in = burn_in
        self.n_aux = n_aux
        self.init = init
        self.n_split_merge = n_split_merge
        self.n_launch = n_launch
        self.thin = thin
        self.prior_only = prior_only
        self.random_state = random_state
        self.progress = progress

    # ------------------------------------------------------------------------------------------
    def _check_params(self) -> tuple[float | None, float | None, float]:
        n_iter = _check_int(self.n_iter, "n_iter", 1)
        burn_in = _check_int(self.burn_in, "burn_in", 0)
        if burn_in >= n_iter:
            raise ValueError(f"burn_in must be < n_iter, got burn_in={burn_in}, n_iter={n_iter}")
        _check_int(self.n_aux, "n_aux", 1)
        _check_int(self.n_split_merge, "n_split_merge", 0)
        _check_int(self.n_launch, "n_launch", 0)
        if self.thin is not None:
            _check_int(self.thin, "thin", 1)
        discount = None
        if self.discount is not None:
            discount = _check_choice(self.discount, "discount", 0.0, 1.0, lo_open=False, hi_open=True)
        alpha = None
        if self.alpha is not None:
            lo = -discount if discount is not None else -1.0
            alpha = _check_choice(self.alpha, "alpha", lo, math.inf, lo_open=True, hi_open=True)
        d_low = max(0.0, -alpha) if (alpha is not None and discount is None) else 0.0
        return alpha, discount, d_low

    def _initial_labels(self, Xw: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        n = Xw.shape[0]
        init = self.init
        if isinstance(init, str):
            if init == "one":
                return np.zeros(n, dtype=np.int64)
            if init != "kmeans":
                raise ValueError(
                    f"init must be 'kmeans', 'one', an int or an array of n labels, got {init!r}"
                )
            k = min(n, math.ceil(2.0 * math.sqrt(n)))
        elif isinstance(init, numbers.Integral) and not isinstance(init, bool):
            if init < 1:
                raise ValueError(f"init as a number of k-means clusters must be >= 1, got {init}")
            k = min(n, int(init))
        else:
            labels = np.asarray(init.detach().cpu().numpy() if isinstance(init, torch.Tensor) else init)
            if labels.shape != (n,):
                raise ValueError(f"init as labels must have shape ({n},) like X's rows, got {labels.shape}")
            return np.unique(labels, return_inverse=True)[1].astype(np.int64).reshape(n)
        k = min(k, np.unique(Xw, axis=0).shape[0])  # k-means cannot make more clusters than distinct points
        if k == 1:
            return np.zeros(n, dtype=np.int64)
        from sklearn.cluster import KMeans

        km = KMeans(n_clusters=k, n_init=1, random_state=int(rng.integers(2**31 - 1)))
        labels = km.fit_predict(Xw)
        return np.unique(labels, return_inverse=True)[1].astype(np.int64)

    # ------------------------------------------------------------------------------------------
    def fit(self, X: object, y: object = None) -> PitmanYorGMM:
        """Run the Gibbs sampler on ``X`` of shape (n_samples, n_features); return ``self``.

        ``X`` is an array-like or a tensor; ``y`` is ignored (present for scikit-learn pipelines).
        """
        from . import _gibbs as g

        t_fit = time.perf_counter()
        alpha, discount, d_low = self._check_params()
        X = _as_features(X)
        rng = numpy_rng(self.random_state)
        n, D = X.shape
        mean, scale = _whitening(X)
        Xw = np.ascontiguousarray(solve_triangular(scale, (X - mean).T, lower=True).T)
        z0 = self._initial_labels(Xw, rng)
        K0 = int(z0.max()) + 1

        cap = n + 1
        z = z0.copy()
        cnt = np.zeros(cap, dtype=np.int64)
        np.add.at(cnt, z, 1)
        mu = np.zeros((cap, D))
        L = np.zeros((cap, D, D))
        ldet = np.zeros(cap)
        act = np.zeros(cap, dtype=np.int64)
        act[:K0] = np.arange(K0)
        pos = -np.ones(cap, dtype=np.int64)
        pos[:K0] = np.arange(K0)
        fre = np.zeros(cap, dtype=np.int64)
        free_slots = np.arange(cap - 1, K0 - 1, -1)
        fre[: free_slots.size] = free_slots
        ist = np.array([K0, free_slots.size], dtype=np.int64)
        sc = np.array([1.0 if alpha is None else alpha, 0.25 if discount is None else discount, float(D)])
        if discount is None and d_low > 0.0:
            sc[1] = d_low + 0.5 * (1.0 - d_low)
        xi = np.zeros(D)
        R = np.eye(D)
        GR = np.eye(D)
        W = np.eye(D)
        GW = np.eye(D)
        use_lik = not self.prior_only
        # Start each component from a draw of its conditional given its initial points.
        means = np.zeros(D)
        for j in range(K0):
            pts = Xw[z == j]
            cm = pts.mean(axis=0)
            dev = pts - cm
            scat = dev.T @ dev
            ldet[j] = g.component_step(
                pts.shape[0] if use_lik else 0, cm, scat, cm.copy() if use_lik else means,
                sc[2], W, R, R @ xi, True, mu[j], L[j], 0.0, rng,
            )[1]  # fmt: skip

        n_iter = int(self.n_iter)
        burn_in = int(self.burn_in)
        thin = int(self.thin) if self.thin is not None else max(1, math.ceil(n_iter / 200))
        snaps = np.zeros(((n_iter - 1) // thin + 1, n), dtype=np.int32)
        snap_sweeps = np.arange(0, n_iter, thin)
        trace = np.zeros((n_iter, len(_TRACE_NAMES)))
        counters = np.zeros(4, dtype=np.int64)
        fit_alpha, fit_d = alpha is None, discount is None
        n_sm, n_launch, n_aux = int(self.n_split_merge), int(self.n_launch), int(self.n_aux)
        state = {"z": z, "cnt": cnt, "mu": mu, "L": L, "ldet": ldet, "act": act, "ist": ist, "sc": sc}
        best = {k: v.copy() for k, v in state.items()}
        best_val = -np.inf

        def run(start: int, count: int) -> None:
            # One sweep = split-merge moves, Neal-8 allocation, components, hyperparameters; each a
            # compiled kernel (the Python loop costs microseconds per sweep).
            nonlocal best_val
            for s in range(start, start + count):
                if n_sm:
                    g.split_merge_moves(
                        n_sm, Xw, z, cnt, mu, L, ldet, act, pos, fre, ist, sc, xi, R, GR, W, GW,
                        n_launch, use_lik, rng, counters,
                    )  # fmt: skip
                g.allocate(Xw, z, cnt, mu, L, ldet, act, pos, fre, ist, sc, xi, GR, W, n_aux, use_lik, rng)
                g.update_components(Xw, z, cnt, mu, L, ldet, act, ist, sc, xi, R, W, use_lik, rng)
                g.update_hyper(
                    mu, L, ldet, act, ist, n, cnt, sc, xi, R, GR, W, GW, fit_alpha, fit_d, d_low, W_FLOOR, rng
                )
                lj = g.log_joint(Xw, z, cnt, mu, L, ldet, act, ist, sc, xi, R, GR, W, GW, use_lik)
                trace[s] = (ist[0], sc[0], sc[1], sc[2], lj)
                if s % thin == 0:
                    snaps[s // thin] = z
                if s >= burn_in and lj > best_val:
                    best_val = lj
                    for k, v in state.items():
                        np.copyto(best[k], v)

        sampling_seconds = self._run_chunks(run, n_iter, n)
        self._store_results(X, mean, scale, trace, snaps, snap_sweeps, counters, best, best_val, burn_in)
        self.n_iter_ = n_iter
        self.sweep_seconds_ = sampling_seconds / n_iter
        self.fit_seconds_ = time.perf_counter() - t_fit
        return self

    def _run_chunks(self, run, n_iter: int, n: int) -> float:
        """Run the sweeps in chunks of about 0.2 s between progress-bar updates; return sampling seconds."""
        from tqdm.auto import tqdm

        bar = tqdm(
            total=n_iter, disable=not self.progress, delay=1.0, unit="sweep", desc="PitmanYorGMM", leave=False
        )
        done = 0
        chunk = 1
        seconds = 0.0
        try:
            while done < n_iter:
                count = min(chunk, n_iter - done)
                t0 = time.perf_counter()
                run(done, count)
                dt = time.perf_counter() - t0
                if done > 0:  # the first call may include numba's compilation or cache load
                    seconds += dt
                else:
                    first = dt
                done += count
                bar.update(count)
                chunk = max(1, min(10 * chunk, int(count * 0.2 / max(dt, 1e-6))))
        finally:
            bar.close()
        if n_iter == 1 or seconds == 0.0:
            return first
        return seconds * n_iter / (n_iter - 1)

    def _store_results(self, X, mean, scale, trace, snaps, snap_sweeps, counters, best, best_val, burn_in):
        from . import _gibbs as g

        D = X.shape[1]
        self.n_features_in_ = D
        self.data_mean_ = mean
        self.data_scale_ = scale
        self.trace_ = {k: trace[:, c].copy() for c, k in enumerate(_TRACE_NAMES)}
        self.trace_["n_clusters"] = self.trace_["n_clusters"].astype(np.int64)
        self.n_clusters_samples_ = self.trace_["n_clusters"][burn_in:]
        self.alpha_samples_ = self.trace_["alpha"][burn_in:]
        self.discount_samples_ = self.trace_["discount"][burn_in:]
        self.beta_samples_ = self.trace_["beta"][burn_in:]
        self.log_posterior_samples_ = self.trace_["log_posterior"][burn_in:]
        self.labels_samples_ = snaps
        self.labels_sweeps_ = snap_sweeps
        self.split_merge_stats_ = {
            "split_proposed": int(counters[g.SPLIT_PROPOSED]),
            "split_accepted": int(counters[g.SPLIT_ACCEPTED]),
            "merge_proposed": int(counters[g.MERGE_PROPOSED]),
            "merge_accepted": int(counters[g.MERGE_ACCEPTED]),
        }
        # MAP sample: components ordered by decreasing size.
        K = int(best["ist"][0])
        slots = best["act"][:K]
        sizes = best["cnt"][slots]
        order = np.argsort(-sizes, kind="stable")
        slots = slots[order]
        relabel = np.full(best["cnt"].shape[0], -1, dtype=np.int64)
        relabel[slots] = np.arange(K)
        self.labels_ = relabel[best["z"]]
        self.map_sweep_ = int(burn_in + np.argmax(self.log_posterior_samples_))
        self.map_log_posterior_ = float(best_val)
        self.alpha_, self.discount_ = float(best["sc"][0]), float(best["sc"][1])
        self.n_clusters_ = K
        d = self.discount_
        sizes = best["cnt"][slots].astype(np.float64)
        self.weights_ = (sizes - d) / (sizes.sum() - d * K)
        self._mu_w = best["mu"][slots].copy()
        self._L_w = best["L"][slots].copy()
        self._ldet_w = best["ldet"][slots].copy()
        # Original coordinates: x = m + A z, so mean = m + A mu and covariance = A S^{-1} A^T.
        self.means_ = mean + self._mu_w @ scale.T
        covs = np.empty((K, D, D))
        prec_chol = np.empty((K, D, D))
        for k in range(K):
            # S^{-1} = L^{-T} L^{-1}; A S^{-1} A^T = B B^T with B = A L^{-T}
            B = solve_triangular(self._L_w[k], scale.T, lower=True, trans="N").T
            covs[k] = B @ B.T
            prec_chol[k] = self._precision_cholesky(covs[k], scale, self._L_w[k])
        self.covariances_ = covs
        self.precisions_cholesky_ = prec_chol

    @staticmethod
    def _precision_cholesky(cov: np.ndarray, scale: np.ndarray, L: np.ndarray) -> np.ndarray:
        """Upper ``U`` with ``U U^T`` = the precision in original coordinates, ``A^{-T} L L^T A^{-1}``."""
        try:
            C = np.linalg.cholesky(cov)
            return solve_triangular(C, np.eye(cov.shape[0]), lower=True).T
        except np.linalg.LinAlgError:
            # Covariance too ill-conditioned to factor: use A^{-T} L, a (non-triangular) valid factor.
            return solve_triangular(scale, L, lower=True, trans="T")

    # ------------------------------------------------------------------------------------------
    def _check_fitted(self) -> None:
        if not hasattr(self, "labels_"):
            raise RuntimeError("this PitmanYorGMM is not fitted yet: call fit(X) first")

    def _component_log_joint(self, X: object) -> np.ndarray:
        """(n, K) ``log weight_k + log N(x | component k)`` in the original coordinates."""
        self._check_fitted()
        X = _as_features(X, n_features=self.n_features_in_)
        D = X.shape[1]
        Zw = solve_triangular(self.data_scale_, (X - self.data_mean_).T, lower=True).T
        # ||L_k^T (z - mu_k)||^2 for every point and component, batched over components
        diff = Zw[:, None, :] - self._mu_w[None, :, :]
        y = np.einsum("nkd,kde->nke", diff, self._L_w)
        quad = np.einsum("nke,nke->nk", y, y)
        log_jac = float(np.log(np.diag(self.data_scale_)).sum())
        return (
            np.log(self.weights_)
            + 0.5 * self._ldet_w
            - 0.5 * D * math.log(2 * math.pi)
            - 0.5 * quad
            - log_jac
        )

    def predict(self, X: object) -> np.ndarray:
        """Return the most likely MAP component (0 … K-1) of every row of ``X`` (n, D), shape (n,)."""
        return np.argmax(self._component_log_joint(X), axis=1)

    def predict_proba(self, X: object) -> np.ndarray:
        """Return the responsibilities of the MAP components for every row of ``X``: shape (n, K), rows sum to 1."""
        lj = self._component_log_joint(X)
        lj -= lj.max(axis=1, keepdims=True)
        p = np.exp(lj)
        return p / p.sum(axis=1, keepdims=True)

    def score_samples(self, X: object) -> np.ndarray:
        """Return the log density of every row of ``X`` under the MAP mixture (original coordinates), shape (n,)."""
        lj = self._component_log_joint(X)
        mx = lj.max(axis=1, keepdims=True)
        return (mx + np.log(np.exp(lj - mx).sum(axis=1, keepdims=True)))[:, 0]

    def fit_predict(self, X: object, y: object = None) -> np.ndarray:
        """Fit and return ``labels_`` (the MAP labels of the training points)."""
        return self.fit(X).labels_

    # ------------------------------------------------------------------------------------------
    def n_clusters_posterior(self) -> dict[int, float]:
        """Return the posterior distribution of K (share of post-burn-in sweeps), as {K: probability}."""
        self._check_fitted()
        values, counts = np.unique(self.n_clusters_samples_, return_counts=True)
        return {int(v): float(c) / self.n_clusters_samples_.size for v, c in zip(values, counts, strict=True)}

    def summary(self) -> str:
        """Return a readable summary of the posterior over K and of the hyperparameters."""
        self._check_fitted()
        post = self.n_clusters_posterior()
        ks = self.n_clusters_samples_
        mode = max(post, key=post.get)
        lo, hi = np.quantile(ks, [0.025, 0.975])
        lines = [
            f"PitmanYorGMM: {self.n_iter_} sweeps ({len(ks)} after burn-in), {self.sweep_seconds_ * 1e3:.2f} ms/sweep",
            f"K: mode {mode} (p = {post[mode]:.3f}), mean {ks.mean():.2f}, 95% interval [{lo:g}, {hi:g}], "
            f"MAP sample K = {self.n_clusters_} (sweep {self.map_sweep_})",
            "P(K): " + ", ".join(f"{k}: {p:.3f}" for k, p in sorted(post.items(), key=lambda kv: -kv[1])[:8]),
        ]
        for name, s in (
            ("alpha", self.alpha_samples_),
            ("d", self.discount_samples_),
            ("beta", self.beta_samples_),
        ):
            q = np.quantile(s, [0.025, 0.5, 0.975])
            lines.append(f"{name}: median {q[1]:.3g}, 95% interval [{q[0]:.3g}, {q[2]:.3g}]")
        st = self.split_merge_stats_
        lines.append(
            f"split-merge: {st['split_accepted']}/{st['split_proposed']} splits, "
            f"{st['merge_accepted']}/{st['merge_proposed']} merges accepted"
        )
        return "\n".join(lines)

    def to_module(self) -> GaussianMixtureClassifier:
        """Return the MAP mixture as a torch module ``features (B, D) -> (labels (B,), log_resp (B, K))``."""
        self._check_fitted()
        return GaussianMixtureClassifier(self.means_, self.precisions_cholesky_, np.log(self.weights_))


# ----------------------------------------------------------------------------------------------
# torch inference (exportable)
# ----------------------------------------------------------------------------------------------
def gaussian_mixture_scores(
    x: torch.Tensor, means: torch.Tensor, precisions_cholesky: torch.Tensor, log_weights: torch.Tensor
) -> torch.Tensor:
    """Return ``log w_k + log N(x | mean_k, (U_k U_k^T)^{-1})`` for every row and component: (B, K).

    Parameters
    ----------
    x : tensor (B, D)
    means : tensor (K, D)
    precisions_cholesky : tensor (K, D, D)
        ``U_k`` with precision ``U_k U_k^T`` (scikit-learn's ``precisions_cholesky_`` convention; any
        such factor works, triangular or not).
    log_weights : tensor (K,)

    Examples
    --------
    >>> s = gaussian_mixture_scores(torch.zeros(1, 2), torch.zeros(1, 2), torch.eye(2)[None], torch.zeros(1))
    >>> round(float(s), 4)  # log N(0 | 0, I) in 2-D = -log(2 pi)
    -1.8379
    """
    D = x.shape[-1]
    y = torch.einsum("bd,kde->bke", x, precisions_cholesky) - torch.einsum(
        "kd,kde->ke", means, precisions_cholesky
    )
    log_det = torch.log(torch.diagonal(precisions_cholesky, dim1=-2, dim2=-1).abs()).sum(-1)
    return log_weights + log_det - 0.5 * D * math.log(2 * math.pi) - 0.5 * (y * y).sum(-1)


class GaussianMixtureClassifier(torch.nn.Module):
    """Most likely component of a Gaussian mixture: ``x (B, D) -> (labels (B,) int64, log_resp (B, K))``.

    Holds ``means`` (K, D), ``precisions_cholesky`` (K, D, D) and ``log_weights`` (K,) as buffers
    (float32 by default) and calls :func:`gaussian_mixture_scores`; exports to ONNX with a dynamic
    batch. ``log_resp`` are the log responsibilities (rows log-sum-exp to 0).
    """

    def __init__(
        self,
        means: object,
        precisions_cholesky: object,
        log_weights: object,
        dtype: torch.dtype = torch.float32,
    ) -> None:
        super().__init__()
        self.register_buffer("means", torch.as_tensor(np.asarray(means), dtype=dtype))
        self.register_buffer(
            "precisions_cholesky", torch.as_tensor(np.asarray(precisions_cholesky), dtype=dtype)
        )
        self.register_buffer("log_weights", torch.as_tensor(np.asarray(log_weights), dtype=dtype))

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        scores = gaussian_mixture_scores(x, self.means, self.precisions_cholesky, self.log_weights)
        log_resp = scores - torch.logsumexp(scores, dim=-1, keepdim=True)
        return torch.argmax(scores, dim=-1), log_resp


# ----------------------------------------------------------------------------------------------
# scikit-learn baselines of the study (Table 2)
# ----------------------------------------------------------------------------------------------
def baseline_clusterings(
    X: object,
    n_clusters: int,
    *,
    max_components: int | None = None,
    random_state: RandomState = None,
) -> dict[str, Mapping[str, object]]:
    """Return the labels of the study's scikit-learn baselines on ``X`` (n, D).

    - ``kmeans``: :class:`sklearn.cluster.KMeans` given the true K (10 restarts);
    - ``em``: :class:`sklearn.mixture.GaussianMixture` (full covariances) given K (5 restarts);
    - ``em_bic``: EM with K chosen in 1 … ``max_components`` by BIC (= MDL up to a factor 1/2);
    - ``variational_dp``: :class:`sklearn.mixture.BayesianGaussianMixture` with a Dirichlet-process
      prior and ``max_components`` components; its K is the number of components that own points.

    ``max_components`` defaults to ``min(n, max(2 n_clusters, 10))``. Each value is a dict with
    ``labels`` (n,), ``n_clusters`` and ``seconds`` (fit time).
    """
    from sklearn.cluster import KMeans
    from sklearn.mixture import BayesianGaussianMixture, GaussianMixture

    X = _as_features(X)
    n = X.shape[0]
    n_clusters = _check_int(n_clusters, "n_clusters", 1)
    if n_clusters > n:
        raise ValueError(f"n_clusters must be <= the number of samples {n}, got {n_clusters}")
    kmax = (
        min(n, max(2 * n_clusters, 10))
        if max_components is None
        else _check_int(max_components, "max_components", 1)
    )
    seed = int(numpy_rng(random_state).integers(2**31 - 1))
    out: dict[str, Mapping[str, object]] = {}

    def record(name: str, fn) -> None:
        t0 = time.perf_counter()
        labels = np.asarray(fn())
        out[name] = {
            "labels": labels,
            "n_clusters": int(np.unique(labels).size),
            "seconds": time.perf_counter() - t0,
        }

    record("kmeans", lambda: KMeans(n_clusters, n_init=10, random_state=seed).fit_predict(X))
    record("em", lambda: GaussianMixture(n_clusters, n_init=5, random_state=seed).fit(X).predict(X))

    def em_bic() -> np.ndarray:
        fits = [GaussianMixture(k, n_init=1, random_state=seed).fit(X) for k in range(1, kmax + 1)]
        return min(fits, key=lambda gm: gm.bic(X)).predict(X)

    record("em_bic", em_bic)
    record(
        "variational_dp",
        lambda: (
            BayesianGaussianMixture(
                n_components=kmax,
                weight_concentration_prior_type="dirichlet_process",
                max_iter=500,
                random_state=seed,
            )
            .fit(X)
            .predict(X)
        ),
    )
    return out
