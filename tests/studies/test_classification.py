import json

from tactile_torch.studies import run_report


def _tables(path):
    data = json.loads((path.parent / "report.json").read_text())
    return {t["caption"]: t["rows"] for s in data["sections"] for t in s["tables"]}


def test_image_classification_study_quick(tmp_path):
    path = run_report(
        tmp_path, quick=True, only=["image_features", "image_classification"], log=lambda s: None
    )
    text = path.read_text()
    assert "## Method 1: HM-SVM vs LDA and kNN on tactile-image features" in text
    tables = _tables(path)
    acc = next(rows for cap, rows in tables.items() if cap.startswith("Test accuracy over the 5 rounds"))
    assert {(r["classifier"], r["features"].split()[0]) for r in acc} == {
        (c, f) for c in ("HM-SVM", "LDA", "kNN") for f in ("fused", "unfused")
    }
    assert all(0.0 <= r["accuracy mean"] <= 1.0 for r in acc)
    chosen = next(rows for cap, rows in tables.items() if cap.startswith("HM-SVM: C and gamma chosen"))
    assert len(chosen) == 10 and all(r["C"] > 0 and r["gamma"] > 0 for r in chosen)
    mc = next(rows for cap, rows in tables.items() if cap.startswith("McNemar"))
    assert len(mc) == 4 and all(r["p-value"] <= 1.0 for r in mc)
    noise = next(rows for cap, rows in tables.items() if cap.startswith("Accuracy with white Gaussian noise"))
    assert [r["SNR (dB)"] for r in noise] == [30, 10, 1]
    assert (tmp_path / "figures" / "image-classification-feature-noise.png").exists()


def test_vibration_classification_study_quick(tmp_path):
    path = run_report(
        tmp_path, quick=True, only=["vibration_features", "vibration_classification"], log=lambda s: None
    )
    text = path.read_text()
    assert "## Method 2: RBF SVM on the vibration features" in text
    tables = _tables(path)
    cv = next(rows for cap, rows in tables.items() if cap.startswith("Stratified 3-fold grid search"))
    assert {(r["C"], r["gamma"]) for r in cv} == {(16.0, 0.0186), (16.0, 0.1)}
    ranking = next(
        rows for cap, rows in tables.items() if cap.startswith("Features ranked by the test accuracy")
    )
    assert sorted(r["features"] for r in ranking) == sorted(
        ["var", "skew", "kurt", "m5", "tv", "cross", "hf"]
    )
    assert [r["accuracy"] for r in ranking] == sorted((r["accuracy"] for r in ranking), reverse=True)
    agreement = next(rows for cap, rows in tables.items() if cap.startswith("Our SVC vs libsvm"))
    assert all(r["dual objective rel diff"] < 1e-3 and r["test agreement"] >= 0.99 for r in agreement)
