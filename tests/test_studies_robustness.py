"""Smoke run of the breaking_points and claims report sections (quick sizes)."""

import json

from tactile_torch.studies import run_report


def test_breaking_points_and_claims_sections_quick(tmp_path):
    path = run_report(tmp_path, quick=True, only=["breaking_points", "claims"], log=lambda s: None)
    text = path.read_text()
    assert (
        "## Breaking points: where each model fails" in text
        and "## Claims checked beyond one generator" in text
    )
    data = json.loads((tmp_path / "report.json").read_text())
    breaking, claims = data["sections"]
    tables = {t["caption"].split(":")[0]: t for t in breaking["tables"]}
    image_rows = tables["method 1"]["rows"]
    assert {r["factor"] for r in image_rows} >= {"feature SNR", "image noise", "frames", "sensel grid"}
    vib_rows = tables["method 2"]["rows"]
    assert {r["factor"] for r in vib_rows} >= {"window", "sensor noise", "quantisation", "sample rate"}
    for name in ("breaking-method-1", "breaking-method-2", "breaking-fig4-noise-stages"):
        assert (tmp_path / "figures" / f"{name}.png").exists()
    where = next(t for t in claims["tables"] if t["caption"].startswith("Where fusion helps"))
    sources = [r["source"] for r in where["rows"]]
    assert sources[:2] == ["bundled generator (default knobs)", "bundled generator (hard knobs)"]
    assert all(r["where"] for r in where["rows"])
    assert any(t["caption"].startswith("Claim 3") for t in claims["tables"])
