import numpy as np
import pytest
import torch
from sklearn.datasets import make_blobs

from tactile_torch.cli import main
from tactile_torch.export.model_graph import pipeline_from_model
from tactile_torch.features.files import FeatureSet, load_features
from tactile_torch.training import load_model, save_model, train_classifier


@pytest.fixture
def feature_npz(tmp_path):
    X, y = make_blobs(120, n_features=5, centers=3, cluster_std=1.0, random_state=0)
    X[:, 2] *= 100.0  # unequal feature scales: the model must scale them
    path = tmp_path / "feats.npz"
    np.savez(path, features=X, labels=y, class_names=np.array(["cork", "felt", "glass"]))
    return path, X, y


def test_cli_train_prints_a_class_report_and_saves_the_model(feature_npz, tmp_path, capsys):
    path, X, _ = feature_npz
    out = tmp_path / "model.npz"
    assert main(["train", "--data", str(path), "--method", "hmsvm", "--out", str(out), "--C", "10"]) == 0
    text = capsys.readouterr().out
    assert "120 samples x 5 features (features), 3 classes" in text
    assert "held-out accuracy from 120 samples; 5 stratified folds" in text  # feature rows: no groups
    assert "trained on all 120 samples" in text
    for name in ("cork", "felt", "glass", "mean", "overall accuracy"):
        assert name in text
    saved = load_model(out)
    assert saved.class_names == ["cork", "felt", "glass"] and saved.method == "hmsvm"
    scale = saved.arrays["scale"]
    assert scale.shape == (5,) and scale[2] > 50 * scale[0]  # per-feature std
    assert saved.header["params"]["C"] == 10.0 and saved.header["head"]["mode"] == "tree"
    # The saved arrays rebuild the SVM's inference path: the estimator's labels on scaled data.
    model = train_classifier(load_features(path), "hmsvm", C=10.0, random_state=0)  # what the CLI fitted
    np.testing.assert_array_equal(model.scale, scale)
    head = pipeline_from_model(saved).head
    labels = head(torch.tensor(X / scale))[0]  # (labels, scores, ood_distance)
    np.testing.assert_array_equal(labels.numpy(), model.estimator.predict(X / scale))


def test_save_model_writes_every_method_and_train_needs_two_samples_per_class(feature_npz, tmp_path):
    features = load_features(feature_npz[0])
    lda = train_classifier(features, "lda", random_state=0)
    saved = load_model(save_model(tmp_path / "lda.npz", lda, features))  # LDA has a model file now (v2)
    assert saved.method == "lda" and saved.header["head"]["type"] == "linear"
    labels = pipeline_from_model(saved).head(torch.tensor(features.X / lda.scale))[
        0
    ]  # (labels, scores, distance)
    np.testing.assert_array_equal(labels.numpy(), lda.estimator.predict(features.X / lda.scale))
    with pytest.raises(TypeError, match="estimator must be a fitted tactile_torch SVM"):
        from tactile_torch.export.classifier_inference import encode_classifier

        encode_classifier(object())
    y = features.y.copy()
    y[y == 2] = 1
    y[0] = 2  # class 'glass' keeps a single sample
    lonely = FeatureSet(features.X, y, features.class_names, features.source)
    with pytest.raises(ValueError, match=r"every class needs at least 2 samples.*\['glass'\] have 1"):
        train_classifier(lonely, "svm")


@pytest.mark.parametrize("method", ["svm", "lda", "knn"])
def test_train_classifier_methods(feature_npz, method):
    path, X, _ = feature_npz
    feats = load_features(path)
    model = train_classifier(feats, method, C=10.0, random_state=0)
    assert model.report.overall_accuracy > 0.9 and len(model.fold_accuracy) == 5
    assert len(model.train_index) == len(model.test_index) == 120  # fitted on all, each held out once
    std = X.std(0, ddof=1)
    np.testing.assert_allclose(model.scale, std)
    np.testing.assert_array_equal(model.predict(X), model.estimator.predict(X / std))


def test_training_errors(tmp_path, feature_npz):
    with pytest.raises(FileNotFoundError, match=r"missing\.npz: no such file"):
        load_features(tmp_path / "missing.npz")
    bad = tmp_path / "bad.npz"
    np.savez(bad, something=np.zeros(3))
    with pytest.raises(ValueError, match=r"expected image explorations .*found keys \['something'\]"):
        load_features(bad)
    with pytest.raises(ValueError, match="method must be one of"):
        train_classifier(load_features(feature_npz[0]), "forest")
    with pytest.raises(ValueError, match="test_size must be in \\(0, 1\\)"):
        train_classifier(load_features(feature_npz[0]), test_size=1.5)
    not_model = tmp_path / "x.npz"
    np.savez(not_model, a=np.zeros(2))
    with pytest.raises(ValueError, match=r"x\.npz: not a tactile-torch model file"):
        load_model(not_model)


def test_train_program_trains_the_study_classifier_on_a_file(feature_npz, tmp_path, capsys):
    import importlib.util
    from pathlib import Path

    program = Path(__file__).resolve().parents[1] / "train" / "classification.py"
    spec = importlib.util.spec_from_file_location("train_classification", program)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    path, _, _ = feature_npz
    assert module.main(["vibration", "--data", str(path), "--out", str(tmp_path), "--C", "4"]) == 0
    saved = load_model(tmp_path / "vibration.npz")
    assert saved.method == "hmsvm" and saved.header["params"]["C"] == 4.0
    assert saved.header["params"]["gamma"] == 0.0186 == saved.header["head"]["gamma"]
    assert "overall accuracy" in capsys.readouterr().out
