"""The k-nearest-neighbour classifier with ties in training order (see the package notes)."""

from __future__ import annotations

import numpy as np
from sklearn.neighbors import KNeighborsClassifier


class StableKNeighborsClassifier(KNeighborsClassifier):
    """scikit-learn's ``KNeighborsClassifier`` whose neighbours are chosen by (distance, training index).

    Every parameter and attribute is scikit-learn's; only :meth:`kneighbors` differs, and with it
    :meth:`predict` and :meth:`predict_proba`: the distances to every training sample are computed by
    brute force (``sklearn.metrics.pairwise_distances`` with the model's metric) and sorted stably, so
    that of samples at equal distance the one that came first in training is nearer. Away from ties
    the neighbours, and so the labels, are scikit-learn's.

    Examples
    --------
    >>> X = np.zeros((4, 1)); y = np.array([0, 1, 1, 1])   # four identical samples
    >>> StableKNeighborsClassifier(1).fit(X, y).predict([[0.0]]).tolist()   # the first one is nearest
    [0]
    """

    def kneighbors(self, X=None, n_neighbors=None, return_distance=True):
        """Return the distances and indices of the ``n_neighbors`` nearest training samples, ties by index.

        Parameters and returns as scikit-learn's ``KNeighborsMixin.kneighbors`` (``X=None``: the neighbours
        of each training sample other than itself).
        """
        from sklearn.metrics import pairwise_distances
        from sklearn.utils.validation import check_is_fitted, validate_data

        check_is_fitted(self)
        k = self.n_neighbors if n_neighbors is None else int(n_neighbors)
        query = X is None
        Q = self._fit_X if query else validate_data(self, X, reset=False)
        if k > self.n_samples_fit_ - int(query):
            raise ValueError(
                f"n_neighbors must be at most the {self.n_samples_fit_ - int(query)} training samples, got {k}"
            )
        dist = pairwise_distances(
            Q, self._fit_X, metric=self.effective_metric_, **self.effective_metric_params_
        )
        if query:
            np.fill_diagonal(dist, np.inf)
        index = np.argsort(dist, axis=1, kind="stable")[:, :k]
        if not return_distance:
            return index
        return np.take_along_axis(dist, index, axis=1), index

    def predict(self, X):
        """Return the class of each sample of ``X`` (the neighbours' vote, as scikit-learn's)."""
        proba = self.predict_proba(X)
        return self.classes_[np.argmax(proba, axis=1)]

    def predict_proba(self, X):
        """Return the neighbours' (weighted) votes per class, ``(N, C)``, as scikit-learn's.

        ``weights="distance"``: ``1 / d``, and a sample at distance 0 from some of its neighbours takes
        the votes of those alone (scikit-learn's rule); ``"uniform"``: one each; a callable: its weights.
        """
        from sklearn.utils.validation import check_is_fitted

        check_is_fitted(self)
        if self.outputs_2d_:
            raise ValueError(
                "y must be one column of labels for StableKNeighborsClassifier, got several outputs"
            )
        distances, index = self.kneighbors(X)
        if self.weights == "distance":
            exact = distances == 0
            with np.errstate(divide="ignore"):
                weights = np.where(
                    exact.any(axis=1, keepdims=True), exact.astype(np.float64), 1.0 / distances
                )
        elif callable(self.weights):
            weights = np.asarray(self.weights(distances), dtype=np.float64)
        else:
            weights = np.ones_like(distances)
        votes = np.zeros((len(index), len(self.classes_)))
        labels = self._y[index]
        for j in range(index.shape[1]):
            np.add.at(votes, (np.arange(len(index)), labels[:, j]), weights[:, j])
        total = votes.sum(axis=1, keepdims=True)
        return votes / np.where(total > 0, total, 1.0)

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.target_tags.multi_output = False
        tags.classifier_tags.multi_label = False
        return tags


__all__ = ["StableKNeighborsClassifier"]
