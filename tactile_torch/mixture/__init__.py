"""Pitman-Yor process mixture of Gaussians, fitted by Gibbs sampling: how many surfaces, and which is which.

:class:`PitmanYorGMM` is the unsupervised half of method 2: an infinite Gaussian mixture
(Rasmussen 2000) with a Pitman-Yor prior on the partition, sampled with Neal's (2000) algorithm 8
plus split-merge moves (Jain & Neal 2007), several chains in parallel. The inner loop is compiled
with numba (:mod:`tactile_torch.mixture._gibbs`): 10,000 sweeps over the study's 1,400 windows take seconds
rather than hours.

It reports the posterior of the number of components K (mode, median, interval), a point estimate of
the partition from all saved samples (:func:`minimize_expected_loss`, Wade & Ghahramani 2018), the
posterior similarity matrix (:func:`posterior_similarity`), convergence diagnostics across chains
(:func:`rhat`, :func:`ess_bulk`, :func:`ess_tail`), predictions with novelty (label -1), and an
exportable torch graph (:class:`GaussianMixtureClassifier`). :func:`baseline_clusterings` runs the
study's scikit-learn baselines.

Submodules: ``_estimator`` (the estimator), ``_chains`` (running the chains), ``_point_estimate``
(the point estimate's partition and components), ``_predictive`` (prediction), ``_summaries``
(posterior of K, the readable summary), ``_partition`` (partitions: prior of K, similarity, point
estimates), ``_diagnostics`` (R-hat, ESS), ``_inference`` (torch graph), ``_baselines``.

Every name is imported on first use, so that a path that needs one part does not pay for the
others: the torch graph alone imports neither scikit-learn nor numba, and the compiled sampler loads
at the first ``fit`` of a process, not at import.
"""

from .._exports import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {
        "_estimator": ("PitmanYorGMM",),
        "_baselines": ("baseline_clusterings",),
        "_diagnostics": ("ess_bulk", "ess_tail", "rhat"),
        "_partition": (
            "expected_loss",
            "minimize_expected_loss",
            "pitman_yor_prior_k",
            "posterior_similarity",
            "variation_of_information",
        ),
        "_inference": ("GaussianMixtureClassifier", "gaussian_mixture_scores"),
        "_novelty": ("window_means",),
    },
)
