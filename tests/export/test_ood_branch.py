"""tactile_torch.export.ood_branch: the "unknown" rule added beside an exported bundle, as the trade-off's
deployed models carry it (model files' bundles compute it inside their head: tests/export/test_model_graph.py)."""

import numpy as np
import onnx
import pytest
from sklearn.discriminant_analysis import LinearDiscriminantAnalysis
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import StandardScaler

from tactile_torch.data import make_vibration_recordings
from tactile_torch.export.fitted import export_model
from tactile_torch.export.ood_branch import add_distance, distance_graph
from tactile_torch.export.parts import export_front
from tactile_torch.features import WindowFeatureTransformer
from tactile_torch.ood import DistanceHead, fit_rule, ood_distance
from tactile_torch.robot.contract import OOD_OUTPUT, THRESHOLD_KEY
from tactile_torch.robot.runtime import OnnxPipeline


@pytest.mark.slow  # two dynamo exports of the window-feature graph: 18 s on a loaded 2-core machine
def test_branch_computes_the_distance_and_the_runtime_says_unknown_beyond_it(tmp_path):
    windows = make_vibration_recordings(3, duration_s=4, random_state=0).windows(64)
    X, y = windows.windows.numpy(), windows.labels.numpy()
    model = Pipeline(
        [
            ("features", WindowFeatureTransformer()),
            ("scale", StandardScaler()),
            ("classifier", LinearDiscriminantAnalysis()),
        ]
    ).fit(X, y)
    features = model.named_steps["features"].transform(X)
    bundle = export_model(model, tmp_path / "lda.onnx", X[:2], ["a", "b", "c"])
    scaler = model.named_steps["scale"]
    rule = fit_rule(features, y, scale=scaler.scale_, center=scaler.mean_)
    head = DistanceHead(rule, scale=scaler.scale_, center=scaler.mean_)
    front = export_front(model.named_steps["features"], X[:2], tmp_path / "front.onnx")
    add_distance(bundle, distance_graph(onnx.load(str(front)), head, features.shape[1]), rule)

    pipe = OnnxPipeline(bundle)
    assert float(pipe.metadata[THRESHOLD_KEY]) == float(rule["threshold"])
    silent = np.zeros((2, *X.shape[1:]), dtype=np.float32)  # a sensor that gives nothing: no surface's
    raw = np.concatenate([X[:5], silent])  # a batch size other than the export's
    arrays = {k: v for k, v in rule.items() if k not in ("threshold", "quantile")}
    want = ood_distance(
        (model.named_steps["features"].transform(raw) - scaler.mean_) / scaler.scale_, **arrays
    )
    np.testing.assert_allclose(pipe.run(pipe.validate(raw))[OOD_OUTPUT], want, rtol=1e-4)
    labels = pipe.predict(raw)
    assert (labels[5:] == -1).all()
    np.testing.assert_array_equal(labels[:5], model.predict(X[:5]))
