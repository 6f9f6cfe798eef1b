"""Learned models, int8 variants and the memory column in the trade-off study (tactile_torch.tradeoff.learned)."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_torch import catalogue
from tactile_torch.data.stylus import make_vibration_recordings
from tactile_torch.robot.runtime import OnnxPipeline
from tactile_torch.tradeoff import run_tradeoff
from tactile_torch.tradeoff.learned import RawInput, is_learned, learned_candidates


def test_catalogue_lists_learned_models_apart_from_the_classifiers():
    assert catalogue.CLASSIFIERS == ("hmsvm", "svc", "lda", "knn", "ncm")
    assert {"cnn-small", "cnn-large", "taxel-cnn", "image-cnn", "learned-front-end"} <= set(catalogue.LEARNED)
    assert catalogue.resolve("1-D CNN small") == "cnn-small"
    assert catalogue.entry("cnn-small").family == "neural" and catalogue.entry("cnn-small").raw_input == (
        "windows",
    )
    assert "cnn-small" not in catalogue.choices()  # train --method takes features: classical only
    clf = catalogue.make_classifier("cnn-large", random_state=3, max_epochs=2)
    assert clf.get_params()["size"] == "large" and clf.random_state == 3
    with pytest.raises(ValueError, match="or a learned model of"):
        catalogue.resolve("resnet")


def test_learned_candidates_take_the_raw_input():
    full = learned_candidates("vibration", "windows-800", window=800)
    assert [c.key for c in full] == ["cnn-small", "cnn-large", "learned-cutoff"]
    assert learned_candidates("vibration", "windows-800", quick=True, window=800) == []  # budget
    quick = learned_candidates("vibration", "windows-800", quick=True, classifiers=["cnn-small"], window=800)
    assert [c.name for c in quick] == ["1-D CNN small | raw window, W = 800"]
    assert quick[0].estimator.named_steps["classifier"].max_epochs == 30
    assert is_learned(quick[0].estimator) and isinstance(quick[0].estimator.steps[0][1], RawInput)
    assert learned_candidates("vibration", "windows-800", classifiers=["lda"]) == []
    assert [c.key for c in learned_candidates("pressure", "pressure", classifiers=["taxel-cnn", "lda"])] == [
        "taxel-cnn"
    ]
    assert learned_candidates("features", "features") == []


def test_tradeoff_lists_neural_and_int8_candidates_with_parameters_and_memory(tmp_path):
    rec = make_vibration_recordings(3, duration_s=8, n_sessions=2, random_state=5)
    path = rec.save(tmp_path / "rec.npz")
    result = run_tradeoff(
        path,
        quick=True,
        windows=[400],
        n_folds=3,
        classifiers=["lda", "cnn-small"],
        out_dir=tmp_path / "o",
        progress=False,
        background=False,
        log=lambda s: None,
    )
    rows = {r["name"]: r for r in result.rows}
    cnn, int8 = (
        rows["1-D CNN small | raw window, W = 400"],
        rows["1-D CNN small | raw window, W = 400 (int8)"],
    )
    assert cnn["family"] == "neural" and int8["quantisation"] == "dynamic"
    assert cnn["n_parameters"] == result.result(cnn["name"]).model.steps[-1][1].n_parameters_
    assert len(int8["fold_accuracy"]) == len(cnn["fold_accuracy"]) >= 2  # every fold scored
    assert int8["size_bytes"] < cnn["size_bytes"] and 0.0 <= int8["onnx_agreement"] <= 1.0
    for r in (cnn, int8, rows["LDA | 21 features, W = 400"]):
        assert r["memory_mib"] is not None and r["memory_mib"] >= 0
        assert r["latency_ms"] > 0 and r["decision_s"] is not None
    # the float file agrees with the torch model at a batch size other than the export's
    model = result.result(cnn["name"]).model.steps[-1][1]
    windows = result.inputs["windows-400"].X[:5]
    labels, scores = OnnxPipeline(tmp_path / "o" / "timing" / cnn["timing_onnx_file"]).predict_scores(windows)
    proba = model.predict_proba(windows)
    assert np.array_equal(labels, proba.argmax(1))
    np.testing.assert_allclose(scores, proba, atol=1e-4)
    assert (
        OnnxPipeline(tmp_path / "o" / "timing" / int8["timing_onnx_file"]).metadata["quantisation"]
        == "dynamic"
    )
