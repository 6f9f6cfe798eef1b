"""scikit-learn's cross-validation on folds the engine made: out-of-fold predictions and per-fold accuracy.

The report's studies that cross-validate one scikit-learn model on given folds (of
:mod:`tactile_torch.model_selection`) call these, never ``sklearn.model_selection.cross_val_*``
themselves, so that every cross-validation of the library goes through the engine. The model is
cloned for every fold (scikit-learn's ``cross_val_predict`` and ``cross_val_score``, one job).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ._split import Fold


def fold_predictions(model: object, X: np.ndarray, y: np.ndarray, folds: Sequence[Fold]) -> np.ndarray:
    """Return every sample's prediction by a clone of ``model`` fitted on the other folds, shape ``(n,)``.

    ``folds`` must test every sample exactly once (scikit-learn's ``cross_val_predict``).

    Examples
    --------
    >>> from sklearn.neighbors import KNeighborsClassifier
    >>> from tactile_torch.model_selection import stratified_folds
    >>> y = np.repeat([0, 1], 6)
    >>> X = y[:, None] + 0.1 * np.arange(12)[:, None] % 0.3
    >>> fold_predictions(KNeighborsClassifier(1), X, y, stratified_folds(y, 3, seed=0)).tolist() == y.tolist()
    True
    """
    from sklearn.model_selection import cross_val_predict

    return cross_val_predict(model, X, y, cv=list(folds))


def fold_scores(model: object, X: np.ndarray, y: np.ndarray, folds: Sequence[Fold]) -> np.ndarray:
    """Return the accuracy (the model's ``score``) of a clone of ``model`` on each fold's test part, shape ``(k,)``.

    scikit-learn's ``cross_val_score`` with the default scoring.
    """
    from sklearn.model_selection import cross_val_score

    return cross_val_score(model, X, y, cv=list(folds))
