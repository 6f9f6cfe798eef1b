"""The scikit-learn estimator :class:`PitmanYorGMM`: parameters, fit, prediction and summaries (the work is in the sibling modules)."""

from __future__ import annotations

import math
import os
import time
import warnings
from numbers import Integral, Real
from typing import ClassVar

import numpy as np
from sklearn.base import BaseEstimator, ClusterMixin, _fit_context
from sklearn.utils._param_validation import Interval, StrOptions
from sklearn.utils.validation import validate_data

from ..validation import RANDOM_STATE, numpy_rng
from ._diagnostics import budget_warning
from ._mfm import coarsening_power, k_ceiling, log_v
from ._point_estimate import _whitening
from ._posterior_mixin import PosteriorMixin
from ._predict_mixin import PredictionMixin, _as_array
from ._predictive import pack_predictive

# Floor on the eigenvalues of the hyperparameter W (whitened units; see the class docstring).
W_FLOOR = 1e-10
# n_split_merge="auto": one split-merge move per this many points (at least 5 per sweep).
SPLIT_MERGE_POINTS = 40
# Sweeps with the starting partition held fixed before a chain runs (components and hyperparameters adapt).
WARM_UP_SWEEPS = 0
# Algorithm 8's auxiliary means are drawn afresh every this many points, reused in between (None: once
# per sweep, Favaro & Teh's "ReUse"; 1: before every point, as in Neal's algorithm 8).
AUX_REFRESH = None
SESSION_SCALE_START = 1.0  # starting value of lambda (the session effects' variance ratio): its prior median


def split_merge_moves(n_split_merge: int | str, n: int) -> int:
    """Split-merge moves per sweep: ``n_split_merge``, or for ``"auto"`` ``max(5, round(n / SPLIT_MERGE_POINTS))``."""
    if n_split_merge == "auto":
        return max(5, round(n / SPLIT_MERGE_POINTS))
    return int(n_split_merge)


class PitmanYorGMM(PredictionMixin, PosteriorMixin, ClusterMixin, BaseEstimator):
    """Pitman-Yor process mixture of Gaussians (infinite GMM) fitted by Gibbs sampling, several chains.

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

    **Sessions** (``fit(X, sessions=...)``, at least two): a point of session s in component j is
    ``z = mu_j + c_s + b_(s,j) + e``: an offset ``c_s ~ N(0, omega I)`` moving every component of
    the session alike (a sensor's gain), an effect ``b_(s,j) ~ N(0, lambda S_j^{-1})`` per
    (component, session) (pressure, speed, wear) and ``e ~ N(0, S_j^{-1})``, so that K counts
    surfaces rather than surface-by-day blobs; ``lambda / (1 + lambda) ~ U(0, 1)`` and ``sqrt(omega)
    ~ half-Cauchy(0, 1)``. The ``b`` are integrated out given ``(mu_j, S_j, lambda)`` and the offsets
    drawn from their normal conditionals: every step stays exact under the same prior
    (``tactile_torch/mixture/_gibbs/sessions.py``, docs/mixture.md). A new window is taken to be of
    a new session: covariance ``(1 + lambda) S_j^{-1} + omega I`` (prediction, export).

    ``Wishart(nu, V)`` has scale matrix ``V`` and mean ``nu V`` (``scipy.stats.wishart(df=nu,
    scale=V)``); ``Gamma(shape, rate)`` has mean shape/rate. On whitened data ``N(0, I)``,
    ``Wishart(D, I/D)`` are exactly Rasmussen's data-dependent hyperpriors ``N(mu_y, Sigma_y)``,
    ``Wishart(D, (D Sigma_y)^{-1})`` and ``Wishart(D, Sigma_y / D)`` stated in the original
    coordinates (the study's design writes the latter ``Sigma ~ W(D, I/D)``). The gamma priors are
    Rasmussen's ``G(1, 1/D)`` and ``G(1, 1)`` in his (shape ``a/2``, mean ``b``) convention. The
    floor on ``W`` (a truncation of its prior, sampled exactly) only matters for degenerate data,
    where the untruncated posterior is improper.

    **Sampler.** Each sweep: ``n_split_merge`` split-merge Metropolis-Hastings moves (Jain & Neal
    2007, restricted Gibbs launch states, exact proposal densities both ways); Neal's (2000)
    algorithm 8 over every point with ``m = n_aux`` auxiliary components (weight ``n_j - d`` for an
    existing component, ``(alpha + d K)/m`` for each auxiliary; the auxiliaries' precisions are
    integrated out); a Gibbs update of every component's ``S_j | mu_j`` then ``mu_j | S_j``; Gibbs
    updates of ``xi``, ``R`` and ``W``, and slice-sampling updates (Neal 2003) of
    ``log(beta - D + 1)``, ``log(alpha)`` and ``d``. Hyperparameters given as numbers are kept
    fixed. ``n_chains`` independent chains, each from its own k-means start and random stream, run
    in parallel threads (the compiled sweeps release the GIL).

    **What it reports** (see ``docs/mixture.md``):

    - *the posterior of K*, the number of components, from every post-burn-in sweep of every chain:
      its mode, median and 95 % interval (:attr:`n_clusters_summary_`, :meth:`summary`);
    - *the point estimate* ``labels_``: the partition that minimises the posterior expected loss
      over all saved partitions, Variation of Information by default (Wade & Ghahramani 2018),
      Binder's loss or the MAP sample on request (``point_estimate``). The MAP sample (the sweep
      with the largest joint density of every sampled variable) is kept as ``map_labels_``; it is
      *not* a good summary of K: the joint density is over spaces whose dimension grows with K, so
      its maximum favours few components and sits in the low tail of the posterior of K;
    - *the point estimate's components* (``means_``, ``covariances_``, ``weights_``, the exported
      graph): posterior means of the component parameters given the partition ``labels_``, from a
      short Gibbs run with the partition held fixed (the sampler's own component and
      hyperparameter updates; no label switching can occur);
    - *convergence*: rank-normalised split R-hat and bulk/tail ESS of K, alpha and d across chains
      (Vehtari et al. 2021, ArviZ's numbers); a warning when a budget of ``n_iter="auto"`` ran
      out before the targets (with a fixed ``n_iter``: when an R-hat exceeds 1.01).

    **Prediction and novelty.** :meth:`predict_proba` averages the posterior predictive over saved
    partitions: for each, the probability that a new point joins each of its components or a new
    one (weights ``n_j - d`` and ``alpha + d K``, the new component's prior predictive density by
    Monte Carlo over its precision), mapped onto the point estimate's clusters by the share of each
    component's training points in each cluster. A point is *novel* (label -1 in :meth:`predict`)
    when the probability of a new component exceeds that of every cluster. ``using="point"``
    computes the same from the point estimate's components alone, as the exported graph does.
    :meth:`calibrate_novelty` replaces the point estimate's rule by a threshold on the
    :meth:`novelty_score` (minus the log density under the point estimate's mixture), one per
    number of consecutive windows averaged (:meth:`novel_after`, ``tactile-torch stream --discover
    N``): quantiles of the scores of windows of known surfaces, so that the false-alarm rate is set
    on those windows rather than hoped for.

    Parameters
    ----------
    model : {"mfm", "pyp"}, default "mfm"
        Prior on the partition. ``"mfm"``: the mixture of finite mixtures (Miller & Harrison 2018):
        K ~ geometric on {1, 2, ...} with mean ``k_prior_mean``, weights ~ symmetric
        Dirichlet(``weight_concentration``); its posterior of K is consistent for the number of
        components, the Pitman-Yor process's is not (Miller & Harrison 2014). Same sampler, weights
        ``n_j + gamma`` and ``gamma V_n(K + 1) / V_n(K)`` (``alpha`` and ``discount`` are unused).
        ``"pyp"``: the study's Pitman-Yor process (with ``coarsen=None``, the study's model and
        prior; the draws of a seed are not those of earlier versions).
    coarsen : float or None, default None
        Coarsened posterior (Miller & Dunson 2018): the likelihood is raised to
        ``zeta = coarsen / (coarsen + n)``, which asks the model to fit the data only up to a
        discrepancy of order ``1 / coarsen`` (non-Gaussian features, session shifts) instead of
        adding components for it (needs ``model="mfm"``). ``None``: the standard posterior, the
        default: measured on five data sources (``docs/mixture.md``), the power merges real,
        separated clusters long before it merges the spurious ones, because the partition prior's
        cost of a split (about ``n`` times the entropy of the weights) is not tempered.
    k_prior_mean : float, default 10
        Mean of the geometric prior on K (``model="mfm"``).
    weight_concentration : float, default 1
        ``gamma`` of the symmetric Dirichlet prior on the weights (``model="mfm"``).
    alpha : float or None, default None
        Pitman-Yor concentration. ``None``: sampled, prior ``1/alpha ~ Gamma(1/2, 1/2)``. A number
        keeps it fixed; it must exceed ``-discount`` (or ``-1`` when the discount is sampled, whose
        support then becomes ``(max(0, -alpha), 1)``).
    discount : float or None, default None
        Pitman-Yor discount ``d`` in ``[0, 1)``. ``None``: sampled, prior ``U(0, 1)``; ``0`` gives the
        Dirichlet process.
    n_iter : int or "auto", default "auto"
        Sweeps per chain, burn-in included (4 chains x 1000 sweeps on 2 cores take the wall time of
        one chain of 2000). ``"auto"``: run 1000 sweeps, then longer rounds until the convergence
        targets hold (rank-normalised R-hat of K, and of alpha and d when sampled, below 1.01 across
        chains; bulk ESS of K at least 400), ``max_iter`` sweeps or ``max_seconds``. Each round is
        sized from the diagnostics: the run so far times ``1.2 x 400 / ESS``, clamped to [1.25, 2]
        and rounded up to a multiple of 500 sweeps. The first eighth of every chain (at least
        ``burn_in``) is discarded. ``stopped_by_`` says what ended the run.
    max_iter : int, default 40000
        Budget of ``n_iter="auto"``: most sweeps per chain. A warning says when it ran out.
    max_seconds : float or None, default 300
        Wall-clock budget of ``n_iter="auto"`` in seconds (None: none); a round is shortened to what
        the remaining time affords. A warning says when it ran out. Only this budget depends on the
        machine: a run that stops on convergence or ``max_iter`` is the same for a seed everywhere.
    burn_in : int, default 250
        Sweeps of each chain discarded from the posterior (``0 <= burn_in < n_iter``); with
        ``n_iter="auto"`` the minimum burn-in.
    n_chains : int, default 4
        Independent chains (R-hat needs at least 2).
    n_jobs : int or None, default None
        Threads running the chains; ``None``: as many as there are chains and available cores.
    n_aux : int, default 5
        Number ``m`` of auxiliary components of algorithm 8.
    init : {"kmeans", "one"}, int or array-like of shape (n,), default "kmeans"
        Starting partition of every chain: k-means (``scipy.cluster.vq.kmeans2``, k-means++ seeds
        from the chain's stream) with a generous ``ceil(2 sqrt(n))`` clusters; an int sets that
        number of k-means clusters; ``"one"`` puts every point in one component; an array gives the
        labels.
    n_split_merge : int or "auto", default "auto"
        Split-merge moves per sweep (0 disables them, leaving plain algorithm 8). ``"auto"``: one
        per ``SPLIT_MERGE_POINTS`` (40) points, at least 5: a move costs about one pass over the
        points of two components, a sweep's allocation one pass over every point and component, so
        larger data afford more moves (docs/mixture.md, "Time to a converged posterior of K").
    split_merge : {"sequential", "restricted"}, default "sequential"
        How a split is proposed. ``"sequential"``: the points of the component are allocated one by
        one, in a random order, to the part of either anchor point with probability proportional
        to its size times a Gaussian predictive given the points already there (Dahl & Newcomb
        2022), then each part draws its parameters by one Gibbs step; one pass over the points.
        ``"restricted"``: Jain & Neal's (2007) launch state and ``n_launch + 1`` restricted Gibbs
        scans (the sampler of the earlier versions). Both are exact Metropolis-Hastings moves; the
        sequential one needs one pass over the two components' points where the restricted one needs
        ``n_launch + 2`` (measured in docs/mixture.md).
    n_launch : int, default 3
        Intermediate restricted Gibbs scans of the split-merge launch states (``"restricted"``).
    near_pairs : float or None, default None
        Share of the split-merge moves whose second point is drawn among the 5 nearest neighbours
        (whitened space) of the first, the rest uniformly. Near pairs propose merges of adjacent
        components, the moves the posterior needs; the pair's probability depends on the data
        only, so the move stays exact. ``None``: 0.9 with ``model="mfm"``, 0 (uniform pairs, the
        study's sampler) with ``model="pyp"``.
    thin : int or None, default None
        Save the partition (and, after burn-in, the components) of every ``thin``-th sweep, counted
        back from the last one. ``None``: about 200 per chain. Scalar traces are kept for every sweep.
        With ``n_iter="auto"`` the partition is saved every 10 sweeps and thinned to 200 per chain
        after the burn-in (``thin`` is not used).
    point_estimate : {"vi", "binder", "map"}, default "vi"
        What ``labels_`` is: the minimiser of the expected Variation of Information, of Binder's
        loss (equal costs), or the MAP sample.
    cluster_features : int or None, default None
        Count and cluster on the first ``cluster_features`` columns of ``X`` only, and score novelty
        with all of them: the sampler, the point estimate, ``predict`` and ``predict_proba`` see
        the leading columns (e.g. the first 3 principal components, where the number of surfaces is
        counted best), while :meth:`score_samples`, :meth:`novelty_score` and the calibrated
        novelty rule use the density of every column (e.g. 5 principal components, where new
        surfaces stand out): a mixture with the point estimate's partition, its components
        estimated on all columns by the same fixed-partition Gibbs run (``density_means_``, ...).
        ``None``: every column for both.
    prior_only : bool, default False
        Ignore the data (likelihood switched off): the chain then samples the prior, which checks
        the sampler against the known prior distribution of K (a diagnostic). With ``coarsen`` the
        partition prior is the coarsened one (counts times ``zeta``).
    random_state : int, numpy.random.Generator, torch.Generator or None
        Seed of every random choice (starts, chains, Monte Carlo draws). Same seed, same result,
        whatever ``n_jobs``.
    progress : bool, default True
        Show a tqdm progress bar when the run lasts more than a second.

    Attributes
    ----------
    labels_ : ndarray of shape (n,)
        The point estimate (see ``point_estimate``), clusters numbered 0 … K-1 by decreasing size.
    n_clusters_ : int
        Number of clusters of ``labels_``.
    n_clusters_summary_ : dict
        ``mode``, ``mode_probability``, ``median``, ``mean``, ``interval`` (95 %, central),
        ``point_estimate`` (K of ``labels_``), ``map`` (K of the MAP sample).
    expected_loss_ : float
        Posterior expected loss of ``labels_``: mean VI in bits (``"vi"``, also reported for
        ``"map"``), or the expected share of misclassified pairs (``"binder"``).
    map_labels_, map_n_clusters_, map_chain_, map_sweep_, map_log_posterior_
        The MAP sample: labels (0 … K-1 by decreasing size), K, chain, sweep, log joint density.
    means_, covariances_ : ndarray of shape (K, D), (K, D, D)
        The point estimate's components in the original coordinates (posterior means given
        ``labels_``); with sessions, the covariance of a window of a new session, ``(1 + lambda) S^{-1}``.
    n_sessions_ : int
        Sessions given to ``fit`` (1: none, or one: no session effects).
    session_scale_ : float or None
        Posterior mean of lambda, the variance of a session's effect relative to a component's
        covariance (None without sessions); ``session_scale_samples_`` its post-burn-in draws.
    session_offsets_ : ndarray of shape (S, D) or None
        Posterior means of the sessions' offsets ``c_s`` in the original coordinates, from the
        point estimate's fixed-partition run (None without sessions); ``offset_variance_samples_``:
        the post-burn-in draws of omega (whitened units).
    precisions_cholesky_ : ndarray of shape (K, D, D)
        Upper-triangular ``U_k`` with precision ``U_k U_k^T`` (scikit-learn's convention).
    weights_ : ndarray of shape (K,)
        ``(n_k - d) / (n - d K)`` with the posterior means of ``d``: the probability that a new point
        joins component k, given that it joins an existing one.
    novelty_weight_ : float
        ``(alpha + d K) / (n + alpha)``: the prior probability that a new point opens a new component.
    novelty_thresholds_ : ndarray of shape (N,) or None
        Threshold of the mean :meth:`novelty_score` over N = 1, 2, ... windows, set by
        :meth:`calibrate_novelty` from windows of known surfaces; None until then (the model's own
        rule: a new component more probable than every cluster).
    alpha_, discount_ : float
        Posterior means given the point estimate.
    n_clusters_samples_, alpha_samples_, discount_samples_, beta_samples_, log_posterior_samples_, session_scale_samples_ : ndarray
        Post-burn-in values of every sweep, chains concatenated (chain-major), shape
        ``(n_chains * (n_iter - burn_in),)``.
    trace_ : dict of ndarray of shape (n_chains, n_iter)
        The same quantities for every sweep, burn-in included.
    labels_samples_ : ndarray of shape (n_chains, n_saved, n)
        Saved partitions (component numbers arbitrary per sweep) at sweeps ``labels_sweeps_``.
    convergence_ : list of dict
        R-hat, bulk and tail ESS for K, alpha and d (``nan`` R-hat with one chain).
    split_merge_stats_ : dict
        Proposed and accepted split and merge moves, all chains.
    data_mean_, data_scale_ : ndarray of shape (D,), (D, D)
        Whitening ``z = data_scale_^{-1} (x - data_mean_)`` (``data_scale_`` lower triangular).
    density_means_, density_covariances_, density_weights_ : ndarray or None
        With ``cluster_features`` below the number of columns: the mixture over every column whose
        log density is the novelty score, shapes (K, F), (K, F, F), (K,); None otherwise.
    stopped_by_ : str
        What ended the run: ``"converged"`` (the targets of ``n_iter="auto"`` hold), ``"max_iter"``
        or ``"max_seconds"`` (a budget of ``n_iter="auto"`` ran out), ``"n_iter"`` (a fixed run), or
        an early stop of ``n_iter="auto"`` when the evidence says the budget cannot reach the targets:
        ``"stuck"`` (chains in different modes of K that none leaves), ``"ceiling"`` (K at the
        largest number of components the prior allows), ``"projected"`` (the ESS of K grows too
        slowly for twice the budget).
    stop_reason_ : str or None
        For an early stop: the evidence and the next step, in one line (also the warning).
    budget_exhausted_ : bool
        Whether the convergence targets were missed when the run stopped.
    n_features_in_, n_iter_ : int
    fit_seconds_, sweep_seconds_ : float
        Wall time of ``fit``; mean time of one sweep of one chain.

    Notes
    -----
    *Degenerate data.* One point or identical points have no covariance: the whitening scale is
    then the identity. When every component holds coincident points the untruncated posterior is
    improper; the floor on ``W`` keeps the chain finite. A single point gives K = 1. D = 1 works.

    References
    ----------
    C. E. Rasmussen, "The infinite Gaussian mixture model", NIPS 12, 2000.
    D. Görür, C. E. Rasmussen, "Dirichlet process Gaussian mixture models: choice of the base
    distribution", J. Computer Science and Technology 25(4), 2010.
    R. M. Neal, "Markov chain sampling methods for Dirichlet process mixture models", JCGS 9, 2000.
    S. Jain, R. M. Neal, "Splitting and merging components of a nonconjugate Dirichlet process
    mixture model", Bayesian Analysis 2(3), 2007.
    D. B. Dahl, S. Newcomb, "Sequentially allocated merge-split samplers for conjugate Bayesian
    nonparametric models", J. Statistical Computation and Simulation 92(7), 2022.
    S. Favaro, Y. W. Teh, "MCMC for normalized random measure mixture models", Statistical Science
    28(3), 2013 (the reuse of algorithm 8's auxiliary components).
    S. Wade, Z. Ghahramani, "Bayesian cluster analysis: point estimation and credible balls",
    Bayesian Analysis 13(2), 2018.
    A. Vehtari, A. Gelman, D. Simpson, B. Carpenter, P.-C. Bürkner, "Rank-normalization, folding,
    and localization: an improved R-hat", Bayesian Analysis 16(2), 2021.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> X = np.concatenate([rng.normal(c, 0.1, size=(30, 2)) for c in (0, 3, 6)])
    >>> model = PitmanYorGMM(n_iter=400, burn_in=100, random_state=0, progress=False).fit(X)
    >>> model.n_clusters_, model.n_clusters_summary_["mode"]
    (3, 3)
    """

    _parameter_constraints: ClassVar[dict] = {
        "model": [StrOptions({"mfm", "pyp"})],
        "coarsen": [Interval(Real, 0, None, closed="neither"), None],
        "k_prior_mean": [Interval(Real, 1, None, closed="left")],
        "weight_concentration": [Interval(Real, 0, None, closed="neither")],
        "alpha": [Interval(Real, -1, None, closed="neither"), None],
        "discount": [Interval(Real, 0, 1, closed="left"), None],
        "n_iter": [Interval(Integral, 1, None, closed="left"), StrOptions({"auto"})],
        "max_iter": [Interval(Integral, 1, None, closed="left")],
        "max_seconds": [Interval(Real, 0, None, closed="neither"), None],
        "burn_in": [Interval(Integral, 0, None, closed="left")],
        "n_chains": [Interval(Integral, 1, None, closed="left")],
        "n_jobs": [Interval(Integral, 1, None, closed="left"), None],
        "n_aux": [Interval(Integral, 1, None, closed="left")],
        "init": [StrOptions({"kmeans", "one"}), Interval(Integral, 1, None, closed="left"), "array-like"],
        "n_split_merge": [Interval(Integral, 0, None, closed="left"), StrOptions({"auto"})],
        "split_merge": [StrOptions({"sequential", "restricted"})],
        "n_launch": [Interval(Integral, 0, None, closed="left")],
        "near_pairs": [Interval(Real, 0, 1, closed="both"), None],
        "thin": [Interval(Integral, 1, None, closed="left"), None],
        "point_estimate": [StrOptions({"vi", "binder", "map"})],
        "cluster_features": [Interval(Integral, 1, None, closed="left"), None],
        "prior_only": ["boolean"],
        "random_state": RANDOM_STATE,
        "progress": ["boolean"],
    }

    def __init__(  # noqa: PLR0913
        self,
        model: str = "mfm",
        coarsen: float | None = None,
        k_prior_mean: float = 10.0,
        weight_concentration: float = 1.0,
        alpha: float | None = None,
        discount: float | None = None,
        n_iter: int | str = "auto",
        max_iter: int = 40000,
        max_seconds: float | None = 300.0,
        burn_in: int = 250,
        n_chains: int = 4,
        n_jobs: int | None = None,
        n_aux: int = 5,
        init: str | int | np.ndarray = "kmeans",
        n_split_merge: int | str = "auto",
        split_merge: str = "sequential",
        n_launch: int = 3,
        near_pairs: float | None = None,
        thin: int | None = None,
        point_estimate: str = "vi",
        cluster_features: int | None = None,
        prior_only: bool = False,
        random_state: object = None,
        progress: bool = True,
    ) -> None:
        self.model = model
        self.coarsen = coarsen
        self.k_prior_mean = k_prior_mean
        self.weight_concentration = weight_concentration
        self.alpha = alpha
        self.discount = discount
        self.n_iter = n_iter
        self.max_iter = max_iter
        self.max_seconds = max_seconds
        self.burn_in = burn_in
        self.n_chains = n_chains
        self.n_jobs = n_jobs
        self.n_aux = n_aux
        self.init = init
        self.n_split_merge = n_split_merge
        self.split_merge = split_merge
        self.n_launch = n_launch
        self.near_pairs = near_pairs
        self.thin = thin
        self.point_estimate = point_estimate
        self.cluster_features = cluster_features
        self.prior_only = prior_only
        self.random_state = random_state
        self.progress = progress

    # ------------------------------------------------------------------------------------------
    # validation
    # ------------------------------------------------------------------------------------------
    def _check_params(self) -> None:
        """Validate the two hyper-parameters that constrain each other (the table is checked by ``fit``)."""
        limit, name = (self.max_iter, "max_iter") if self.n_iter == "auto" else (self.n_iter, "n_iter")
        if self.burn_in >= limit:
            raise ValueError(f"burn_in must be < {name}, got burn_in={self.burn_in}, {name}={limit}")
        if self.model == "mfm" and (self.alpha is not None or self.discount is not None):
            raise ValueError(
                f"alpha and discount apply to model='pyp' (the Pitman-Yor mixture), got alpha={self.alpha}, "
                f"discount={self.discount} with model='mfm'"
            )
        if self.model == "pyp" and self.coarsen is not None:
            raise ValueError(
                f"coarsen needs model='mfm' (the coarsened partition prior is the mixture of finite "
                f"mixtures'), got model='pyp', coarsen={self.coarsen}; pass coarsen=None with model='pyp'"
            )
        if self.alpha is not None and self.discount is not None and not self.alpha > -self.discount:
            raise ValueError(
                f"alpha must be > -discount = {-self.discount}, got alpha={self.alpha}, discount={self.discount}"
            )

    def _initial_labels(self, Xw: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        n = Xw.shape[0]
        init = self.init
        if isinstance(init, str):
            if init == "one":
                return np.zeros(n, dtype=np.int64)
            k = min(n, math.ceil(2.0 * math.sqrt(n)))
        elif isinstance(init, Integral) and not isinstance(init, bool):
            k = min(n, int(init))
        else:
            labels = np.asarray(_as_array(init))
            if labels.shape != (n,):
                raise ValueError(f"init as labels must have shape ({n},) like X's rows, got {labels.shape}")
            return np.unique(labels, return_inverse=True)[1].astype(np.int64).reshape(n)
        k = min(k, np.unique(Xw, axis=0).shape[0])  # k-means cannot make more clusters than distinct points
        if k <= 1:
            return np.zeros(n, dtype=np.int64)
        from scipy.cluster.vq import kmeans2

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # an empty cluster is dropped below
            _, labels = kmeans2(Xw, k, iter=20, minit="++", seed=rng)
        return np.unique(labels, return_inverse=True)[1].astype(np.int64)

    def _session_ids(self, sessions: object, n: int) -> np.ndarray | None:
        """Sessions as integers 0 .. S-1 (n,), or None for none or a single one; refuse what cannot be combined."""
        if sessions is None:
            return None
        labels = np.asarray(_as_array(sessions))
        if labels.shape != (n,):
            raise ValueError(f"sessions must have shape ({n},) like X's rows, got {labels.shape}")
        if labels.dtype.kind not in "iubUSO":
            raise ValueError(f"sessions must hold labels (integers or strings), got dtype {labels.dtype}")
        ids = np.unique(labels.astype(str) if labels.dtype.kind == "O" else labels, return_inverse=True)[1]
        ids = ids.astype(np.int64).reshape(n)
        if ids.max(initial=0) < 1:
            return None
        if self.coarsen is not None:
            raise ValueError(
                f"coarsen cannot be combined with sessions (the session effects are integrated out under the "
                f"standard likelihood), got coarsen={self.coarsen}; pass coarsen=None or no sessions"
            )
        if self.split_merge != "sequential":
            raise ValueError(f"sessions need split_merge='sequential', got split_merge={self.split_merge!r}")
        return ids

    # ------------------------------------------------------------------------------------------
    # fit
    # ------------------------------------------------------------------------------------------
    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X: object, y: object = None, sessions: object = None) -> PitmanYorGMM:
        """Run the chains on ``X`` of shape (n_samples, n_features); return ``self``.

        ``X`` is an array-like or a tensor; ``y`` is ignored (present for scikit-learn pipelines).
        ``sessions`` (n_samples,): the session (day) of every row, any labels (*Sessions* above);
        ``None`` or a single session: no session effects.
        """
        t_fit = time.perf_counter()
        self._check_params()
        # the compiled kernels load here, at the first fit of a process, not at import
        from . import _gibbs as g
        from ._chains import Chains, chain_attributes, neighbours, run_to_targets, warm_up

        X = validate_data(self, _as_array(X), dtype=np.float64)
        rng = numpy_rng(self.random_state)
        n, F = X.shape
        session_ids = self._session_ids(sessions, n)
        D = F if self.cluster_features is None else int(self.cluster_features)
        if D > F:
            raise ValueError(
                f"cluster_features must be at most the number of columns of X ({F}), got {self.cluster_features}"
            )
        mean, scale = _whitening(X[:, :D])
        Xw = np.ascontiguousarray(np.linalg.solve(scale, (X[:, :D] - mean).T).T)
        mfm = self.model == "mfm"
        fit_alpha, fit_d = self.alpha is None and not mfm, self.discount is None and not mfm
        d_low, alpha0, d0, gamma, lv = self._prior_start(n, fit_alpha, fit_d)
        zeta = coarsening_power(self.coarsen, n)
        self.zeta_ = zeta
        auto = self.n_iter == "auto"
        n_iter = int(self.max_iter) if auto else int(self.n_iter)
        burn_in, n_chains = int(self.burn_in), int(self.n_chains)
        thin = int(self.thin) if self.thin is not None else max(1, math.ceil(n_iter / 200))
        snap_sweeps = np.arange(n_iter - 1, -1, -thin)[::-1]
        cfg = g.Settings(
            n_aux=int(self.n_aux),
            n_split_merge=split_merge_moves(self.n_split_merge, n),
            n_launch=int(self.n_launch),
            use_lik=not bool(self.prior_only),
            fit_alpha=fit_alpha,
            fit_d=fit_d,
            allocate=True,
            d_low=float(d_low),
            w_min=W_FLOOR,
            burn_in=burn_in,
            near=float(self.near_pairs if self.near_pairs is not None else (0.9 if mfm else 0.0)),
            sequential=self.split_merge == "sequential",
            refresh=max(1, n) if AUX_REFRESH is None else AUX_REFRESH,
            fit_lambda=session_ids is not None,
        )
        nbr = neighbours(Xw) if cfg.near > 0 and cfg.n_split_merge > 0 else np.zeros((n, 0), dtype=np.int64)
        chain_rngs = rng.spawn(n_chains)
        states = []
        for c in range(n_chains):
            lam = 0.0 if session_ids is None else SESSION_SCALE_START
            st = g.new_state(
                self._initial_labels(Xw, chain_rngs[c]), D, alpha0, d0, zeta, gamma, lv, session_ids, lam
            )
            g.init_components(Xw, st, cfg.use_lik, chain_rngs[c])
            warm_up(Xw, st, cfg, chain_rngs[c], WARM_UP_SWEEPS)
            states.append(st)
        workers = self.n_jobs or min(
            n_chains,
            len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1),
        )
        chains = Chains(Xw, states, cfg, chain_rngs, nbr, workers, bool(self.progress))
        quantities = ("n_clusters",) + ("alpha",) * fit_alpha + ("discount",) * fit_d
        ceiling = k_ceiling(n) if mfm else None
        runs, snap_sweeps, n_iter, burn_in, self.stopped_by_, self.stop_reason_, self.budget_exhausted_ = (
            run_to_targets(chains, n_iter, burn_in, snap_sweeps, quantities, auto, self.max_seconds, ceiling)
        )
        self.n_features_in_ = F
        self.n_sessions_ = 1 if session_ids is None else int(session_ids.max()) + 1
        self.data_mean_, self.data_scale_ = mean, scale
        self.n_iter_ = n_iter
        for name, value in chain_attributes(
            runs, snap_sweeps, burn_in, self.alpha is None and not mfm, self.discount is None and not mfm
        ).items():
            setattr(self, name, value)
        self.session_scale_ = None if session_ids is None else float(np.mean(self.session_scale_samples_))
        if session_ids is None:
            self.session_scale_samples_ = self.offset_variance_samples_ = None
        self._store_point_estimate(Xw, runs, cfg, rng, X if D < F else None)
        self._pred = pack_predictive(runs, n, self.labels_, rng, float(self.k_prior_mean))
        self.sweep_seconds_ = float(np.mean([r["seconds"] for r in runs]) / n_iter)
        self.fit_seconds_ = time.perf_counter() - t_fit
        warning = budget_warning(self, auto)
        if warning:
            warnings.warn(warning, RuntimeWarning, stacklevel=2)
        return self

    def _prior_start(self, n: int, fit_alpha: bool, fit_d: bool) -> tuple:
        """(d_low, alpha0, d0, gamma, log V or None): the partition prior's bounds and the chains' start."""
        mfm = self.model == "mfm"
        d_low = max(0.0, -float(self.alpha)) if (not fit_alpha and fit_d) else 0.0
        alpha0 = 1.0 if fit_alpha else float(self.alpha or 0.0)
        d0 = (d_low + 0.5 * (1.0 - d_low) if d_low > 0 else 0.25) if fit_d else float(self.discount or 0.0)
        gamma = float(self.weight_concentration) if mfm else 0.0
        if mfm:
            return d_low, 0.0, -gamma, gamma, log_v(n, gamma, float(self.k_prior_mean))
        return d_low, alpha0, d0, gamma, None

    def fit_predict(self, X: object, y: object = None, sessions: object = None) -> np.ndarray:
        """Fit (``sessions`` as :meth:`fit`'s) and return ``labels_``, the point estimate of the partition."""
        return self.fit(X, sessions=sessions).labels_
