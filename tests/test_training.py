import numpy as np
import pytest
import torch
from sklearn.datasets import make_blobs

from tactile_torch.cli import main
from tactile_torch.svm import SVMInference
from tactile_torch.training import load_features, load_model, make_classifier, train_classifier


@pytest.fixture
def feature_npz(tmp_path):
    X, y = make_blobs(120, n_features=5, centers=3, cluster_std=1.0, random_state=0)
    X[:, 2] *= 100.0  # unequal feature scales: the model must scale them
    path = tmp_path / "feats.npz"
    np.savez(path, features=X, labels=y, class_names=np.array(["cork", "felt", "glass"]))
    return path, X, y


def test_cli_train_prints_a_class_report_and_saves_the_model(feature_npz, tmp_path, capsys):
    path, X, _ = feature_npz
    out = tmp_path / "model.pt"
    assert main(["train", "--data", str(path), "--method", "hmsvm", "--out", str(out), "--C", "10"]) == 0
    text = capsys.readouterr().out
    assert "120 samples x 5 features (features), 3 classes" in text
    assert "trained on 90, tested on 30 held-out samples" in text
    for name in ("cork", "felt", "glass", "mean", "overall accuracy"):
        assert name in text
    saved = load_model(out)
    assert saved["class_names"] == ["cork", "felt", "glass"] and saved["method"] == "hmsvm"
    assert saved["scale"].shape == (5,) and saved["scale"][2] > 50 * saved["scale"][0]  # per-feature std
    # The saved inference state rebuilds a module that gives the estimator's labels on scaled data.
    inf = saved["inference"]
    state = inf["state_dict"]
    tree = {k: state[k] for k in ("left", "right", "column", "leaf_label", "path_sign")}
    module = SVMInference(
        state["support_vectors"],
        state["dual_coef"],
        state["intercept"],
        kernel=inf["kernel"],
        gamma=inf["gamma"],
        mode=inf["mode"],
        tree=tree,
        depth=inf["depth"],
    )
    scaled = X / saved["scale"]
    labels, _ = module(torch.tensor(scaled))
    np.testing.assert_array_equal(labels.numpy(), saved["estimator"].predict(scaled))


@pytest.mark.parametrize("method", ["svm", "lda", "knn"])
def test_train_classifier_methods(feature_npz, method):
    path, X, _ = feature_npz
    feats = load_features(path)
    model = train_classifier(feats, method, C=10.0, random_state=0)
    assert model.report.overall_accuracy > 0.9
    assert len(model.train_index) + len(model.test_index) == 120
    std = X[model.train_index].std(0, ddof=1)
    np.testing.assert_allclose(model.scale, std)
    np.testing.assert_array_equal(
        model.predict(X[model.test_index]), model.estimator.predict(X[model.test_index] / std)
    )


def test_training_errors(tmp_path, feature_npz):
    with pytest.raises(FileNotFoundError, match=r"data must name an existing \.npz file"):
        load_features(tmp_path / "missing.npz")
    bad = tmp_path / "bad.npz"
    np.savez(bad, something=np.zeros(3))
    with pytest.raises(ValueError, match=r"expected an image .*got keys \['something'\]"):
        load_features(bad)
    with pytest.raises(ValueError, match="method must be one of"):
        make_classifier("forest")
    with pytest.raises(ValueError, match="test_size must be in \\(0, 1\\)"):
        train_classifier(load_features(feature_npz[0]), test_size=1.5)
    not_model = tmp_path / "x.pt"
    torch.save({"a": 1}, not_model)
    with pytest.raises(ValueError, match=r"not a tactile-torch classifier"):
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
    saved = load_model(tmp_path / "vibration.pt")
    assert saved["method"] == "hmsvm" and saved["estimator"].C == 4.0 and saved["estimator"].gamma == 0.0186
    assert "overall accuracy" in capsys.readouterr().out
