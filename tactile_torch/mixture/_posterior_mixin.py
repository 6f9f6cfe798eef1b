"""Methods of a fitted :class:`~tactile_torch.mixture.PitmanYorGMM` that store and summarise its posterior: the point estimate, K, similarity, export."""

from __future__ import annotations

import math

import numpy as np
from sklearn.utils.validation import check_is_fitted

from ._point_estimate import _whitening, choose_partition, partition_components
from ._summaries import n_clusters_posterior, n_clusters_summary, summary_text


class PosteriorMixin:
    """The point estimate and the summaries of a fitted :class:`~tactile_torch.mixture.PitmanYorGMM`."""

    def _saved_partitions(self) -> np.ndarray:
        """Post-burn-in saved partitions of every chain, (n_saved_total, n) int64."""
        keep = self.labels_sweeps_ >= self._burn_in
        return self.labels_samples_[:, keep].reshape(-1, self.labels_samples_.shape[-1]).astype(np.int64)

    def _store_point_estimate(
        self, Xw: np.ndarray, runs: list[dict], cfg, rng, X_all: np.ndarray | None
    ) -> None:
        labels, loss = choose_partition(self._saved_partitions(), self.map_labels_, self.point_estimate)
        self.labels_ = labels
        self.n_clusters_ = int(labels.max()) + 1
        self.expected_loss_ = loss
        self.n_clusters_summary_ = n_clusters_summary(
            self.n_clusters_samples_, self.n_clusters_, self.map_n_clusters_
        )
        c = partition_components(
            Xw, labels, self._map_state, cfg, rng, self.data_mean_, self.data_scale_, float(self.k_prior_mean)
        )
        self.alpha_, self.discount_ = c.alpha, c.discount
        self.weights_, self.novelty_weight_ = c.weights, c.novelty_weight
        self.means_, self.covariances_ = c.means, c.covariances
        self.precisions_cholesky_ = c.precisions_cholesky
        self.session_offsets_ = c.offsets
        self._components = c
        self._density = None
        self.density_means_ = self.density_covariances_ = self.density_weights_ = None
        if X_all is not None:  # novelty scored on every column: the partition's components there
            mean, scale = _whitening(X_all)
            Zw = np.ascontiguousarray(np.linalg.solve(scale, (X_all - mean).T).T)
            d = partition_components(
                Zw,
                labels,
                self._map_state,
                cfg,
                rng,
                mean,
                scale,
                float(self.k_prior_mean),
                same_features=False,
            )
            self._density = d
            self.density_means_, self.density_covariances_, self.density_weights_ = (
                d.means,
                d.covariances,
                d.weights,
            )
        self.novelty_thresholds_ = None  # the model's own rule until calibrate_novelty

    def n_clusters_posterior(self) -> dict[int, float]:
        """Return the posterior distribution of K (share of post-burn-in sweeps of all chains), as {K: probability}."""
        check_is_fitted(self)
        return n_clusters_posterior(self.n_clusters_samples_)

    def n_components_posterior(self) -> dict[int, float]:
        """Return the posterior of the number of *components* K (empty ones included), as {K: probability}.

        Mixture of finite mixtures: the Rao-Blackwellised estimate ``mean over sweeps of P(K | T =
        t_s)`` from the number of occupied clusters ``t_s`` of each post-burn-in sweep (Miller &
        Harrison 2018; :func:`~tactile_torch.mixture._mfm.components_given_clusters`), exact given
        the sampled ``t``. It is at least the posterior of the clusters (K >= T; with ``n`` far
        above K the two nearly coincide). Its precision is that of the sampled ``t``: being a
        function of ``t`` per sweep, it has the ESS of K's trace. Pitman-Yor: the process has
        infinitely many components, so this raises ``ValueError``.
        """
        check_is_fitted(self)
        if self.model != "mfm":
            raise ValueError(
                "n_components_posterior needs model='mfm' (a Pitman-Yor process has infinitely many components)"
            )
        from ._mfm import components_given_clusters

        n = self.zeta_ * len(self.labels_)
        ts, counts = np.unique(self.n_clusters_samples_, return_counts=True)
        span = 200
        total = np.zeros(int(ts.max()) + span + 1)
        for t, c in zip(ts, counts, strict=True):
            p = components_given_clusters(
                n, float(self.weight_concentration), float(self.k_prior_mean), int(t), span
            )
            total[: p.size] += c * p
        total /= counts.sum()
        return {int(k): float(v) for k, v in enumerate(total) if v > 1e-9}

    def posterior_similarity(self) -> np.ndarray:
        """Return the posterior similarity matrix (n, n): probability that two training points share a component."""
        check_is_fitted(self)
        from ._partition import posterior_similarity

        return posterior_similarity(self._saved_partitions())

    def summary(self) -> str:
        """Return a readable summary: the posterior of K first, then the point estimate, the MAP sample, convergence."""
        check_is_fitted(self)
        return summary_text(self)

    def to_module(self):
        """Return the point estimate's mixture as a torch module ``features (B, D) -> (labels, log_resp, novel, novelty)``.

        Components: ``means_``, ``precisions_cholesky_``, ``log(weights_)``. ``novelty`` is
        :meth:`novelty_score` (minus the log density). ``novel``: once :meth:`calibrate_novelty` has
        run, ``novelty > novelty_thresholds_[0]`` (the thresholds travel as a buffer); before, a
        row is novel when ``log novelty_weight_ + log p_new(x)`` exceeds ``log((1 -
        novelty_weight_) w_k) + log N(x | k)`` for every k, with ``p_new`` the prior predictive
        density of a new component approximated by an equal mixture of 64 Gaussians ``N(xi, S^{-1}
        + R^{-1})`` (``S`` drawn from its prior, hyperparameters from the fixed-partition run).
        Either way exactly :meth:`predict` with ``using="point"``.
        """
        check_is_fitted(self)
        from ._inference import GaussianMixtureClassifier

        density = self._density
        return GaussianMixtureClassifier(
            self.means_,
            self.precisions_cholesky_,
            np.log(self.weights_),
            novelty_means=self._components.novelty_means,
            novelty_precisions_cholesky=self._components.novelty_precisions_cholesky,
            novelty_log_weight=math.log(self.novelty_weight_) - math.log(1.0 - self.novelty_weight_),
            novelty_thresholds=self.novelty_thresholds_,
            density_means=None if density is None else density.means,
            density_precisions_cholesky=None if density is None else density.precisions_cholesky,
            density_log_weights=None if density is None else np.log(density.weights),
            cluster_features=None if density is None else self.means_.shape[1],
        )
