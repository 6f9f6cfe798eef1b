"""The breaking_points and claims report sections: their pieces on tiny data, and a quick run (slow)."""

import json

import numpy as np
import pytest
from sklearn.neighbors import NearestCentroid

from tactile_torch.data.vibration import VibrationRecordings
from tactile_torch.robustness.sweeps import sweep
from tactile_torch.studies import breaking_points, claims, run_report
from tactile_torch.studies.report import Report


def test_breaking_points_results_go_into_a_section(tmp_path):
    rng = np.random.default_rng(0)
    X = rng.normal(size=(40, 3)) + np.repeat(np.eye(2, 3) * 2, 20, axis=0)
    y = np.repeat([0, 1], 20)
    result = sweep(
        {"a": NearestCentroid()}, X, y, factors=["feature SNR", "drift"], n_trials=1, random_state=0
    )
    rep = Report(tmp_path)
    breaking_points.add_results(rep.section("s"), result, name="demo", study_model="a")
    rep.write()
    text = (tmp_path / "report.md").read_text()
    assert "| feature SNR | a |" in text and "Not swept here: drift" in text
    assert (tmp_path / "figures" / "breaking-demo.png").exists()


def test_claims_verdicts_and_summary():
    y = np.repeat([0, 1], 30)
    good, bad = y.copy(), y.copy()
    bad[:20] = 1 - bad[:20]  # 20 errors where the other is right: McNemar rejects
    preds = {("stratified", "LDA", "fused"): good, ("stratified", "LDA", "concatenated"): bad}
    rows = claims._fusion_rows("src", preds, y, 5)
    assert rows[0]["verdict (5 %)"] == "fusion better" and rows[0]["gain"] == pytest.approx(20 / 60)
    reverse = {("stratified", "LDA", "fused"): bad, ("stratified", "LDA", "concatenated"): good}
    assert claims._fusion_rows("src", reverse, y, 5)[0]["verdict (5 %)"] == "concatenation better"
    neutral = dict(rows[0], source="other", gain=0.0)
    neutral["verdict (5 %)"] = "no significant difference"
    summary = claims._summary([rows[0], neutral])
    assert [s["where"] for s in summary] == ["fusion helps", "no significant difference"]


def test_claims_window_rows_on_small_recordings():
    rng = np.random.default_rng(1)
    signals = [
        rng.normal(scale=0.05 * (1 + k), size=(800, 3)).astype(np.float32) for k in range(3) for _ in range(1)
    ]
    rec = VibrationRecordings(signals, np.arange(3), ("a", "b", "c"), 100.0)
    rows = claims.window_rows([{"name": "tiny", "rec": rec}])
    assert rows[0]["source"] == "tiny" and rows[0]["W (samples)"] == "25 / 50 / 100 / 200"
    assert rows[0]["verdict (95 %)"] in ("rises", "falls", "no significant change")


@pytest.mark.slow
def test_breaking_points_and_claims_sections_quick(tmp_path):
    path = run_report(tmp_path, quick=True, only=["breaking_points", "claims"], log=lambda s: None)
    text = path.read_text()
    assert (
        "## Breaking points: where each model fails" in text
        and "## Claims checked beyond one generator" in text
    )
    data = json.loads((tmp_path / "report.json").read_text())
    breaking, claims_section = data["sections"]
    tables = {t["caption"].split(":")[0]: t for t in breaking["tables"]}
    image_rows = tables["method 1"]["rows"]
    assert {r["factor"] for r in image_rows} >= {"feature SNR", "image noise", "frames", "sensel grid"}
    vib_rows = tables["method 2"]["rows"]
    assert {r["factor"] for r in vib_rows} >= {"window", "sensor noise", "quantisation", "sample rate"}
    for name in ("breaking-method-1", "breaking-method-2", "breaking-fig4-noise-stages"):
        assert (tmp_path / "figures" / f"{name}.png").exists()
    where = next(t for t in claims_section["tables"] if t["caption"].startswith("Where fusion helps"))
    sources = [r["source"] for r in where["rows"]]
    assert sources[:2] == ["bundled generator (default knobs)", "bundled generator (hard knobs)"]
    assert any(t["caption"].startswith("Claim 3") for t in claims_section["tables"])
