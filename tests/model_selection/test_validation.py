"""The evaluation engine (tactile_torch.model_selection): grouped folds, feature caching, nested tuning, backends."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.discriminant_analysis import LinearDiscriminantAnalysis
from sklearn.model_selection import GridSearchCV
from sklearn.neighbors import KNeighborsClassifier, NearestCentroid
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import FunctionTransformer, StandardScaler

from tactile_torch import catalogue
from tactile_torch.model_selection import (
    Backend,
    Tuning,
    cross_validate,
    inner_splits,
    make_folds,
    needs_fit,
    seed_of,
)


def _data(n_groups=12, per_group=6, n_classes=3, seed=0):
    """Features (N, 4) with a group effect: samples of one group share an offset."""
    rng = np.random.default_rng(seed)
    groups = np.repeat(np.arange(n_groups), per_group)
    y = groups % n_classes
    offset = rng.normal(scale=0.7, size=(n_groups, 4))[groups]
    X = rng.normal(size=(len(y), 4)) + 1.5 * np.eye(n_classes, 4)[y] + offset
    return X, y, groups


def _mean_std(X):
    return np.concatenate([X.mean(axis=1, keepdims=True), X.std(axis=1, keepdims=True), X], axis=1)


class Fitted(FunctionTransformer):
    """The same features, declared as needing a fit (computed per fold)."""

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.requires_fit = True
        return tags


def _pipe(classifier, features=None):
    features = features if features is not None else FunctionTransformer(_mean_std)
    return Pipeline([("features", features), ("scale", StandardScaler()), ("classifier", classifier)])


def test_grouped_folds_never_split_a_group():
    X, y, groups = _data()
    folds = make_folds(y, groups, 4, seed=3)
    for train, test in folds:
        assert not set(groups[train]) & set(groups[test])
    assert np.array_equal(np.sort(np.concatenate([te for _, te in folds])), np.arange(len(y)))
    res = cross_validate({"lda": _pipe(LinearDiscriminantAnalysis())}, X, y, folds, groups=groups)["lda"]
    for g in np.unique(groups):  # one fold tests the whole group
        assert len(np.unique(res.fold[groups == g])) == 1
    for train, _ in folds:  # inner tuning folds keep the training part's groups apart too
        splits, how = inner_splits(y[train], groups[train], 3, seed=1)
        assert "grouped" in how and len(splits) == 3
        for a, b in splits:
            assert not set(groups[train][a]) & set(groups[train][b])


def test_grouped_folds_need_two_groups_per_class():
    y = np.array([0, 0, 1, 1])
    with pytest.raises(ValueError, match="groups must give every class at least 2 groups"):
        make_folds(y, np.array([0, 0, 1, 2]), 2, seed=0)


def test_per_sample_outputs_equal_fitting_each_fold_by_hand():
    X, y, groups = _data()
    folds = make_folds(y, groups, 3, seed=0)
    res = cross_validate({"knn": _pipe(KNeighborsClassifier(3))}, X, y, folds, groups=groups)["knn"]
    assert np.array_equal(res.groups, groups)
    for k, (train, test) in enumerate(folds):
        model = _pipe(KNeighborsClassifier(3)).fit(X[train], y[train])
        expected = model.predict(X[test])
        assert np.array_equal(res.predictions[test], expected)
        assert (res.fold[test] == k).all()
        assert res.fold_accuracy[k] == pytest.approx(np.mean(expected == y[test]))
    assert len(res.fit_seconds) == len(folds) and all(s >= 0 for s in res.fit_seconds)
    assert res.params == [{}] * len(folds) and res.tune_seconds == [0.0] * len(folds)


def test_a_step_that_needs_no_fit_is_computed_once_and_gives_the_same_result():
    X, y, groups = _data()
    folds = make_folds(y, groups, 3, seed=0)
    calls = []

    def counted(Z):
        calls.append(len(Z))
        return _mean_std(Z)

    shared = FunctionTransformer(counted)
    models = {"lda": _pipe(LinearDiscriminantAnalysis(), shared), "ncm": _pipe(NearestCentroid(), shared)}
    cached = cross_validate(models, X, y, folds)
    assert calls == [len(y)]  # once, on every sample, for both models

    assert not needs_fit(FunctionTransformer(_mean_std)) and needs_fit(Fitted(_mean_std))
    per_fold = cross_validate(
        {
            "lda": _pipe(LinearDiscriminantAnalysis(), Fitted(_mean_std)),
            "ncm": _pipe(NearestCentroid(), Fitted(_mean_std)),
        },
        X,
        y,
        folds,
    )
    for name in models:
        assert np.array_equal(cached[name].predictions, per_fold[name].predictions)


def test_one_no_fit_protocol_the_scikit_learn_tag():
    from tactile_torch.features.transformers import (
        FeaturePassthrough,
        ImageFeatureTransformer,
        PressureImageFeatures,
        TaxelFeatureTransformer,
        WindowFeatureTransformer,
    )

    assert not needs_fit(WindowFeatureTransformer()) and not needs_fit(FeaturePassthrough())
    assert not needs_fit(TaxelFeatureTransformer()) and not needs_fit(ImageFeatureTransformer())
    assert needs_fit(ImageFeatureTransformer(threshold="otsu")) and needs_fit(PressureImageFeatures())
    assert needs_fit(StandardScaler()) and not needs_fit(None)
    for step in (WindowFeatureTransformer(), ImageFeatureTransformer(), PressureImageFeatures()):
        assert not hasattr(step, "stateless")  # the old attribute protocol is gone


def test_nested_tuning_chooses_inside_the_training_fold():
    X, y, groups = _data(n_groups=15)
    folds = make_folds(y, groups, 3, seed=0)
    tuning = Tuning({"classifier__n_neighbors": [1, 5, 9]}, n_splits=3)

    def run(labels):
        models = {"knn": _pipe(KNeighborsClassifier())}
        return cross_validate(
            models, X, labels, folds, groups=groups, tuning={"knn": tuning}, random_state=4
        )["knn"]

    res = run(y)
    for k, (train, test) in enumerate(folds):
        # The same inner folds by hand, on the training part only: the same choice.
        splits, _ = inner_splits(y[train], groups[train], 3, seed_of(4, "knn", k))
        search = GridSearchCV(_pipe(KNeighborsClassifier()), tuning.grid, cv=splits).fit(X[train], y[train])
        assert res.params[k] == search.best_params_
        model = clone(_pipe(KNeighborsClassifier())).set_params(**search.best_params_).fit(X[train], y[train])
        assert np.array_equal(res.predictions[test], model.predict(X[test]))
    assert all(t > 0 for t in res.tune_seconds)
    assert all(f >= t for f, t in zip(res.fit_seconds, res.tune_seconds, strict=True))  # tuning counts in fit
    shuffled = y.copy()  # fold 0's test labels play no part in fold 0's choice
    shuffled[folds[0][1]] = (y[folds[0][1]] + 1) % 3
    assert run(shuffled).params[0] == res.params[0]


def test_validation_protocol_uses_one_held_out_part():
    X, y, groups = _data(n_groups=16)
    folds = make_folds(y, groups, 4, seed=0)
    tuning = Tuning({"classifier__n_neighbors": [1, 7]}, n_splits=4, protocol="validation")
    res = cross_validate(
        {"knn": _pipe(KNeighborsClassifier())}, X, y, folds, groups=groups, tuning={"knn": tuning}
    )["knn"]
    assert all(how.startswith("one validation part") for how in res.tuning_notes)
    with pytest.raises(ValueError, match="protocol must be one of"):
        Tuning({"a": [1]}, protocol="holdout")
    with pytest.raises(ValueError, match="n_splits must be an integer >= 2"):
        Tuning({"a": [1]}, n_splits=1)


def test_tuned_svm_matches_scikit_learn_grid_search_on_the_same_folds():
    """The batched nested search of our SVC against scikit-learn's GridSearchCV(SVC()) on the same folds."""
    from sklearn.svm import SVC as SkSVC

    X, y, groups = _data(n_groups=18, per_group=5)
    folds = make_folds(y, groups, 3, seed=0)
    grid = catalogue.param_grid("svc", X.shape[1] + 2, quick=True)
    tuning = Tuning(catalogue.prefixed(grid, "classifier__"), n_splits=3)
    ours = cross_validate(
        {"svc": _pipe(catalogue.make_classifier("svc", random_state=0))},
        X,
        y,
        folds,
        groups=groups,
        tuning={"svc": tuning},
    )["svc"]
    theirs = []
    for k, (train, test) in enumerate(folds):
        splits, _ = inner_splits(y[train], groups[train], 3, seed_of(0, "svc", k))
        search = GridSearchCV(_pipe(SkSVC()), catalogue.prefixed(grid, "classifier__"), cv=splits).fit(
            X[train], y[train]
        )
        theirs.append(np.mean(search.predict(X[test]) == y[test]))
        assert ours.params[k]["classifier__C"] in grid["C"]
    # Warm-started solutions equal independent fits up to the solver's tolerance: at most one
    # prediction per fold may flip, on average.
    assert abs(ours.accuracy - np.mean(theirs)) <= 1.0 / min(len(te) for _, te in folds)


def test_final_model_is_tuned_and_fitted_on_all_data():
    X, y, groups = _data()
    folds = make_folds(y, groups, 3, seed=0)
    tuning = Tuning({"classifier__n_neighbors": [1, 5]})
    res = cross_validate(
        {"knn": _pipe(KNeighborsClassifier())}, X, y, folds, groups=groups, tuning={"knn": tuning}
    )["knn"]
    model, params = res.final_model(X, y, groups)
    assert params["classifier__n_neighbors"] in (1, 5)
    assert model.named_steps["classifier"].n_neighbors == params["classifier__n_neighbors"]
    assert model.named_steps["classifier"].n_samples_fit_ == len(y)


def test_a_model_that_cannot_be_fitted_is_reported_not_raised():
    X, y, groups = _data()
    folds = make_folds(y, groups, 3, seed=0)
    res = cross_validate({"bad": _pipe(KNeighborsClassifier(n_neighbors=500))}, X, y, folds)["bad"]
    assert res.error and "ValueError" in res.error and res.fold_accuracy == [] and (res.fold == -1).all()


def _study(backend=None, n_jobs=None, scheduler=None):
    X, y, groups = _data(n_groups=12)
    folds = make_folds(y, groups, 3, seed=0)
    models = {
        "svc": _pipe(catalogue.make_classifier("svc", random_state=0)),
        "lda": _pipe(catalogue.make_classifier("lda")),
        "knn": _pipe(catalogue.make_classifier("knn")),
    }
    tuning = {
        key: Tuning(catalogue.prefixed(catalogue.param_grid(key, 6, quick=True), "classifier__"))
        for key in models
    }
    out = cross_validate(
        models,
        X,
        y,
        folds,
        groups=groups,
        tuning=tuning,
        backend=backend,
        n_jobs=n_jobs,
        scheduler=scheduler,
        random_state=7,
    )
    return {k: (r.predictions.tolist(), r.fold_accuracy, r.params) for k, r in out.items()}


def test_results_do_not_depend_on_the_backend_or_the_workers():
    local = _study()
    assert _study("threading", 2) == local
    assert _study("loky", 2) == local


def test_dask_cluster_gives_the_local_results():
    """A real dask.distributed LocalCluster of two worker processes runs the same study."""
    distributed = pytest.importorskip("distributed", reason="the optional extra dask is not installed")
    with distributed.LocalCluster(
        n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None
    ) as cluster:
        remote = _study("dask", scheduler=cluster.scheduler_address)
    assert remote == _study()


def test_backend_errors_name_the_argument(monkeypatch):
    with pytest.raises(ValueError, match="backend must be one of"):
        Backend("spark")
    with pytest.raises(ValueError, match="n_jobs must be a non-zero integer"):
        Backend("loky", 0)
    with pytest.raises(ValueError, match="scheduler is the address of a Dask scheduler"):
        Backend("loky", scheduler="tcp://localhost:8786")
    monkeypatch.setitem(sys.modules, "distributed", None)  # as if the extra were not installed
    with pytest.raises(ValueError, match=r"needs the optional extra dask.*tactile-torch\[dask\]"):
        Backend("dask")


def test_breaking_point_sweeps_run_on_the_engine_backends():
    from tactile_torch.robustness.sweeps import sweep

    X, y, groups = _data(n_groups=12)
    models = {"lda": _pipe(LinearDiscriminantAnalysis()), "ncm": _pipe(NearestCentroid())}
    options = dict(factors=["feature SNR", "training samples"], n_splits=3, n_trials=1, n_bootstrap=50)
    local = sweep(models, X, y, groups, random_state=3, **options)
    threads = sweep(models, X, y, groups, random_state=3, backend="threading", n_jobs=2, **options)
    assert len(local.curves) == len(threads.curves) == 4
    for a, b in zip(local.curves, threads.curves, strict=True):
        assert (a.factor.name, a.model, a.clean) == (b.factor.name, b.model, b.clean)
        assert np.array_equal(a.accuracy, b.accuracy) and a.breaking.text == b.breaking.text
