"""tactile_torch.tradeoff.bundle and tactile_torch.tradeoff.unknown: a candidate's file, written the same way
for timing and for deployment, with its "unknown" rule measured on what the file computes anyway."""

import numpy as np
import onnx
import pytest
import torch
from sklearn.discriminant_analysis import LinearDiscriminantAnalysis
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import StandardScaler

from tactile_torch.export.neural import EMBEDDING_OUTPUT
from tactile_torch.export.parts import ExportPool
from tactile_torch.features import RawInput, TaxelFeatureTransformer
from tactile_torch.neural import TaxelCNNClassifier
from tactile_torch.ood import ood_distance
from tactile_torch.robot.contract import OOD_OUTPUT, PRESSURE_LAYOUT, THRESHOLD_KEY
from tactile_torch.robot.runtime import OnnxPipeline
from tactile_torch.tradeoff.bundle import bare_bundle, finish_bundle, touch_cost
from tactile_torch.tradeoff.inputs import Samples


def _fingertip(n=36, t=24, seed=0):
    """4 x 4 pressure maps of 3 classes (a different region pressed per class), raw counts resting at 10."""
    rng = np.random.default_rng(seed)
    maps = rng.normal(10.0, 0.5, (n, t, 4, 4)).astype(np.float32)
    regions = [np.s_[:, :2, :], np.s_[:, 2:, :], np.s_[:, :, 1:3]]
    y = np.arange(n) % 3
    for i in range(n):
        maps[i][regions[y[i]]] += np.linspace(5, 30, t)[:, None, None] * rng.uniform(0.8, 1.2)
    return maps, y


def _ops(path):
    return [n.op_type for n in onnx.load(str(path)).graph.node]


@pytest.mark.slow  # two dynamo exports (the network, the distance part): 11 s on a loaded 2-core machine
def test_a_networks_rule_reads_its_embedding_and_adds_no_feature_graph(tmp_path):
    """The distance of a learned candidate is on its embedding: the file is the network plus a few small
    products (before: a second graph computing the fused image features of every frame)."""
    X, y = _fingertip()
    model = Pipeline(
        [
            ("features", RawInput()),
            ("classifier", TaxelCNNClassifier(max_epochs=3, progress=False, random_state=0)),
        ]
    ).fit(X, y)
    with ExportPool(tmp_path / "parts", background=False) as pool:
        bare = bare_bundle(
            model, X[:2], tmp_path / "bare.onnx", {}, pool, front=("front", "raw"), class_names=("a", "b", "c"),
            layout=PRESSURE_LAYOUT,
        )  # fmt: skip
        path, (rule, part, n_inputs, reads, front) = finish_bundle(
            bare, tmp_path / "cnn.onnx", model, X, y, pool
        )
    graph = onnx.load(str(path)).graph
    assert [o.name for o in graph.output] == ["labels", "scores", OOD_OUTPUT]  # the embedding is inner
    assert {o.name for o in onnx.load(str(bare)).graph.output} >= {EMBEDDING_OUTPUT}
    assert (
        n_inputs == 2 * 32 and reads == EMBEDDING_OUTPUT and front is None
    )  # TaxelCNN: mean and max per channel
    added = len(_ops(path)) - len(_ops(bare))
    assert 0 < added < 40 and "Conv" not in _ops(path)[len(_ops(bare)) :]
    pipe = OnnxPipeline(path)
    assert float(pipe.metadata[THRESHOLD_KEY]) == pytest.approx(float(rule["threshold"]))
    raw = X[:7]  # a batch size other than the export's
    with torch.no_grad():
        E = model.steps[-1][1].to_module().embed(torch.from_numpy(raw)).double().numpy()
    arrays = {k: v for k, v in rule.items() if k not in ("threshold", "quantile")}
    center, scale = (part.standardise.mean.numpy(), part.standardise.scale.numpy())
    out = pipe.run(pipe.validate(raw))
    np.testing.assert_allclose(out[OOD_OUTPUT], ood_distance((E - center) / scale, **arrays), rtol=1e-3)
    np.testing.assert_array_equal(
        out["labels"], model.steps[-1][1].to_module()(torch.from_numpy(raw))[0].numpy()
    )


@pytest.mark.slow  # three dynamo exports (features, head, distance part): 14 s on a loaded 2-core machine
def test_a_classical_rule_reads_the_features_its_head_reads_and_equals_the_numpy_rule(tmp_path):
    X, y = _fingertip()
    model = Pipeline(
        [
            ("features", TaxelFeatureTransformer()),
            ("scale", StandardScaler()),
            ("classifier", LinearDiscriminantAnalysis()),
        ]
    ).fit(X, y)
    with ExportPool(tmp_path / "parts", background=False) as pool:
        key = ("front", "taxels")
        bare = bare_bundle(
            model, X[:2], tmp_path / "bare.onnx", {}, pool, front=key, class_names=("a", "b", "c"), layout=PRESSURE_LAYOUT
        )  # fmt: skip
        path, (rule, *_) = finish_bundle(bare, tmp_path / "lda.onnx", model, X, y, pool)
    ops = _ops(path)
    assert ops.count("ReduceMean") == _ops(bare).count("ReduceMean")  # one feature graph, read twice
    pipe = OnnxPipeline(path)
    scaler = model.named_steps["scale"]
    arrays = {k: v for k, v in rule.items() if k not in ("threshold", "quantile")}
    features = model.named_steps["features"].transform(X[:5])
    want = ood_distance((features - scaler.mean_) / scaler.scale_, **arrays)
    np.testing.assert_allclose(pipe.run(pipe.validate(X[:5]))[OOD_OUTPUT], want, rtol=2e-4)
    np.testing.assert_array_equal(pipe.predict(X[:5]), model.predict(X[:5]))


def test_the_per_touch_cost_counts_the_early_checkpoints_of_frame_bundles_only():
    frames = Samples("pressure", np.zeros((2, 8, 4, 4)), np.zeros(2, int), [], PRESSURE_LAYOUT, 0.8, "")
    windows = Samples("windows-800", np.zeros((2, 3, 800)), np.zeros(2, int), [], "B,3,W", 0.8, "")
    assert touch_cost(0.5, {"threshold": 1.2, "checkpoints": [1, 2, 4]}, frames) == pytest.approx(2.0)
    assert touch_cost(0.5, {"threshold": None, "checkpoints": [1, 2, 4]}, frames) == pytest.approx(0.5)
    assert touch_cost(0.5, None, frames) == pytest.approx(0.5)
    assert touch_cost(0.5, None, windows) is None
