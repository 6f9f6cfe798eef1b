"""The torch-free runtime (onnxruntime and numpy): validation, labels, "unknown" and its reasons.

Runs on the robot install (no torch, no onnx): the bundle is the hand-encoded energy bundle of
``tests/stream_helpers.py`` (scores = per-axis mean square, label = argmax), checked against NumPy.
"""

import numpy as np
import pytest

from tactile_torch.robot.runtime import OnnxPipeline
from tests.conftest import run_without_torch
from tests.stream_helpers import energy_bundle


@pytest.fixture(scope="module")
def bundle(tmp_path_factory):
    return energy_bundle(tmp_path_factory.mktemp("rt") / "energy.onnx", window=16)


def test_predict_matches_numpy_at_any_batch_size(bundle):
    pipe = OnnxPipeline(bundle)
    rng = np.random.default_rng(0)
    raw = (
        (rng.normal(size=(9, 3, 16)) * rng.uniform(0.2, 1.2, size=(9, 3, 1)))
        .clip(-4.9, 4.9)
        .astype(np.float32)
    )
    labels, scores = pipe.predict_scores(raw)
    want_scores = (raw.astype(np.float64) ** 2).mean(axis=-1)
    np.testing.assert_array_equal(labels, want_scores.argmax(axis=1))
    np.testing.assert_allclose(scores, want_scores, rtol=1e-5, atol=1e-6)
    assert pipe.predict_names(raw) == [["x", "y", "z"][i] for i in labels]
    assert pipe.input_shape == (None, 3, 16) and pipe.metadata["window_size"] == "16"
    np.testing.assert_array_equal(pipe.predict(raw.astype(np.float64)), labels)
    np.testing.assert_array_equal(np.concatenate([pipe.predict(raw[i : i + 1]) for i in range(9)]), labels)
    assert "vibration-energy" in repr(pipe)


@pytest.mark.parametrize(
    ("raw", "err", "match"),
    [
        ([[0.0] * 16] * 3, TypeError, "raw must be a numpy.ndarray, got list"),
        (np.zeros((3, 16), np.float32), ValueError, r"raw must have shape \(B, 3, W\) = \('B', 3, 16\)"),
        (np.zeros((2, 3, 17), np.float32), ValueError, r"got \(2, 3, 17\)"),
        (np.zeros((0, 3, 16), np.float32), ValueError, "at least one sample"),
        (np.zeros((2, 3, 16), np.uint8), TypeError, "dtype float32, float64, got uint8"),
        (np.full((2, 3, 16), np.nan, np.float32), ValueError, "raw must be finite, got 96 NaN/inf"),
    ],
)
def test_bad_input_is_named(bundle, raw, err, match):
    with pytest.raises(err, match=match):
        OnnxPipeline(bundle).predict(raw)


def test_bad_construction(tmp_path, bundle):
    with pytest.raises(
        FileNotFoundError, match=r"missing\.onnx: no such file, expected an exported \.onnx bundle"
    ):
        OnnxPipeline(tmp_path / "missing.onnx")
    with pytest.raises(ValueError, match="intra_op_threads must be an int >= 0, got -1"):
        OnnxPipeline(bundle, intra_op_threads=-1)


def test_runtime_runs_where_torch_cannot_be_imported(bundle):
    out = run_without_torch(
        f"""
        import numpy as np
        from tactile_torch.robot.runtime import OnnxPipeline

        pipe = OnnxPipeline({str(bundle)!r})
        print(pipe.predict(np.ones((1, 3, 16), np.float32) * np.arange(16) / 16).tolist(), "torch" in sys.modules)
        """
    )
    assert out.returncode == 0, out.stderr
    out = out.stdout
    assert out.split() == ["[0]", "False"]  # the same energy on each axis: the first


def test_no_label_is_returned_with_a_non_finite_score(bundle):
    import math

    from tactile_torch.robot.runtime import NonFiniteScoresError

    pipe = OnnxPipeline(bundle)
    raw = np.ones((4, 3, 16), np.float32) * np.linspace(-1, 1, 16, dtype=np.float32)
    raw[2, 0, 5] = 1e30  # finite input; its square overflows float32 in the scores
    with pytest.raises(
        NonFiniteScoresError, match=r"non-finite scores for 1 of 4 sample\(s\) \(rows 2\)"
    ) as err:
        pipe.predict(raw, range_g=math.inf)
    np.testing.assert_array_equal(err.value.rows, [2])
    with pytest.raises(ValueError, match="no label is returned"):
        pipe.predict_scores(raw, range_g=math.inf)
    prediction = pipe.classify(raw, range_g=math.inf)
    assert prediction.labels[2] == -1 and prediction.reasons[2].startswith("scores not finite")
    assert pipe.predict(raw[[0, 1, 3]]).shape == (3,)


def test_a_window_beyond_the_sensor_range_is_unknown_in_the_api(bundle):
    """The API applies the bundle's range as the CLI does: a 20 g sample is not classified."""
    pipe = OnnxPipeline(bundle)
    raw = np.ones((3, 3, 16), np.float32) * np.linspace(-1, 1, 16, dtype=np.float32)
    raw[1, 2, 7] = 20.0
    raw[2, 0, 0] = 1e30
    assert pipe.predict_names(raw)[1:] == ["unknown", "unknown"]
    prediction = pipe.classify(raw)
    assert prediction.labels.tolist()[1:] == [-1, -1] and prediction.labels[0] >= 0
    assert prediction.reasons[1] == "a sample of 20 g, beyond the sensor's range ±5 g"
    assert prediction.reasons[2] == "a sample of 1e+30 g, beyond the sensor's range ±5 g"
    assert np.isnan(prediction.scores[1:]).all() and np.isfinite(prediction.scores[0]).all()
    assert pipe.predict(raw, range_g=25.0)[1] >= 0  # a wider range classifies it


def test_a_constant_window_is_unknown(bundle):
    pipe = OnnxPipeline(bundle)
    raw = np.zeros((2, 3, 16), np.float32)
    raw[1] = np.array([0.0, 0.0, 1.0])[:, None]  # a constant 1 g
    prediction = pipe.classify(raw)
    assert prediction.labels.tolist() == [-1, -1]
    assert prediction.reasons[1] == "no vibration: every axis is constant (0, 0, 1 g)"


def test_beyond_range_flags_the_windows_holding_a_value_past_the_range():
    from tactile_torch.robot.runtime import beyond_range

    raw = np.zeros((6, 3, 16), np.float32)
    raw[0, 2, 3] = 5.0  # the bounds are in range
    raw[0, 1, 4] = -5.0
    raw[1, 0, 15] = 5.001
    raw[2, 1, 0] = -7.0
    raw[3, 2, 9] = np.nan
    raw[4, 0, 7] = 1e30
    want = [
        any(not -5.0 <= v <= 5.0 for v in row.ravel().tolist()) for row in raw
    ]  # per sample, as the stream
    np.testing.assert_array_equal(beyond_range(raw, 5.0), want)
    assert want == [False, True, True, True, True, False]
    np.testing.assert_array_equal(beyond_range(raw, np.inf), [False, False, False, True, False, False])


@pytest.mark.parametrize(
    ("metadata", "match"),
    [
        ({"window_size": "5"}, r"window_size = '5' \(the graph takes windows of 16 samples\)"),
        ({"input_shape": "[null, 3, 5]"}, "input_shape axis 2 is 5, the graph takes 16"),
        ({"input_shape": "[null, 4, 16]"}, "input_shape axis 1 is 4, the graph takes 3"),
        ({"sample_rate_hz": "0"}, "sample_rate_hz = '0'"),
        ({"class_names": '["x", "y"]'}, "2 class_names, the graph gives 3 scores"),
        ({"input_shape": '"lots"'}, "input_shape must be a JSON list"),
    ],
)
def test_a_header_that_disagrees_with_its_graph_is_refused(tmp_path, metadata, match):
    path = energy_bundle(tmp_path / "lying.onnx", window=16, metadata=metadata)
    with pytest.raises(ValueError, match=match):
        OnnxPipeline(path)
