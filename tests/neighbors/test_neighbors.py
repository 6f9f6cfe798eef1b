"""tactile_torch.neighbors: k nearest neighbours with ties in training order, and an exported graph that
resolves them the same way (scikit-learn's own leaves them to its search tree)."""

import numpy as np
import pytest
import torch
from sklearn.neighbors import KNeighborsClassifier

from tactile_torch.export import export_onnx
from tactile_torch.export.classifier_inference import inference_module
from tactile_torch.neighbors import StableKNeighborsClassifier


def _ties(seed=0):
    """Training samples on a small integer grid (many at equal distance) and duplicated zero rows."""
    rng = np.random.default_rng(seed)
    X = np.zeros((60, 4))
    X[30:] = rng.integers(0, 3, (30, 4))
    y = rng.integers(0, 5, 60)
    Q = rng.integers(0, 3, (50, 4)).astype(float)
    Q[:10] = 0.0  # at distance 0 from 30 training samples of every class
    return X, y, Q


@pytest.mark.parametrize("weights", ["distance", "uniform"])
def test_neighbours_are_scikit_learns_away_from_ties_and_ordered_by_index_on_them(weights):
    rng = np.random.default_rng(1)
    X, y, Q = rng.normal(size=(120, 5)), rng.integers(0, 3, 120), rng.normal(size=(40, 5))
    ours = StableKNeighborsClassifier(5, metric="cityblock", weights=weights).fit(X, y)
    ref = KNeighborsClassifier(5, metric="cityblock", weights=weights).fit(X, y)
    np.testing.assert_array_equal(ours.kneighbors(Q)[1], ref.kneighbors(Q)[1])
    np.testing.assert_allclose(ours.predict_proba(Q), ref.predict_proba(Q), atol=1e-12)
    X, y, Q = _ties()
    distances, index = StableKNeighborsClassifier(3, metric="cityblock").fit(X, y).kneighbors(Q)
    full = np.abs(Q[:, None, :] - X[None, :, :]).sum(-1)
    np.testing.assert_array_equal(index, np.argsort(full, axis=1, kind="stable")[:, :3])  # (distance, index)
    np.testing.assert_array_equal(distances, np.take_along_axis(full, index, axis=1))


@pytest.mark.parametrize("weights", ["distance", "uniform"])
def test_the_torch_graph_and_its_onnx_export_give_the_models_labels_on_ties(tmp_path, weights):
    """scikit-learn's own kNN disagrees with any graph on such ties (its ball tree keeps other samples)."""
    import onnxruntime as ort

    X, y, Q = _ties()
    model = StableKNeighborsClassifier(3, metric="cityblock", weights=weights).fit(X, y)
    module = inference_module(model).eval()
    eager = module(torch.from_numpy(Q))[0].numpy()
    np.testing.assert_array_equal(model.classes_[eager], model.predict(Q))
    path = export_onnx(module, (torch.from_numpy(Q[:2]).float(),), tmp_path / "knn.onnx",
                       input_names=["features"], output_names=["labels", "scores"])  # fmt: skip
    session = ort.InferenceSession(str(path))
    labels = session.run(None, {"features": Q[:17].astype(np.float32)})[0]  # another batch size
    np.testing.assert_array_equal(model.classes_[labels], model.predict(Q[:17]))


def test_training_neighbours_exclude_the_sample_itself_and_errors_name_the_argument():
    X, y, _ = _ties()
    model = StableKNeighborsClassifier(2, metric="cityblock").fit(X, y)
    index = model.kneighbors(return_distance=False)
    assert not (index == np.arange(len(X))[:, None]).any()
    with pytest.raises(ValueError, match="n_neighbors must be at most the 60 training samples, got 61"):
        model.kneighbors(X[:2], n_neighbors=61)
    with pytest.raises(ValueError, match="y must be one column of labels"):
        StableKNeighborsClassifier(1).fit(X, np.stack([y, y], axis=1)).predict(X[:1])
