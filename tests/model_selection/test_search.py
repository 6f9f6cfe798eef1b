import numpy as np
import pytest
import torch
from joblib import parallel_backend
from sklearn.base import clone
from sklearn.datasets import make_blobs
from sklearn.discriminant_analysis import LinearDiscriminantAnalysis
from sklearn.model_selection import GridSearchCV, StratifiedKFold
from sklearn.neighbors import KNeighborsClassifier
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler

from tactile_torch.model_selection import (
    SVMGridSearchCV,
    grid_search_validation,
    odd_even_split,
    parameter_grid,
    rank_feature_groups,
    rotating_splits,
    run_holdout_protocol,
    stratified_grid_search,
    supports_batched_search,
)
from tactile_torch.svm import SVC, HierarchicalSVC


def test_rotating_splits_partition_and_stratify():
    y = np.repeat(np.arange(4), [10, 15, 20, 25])
    splits = rotating_splits(y, random_state=0)
    assert len(splits) == 5
    tested = np.concatenate([s.test for s in splits])
    assert np.array_equal(np.sort(tested), np.arange(70))  # every sample tested exactly once
    for k, s in enumerate(splits):
        parts = np.concatenate([s.train, s.validation, s.test])
        assert np.array_equal(np.sort(parts), np.arange(70))  # a partition
        assert len(s.train) == 42 and len(s.validation) == 14 and len(s.test) == 14  # 60/20/20
        assert np.array_equal(s.validation, splits[(k + 1) % 5].test)
        for c, n in zip(range(4), [10, 15, 20, 25], strict=True):
            assert np.sum(y[s.test] == c) == n // 5  # stratified
    again = rotating_splits(y, random_state=0)
    assert all(np.array_equal(a.test, b.test) for a, b in zip(splits, again, strict=True))


def test_rotating_splits_errors():
    with pytest.raises(ValueError, match="at least n_folds=5 samples"):
        rotating_splits(np.repeat([0, 1], [10, 4]))
    with pytest.raises(ValueError, match="n_folds must be >= 3"):
        rotating_splits(np.repeat([0, 1], 10), n_folds=2)


def test_parameter_grid_order_and_errors():
    assert parameter_grid({"C": [1, 2], "gamma": [0.1, 0.2]})[:2] == [
        {"C": 1, "gamma": 0.1},
        {"C": 1, "gamma": 0.2},
    ]
    with pytest.raises(ValueError, match="param_grid\\['C'\\] must list at least one value"):
        parameter_grid({"C": []})


def test_grid_search_validation_picks_the_best_by_brute_force():
    X, y = make_blobs(120, centers=3, cluster_std=3.0, random_state=0)
    train, val = np.arange(80), np.arange(80, 120)
    grid = {"n_neighbors": [1, 3, 9, 15]}
    best, scores = grid_search_validation(KNeighborsClassifier(), grid, X, y, train, val)
    accs = [
        np.mean(KNeighborsClassifier(n_neighbors=k).fit(X[train], y[train]).predict(X[val]) == y[val])
        for k in grid["n_neighbors"]
    ]
    assert [s["validation accuracy"] for s in scores] == pytest.approx(accs)
    assert best == {"n_neighbors": grid["n_neighbors"][int(np.argmax(accs))]}  # first of the best


def test_holdout_protocol_pools_test_predictions():
    X, y = make_blobs(100, centers=4, cluster_std=2.5, random_state=1)
    splits = rotating_splits(y, random_state=0)
    res = run_holdout_protocol(HierarchicalSVC(random_state=0), X, y, splits, {"C": [0.5, 5.0]})
    assert len(res.chosen) == 5 and all(c["C"] in (0.5, 5.0) for c in res.chosen)
    for s, acc in zip(splits, res.fold_accuracy, strict=True):
        assert acc == pytest.approx(np.mean(res.y_pred[s.test] == y[s.test]))
    assert res.mean_accuracy > 0.7
    lda = run_holdout_protocol(LinearDiscriminantAnalysis(), X, y, splits)
    assert lda.chosen == [{}] * 5 and len(lda.fit_seconds) == 5
    with pytest.raises(ValueError, match="test every sample once"):
        run_holdout_protocol(LinearDiscriminantAnalysis(), X, y, splits[:2])


def test_stratified_grid_search_is_gridsearchcv_or_batched():
    X, y = make_blobs(100, centers=2, random_state=0)
    search = stratified_grid_search(
        KNeighborsClassifier(), {"n_neighbors": [1, 5]}, X, y, n_folds=10, random_state=0
    )
    assert isinstance(search, GridSearchCV) and search.n_splits_ == 10
    assert search.best_params_["n_neighbors"] in (1, 5)
    svm = stratified_grid_search(SVC(), {"C": [1.0, 10.0]}, X, y, n_folds=5, random_state=0)
    assert isinstance(svm, SVMGridSearchCV) and svm.n_splits_ == 5 and hasattr(svm, "best_estimator_")


def test_odd_even_split():
    train, test = odd_even_split(7)
    assert train.tolist() == [0, 2, 4, 6] and test.tolist() == [1, 3, 5]
    # windows of several recordings, numbered inside each recording (VibrationWindows.position)
    train, test = odd_even_split(torch.tensor([0, 1, 2, 0, 1, 2, 3]))
    assert train.tolist() == [0, 2, 3, 5] and test.tolist() == [1, 4, 6]
    with pytest.raises(ValueError, match="position must hold the windows' indices"):
        odd_even_split(np.array([0.5, 1.0]))
    with pytest.raises(ValueError, match="position must be a 1-D array"):
        odd_even_split(np.zeros((2, 2), dtype=int))


def test_rank_feature_groups_puts_the_informative_feature_first():
    rng = np.random.default_rng(0)
    y = np.repeat([0, 1, 2], 40)
    X = np.column_stack([y + rng.normal(0, 0.2, 120), rng.normal(size=120), rng.normal(size=120)])
    train, test = odd_even_split(120)
    rows = rank_feature_groups(
        LinearDiscriminantAnalysis(), X, y, {"noise": [1], "signal": [0], "both noise": [1, 2]}, train, test
    )
    assert rows[0]["features"] == "signal" and rows[0]["accuracy"] > 0.9
    assert [r["columns"] for r in rows if r["features"] == "both noise"] == [2]


def _small_problem():
    X, y = make_blobs(240, centers=4, cluster_std=2.5, random_state=2)
    return X, y


GRID = {"C": [0.5, 4.0, 32.0], "gamma": [0.05, 0.5]}


@pytest.mark.parametrize("estimator", [HierarchicalSVC(random_state=0), SVC()])
def test_batched_search_equals_gridsearchcv(estimator):
    X, y = _small_problem()
    cv = StratifiedKFold(4, shuffle=True, random_state=0)
    ours = SVMGridSearchCV(estimator, GRID, cv=cv).fit(X, y)
    ref = GridSearchCV(estimator, GRID, cv=cv).fit(X, y)
    assert ours.cv_results_["params"] == ref.cv_results_["params"]  # same candidates, same order
    for key in ("mean_test_score", "split0_test_score", "rank_test_score"):
        assert key in ours.cv_results_
    # Warm starts along C reach the same optima within tol: a fold's accuracy moves by at most a
    # sample that sits on the boundary.
    np.testing.assert_allclose(
        ours.cv_results_["mean_test_score"], ref.cv_results_["mean_test_score"], atol=1 / 60
    )
    assert ours.best_params_ == ref.best_params_ and ours.n_splits_ == 4
    np.testing.assert_array_equal(ours.predict(X), ref.predict(X))


def test_batched_search_with_a_pipeline_and_other_parameters():
    X, y = _small_problem()
    X = X * [1.0, 100.0]  # unequal scales: the pipeline standardises each fold's training part
    pipe = make_pipeline(StandardScaler(), SVC())
    grid = {"svc__C": [1.0, 10.0], "svc__gamma": [0.1, 1.0], "svc__multi_class": ["ovo", "ovr"]}
    ours = SVMGridSearchCV(pipe, grid, cv=3).fit(X, y)
    ref = GridSearchCV(pipe, grid, cv=3).fit(X, y)
    np.testing.assert_allclose(
        ours.cv_results_["mean_test_score"], ref.cv_results_["mean_test_score"], atol=0.02
    )
    assert ours.best_estimator_.named_steps["svc"].C == ours.best_params_["svc__C"]


def test_grid_search_validation_batches_our_svms_and_matches_the_loop():
    X, y = _small_problem()
    train, val = np.arange(160), np.arange(160, 240)
    pipe = make_pipeline(StandardScaler(), HierarchicalSVC(random_state=0))
    grid = {"hierarchicalsvc__C": [1.0, 100.0], "hierarchicalsvc__gamma": [0.25, 1.0]}
    best, scores = grid_search_validation(pipe, grid, X, y, train, val)
    for row in scores:  # each candidate fitted on its own gives the same validation accuracy
        params = {k: v for k, v in row.items() if k != "validation accuracy"}
        model = clone(pipe).set_params(**params).fit(X[train], y[train])
        assert row["validation accuracy"] == pytest.approx(
            np.mean(model.predict(X[val]) == y[val]), abs=1 / 80
        )
    assert [list(s)[:2] for s in scores] == [list(grid)] * 4 and best in [
        {k: v for k, v in s.items() if k != "validation accuracy"} for s in scores
    ]


def test_gridsearchcv_runs_our_svms_in_parallel_processes():
    X, y = _small_problem()
    grid = {"C": [0.5, 8.0]}
    one = GridSearchCV(HierarchicalSVC(random_state=0, n_jobs=1), grid, cv=3, n_jobs=1).fit(X, y)
    with parallel_backend("loky"):
        two = GridSearchCV(HierarchicalSVC(random_state=0, n_jobs=1), grid, cv=3, n_jobs=2).fit(X, y)
    np.testing.assert_array_equal(one.cv_results_["mean_test_score"], two.cv_results_["mean_test_score"])


def test_batched_search_rejects_other_estimators():
    assert not supports_batched_search(KNeighborsClassifier())
    with pytest.raises(TypeError, match=r"estimator must be tactile_torch\.svm\.SVC or HierarchicalSVC"):
        SVMGridSearchCV(KNeighborsClassifier(), {"n_neighbors": [1]}).fit(*_small_problem())
