"""Evaluation protocols of the two studies, for any scikit-learn-style classifier, and the batched
grid search of the SVMs.

Method 1 (tactile images): 5-fold cross-validation where each round trains on 3 folds (60 %),
chooses the hyper-parameters on a 4th (validation, 20 %) and tests on the 5th (20 %):
:func:`rotating_splits`, :func:`grid_search_validation`, :func:`run_holdout_protocol`. Every sample
is tested exactly once, so the test predictions pool into one prediction per sample (what McNemar's
test compares). Method 2 (vibration): stratified 10-fold grid search (:func:`stratified_grid_search`),
the odd/even window split (:func:`odd_even_split`) and the ranking of features by the accuracy each
reaches alone (:func:`rank_feature_groups`).

:class:`SVMGridSearchCV` runs a grid over C and gamma of :class:`~tactile_torch.svm.SVC` or
:class:`~tactile_torch.svm.HierarchicalSVC` (alone or last in a ``Pipeline``) as one batched job:
one float32 kernel matrix per gamma serves every fold, C value and binary problem, and each binary
problem is solved along increasing C, every solution warm-starting the next. Both studies' searches
go through it (:func:`stratified_grid_search`, :func:`grid_search_validation`); any other estimator
goes through scikit-learn's ``GridSearchCV``, which also runs our SVMs (they are clone-able), on any
joblib backend (a cluster through Dask or Ray).

These live apart from :mod:`tactile_torch.svm` because they serve every classifier of the studies:
the HM-SVM and the LDA and kNN baselines go through the same splits and the same selection.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from numbers import Integral
from typing import ClassVar

import numpy as np
from scipy.sparse import issparse
from scipy.stats import rankdata
from sklearn.base import BaseEstimator, ClassifierMixin, MetaEstimatorMixin, _fit_context, clone
from sklearn.model_selection import GridSearchCV, ParameterGrid, check_cv
from sklearn.pipeline import Pipeline
from sklearn.utils._param_validation import Interval, Options
from sklearn.utils.validation import check_is_fitted

from ..exceptions import InputTypeError
from ..validation import RandomState, numpy_rng
from ._split import Split, stratified_splitter
from ._split import labels_1d as _labels

VIBRATION_STUDY_C = 16.0
"""Method 2: the RBF SVM's penalty ``C`` the study chose (stratified 10-fold CV)."""
VIBRATION_STUDY_GAMMA = 0.0186
"""Method 2: the RBF kernel's ``gamma`` the study chose, on features scaled to unit std."""


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
    scored on ``X[validation]``; for our SVMs as one batched job (:class:`SVMGridSearchCV`). Ties go
    to the first combination in grid order.

    Returns
    -------
    best : dict
    scores : list of dict
        ``{**params, "validation accuracy": ...}`` per combination, in grid order.
    """
    X = np.asarray(X)
    y = _labels(y)
    scores = []
    combinations = parameter_grid(param_grid)
    if supports_batched_search(estimator):
        search = SVMGridSearchCV(estimator, dict(param_grid), cv=[(train, validation)], refit=False)
        search.fit(X, y)
        by_params = {
            _key(p): float(a)
            for p, a in zip(search.cv_results_["params"], search.cv_results_["mean_test_score"], strict=True)
        }
        scores = [{**params, "validation accuracy": by_params[_key(params)]} for params in combinations]
    for params in combinations if not scores else []:
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
    """Return a grid search fitted with stratified, shuffled ``n_folds``-fold CV (method 2: 10 folds),
    scored by accuracy and refitted on all of ``X`` with the best parameters: :class:`SVMGridSearchCV`
    for our SVMs, scikit-learn's ``GridSearchCV`` otherwise (same attributes: ``cv_results_``,
    ``best_params_``, ``best_estimator_`` ...)."""
    seed = int(numpy_rng(random_state).integers(2**31))
    cv = stratified_splitter(n_folds, seed)
    if supports_batched_search(estimator):
        return SVMGridSearchCV(estimator, dict(param_grid), cv=cv).fit(np.asarray(X), _labels(y))
    return GridSearchCV(estimator, dict(param_grid), cv=cv, scoring="accuracy", refit=True).fit(
        np.asarray(X), _labels(y)
    )


def _key(params: Mapping) -> tuple:
    return tuple(sorted((k, repr(v)) for k, v in params.items()))


def _final_step(estimator: object) -> tuple[object, str]:
    """The SVM of ``estimator`` (itself, or the last step of a ``Pipeline``) and its parameter prefix."""
    if isinstance(estimator, Pipeline):
        name, last = estimator.steps[-1]
        return last, f"{name}__"
    return estimator, ""


def supports_batched_search(estimator: object) -> bool:
    """True for :class:`~tactile_torch.svm.SVC`, :class:`~tactile_torch.svm.HierarchicalSVC`, and a
    ``Pipeline`` that ends with one (the estimators :class:`SVMGridSearchCV` batches)."""
    return hasattr(_final_step(estimator)[0], "fit_path")


class SVMGridSearchCV(MetaEstimatorMixin, ClassifierMixin, BaseEstimator):
    """Exhaustive grid search over the parameters of an SVM, with C and gamma batched: a drop-in for
    scikit-learn's ``GridSearchCV`` (accuracy scoring) that shares what the grid points share.

    The candidates are those of ``GridSearchCV`` (``ParameterGrid``, same order, same ``cv_results_``
    keys, ties to the first). Candidates that differ only in C form one job per cross-validation
    split: the estimator's ``fit_path`` solves each binary problem at the smallest C and warm-starts
    every larger C from it. For a numeric gamma and no preprocessing, one float32 kernel matrix of
    all of ``X`` (computed on the threads) serves every split and C value of that gamma, when it fits
    in the estimator's ``cache_size``. Splits run on ``n_jobs`` Python threads (the compiled solver
    releases the GIL). With preprocessing (a ``Pipeline`` ending with the SVM), the preceding steps
    are fitted on each split's training part, once per split and gamma.

    A warm-started solution equals an independent fit up to the solver's tolerance, so a score can
    differ from ``GridSearchCV``'s by a prediction that flips between two solutions within ``tol``.

    Parameters
    ----------
    estimator : SVC, HierarchicalSVC, or a Pipeline ending with one
    param_grid : dict or list of dicts
        As ``GridSearchCV``'s; keys name the estimator's parameters (``"svc__C"`` in a pipeline).
    cv : int, cross-validation splitter or iterable of (train, test), default 5
        As ``GridSearchCV``'s (an int: stratified k-fold without shuffling).
    refit : bool, default True
        Refit the best candidate on all of ``X`` (``best_estimator_``, ``predict`` ...).
    n_jobs : int or None, default None
        Python threads (``None``: ``torch.get_num_threads()``; -1: every core).

    Attributes
    ----------
    cv_results_ : dict of arrays
        ``params``, ``param_<name>``, ``split<k>_test_score``, ``mean_test_score``,
        ``std_test_score``, ``rank_test_score``, as ``GridSearchCV``'s.
    best_index_, best_params_, best_score_
    best_estimator_ : estimator (``refit=True``)
    n_features_in_ : int
    n_splits_ : int
    search_time_ : float
        Seconds of the search (without the refit); ``refit_time_``: seconds of the refit.

    Examples
    --------
    >>> from sklearn.datasets import make_blobs
    >>> from tactile_torch.svm import HierarchicalSVC
    >>> X, y = make_blobs(150, centers=3, random_state=0)
    >>> search = SVMGridSearchCV(HierarchicalSVC(random_state=0), {"C": [1, 10], "gamma": [0.1, 1]}, cv=3)
    >>> sorted(search.fit(X, y).best_params_)
    ['C', 'gamma']
    """

    _parameter_constraints: ClassVar[dict] = {
        "estimator": [object],
        "param_grid": [dict, list],
        "cv": ["cv_object"],
        "refit": ["boolean"],
        "n_jobs": [None, Options(Integral, {-1}), Interval(Integral, 1, None, closed="left")],
    }

    def __init__(self, estimator, param_grid, *, cv=5, refit: bool = True, n_jobs: int | None = None) -> None:
        self.estimator = estimator
        self.param_grid = param_grid
        self.cv = cv
        self.refit = refit
        self.n_jobs = n_jobs

    # the searched estimator's own parameters are validated by its fits (not skipped as nested)
    @_fit_context(prefer_skip_nested_validation=False)
    def fit(self, X: object, y: object) -> SVMGridSearchCV:
        """Run the search on ``X`` (n_samples, n_features) and labels ``y``; return ``self``."""
        from ..svm.kernels import KernelData
        from ..svm.threads import resolve_threads, run_blocks

        if not supports_batched_search(self.estimator):
            raise InputTypeError(
                "estimator must be tactile_torch.svm.SVC or HierarchicalSVC, or a Pipeline ending with "
                f"one, got {type(self.estimator).__name__} (use sklearn's GridSearchCV for others)"
            )
        if issparse(X):
            raise InputTypeError("X must be a dense array or tensor: sparse input is not supported")
        if y is None:
            raise ValueError("SVMGridSearchCV requires y to be passed, but the target y is None")
        X = np.asarray(X.detach().cpu() if hasattr(X, "detach") else X)
        y = _labels(y)
        if X.ndim != 2 or X.shape[0] != y.shape[0]:
            raise ValueError(
                f"X must have shape (n_samples, n_features) with y's {y.shape[0]} samples, got {X.shape}"
            )
        self.n_features_in_ = X.shape[1]
        start = time.perf_counter()
        splits = list(check_cv(self.cv, y, classifier=True).split(X, y))
        candidates = list(ParameterGrid(self.param_grid))
        _, prefix = _final_step(self.estimator)
        c_name = prefix + "C"
        threads = resolve_threads(self.n_jobs)
        groups: dict[tuple, list[int]] = {}
        for index, params in enumerate(candidates):
            others = {k: v for k, v in params.items() if k != c_name}
            groups.setdefault(_key(others), []).append(index)
        scores = np.empty((len(candidates), len(splits)))
        for members in groups.values():
            others = {k: v for k, v in candidates[members[0]].items() if k != c_name}
            estimator = clone(self.estimator).set_params(**others)
            svm, _ = _final_step(estimator)
            svm.set_params(n_jobs=1)  # the splits take the threads
            c_values = [candidates[i].get(c_name, svm.C) for i in members]
            Cs = sorted(set(float(c) for c in c_values))
            shared = None
            gamma = svm.gamma
            if prefix == "" and not isinstance(gamma, str) and X.shape[0] ** 2 * 4 <= svm.cache_size * 2**20:
                shared = KernelData.precomputed(X, svm.kernel, float(gamma), threads)

            def run(split, estimator=estimator, Cs=Cs, shared=shared):
                return _path_scores(estimator, X, y, split, Cs, shared)

            per_split = run_blocks(run, splits, threads)
            for k, accuracy in enumerate(per_split):
                for i, c in zip(members, c_values, strict=True):
                    scores[i, k] = accuracy[Cs.index(float(c))]
        self.search_time_ = time.perf_counter() - start
        self._store_results(candidates, scores)
        self.n_splits_ = len(splits)
        if self.refit:
            start = time.perf_counter()
            self.best_estimator_ = clone(self.estimator).set_params(**self.best_params_).fit(X, y)
            self.refit_time_ = time.perf_counter() - start
            self.classes_ = self.best_estimator_.classes_
        return self

    def _store_results(self, candidates: list[dict], scores: np.ndarray) -> None:
        mean, std = scores.mean(axis=1), scores.std(axis=1)
        rank = rankdata(-mean, method="min").astype(np.int32)
        results: dict = {"params": candidates}
        for name in sorted({k for c in candidates for k in c}):
            column = np.ma.masked_all(len(candidates), dtype=object)
            for i, c in enumerate(candidates):
                if name in c:
                    column[i] = c[name]
            results[f"param_{name}"] = column
        for k in range(scores.shape[1]):
            results[f"split{k}_test_score"] = scores[:, k]
        results.update(mean_test_score=mean, std_test_score=std, rank_test_score=rank)
        self.cv_results_ = results
        self.best_index_ = int(rank.argmin())
        self.best_params_ = candidates[self.best_index_]
        self.best_score_ = float(mean[self.best_index_])

    def predict(self, X: object) -> np.ndarray:
        """Predict with the refitted best estimator."""
        check_is_fitted(self, "best_estimator_")
        return self.best_estimator_.predict(X)

    def decision_function(self, X: object) -> np.ndarray:
        """Decision values of the refitted best estimator."""
        check_is_fitted(self, "best_estimator_")
        return self.best_estimator_.decision_function(X)


def _path_scores(estimator, X, y, split, Cs, shared) -> list[float]:
    """Test accuracy, on one split, of the estimator fitted along ``Cs`` (increasing)."""
    train, test = split
    svm, _ = _final_step(estimator)
    X_train, X_test = X[train], X[test]
    if isinstance(estimator, Pipeline):
        head = Pipeline(clone(estimator).steps[:-1]).fit(X_train, y[train])
        X_train, X_test = head.transform(X_train), head.transform(X_test)
    if shared is not None:
        models = svm.fit_path(
            X_train, y[train], Cs, kernel_data=shared, rows=np.asarray(train, dtype=np.int64)
        )
    else:
        models = svm.fit_path(X_train, y[train], Cs)
    return [float(np.mean(model.predict(X_test) == y[test])) for model in models]


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
