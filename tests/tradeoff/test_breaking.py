"""The trade-off's late stages on every candidate family (tactile_torch.tradeoff.breaking, .job, .deploy):
breaking points of a network that classifies raw windows and of int8 variants, a late failure that keeps
what the earlier stages computed (status 1, never 2), and the deployed files' "unknown" rule.

The data: vibration whose two classes differ only by the direction of a sawtooth (rising, falling). The
21 window features cannot tell a signal from its time reversal (variance, moments, total variation,
crossings and the amplitude spectrum are all unchanged by it), a 1-D CNN can: the network wins, as in
the issue where the default trade-off crashed after recommending it.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from tactile_torch.data.vibration import VibrationRecordings


def sawtooth_recordings(seconds: float, *, sessions: int = 4, random_state: int = 0) -> VibrationRecordings:
    """Rising and falling sawtooth vibration (g, 800 Hz) recorded on ``sessions`` days."""
    rng = np.random.default_rng(random_state)
    rate, n = 800.0, int(seconds * 800)
    t = np.arange(n) / rate
    signals, labels, session = [], [], []
    for c in range(2):
        for k in range(sessions):
            phase = (rng.uniform(18, 26) * t + rng.uniform()) % 1.0
            wave = (phase, 1.0 - phase)[c] - 0.5
            a = 0.3 * wave[:, None] * np.array([1.0, 0.5, 0.8]) + rng.normal(0, 0.02, (n, 3))
            a[:, 2] += 1.0
            signals.append(a.astype(np.float32))
            labels.append(c)
            session.append(f"day{k + 1}")
    return VibrationRecordings(
        signals=signals,
        labels=np.array(labels),
        class_names=("rising", "falling"),
        rate_hz=rate,
        session=np.array(session),
    )


@pytest.mark.slow  # 42 s on a quiet 2-core machine: the default run stays under 10 minutes (make test-all runs it)
def test_a_cnn_recommended_is_swept_and_a_late_failure_keeps_the_outputs(tmp_path, monkeypatch, capsys):
    """The trade-off command end to end with a CNN offered on a tiny budget (6 epochs): the CNN wins and
    its breaking points are swept (the feature SNR says in one line why it does not apply); a factor that
    fails (injected) leaves every other output written and ends with status 1, "internal error", never 2;
    ``--quiet`` leaves stderr to that line; the sessions keep their names; the deployed file carries the
    "unknown" rule."""
    import tactile_torch.robustness._evaluation as evaluation
    import tactile_torch.tradeoff.learned as learned
    from tactile_torch.cli import main
    from tactile_torch.data.out_of_distribution import out_of_distribution_signals
    from tactile_torch.robot.runtime import OnnxPipeline

    monkeypatch.setattr(learned, "QUICK_EPOCHS", 6)
    build_curve = evaluation.build_curve

    def failing(f, *args, **kwargs):
        if f.name == "saturation":
            raise RuntimeError("injected failure")
        return build_curve(f, *args, **kwargs)

    monkeypatch.setattr(evaluation, "build_curve", failing)
    path = sawtooth_recordings(2.0).save(tmp_path / "saw.npz")
    out = tmp_path / "study"
    argv = ["tradeoff", "--data", str(path), "--out", str(out), "--quick", "--quiet", "--windows", "200"]
    int8_name = "1-D CNN small | raw window, W = 200 (int8)"  # a name of tradeoff.json, made after the folds
    status = main([*argv, "--classifiers", "lda,cnn-small", "--folds", "2", "--deploy", int8_name])
    captured = capsys.readouterr()
    assert status == 1, captured.err
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("tactile-torch tradeoff: internal error in breaking points: ")
    assert "saturation" in err[0] and "injected failure" in err[0] and "everything else is written" in err[0]
    doc = json.loads((out / "tradeoff.json").read_text())
    assert doc["complete"] is False and doc["incomplete"][0]["stage"].startswith(
        "breaking points: saturation"
    )
    assert doc["recommended"].startswith("1-D CNN small | raw window, W = 200")
    points = doc["breaking_points"]
    assert points["failed"] and "saturation" in points["failed"][0][0]
    swept = {r["factor"] for r in points["rows"] if "1-D CNN small" in r["model"]}
    assert swept >= {"window", "sensor noise", "quantisation", "sample rate", "training samples"}
    snr = [why for name, why in points["skipped"] if name.startswith("windows-200: feature SNR for ")]
    assert snr and all(
        w.startswith("does not apply: the model classifies the raw input (3, 200)") for w in snr
    )
    if "int8" in doc["recommended"]:  # a variant is swept as its float model, said in one line
        assert any("swept as its float model" in n for n in points["notes"])
    assert "**Incomplete**" in (out / "tradeoff.md").read_text()
    for figure in points["figures"]:
        assert (out / figure).read_bytes()[:4] == b"\x89PNG"
    assert {u["unit"] for r in doc["candidates"] for u in r["unit_accuracy"]} == {
        "day1",
        "day2",
        "day3",
        "day4",
    }
    assert doc["units"]["windows-200"]["names"] == ["day1", "day2", "day3", "day4"]
    rows = {r["name"]: r for r in doc["candidates"]}
    cnn, int8 = (
        rows["1-D CNN small | raw window, W = 200"],
        rows["1-D CNN small | raw window, W = 200 (int8)"],
    )
    assert cnn["accuracy"] > rows["LDA | 21 features, W = 200"]["accuracy"]  # the features cannot tell
    # the learned and int8 candidates: parameters, every fold scored, a smaller file, memory measured
    assert cnn["family"] == "neural" and cnn["n_parameters"] > 1000 and int8["quantisation"] == "dynamic"
    assert len(int8["fold_accuracy"]) == len(cnn["fold_accuracy"]) == 2
    assert int8["size_bytes"] < cnn["size_bytes"] and 0.0 <= int8["onnx_agreement"] <= 1.0
    for r in (cnn, int8):  # --quick measures the memory of the learned, int8 and Pareto candidates
        assert r["memory_mib"] is not None and r["memory_mib"] >= 0
        assert r["latency_ms"] > 0 and r["decision_s"] is not None
    assert OnnxPipeline(out / "timing" / int8["timing_onnx_file"]).metadata["quantisation"] == "dynamic"
    # the deployed network says "unknown" to a still sensor, zeros and noise, and knows its surfaces
    bundle = OnnxPipeline(out / "recommended.onnx")
    assert bundle.ood_threshold == pytest.approx(doc["deployed"][0]["ood_threshold"])
    junk = out_of_distribution_signals(
        20, 200, 800.0, 0, kinds=["zeros", "still sensor", "white noise sd 1 g"]
    )
    for kind, x in junk.items():
        assert np.mean(bundle.predict(x) == -1) >= 0.95, kind
    held_in = sawtooth_recordings(1.0, sessions=1, random_state=9).windows(200).windows.numpy()
    assert np.mean(bundle.predict(held_in) == -1) <= 0.1
    # --deploy of an int8 variant: quantised, with the same rule as its float twin
    deployed = {d["name"]: d for d in doc["deployed"]}
    quantised = OnnxPipeline(out / deployed[int8_name]["onnx"])
    assert quantised.metadata["quantisation"] == "dynamic"
    assert quantised.ood_threshold == pytest.approx(deployed[int8_name]["ood_threshold"])
    assert np.mean(quantised.predict(junk["still sensor"]) == -1) >= 0.95


@pytest.mark.slow  # the whole default study (every candidate, every factor at every level): minutes
def test_the_default_tradeoff_end_to_end_where_the_cnn_wins(tmp_path, capsys):
    """Issue 34's run: the default (full) trade-off, the CNN recommended, breaking points of every factor,
    status 0, and a deployed network that answers "unknown" to a still sensor."""
    from tactile_torch.cli import main
    from tactile_torch.data.out_of_distribution import out_of_distribution_signals
    from tactile_torch.robot.runtime import OnnxPipeline

    path = sawtooth_recordings(3.0).save(tmp_path / "saw.npz")
    out = tmp_path / "study"
    assert main(["tradeoff", "--data", str(path), "--out", str(out), "--quiet"]) == 0, capsys.readouterr().err
    doc = json.loads((out / "tradeoff.json").read_text())
    assert doc["complete"] is True and doc["recommended"].startswith(("1-D CNN", "learned cut-off"))
    points = doc["breaking_points"]
    assert not points["failed"] and any(
        doc["recommended"].split(" (int8)")[0] in r["model"] for r in points["rows"]
    )
    assert any("feature SNR for recommended" in name for name, _ in points["skipped"])
    still = out_of_distribution_signals(
        20, OnnxPipeline(out / "recommended.onnx").input_shape[-1], 800.0, 0, kinds=["still sensor"]
    )
    assert np.mean(OnnxPipeline(out / "recommended.onnx").predict(still["still sensor"]) == -1) >= 0.95


def test_the_deployed_model_is_fitted_on_every_sample_not_the_studys_share():
    """--quick studies 60 windows per class; the deployed model trains on all of them (issue 34: 360 of 960)."""
    from types import SimpleNamespace

    from tactile_torch.tradeoff.deploy import deployment_samples
    from tactile_torch.tradeoff.inputs import vibration_data, vibration_samples

    rec = sawtooth_recordings(16.0)  # 2 classes x 4 sessions x 64 windows of 200
    studied = vibration_samples(rec, 200, n_folds=4, max_per_class=60)
    result = SimpleNamespace(inputs={studied.key: studied}, data=vibration_data(rec, "saw"))
    full, available = deployment_samples(result, studied.key)
    assert len(studied.y) == 120 and len(full.y) == available == 512
    assert np.array_equal(np.bincount(full.y), [256, 256]) and len(np.unique(full.groups)) == 4
