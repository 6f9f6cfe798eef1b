"""Neural candidates, the learned front end, int8 variants and the memory measurement.

The neural classifiers take 3-D to 5-D raw inputs, so the scikit-learn checks that fit on 2-D
matrices do not apply; those that do (clone, ``get_params``, parameter validation) run in
``test_estimator_checks.py``, and the conventions that need real inputs are tested here:
``NotFittedError``, determinism for one seed, probabilities that sum to one.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from sklearn.base import clone
from sklearn.exceptions import NotFittedError

from tactile_torch.export import export_classifier
from tactile_torch.export.int8 import quantise_bundle
from tactile_torch.neural import ExplorationCNNClassifier, TaxelCNNClassifier, WindowCNNClassifier
from tactile_torch.neural.front_end import LearnedFrontEndClassifier, SoftFrontEnd, crammer_singer_loss
from tactile_torch.neural.networks import WINDOW_WIDTHS, WindowCNN, build, count_parameters
from tactile_torch.neural.training import inner_split
from tactile_torch.robot.runtime import OnnxPipeline
from tactile_torch.tradeoff.memory import peak_memory_mib

FAST = {"max_epochs": 3, "progress": False, "random_state": 0}


def _windows(n: int = 48, width: int = 64, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Two classes of windows: a slow and a fast sinusoid on every axis, with noise."""
    rng = np.random.default_rng(seed)
    y = np.arange(n) % 2
    t = np.arange(width)
    freq = np.where(y == 0, 0.05, 0.25)[:, None, None]
    X = np.sin(2 * np.pi * freq * t + rng.uniform(0, 6, (n, 3, 1))) + 0.3 * rng.normal(size=(n, 3, width))
    return X.astype(np.float32), y


def _frames(n: int = 8, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """White 24 x 24 frames with a dark square (class 0) or a dark bar (class 1)."""
    rng = np.random.default_rng(seed)
    frames = np.full((n, 4, 3, 24, 24), 255, dtype=np.uint8)
    y = np.arange(n) % 2
    for i in range(n):
        r, c = rng.integers(2, 8, 2)
        if y[i] == 0:
            frames[i, :, :, r : r + 10, c : c + 10] = 40
        else:
            frames[i, :, :, r : r + 3, 2:22] = 40
    return frames, y


def test_window_cnn_sizes_have_the_documented_parameter_counts():
    small = build(WindowCNN, 5, WINDOW_WIDTHS["small"], generator=torch.Generator().manual_seed(0))
    large = build(WindowCNN, 5, WINDOW_WIDTHS["large"], generator=torch.Generator().manual_seed(0))
    assert 3_000 <= count_parameters(small) <= 6_000
    assert 80_000 <= count_parameters(large) <= 120_000


def test_build_leaves_the_global_random_state_alone():
    before = torch.random.get_rng_state()
    build(WindowCNN, 3, generator=torch.Generator().manual_seed(1))
    assert torch.equal(before, torch.random.get_rng_state())


def test_window_cnn_is_deterministic_clone_able_and_gives_probabilities():
    X, y = _windows()
    a = WindowCNNClassifier(**FAST).fit(X, y)
    b = clone(a).fit(X, y)
    for (name, p), (_, q) in zip(a.network_.named_parameters(), b.network_.named_parameters(), strict=True):
        assert torch.equal(p, q), name
    c = WindowCNNClassifier(**{**FAST, "random_state": 1}).fit(X, y)
    assert not torch.equal(a.network_.head.weight, c.network_.head.weight)
    proba = a.predict_proba(X)
    assert proba.shape == (len(X), 2)
    np.testing.assert_allclose(proba.sum(1), 1.0, atol=1e-6)
    assert np.array_equal(a.predict(X), a.classes_[proba.argmax(1)])
    assert a.get_params()["size"] == "small" and clone(a).get_params() == a.get_params()
    assert a.n_parameters_ == count_parameters(a.network_)


def test_window_cnn_learns_a_separable_problem():
    X, y = _windows(96)
    clf = WindowCNNClassifier(max_epochs=40, learning_rate=1e-2, progress=False, random_state=0)
    train = np.arange(len(y)) % 4 < 2  # both classes on both sides
    clf.fit(X[train], y[train])
    assert clf.score(X[~train], y[~train]) >= 0.9
    assert 1 <= clf.training_log_.best_epoch <= clf.n_epochs_


def test_early_stopping_stops_before_max_epochs_when_validation_loss_rises():
    X, y = _windows(40)
    rng = np.random.default_rng(0)
    y = rng.permutation(y)  # no signal: the held-out loss cannot keep falling
    clf = WindowCNNClassifier(size="large", max_epochs=200, patience=3, learning_rate=1e-2, progress=False)
    clf.set_params(random_state=0).fit(X, y)
    assert clf.n_epochs_ < 200
    assert clf.n_epochs_ - clf.training_log_.best_epoch == 3


def test_inner_split_keeps_groups_whole_and_every_class_in_training():
    y = np.repeat([0, 1, 2], 12)
    groups = np.repeat(np.arange(9), 4)
    train, held = inner_split(y, groups, 0.3, np.random.default_rng(0))
    assert not set(groups[train]) & set(groups[held])
    assert set(y[train]) == {0, 1, 2} and set(y[held]) == {0, 1, 2}
    train, held = inner_split(np.array([0, 1]), None, 0.5, np.random.default_rng(0))
    assert len(held) == 0 and len(train) == 2  # one sample per class: nothing can be held out


def test_taxel_and_exploration_cnns_fit_and_predict():
    frames, y = _frames()
    maps = (255 - frames[:, :, 0]).astype(np.float32) / 255  # (N, T, H, W) pressure
    taxel = TaxelCNNClassifier(**FAST).fit(maps, y)
    explore = ExplorationCNNClassifier(**FAST).fit(frames, y)
    for clf, X in ((taxel, maps), (explore, frames)):
        proba = clf.predict_proba(X)
        np.testing.assert_allclose(proba.sum(1), 1.0, atol=1e-6)
        assert clf.n_parameters_ > 0
    # float frames in [0, 1] are the same input as their uint8 levels
    np.testing.assert_allclose(
        explore.predict_proba(frames / 255.0), explore.predict_proba(frames), atol=1e-6
    )


@pytest.mark.parametrize(
    ("make", "X", "match"),
    [
        (
            lambda: WindowCNNClassifier(),
            np.zeros((4, 2, 16), np.float32),
            r"windows must have shape \(N, 3, W\)",
        ),
        (lambda: WindowCNNClassifier(), np.full((4, 3, 16), np.nan, np.float32), "windows must be finite"),
        (lambda: TaxelCNNClassifier(), np.zeros((4, 5), np.float32), r"maps must have shape \(N, T, H, W\)"),
        (lambda: ExplorationCNNClassifier(), np.zeros((4, 2, 1, 8, 8), np.uint8), r"\(N, T, 3, H, W\)"),
        (
            lambda: ExplorationCNNClassifier(),
            np.full((4, 2, 3, 8, 8), 2.0),
            r"uint8 \(0-255\) or float in \[0, 1\]",
        ),
    ],
)
def test_neural_classifiers_reject_bad_input(make, X, match):
    with pytest.raises(ValueError, match=match):
        make().fit(X, np.arange(len(X)) % 2)


def test_neural_classifier_errors_for_parameters_and_unfitted_use():
    X, y = _windows(8)
    with pytest.raises(ValueError, match="size"):
        WindowCNNClassifier(size="huge").fit(X, y)
    with pytest.raises(ValueError, match="max_epochs"):
        WindowCNNClassifier(max_epochs=0).fit(X, y)
    with pytest.raises(NotFittedError):
        WindowCNNClassifier().predict(X)
    clf = WindowCNNClassifier(**FAST).fit(X, y)
    with pytest.raises(ValueError, match=r"windows must have shape \(N, 3, 64\) as in fit"):
        clf.predict(X[:, :, :32])


@pytest.mark.parametrize("kind", ["windows", "maps", "frames"])
def test_onnx_bundle_matches_the_torch_model_at_another_batch_size(tmp_path, kind):
    if kind == "windows":
        X, y = _windows(24)
        clf = WindowCNNClassifier(**FAST).fit(X, y)
    else:
        X, y = _frames()
        if kind == "maps":
            X = (255 - X[:, :, 0]).astype(np.float32) / 255
            clf = TaxelCNNClassifier(**FAST).fit(X, y)
        else:
            clf = ExplorationCNNClassifier(**FAST).fit(X, y)
    path = export_classifier(clf, tmp_path / "m.onnx", X[:2], class_names=["a", "b"])
    pipe = OnnxPipeline(path)
    labels, scores = pipe.predict_scores(X[:5])  # exported at batch 2, run at batch 5
    proba = clf.predict_proba(X[:5])
    assert np.array_equal(labels, proba.argmax(1))
    np.testing.assert_allclose(scores, proba, atol=1e-4)
    assert pipe.class_names == ["a", "b"] and pipe.metadata["n_parameters"] == str(clf.n_parameters_)


def test_int8_bundles_load_and_mostly_agree(tmp_path):
    X, y = _windows(96)
    clf = WindowCNNClassifier(size="large", max_epochs=30, learning_rate=1e-2, progress=False, random_state=0)
    train = np.arange(len(y)) % 4 < 2
    clf.fit(X[train], y[train])
    path = export_classifier(clf, tmp_path / "float.onnx", X[:2])
    float_labels = OnnxPipeline(path).predict(X[~train])
    for mode in ("static", "dynamic"):
        out, used = quantise_bundle(path, tmp_path / f"{mode}.onnx", calibration=X[train][:16], mode=mode)
        assert used == mode
        q = OnnxPipeline(out)
        assert (
            q.sealed
            and q.metadata["tactile_torch.sha256"] != OnnxPipeline(path).metadata["tactile_torch.sha256"]
        )
        assert (
            q.metadata["quantisation"] == mode
            and q.metadata["class_names"] == OnnxPipeline(path).metadata["class_names"]
        )
        assert np.mean(q.predict(X[~train]) == float_labels) >= 0.9
        assert out.stat().st_size < path.stat().st_size
    with pytest.raises(ValueError, match="calibration must hold at least one raw input"):
        quantise_bundle(path, tmp_path / "x.onnx", mode="static")
    with pytest.raises(ValueError, match="mode must be one of"):
        quantise_bundle(path, tmp_path / "x.onnx", mode="int4")


def test_peak_memory_is_measured_in_a_child_process(tmp_path):
    X, y = _windows(8)
    clf = WindowCNNClassifier(**FAST).fit(X, y)
    path = export_classifier(clf, tmp_path / "m.onnx", X[:2])
    mib = peak_memory_mib(path, X[:1])
    assert 0.0 <= mib < 500.0
    with pytest.raises(ValueError, match=r"sample must hold one raw input \(batch 1\)"):
        peak_memory_mib(path, X[:2])
    with pytest.raises(RuntimeError, match="memory measurement of"):
        peak_memory_mib(tmp_path / "missing.onnx", X[:1])


def test_crammer_singer_loss_matches_its_definition():
    scores = torch.tensor([[2.0, 0.5, 1.8], [0.0, 3.0, 1.0]])
    y = torch.tensor([0, 2])
    # sample 0: 1 + 1.8 - 2.0 = 0.8; sample 1: 1 + 3.0 - 1.0 = 3.0
    assert float(crammer_singer_loss(scores, y)) == pytest.approx((0.8 + 3.0) / 2)


def test_soft_front_end_gradient_reaches_threshold_and_temperatures():
    frames, _ = _frames(2)
    front = SoftFrontEnd(240 / 255, 0.5, 2)
    front(torch.from_numpy(frames).float() / 255).sum().backward()
    for name in ("threshold_logit", "log_edge_threshold", "log_temperatures"):
        grad = getattr(front, name).grad
        assert grad is not None and torch.isfinite(grad).all() and grad.abs().sum() > 0, name


def test_learned_front_end_moves_its_settings_and_exports(tmp_path):
    frames, y = _frames(12)
    kw = {"epochs": 2, "frames_per_step": 2, "batch_size": 4, "head_steps": 50, "progress": False}
    hand = LearnedFrontEndClassifier(False, random_state=0, **kw).fit(frames, y)
    learned = LearnedFrontEndClassifier(True, random_state=0, **kw).fit(frames, y)
    assert hand.threshold_ == 240 / 255 and hand.edge_threshold_ == 0.5
    assert learned.threshold_ != pytest.approx(240 / 255, abs=1e-4)
    assert learned.learned_settings()["threshold"][0] == 240 / 255
    assert len(learned.history_) == 3
    path = export_classifier(learned, tmp_path / "front.onnx", frames[:2])
    labels, scores = OnnxPipeline(path).predict_scores(frames[:5])
    expected = learned.decision_function(frames[:5])
    assert np.array_equal(labels, expected.argmax(1))
    np.testing.assert_allclose(scores, expected, atol=1e-4)
    with pytest.raises(TypeError, match="frames must be uint8"):
        LearnedFrontEndClassifier(**kw).fit(frames.astype(np.float32), y)


def test_cutoff_features_at_the_hand_set_value_are_the_21_features():
    from tactile_torch.neural.cutoff import CutoffWindowFeatures
    from tactile_torch.signal import window_features

    X, _ = _windows(6, width=128)
    ours = CutoffWindowFeatures(128, 0.5)(torch.from_numpy(X)).double()
    np.testing.assert_allclose(ours.numpy(), window_features(torch.from_numpy(X)).double().numpy(), rtol=1e-5)


def test_learned_cutoff_moves_and_exports(tmp_path):
    from tactile_torch.neural.cutoff import LearnedCutoffClassifier

    X, y = _windows(48, width=128)
    hand = LearnedCutoffClassifier(False, head_steps=50, random_state=0).fit(X, y)
    learned = LearnedCutoffClassifier(True, epochs=5, head_steps=50, random_state=0).fit(X, y)
    assert hand.cutoff_ == 0.5
    assert learned.cutoff_ != pytest.approx(0.5, abs=1e-4)
    assert len(learned.history_) == 6
    path = export_classifier(learned, tmp_path / "cut.onnx", X[:2])
    assert OnnxPipeline(path).sealed
    labels, scores = OnnxPipeline(path).predict_scores(X[:5])
    expected = learned.decision_function(X[:5])
    assert np.array_equal(labels, expected.argmax(1))
    np.testing.assert_allclose(scores, expected, atol=1e-4)
    with pytest.raises(ValueError, match=r"windows must have shape \(N, 3, W\)"):
        LearnedCutoffClassifier().fit(X[:, :2], y)


def test_comparison_scores_every_group_once_and_rebinds_the_folds(tmp_path):
    from tactile_torch.data.stylus import make_vibration_recordings
    from tactile_torch.export.fitted import rebind
    from tactile_torch.tradeoff.comparison import ModelSpec, compare_models
    from tactile_torch.tradeoff.inputs import vibration_samples

    rec = make_vibration_recordings(3, duration_s=6, random_state=0)
    samples = vibration_samples(rec, 200, n_folds=3, max_per_class=9, random_state=0)
    spec = ModelSpec("cnn", "neural", WindowCNNClassifier(**FAST), int8=True)
    rows = compare_models([spec], samples, list(rec.class_names), tmp_path, log=lambda s: None)
    assert [r["name"] for r in rows] == ["cnn", "cnn (int8 static)", "cnn (int8 dynamic)"]
    for r in rows:
        assert r["by"] == "group" and r["units"] == len(np.unique(samples.groups))
        assert r["accuracy_low"] <= r["accuracy"] <= r["accuracy_high"]
        assert r["memory_mib"] >= 0 and r["latency_ms"] > 0
    assert rows[0]["onnx_agreement"] == 1.0 and rows[0]["quantisation"] is None
    # a file exported for one fit takes another fit's weights and then agrees with it
    X = samples.X
    other = WindowCNNClassifier(**{**FAST, "random_state": 7}).fit(X, samples.y)
    path = rebind(tmp_path / "cnn.onnx", other, X[:4], tmp_path / "other.onnx")
    assert path is not None and OnnxPipeline(path).sealed  # new weights, new digest
    labels, scores = OnnxPipeline(path).predict_scores(X[:6])
    np.testing.assert_allclose(scores, other.predict_proba(X[:6]), atol=1e-4)
    assert np.array_equal(labels, other.predict_proba(X[:6]).argmax(1))


def test_int8_accepts_a_joined_model_listing_its_opset_twice(tmp_path):
    from onnx import TensorProto, helper, numpy_helper

    from tactile_torch.export import save_onnx

    weight = numpy_helper.from_array(np.random.default_rng(0).normal(size=(4, 3)).astype(np.float32), "w")
    graph = helper.make_graph(
        [
            helper.make_node("MatMul", ["raw", "w"], ["scores"]),
            helper.make_node("ArgMax", ["scores"], ["labels"], axis=1, keepdims=0),
        ],
        "joined",
        [helper.make_tensor_value_info("raw", TensorProto.FLOAT, [None, 4])],
        [
            helper.make_tensor_value_info("labels", TensorProto.INT64, [None]),
            helper.make_tensor_value_info("scores", TensorProto.FLOAT, [None, 3]),
        ],
        [weight],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 20), helper.make_opsetid("", 20)])
    model.ir_version = 10
    save_onnx(model, tmp_path / "joined.onnx")  # as export.parts.join writes a merged front and head
    X = np.random.default_rng(1).normal(size=(20, 4)).astype(np.float32)
    out, mode = quantise_bundle(tmp_path / "joined.onnx", tmp_path / "q.onnx", calibration=X[:8])
    assert mode == "static"
    assert np.mean(OnnxPipeline(out).predict(X) == OnnxPipeline(tmp_path / "joined.onnx").predict(X)) >= 0.8
