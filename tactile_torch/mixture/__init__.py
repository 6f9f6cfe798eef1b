"""Pitman-Yor process mixture of Gaussians, fitted by Gibbs sampling: how many surfaces, and which is which.

:class:`PitmanYorGMM` is the unsupervised half of method 2: an infinite Gaussian mixture
(Rasmussen 2000) with a Pitman-Yor prior on the partition, sampled with Neal's (2000) algorithm 8
plus split-merge moves (Jain & Neal 2007), several chains in parallel. The inner loop is compiled
with numba (:mod:`tactile_torch._gibbs`): 10,000 sweeps over the study's 1,400 windows take seconds
rather than hours.

It reports the posterior of the number of components K (mode, median, interval), a point estimate of
the partition from all saved samples (:func:`minimize_expected_loss`, Wade & Ghahramani 2018), the
posterior similarity matrix (:func:`posterior_similarity`), convergence diagnostics across chains
(:func:`rhat`, :func:`ess_bulk`, :func:`ess_tail`), predictions with novelty (label -1), and an
exportable torch graph (:class:`GaussianMixtureClassifier`). :func:`baseline_clusterings` runs the
study's scikit-learn baselines.

Submodules: ``_estimator`` (the estimator), ``_partition`` (partitions: prior of K, similarity,
point estimates), ``_diagnostics`` (R-hat, ESS), ``_inference`` (torch graph), ``_baselines``.
The torch graph is imported on first use, so that fitting does not import torch.
"""

from __future__ import annotations

from ._baselines import baseline_clusterings
from ._diagnostics import ess_bulk, ess_tail, rhat
from ._estimator import PitmanYorGMM
from ._partition import (
    expected_loss,
    minimize_expected_loss,
    pitman_yor_prior_k,
    posterior_similarity,
    variation_of_information,
)

_TORCH = {"GaussianMixtureClassifier", "gaussian_mixture_scores"}


def __getattr__(name: str):
    if name in _TORCH:
        from . import _inference

        return getattr(_inference, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "GaussianMixtureClassifier",
    "PitmanYorGMM",
    "baseline_clusterings",
    "ess_bulk",
    "ess_tail",
    "expected_loss",
    "gaussian_mixture_scores",
    "minimize_expected_loss",
    "pitman_yor_prior_k",
    "posterior_similarity",
    "rhat",
    "variation_of_information",
]
