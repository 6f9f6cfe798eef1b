"""Tests of the clustering report section (tactile_torch.studies.clustering) and its experiments
(tactile_torch.studies.clustering_experiments)."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_torch.studies.clustering_experiments import have_vibration_features

# Short chains in these tests: their R-hat warnings are expected, not failures.
pytestmark = pytest.mark.filterwarnings("ignore:PitmanYorGMM. R-hat:RuntimeWarning")


def test_clustering_study_quick_mode_writes_its_section(tmp_path):
    import json

    from tactile_torch.studies import run_report

    path = run_report(tmp_path, quick=True, only=["clustering"], log=lambda s: None)
    text = path.read_text()
    assert "## Clustering: how many surfaces" in text
    assert "Pitman-Yor mixture: point estimate" in text and "variational DP mixture" in text
    assert "Table 1" in text and "Novelty" in text and "R-hat" in text
    for name in (
        "clustering-posterior-k",
        "clustering-similarity",
        "clustering-accuracy-along-chain",
        "clustering-discount",
        "clustering-confusion",
        "clustering-learning-curve",
    ):
        assert (tmp_path / "figures" / f"{name}.png").exists(), name
    tables = json.loads((tmp_path / "report.json").read_text())["sections"][0]["tables"]
    pyp, kmeans = tables[0]["rows"][0], tables[0]["rows"][2]
    # a smoke run on 6 windows of 6 surfaces (two pairs deliberately alike): a plausible K and accuracy
    assert pyp["method"].startswith("Pitman-Yor") and 2 <= pyp["K found"] <= 2 * kmeans["K found"]
    assert pyp["pairwise accuracy"] > 0.7
    novelty = next(t for t in tables if t["caption"].startswith("Novelty"))["rows"]
    for row in novelty:  # the calibrated rule beside the model's own
        assert 0.0 <= row["recall (calibrated 2 %)"] <= 1.0
        after = row["false alarms (calibrated, mean of 3)"]  # NaN: no run of 3 (6 windows per surface)
        assert np.isnan(after) or 0.0 <= after <= 1.0


def test_learning_curve_rows():
    from tactile_torch.studies.clustering_experiments import learning_curve, synthetic_clusters

    X, y = synthetic_clusters(4, 6, seed=1)
    rows = learning_curve(X, y, [1, 6], n_iter=40, burn_in=10, random_state=0)
    assert [(r["per class"], r["prior"], r["points"]) for r in rows] == [
        (1, "DP", 4),
        (1, "PYP", 4),
        (6, "DP", 24),
        (6, "PYP", 24),
    ]
    assert rows[-1]["pairwise accuracy"] == 1.0 and rows[-1]["K point estimate"] == 4


@pytest.mark.slow
def test_real_accelerometer_sets_go_through_the_clustering_study(shared_data, tmp_path):
    # real-data counterpart of test_clustering_study_quick_mode_writes_its_section (synthetic data)
    if not have_vibration_features():
        pytest.skip("tactile_torch.signal (the vibration features) is not installed")
    from tactile_torch.studies import RunContext
    from tactile_torch.studies.clustering import real_data
    from tactile_torch.studies.report import Report

    shared_data("hapmat_imu5")
    section = Report(tmp_path).section("real")
    real_data(section, RunContext(quick=True), n_iter=40, burn_in=15)
    k_rows, novelty_rows = section.tables[-2]["rows"], section.tables[-1]["rows"]
    row = next(r for r in k_rows if r["data set"] == "hapmat_imu5")
    assert row["classes"] == 5 and 0.0 <= row["pairwise accuracy (point estimate)"] <= 1.0
    lo, hi = (float(v) for v in row["K 95% interval"].strip("[]").split(","))
    assert lo <= row["K posterior mode"] <= hi
    nov = next(r for r in novelty_rows if r["data"] == "hapmat_imu5")
    assert 0.0 <= nov["recall (samples)"] <= 1.0 and 0.0 <= nov["false alarms (samples)"] <= 1.0
    assert 0.0 <= nov["recall (calibrated 2 %)"] <= 1.0


def test_the_convergence_line_says_the_study_fit_apart_from_the_fixed_chains():
    from types import SimpleNamespace

    from tactile_torch.studies.clustering import convergence_line

    default = {"n_iter": "auto", "max_seconds": 20.0, "other_n_iter": 700}
    done = SimpleNamespace(stopped_by_="converged", fit_seconds_=15.1)
    line = convergence_line(default, done, 3)
    assert line.startswith("the study's fit (the headline K) converged in 15.1 s")
    assert "3 of the section's other fits, at fixed chains of 700 sweeps or fewer, missed them: read" in line
    missed = SimpleNamespace(stopped_by_="max_seconds", fit_seconds_=20.3)
    line = convergence_line(default, missed, 3)
    assert "missed the targets in 20.3 s" in line and "; 2 of the section's other fits" in line
    assert convergence_line(default, done, 0).endswith("missed them.")  # none of them did: said as 0
    assert convergence_line({"n_iter": 150}, done, 4).startswith("4 of this section's fits missed")
    assert convergence_line({"n_iter": "auto"}, done, 0).startswith("every mixture of this section converged")
