"""tactile_torch.export.ood_branch: the "unknown" rule attached to an exported bundle, reading the tensor it is
measured on, as the trade-off's files carry it (model files' bundles compute it inside their head:
tests/export/test_model_graph.py)."""

import numpy as np
import onnx
import pytest
from sklearn.discriminant_analysis import LinearDiscriminantAnalysis
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import StandardScaler

from tactile_torch.data import make_vibration_recordings
from tactile_torch.export import save_onnx
from tactile_torch.export.ood_branch import attach_distance
from tactile_torch.export.parts import bind_head, export_front, export_head, head_modules, join
from tactile_torch.features import WindowFeatureTransformer
from tactile_torch.ood import DistanceHead, fit_rule, ood_distance
from tactile_torch.robot.contract import (
    CLASS_NAMES_KEY,
    FEATURES_NAME,
    INPUT_LAYOUT_KEY,
    INPUT_SHAPE_KEY,
    OOD_OUTPUT,
    THRESHOLD_KEY,
    WINDOWS_LAYOUT,
)
from tactile_torch.robot.runtime import OnnxPipeline


@pytest.mark.slow  # three dynamo exports (the window-feature graph, the head, the distance part): 15 s on a loaded 2-core machine
def test_part_reads_the_bundles_features_and_the_runtime_says_unknown_beyond_it(tmp_path):
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
    front = export_front(model.named_steps["features"], X[:2], tmp_path / "front.onnx")
    modules = head_modules(model)
    template = export_head(modules, features.shape[1], tmp_path / "head.onnx")
    meta = {
        CLASS_NAMES_KEY: ["a", "b", "c"],
        INPUT_SHAPE_KEY: [None, *X.shape[1:]],
        INPUT_LAYOUT_KEY: WINDOWS_LAYOUT,
    }
    bundle = join(
        onnx.load(str(front)), bind_head(onnx.load(str(template)), modules), tmp_path / "lda.onnx", meta
    )
    scaler = model.named_steps["scale"]
    rule = fit_rule(features, y, scale=scaler.scale_, center=scaler.mean_)
    head = DistanceHead(rule, scale=scaler.scale_, center=scaler.mean_)
    part = export_head([head], features.shape[1], tmp_path / "part.onnx", output_names=(OOD_OUTPUT,))
    proto = onnx.load(str(bundle))
    with pytest.raises(ValueError, match="reads must name a tensor the bundle computes"):
        attach_distance(proto, bind_head(onnx.load(str(part)), [head]), rule, reads="nothing")
    save_onnx(
        attach_distance(proto, bind_head(onnx.load(str(part)), [head]), rule, reads=FEATURES_NAME), bundle
    )
    # one feature graph: the part reads the features the classifier reads, not a copy of them
    assert sum(n.op_type == "DFT" for n in onnx.load(str(bundle)).graph.node) <= 1

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
