"""Learned models, int8 variants and the memory column in the trade-off study (tactile_torch.tradeoff.learned).

The study with a network and its int8 variant end to end (rows, every fold scored, memory, breaking points,
the deployed file): tests/tradeoff/test_breaking.py."""

from __future__ import annotations

import pytest

from tactile_torch import catalogue
from tactile_torch.features.transformers import RawInput
from tactile_torch.tradeoff.candidates import is_learned
from tactile_torch.tradeoff.learned import learned_candidates


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
    networks = [
        c.estimator.named_steps["classifier"]
        for c in full
        if "classifier__progress" in c.estimator.get_params()
    ]
    assert networks and all(n.progress for n in networks)  # their own bars over the epochs, unless ...
    quiet = learned_candidates("vibration", "windows-800", window=800, progress=False)
    assert not any(c.estimator.get_params().get("classifier__progress", False) for c in quiet)  # --quiet
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


def test_a_window_cnn_is_timed_with_its_unknown_rule_on_the_window_features(tmp_path, capsys):
    # the rule a deployed 1-D CNN carries (a distance on the 21 window features, module
    # tactile_torch.tradeoff.unknown) is in its timing files too, float and int8, so the study ranks
    # it by what the robot runs: its files carry the window-feature graph, as large as the LDA's
    import json

    from tactile_torch.cli import main
    from tactile_torch.data.stylus import make_vibration_recordings

    make_vibration_recordings(4, duration_s=8.0, n_sessions=3, random_state=0).save(tmp_path / "rec.npz")
    out = tmp_path / "o"
    argv = ["tradeoff", "--data", str(tmp_path / "rec.npz"), "--out", str(out), "--quick", "--quiet"]
    assert main([*argv, "--classifiers", "LDA,1-D CNN small", "--windows", "400", "--no-breaking"]) == 0
    capsys.readouterr()
    rows = {r["name"]: r for r in json.loads((out / "tradeoff.json").read_text())["candidates"]}
    lda = rows["LDA | 21 features, W = 400"]
    features_graph = (out / "timing" / lda["timing_onnx_file"]).stat().st_size
    cnns = [r for name, r in rows.items() if name.startswith("1-D CNN small")]
    assert len(cnns) == 2  # the float file and its int8 copy
    for row in cnns:
        size = (out / "timing" / row["timing_onnx_file"]).stat().st_size
        assert row.get("timing_size_bytes", row["size_bytes"]) == size
        assert size > 0.9 * features_graph, (row["name"], size, features_graph)
