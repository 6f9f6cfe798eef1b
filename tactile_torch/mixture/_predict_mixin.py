"""Prediction with a fitted :class:`PitmanYorGMM`: clusters, novelty (one window or N), densities.

:class:`PredictionMixin` holds the methods that use a fitted mixture (the estimator's fit is in
:mod:`._estimator`); the numerical work is in :mod:`._predictive` and :mod:`._novelty`.
"""

from __future__ import annotations

import math
from numbers import Integral, Real

import numpy as np
from sklearn.utils.validation import check_is_fitted, validate_data

from ._novelty import calibrate_thresholds, novel_after
from ._predictive import normalise, point_scores, posterior_predictive

# Rows further than this from the data mean (whitened units) are novel by definition (prediction).
_BEYOND = 1e100


def _as_array(X: object) -> object:
    if type(X).__module__.startswith("torch"):
        return X.detach().cpu().numpy()
    return X


class PredictionMixin:
    """Methods of a fitted :class:`PitmanYorGMM` that classify, score and flag new rows."""

    def _checked(self, X: object) -> np.ndarray:
        """``X`` validated against the fit (every column)."""
        check_is_fitted(self)
        return validate_data(self, _as_array(X), dtype=np.float64, reset=False)

    def _whiten(self, X: object) -> np.ndarray:
        X = self._checked(X)[:, : self.data_mean_.size]  # the columns the chains clustered
        return np.linalg.solve(self.data_scale_, (X - self.data_mean_).T).T

    def _cluster_and_new(self, X: object, using: str) -> tuple[np.ndarray, np.ndarray]:
        """(n, K) log probability of joining each cluster and (n,) of a new component.

        A row more than ``_BEYOND`` whitened units from the data mean (where every Gaussian log
        density overflows the float range) is novel by definition: log P(new) = 0, the clusters
        equally likely.
        """
        if using not in ("samples", "point"):
            raise ValueError(f"using must be 'samples' or 'point', got {using!r}")
        Z = self._whiten(X)
        beyond = np.abs(Z).max(axis=1) > _BEYOND
        if using == "samples":
            log_joint, log_new = posterior_predictive(Z, self._pred, self.n_clusters_)
        else:
            log_joint, log_new = normalise(*self._point_scores(X))
        log_joint[beyond] = -math.log(self.n_clusters_)
        log_new[beyond] = 0.0
        return log_joint, log_new

    def _point_scores(self, X: object) -> tuple[np.ndarray, np.ndarray]:
        return point_scores(self._checked(X)[:, : self.data_mean_.size], self._components)

    def predict(self, X: object, *, using: str = "samples") -> np.ndarray:
        """Return the cluster (0 … K-1) of every row of ``X`` (n, D), or -1 where it is novel; shape (n,).

        ``using="samples"``: the posterior predictive averaged over saved partitions (default);
        ``"point"``: the point estimate's components, as in the exported graph. A row is novel when
        a new component is more probable than every cluster (the model's own rule), or, with
        ``using="point"`` once :meth:`calibrate_novelty` has run, when its :meth:`novelty_score`
        exceeds the calibrated threshold. A row more than 1e100 whitened units from the data is
        novel by definition.
        """
        joint, new = self._cluster_and_new(X, using)
        labels = np.argmax(joint, axis=1)
        if using == "point" and self.novelty_thresholds_ is not None:
            labels[self.novelty_score(X) > self.novelty_thresholds_[0]] = -1
        else:
            labels[new > joint.max(axis=1)] = -1
        return labels

    def novelty_score(self, X: object) -> np.ndarray:
        """Return the novelty score of every row of ``X``: minus its log density under the point estimate's mixture, shape (n,).

        ``-score_samples(X)``: the exported graph's ``novelty`` output. Finite for every finite row.
        """
        return -self.score_samples(X)

    def calibrate_novelty(
        self, X: object, *, false_alarm: float = 0.02, max_windows: int = 10, groups: object = None
    ) -> PredictionMixin:
        """Set ``novelty_thresholds_`` from windows ``X`` of known surfaces (not used in fit); return ``self``.

        For N = 1 … ``max_windows``, the threshold of N is the ``1 - false_alarm`` quantile (the
        sample value just above) of the mean :meth:`novelty_score` over every N consecutive rows
        of ``X`` (rows in time order; ``groups`` (n,), e.g. the recording of each row, keeps runs
        within one group). At most ``false_alarm`` of these windows' decisions are then novel by
        construction; on later windows it holds as far as they resemble these. Used by
        ``predict(using="point")``, :meth:`novel_after` and the exported graph.
        """
        if not (isinstance(false_alarm, Real) and 0.0 < false_alarm < 1.0):
            raise ValueError(f"false_alarm must be a number in (0, 1), got {false_alarm!r}")
        if isinstance(max_windows, bool) or not isinstance(max_windows, Integral) or max_windows < 1:
            raise ValueError(f"max_windows must be an int >= 1, got {max_windows!r}")
        score = self.novelty_score(X)
        groups = None if groups is None else np.asarray(groups).ravel()
        if groups is not None and groups.shape != score.shape:
            raise ValueError(
                f"groups must have one entry per row of X ({score.size}), got shape {groups.shape}"
            )
        if score.size < 1:
            raise ValueError("calibrate_novelty needs at least one row of X")
        self.novelty_thresholds_ = calibrate_thresholds(score, float(false_alarm), int(max_windows), groups)
        return self

    def novel_after(self, X: object, n_windows: int = 1, *, groups: object = None) -> np.ndarray:
        """Return the novelty decision after ``n_windows`` consecutive rows ending at each row, shape (n,) bool.

        Calibrated (:meth:`calibrate_novelty`): the mean :meth:`novelty_score` of the
        ``n_windows`` rows exceeds the threshold of that N (beyond ``max_windows``, the last
        threshold). Not calibrated: the ``n_windows`` rows are all novel by the model's own rule
        (``predict(using="point") == -1``). Rows in time order (``groups`` (n,): runs stay within
        a group; the first ``n_windows - 1`` rows of a group get False). The decision
        ``tactile-torch stream --discover N`` makes.
        """
        if isinstance(n_windows, bool) or not isinstance(n_windows, Integral) or n_windows < 1:
            raise ValueError(f"n_windows must be an int >= 1, got {n_windows!r}")
        n = int(n_windows)
        groups = None if groups is None else np.asarray(groups).ravel()
        t = self.novelty_thresholds_
        if t is None:  # n flags in a row <=> their mean is 1
            flags = (self.predict(X, using="point") == -1).astype(float)
            return novel_after(flags, np.full(n, 1.0 - 0.5 / n), n, groups)
        t = np.r_[t, np.full(max(0, n - t.size), t[-1])]
        return novel_after(self.novelty_score(X), t, n, groups)

    def predict_proba(self, X: object, *, using: str = "samples") -> np.ndarray:
        """Return the probability of each cluster for every row of ``X``, given that it joins one: (n, K), rows sum to 1."""
        from scipy.special import softmax

        log_joint, _ = self._cluster_and_new(X, using)
        return softmax(log_joint, axis=1)  # log space: finite for every finite row (see LOG_FLOOR)

    def novelty_proba(self, X: object, *, using: str = "samples") -> np.ndarray:
        """Return the probability that each row of ``X`` opens a new component (a new surface), shape (n,)."""
        return np.exp(self._cluster_and_new(X, using)[1])

    def score_samples(self, X: object) -> np.ndarray:
        """Return the log density of every row of ``X`` under the point estimate's mixture (``weights_``), shape (n,).

        With ``cluster_features`` below the number of columns: under the mixture over every column
        (``density_means_``, ...), whose partition is the point estimate's.

        Finite for every finite row: a density below ``exp(-1.8e308)`` (a point ~1e154 standard
        deviations from every component) is reported as ``-1.8e308``.
        """
        from ._predictive import LOG_FLOOR, log_gauss_upper

        X = self._checked(X)
        if self._density is not None:  # novelty scored on every column (cluster_features)
            d = self._density
            known = log_gauss_upper(X, d.means, d.precisions_cholesky) + np.log(d.weights)
            return np.maximum(np.logaddexp.reduce(known, axis=1), LOG_FLOOR)
        known, _ = self._point_scores(X)
        return np.maximum(np.logaddexp.reduce(known - math.log(1 - self.novelty_weight_), axis=1), LOG_FLOOR)
