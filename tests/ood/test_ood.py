"""tactile_torch.ood: the class-conditional Mahalanobis distance against SciPy, its graph, its threshold.

The bundles' "unknown" rule end to end (model file → ONNX → predict) is tested in
tests/export/test_model_graph.py; here the estimator's numbers themselves.
"""

import numpy as np
import pytest
import torch
from scipy.spatial.distance import mahalanobis

from tactile_torch.ood import DEFAULT_QUANTILE, distance_module, fit_ood, fit_rule, ood_distance, signed_log


def _blobs(seed=0, n=40, f=4):
    rng = np.random.default_rng(seed)
    labels = np.repeat([0, 1, 2], n)
    features = rng.normal(size=(len(labels), f)) * [1.0, 2.0, 0.5, 3.0] + 4.0 * np.eye(3, f)[labels]
    return features, labels


def test_first_view_is_the_mahalanobis_distance_to_the_nearest_class():
    features, labels = _blobs()
    state = fit_ood(features, labels)
    u = signed_log(features)
    means = np.stack([u[labels == c].mean(axis=0) for c in range(3)])
    residual = u - means[labels]
    cov = residual.T @ residual / (len(u) - 3)  # pooled within-class covariance
    cov += 1e-3 * np.trace(cov) / len(cov) * np.eye(len(cov))  # the documented ridge
    precision = np.linalg.inv(cov)
    queries = np.random.default_rng(1).normal(size=(7, 4)) * 3.0
    want = [min(mahalanobis(q, m, precision) for m in means) for q in signed_log(queries)]
    got = ood_distance(queries, state["means"], state["precision_cholesky"])
    np.testing.assert_allclose(got, want, rtol=1e-10)


def test_threshold_is_the_quantile_of_out_of_fold_training_distances():
    features, labels = _blobs(seed=2)
    rule = fit_rule(features, labels, scale=np.full(4, 2.0))
    assert rule["quantile"] == DEFAULT_QUANTILE
    # out-of-fold distances run longer than in-sample ones: almost every training row is within
    arrays = {k: v for k, v in rule.items() if k not in ("threshold", "quantile")}
    inside = ood_distance(features / 2.0, **arrays)
    assert np.mean(inside <= rule["threshold"]) >= DEFAULT_QUANTILE
    far = ood_distance(np.full((1, 4), 1e3), **arrays)
    assert far[0] > rule["threshold"]


def test_graph_equals_numpy_in_both_views():
    features, labels = _blobs(seed=3)
    rule = fit_rule(features, labels, scale=np.ones(4), center=features.mean(axis=0))
    x = np.random.default_rng(4).normal(size=(9, 4)) * 2.0
    arrays = {k: v for k, v in rule.items() if k not in ("threshold", "quantile")}
    want = ood_distance(x, **arrays)
    got = distance_module(rule)(torch.from_numpy(x)).numpy()
    np.testing.assert_allclose(got, want, rtol=1e-4)  # the graph runs in float32


def test_bad_input_is_named():
    features, labels = _blobs()
    with pytest.raises(ValueError, match="features must be"):
        fit_ood(features[:, 0], labels)
    with pytest.raises(ValueError, match="quantile must be in"):
        fit_ood(features, labels, quantile=0.2)
    with pytest.raises(ValueError, match="labels must hold every class"):
        fit_ood(features, labels + 1)
