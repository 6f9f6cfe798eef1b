"""The classifier catalogue: one key, name, settings and grid per classifier, read everywhere."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.model_selection import ParameterGrid

from tactile_torch import catalogue, training
from tactile_torch.tradeoff import candidates


@pytest.mark.parametrize("key", catalogue.CLASSIFIERS)
def test_every_key_builds_a_clone_able_classifier_that_fits(key):
    rng = np.random.default_rng(0)
    y = np.repeat([0, 1, 2], 10)
    X = rng.normal(size=(30, 4)) + np.eye(3, 4)[y] * 3
    model = catalogue.make_classifier(key, random_state=0)
    copy = clone(model)
    assert copy.get_params() == model.get_params()
    assert np.mean(copy.fit(X, y).predict(X) == y) > 0.8
    grid = catalogue.param_grid(key, 4)
    quick = catalogue.param_grid(key, 4, quick=True)
    for params in ParameterGrid(grid):  # every grid point is a valid setting of the estimator
        clone(model).set_params(**params)
    names = {n for g in ParameterGrid(quick) for n in g}
    assert names == {n for g in ParameterGrid(grid) for n in g}  # quick tunes the same parameters
    assert 1 < len(ParameterGrid(quick)) <= len(ParameterGrid(grid))
    entry = catalogue.entry(key)
    assert entry.family == "classical" and entry.needs_scaling and entry.description


def test_names_are_unique_and_resolve_in_any_spelling():
    names = [catalogue.display_name(k) for k in catalogue.CLASSIFIERS]
    assert len(set(names)) == len(names) == len(catalogue.CLASSIFIERS)
    assert all(k == k.lower() for k in catalogue.CLASSIFIERS)
    for key in catalogue.CLASSIFIERS:
        assert catalogue.resolve(key) == key
        assert catalogue.resolve(catalogue.display_name(key)) == key
        assert catalogue.resolve(catalogue.display_name(key).upper()) == key
    assert catalogue.resolve("svm") == "svc"  # what `train --method svm` always meant: one-vs-one
    with pytest.raises(ValueError, match=r"classifier must be one of \['hmsvm'"):
        catalogue.resolve("forest")
    with pytest.raises(ValueError, match="n_features must be an integer >= 1"):
        catalogue.param_grid("svc", 0)


def test_knn_has_the_studys_settings_everywhere():
    from tactile_torch.studies._models import classifiers
    from tactile_torch.studies.image_classification import classifiers as image_classifiers

    knn = catalogue.make_classifier("knn")
    assert (knn.n_neighbors, knn.metric, knn.weights) == (3, "cityblock", "distance")
    same = [
        catalogue.make_classifier("kNN", n_features=21),
        catalogue.classifier_pipeline("knn", scaling="unit").named_steps["classifier"],
        classifiers(0)["kNN"],
        image_classifiers(0)["kNN"][-1],
    ]
    for other in same:
        assert other.get_params() == knn.get_params()


def test_training_trade_off_and_cli_read_the_catalogue():
    from tactile_torch.cli import build_parser

    assert set(catalogue.CLASSIFIERS) <= set(training.METHODS)
    assert candidates.CLASSIFIERS == tuple(catalogue.display_name(k) for k in catalogue.CLASSIFIERS)
    train = build_parser()._subparsers._group_actions[0].choices["train"]
    method = next(a for a in train._actions if a.dest == "method")
    assert list(method.choices) == catalogue.choices()
    svm = catalogue.make_classifier("svm", C=4.0, n_features=8)
    assert type(svm).__name__ == "SVC" and (svm.C, svm.gamma) == (4.0, 1 / 8)
    assert type(catalogue.make_classifier("ncm", n_features=8)).__name__ == "NearestCentroid"
    with pytest.raises(ValueError, match="classifier must be one of"):
        catalogue.make_classifier("forest")


def test_candidates_take_keys_or_names_and_are_tuned_by_default():
    sets, _ = candidates.feature_sets("features", (5,), n_features=5, quick=True)
    by_key = candidates.build_candidates(sets[:1], classifiers=["lda", "knn"])
    by_name = candidates.build_candidates(sets[:1], classifiers=["LDA", "kNN"])
    assert (
        [c.name for c in by_key]
        == [c.name for c in by_name]
        == ["LDA | all 5 features", "kNN | all 5 features"]
    )
    assert [c.key for c in by_key] == ["lda", "knn"]
    assert by_key[1].tuning.grid == {"classifier__n_neighbors": list(catalogue.KNN_K_GRID)}
    untuned = candidates.build_candidates(sets[:1], classifiers=["knn"], tune=False)
    assert untuned[0].tuning is None
    with pytest.raises(ValueError, match="classifiers must name some of"):
        candidates.build_candidates(sets, classifiers=["forest"])


def test_the_studys_model_is_tuned_by_the_studys_protocol():
    vib, _ = candidates.feature_sets("vibration", (), windows=[800], quick=True)
    study = candidates.build_candidates(vib[:1], classifiers=["hmsvm", "svc"])
    assert (study[0].tuning.protocol, study[0].tuning.n_splits) == ("kfold", 10)  # method 2: 10-fold
    assert (study[1].tuning.protocol, study[1].tuning.n_splits) == ("kfold", 3)
    img, _ = candidates.feature_sets("image", (10, 3, 32, 32))
    study = candidates.build_candidates(img[:1], classifiers=["hmsvm"])
    assert (study[0].tuning.protocol, study[0].tuning.n_splits) == ("validation", 4)  # method 1: 60/20/20
