"""Evaluation protocols of the two studies, for any scikit-learn-style classifier.

Method 1 (tactile images): 5-fold cross-validation where each round trains on 3 folds (60 %),
chooses the hyper-parameters on a 4th (validation, 20 %) and tests on the 5th (20 %):
:func:`rotating_splits`, :func:`grid_search_validation`, :func:`run_holdout_protocol`. Every sample
is tested exactly once, so the test predictions pool into one prediction per sample (what McNemar's
test compares). Method 2 (vibration): stratified 10-fold grid search (:func:`stratified_grid_search`,
scikit-learn's ``GridSearchCV``), the odd/even window split (:func:`odd_even_split`) and the ranking
of features by the accuracy each reaches alone (:func:`rank_feature_groups`).

These live apart from :mod:`tactile_torch.svm` because they serve every classifier of the studies:
the HM-SVM and the LDA and kNN baselines go through the same splits and the same selection.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from numbers import Integral

import numpy as np
from sklearn.base import clone
from sklearn.model_selection import GridSearchCV, StratifiedKFold

from ._checks import RandomState, numpy_rng

VIBRATION_STUDY_C = 16.0
"""Method 2: the RBF SVM's penalty ``C`` the study chose (stratified 10-fold CV)."""
VIBRATION_STUDY_GAMMA = 0.0186
"""Method 2: the RBF kernel's ``gamma`` the study chose, on features scaled to unit std."""


@dataclass(frozen=True)
class Split:
    """Indices of one round of the 60/20/20 protocol."""

    train: np.ndarray
    validation: np.ndarray
    test: np.ndarray


def _labels(y: object, name: str = "y") -> np.ndarray:
    if hasattr(y, "detach"):
        y = y.detach().cpu().numpy()
    y = np.asarray(y)
    if y.ndim != 1:
        raise ValueError(f"{name} must be a 1-D array, got shape {y.shape}")
    return y


def rotating_splits(y: object, *, n_folds: int = 5, random_state: RandomState = None) -> list[Split]:
    """Return method 1's rounds: stratified folds; round ``k`` tests on fold ``k``, validates on fold
    ``k + 1`` and trains on the others (with 5 folds: 60 % / 20 % / 20 %).

    Every sample is in exactly one test fold. Folds are stratified (each class spread evenly),
    which needs at least ``n_folds`` samples of every class.

    Parameters
    ----------
    y : array-like of shape (n,)
    n_folds : int, default 5
    random_state : int, numpy or torch Generator, or None
        Shuffles the samples before folding.

    Returns
    -------
    list of ``n_folds`` :class:`Split`

    Examples
    --------
    >>> splits = rotating_splits(np.repeat([0, 1], 10), random_state=0)
    >>> [(len(s.train), len(s.validation), len(s.test)) for s in splits][:2]
    [(12, 4, 4), (12, 4, 4)]
    """
    y = _labels(y)
    if n_folds < 3:
        raise ValueError(f"n_folds must be >= 3 (train, validation and test folds), got {n_folds}")
    _, counts = np.unique(y, return_counts=True)
    if counts.min() < n_folds:
        raise ValueError(
            f"every class needs at least n_folds={n_folds} samples for stratified folds, "
            f"got a class with {counts.min()}"
        )
    seed = int(numpy_rng(random_state).integers(2**31))
    folds = [test for _, test in StratifiedKFold(n_folds, shuffle=True, random_state=seed).split(y, y)]
    splits = []
    for k in range(n_folds):
        validation = folds[(k + 1) % n_folds]
        train = np.sort(np.concatenate([folds[j] for j in range(n_folds) if j not in (k, (k + 1) % n_folds)]))
        splits.append(Split(train=train, validation=np.sort(validation), test=np.sort(folds[k])))
    return splits


def parameter_grid(grid: Mapping[str, Sequence]) -> list[dict]:
    """Return every combination of a parameter grid, in order (the last name varies fastest).

    Examples
    --------
    >>> parameter_grid({"C": [1, 10], "gamma": [0.1]})
    [{'C': 1, 'gamma': 0.1}, {'C': 10, 'gamma': 0.1}]
    """
    names = list(grid)
    for name in names:
        if len(grid[name]) == 0:
            raise ValueError(f"param_grid[{name!r}] must list at least one value, got an empty list")
    return [dict(zip(names, values, strict=True)) for values in itertools.product(*(grid[n] for n in names))]


def grid_search_validation(
    estimator: object,
    param_grid: Mapping[str, Sequence],
    X: object,
    y: object,
    train: np.ndarray,
    validation: np.ndarray,
) -> tuple[dict, list[dict]]:
    """Return the parameters with the best validation accuracy, and every candidate's score.

    Each combination of ``param_grid`` is fitted (on a clone of ``estimator``) on ``X[train]`` and
    scored on ``X[validation]``. Ties go to the first combination in grid order.

    Returns
    -------
    best : dict
    scores : list of dict
        ``{**params, "validation accuracy": ...}`` per combination, in grid order.
    """
    X = np.asarray(X)
    y = _labels(y)
    scores = []
    for params in parameter_grid(param_grid):
        model = clone(estimator).set_params(**params).fit(X[train], y[train])
        accuracy = float(np.mean(model.predict(X[validation]) == y[validation]))
        scores.append({**params, "validation accuracy": accuracy})
    best = max(range(len(scores)), key=lambda i: (scores[i]["validation accuracy"], -i))
    return {k: v for k, v in scores[best].items() if k != "validation accuracy"}, scores


@dataclass
class ProtocolResult:
    """What :func:`run_holdout_protocol` measured.

    Attributes
    ----------
    y_pred : ndarray of shape (n,)
        Each sample's prediction from the round that tested it (pooled test folds).
    fold_accuracy : list of float
        Test accuracy of each round.
    chosen : list of dict
        Parameters chosen on each round's validation fold.
    fit_seconds : list of float
        Time to fit the final model of each round.
    predict_seconds_per_sample : list of float
        Time to classify the test fold of each round, per sample.
    validation_scores : list of list of dict
        Every candidate's validation accuracy, per round.
    """

    y_pred: np.ndarray
    fold_accuracy: list[float] = field(default_factory=list)
    chosen: list[dict] = field(default_factory=list)
    fit_seconds: list[float] = field(default_factory=list)
    predict_seconds_per_sample: list[float] = field(default_factory=list)
    validation_scores: list[list[dict]] = field(default_factory=list)

    @property
    def mean_accuracy(self) -> float:
        return float(np.mean(self.fold_accuracy))


def run_holdout_protocol(
    estimator: object,
    X: object,
    y: object,
    splits: Iterable[Split],
    param_grid: Mapping[str, Sequence] | None = None,
) -> ProtocolResult:
    """Run method 1's protocol: per round, choose parameters on validation, fit on train, test.

    Without ``param_grid`` the estimator's own parameters are used (no validation fit). The final
    model of each round is fitted on the training folds only (the validation fold only chooses).

    Returns
    -------
    ProtocolResult
    """
    X = np.asarray(X)
    y = _labels(y)
    if X.shape[0] != y.shape[0]:
        raise ValueError(f"X and y must have the same number of samples, got {X.shape[0]} and {y.shape[0]}")
    y_pred = np.empty_like(y)
    tested = np.zeros(y.shape[0], dtype=bool)
    result = ProtocolResult(y_pred=y_pred)
    for split in splits:
        params, scores = ({}, [])
        if param_grid:
            params, scores = grid_search_validation(
                estimator, param_grid, X, y, split.train, split.validation
            )
        model = clone(estimator).set_params(**params)
        start = time.perf_counter()
        model.fit(X[split.train], y[split.train])
        result.fit_seconds.append(time.perf_counter() - start)
        start = time.perf_counter()
        pred = model.predict(X[split.test])
        result.predict_seconds_per_sample.append((time.perf_counter() - start) / len(split.test))
        y_pred[split.test] = pred
        tested[split.test] = True
        result.fold_accuracy.append(float(np.mean(pred == y[split.test])))
        result.chosen.append(params)
        result.validation_scores.append(scores)
    if not tested.all():
        raise ValueError("splits must test every sample once (pooled test folds), some were never tested")
    return result


def stratified_grid_search(
    estimator: object,
    param_grid: Mapping[str, Sequence],
    X: object,
    y: object,
    *,
    n_folds: int = 10,
    random_state: RandomState = None,
) -> GridSearchCV:
    """Return scikit-learn's ``GridSearchCV`` fitted with stratified, shuffled ``n_folds``-fold CV
    (method 2: 10 folds), scored by accuracy and refitted on all of ``X`` with the best parameters."""
    seed = int(numpy_rng(random_state).integers(2**31))
    cv = StratifiedKFold(n_folds, shuffle=True, random_state=seed)
    return GridSearchCV(estimator, dict(param_grid), cv=cv, scoring="accuracy", refit=True).fit(
        np.asarray(X), _labels(y)
    )


def odd_even_split(position: int | object) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(train, test)`` indices: odd-numbered windows train, even-numbered ones test.

    Windows are numbered from 1 in recording order, as in method 2's study (so the first window of a
    recording, numbered 1, is odd and trains).

    Parameters
    ----------
    position : int or array-like of shape (n,)
        The number of windows of one recording, or the index of every window inside its own
        recording (``VibrationWindows.position``), for windows of several recordings.

    Examples
    --------
    >>> odd_even_split(5)
    (array([0, 2, 4]), array([1, 3]))
    >>> odd_even_split([0, 1, 2, 0, 1])  # two recordings: windows 1, 2, 3 and 1, 2
    (array([0, 2, 3]), array([1, 4]))
    """
    if isinstance(position, Integral) and not isinstance(position, bool):
        if position < 0:
            raise ValueError(f"position must be a number of windows >= 0, got {position}")
        position = np.arange(position)
    else:
        position = _labels(position, "position")
        if not np.issubdtype(position.dtype, np.integer) or (position < 0).any():
            raise ValueError(
                "position must hold the windows' indices (integers >= 0) inside their recordings"
            )
    return np.flatnonzero(position % 2 == 0), np.flatnonzero(position % 2 == 1)


def rank_feature_groups(
    estimator: object,
    X: object,
    y: object,
    groups: Mapping[str, Sequence[int]],
    train: np.ndarray,
    test: np.ndarray,
) -> list[dict]:
    """Return feature groups ranked by the test accuracy a classifier reaches on them alone.

    For each named group of columns (a feature over the three axes, or one feature on one axis), a
    clone of ``estimator`` is fitted on ``X[train][:, columns]`` and scored on ``X[test]``.

    Returns
    -------
    list of ``{"features": name, "columns": n, "accuracy": float}``, best first.
    """
    X = np.asarray(X)
    y = _labels(y)
    rows = []
    for name, columns in groups.items():
        cols = list(columns)
        model = clone(estimator).fit(X[train][:, cols], y[train])
        accuracy = float(np.mean(model.predict(X[test][:, cols]) == y[test]))
        rows.append({"features": name, "columns": len(cols), "accuracy": accuracy})
    return sorted(rows, key=lambda r: -r["accuracy"])


__all__ = [
    "VIBRATION_STUDY_C",
    "VIBRATION_STUDY_GAMMA",
    "ProtocolResult",
    "Split",
    "grid_search_validation",
    "odd_even_split",
    "parameter_grid",
    "rank_feature_groups",
    "rotating_splits",
    "run_holdout_protocol",
    "stratified_grid_search",
]
