"""Tests of novelty discovery (tactile_torch.robot.discovery.SurfaceDiscovery) and ``tactile-torch stream --discover``."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_torch.robot.discovery import SurfaceDiscovery

# Short chains in these tests: their R-hat warnings are expected, not failures.
pytestmark = pytest.mark.filterwarnings("ignore:PitmanYorGMM. R-hat:RuntimeWarning")


def test_surface_discovery_proposes_after_n_consecutive_novel_windows():
    d = SurfaceDiscovery(n_consecutive=3, known_names=["a", "b"])
    flags = [False, True, True, False, True, True, True, True, False, True, True, True]
    verdicts = [d.update(0, f) for f in flags]
    assert [v.proposed for v in verdicts].count(True) == 2
    assert [v.name for v in verdicts][4:9] == ["a", "a", "new surface 1", "new surface 1", "a"]
    assert d.proposals == [
        {"name": "new surface 1", "first_window": 4, "windows": 4},
        {"name": "new surface 2", "first_window": 9, "windows": 3},
    ]
    with pytest.raises(ValueError, match="n_consecutive must be an int >= 1, got 0"):
        SurfaceDiscovery(n_consecutive=0)


def test_cli_stream_discover_proposes_a_surface_the_clustering_never_saw(tmp_path, monkeypatch, capsys):
    import io

    import serial

    from tactile_torch.cli import main
    from tactile_torch.data.stylus import SURFACES, make_vibration_recordings
    from tactile_torch.robot.stream import format_sample

    known = [SURFACES[0], SURFACES[5], SURFACES[7]]  # glass, cork, rubber
    rec = make_vibration_recordings(surfaces=known, duration_s=8.0, random_state=0)
    np.savez(
        tmp_path / "rec.npz",
        signals=np.stack(rec.signals),
        rate_hz=rec.rate_hz,
        labels=rec.labels,
        class_names=np.array(rec.class_names),
    )
    out = tmp_path / "cl"
    common = ["--window", "400", "--n-iter", "60", "--burn-in", "20", "--chains", "2", "--quiet"]
    assert main(["cluster", "--data", str(tmp_path / "rec.npz"), "--out", str(out), *common]) == 0
    assert main(["export", "--model", str(out / "model.npz"), "--out", str(tmp_path / "cl.onnx")]) == 0
    # the stream: a known surface, then one the clustering never saw (the coarsest sandpaper)
    unseen = make_vibration_recordings(surfaces=[SURFACES[27]], duration_s=4.0, random_state=1).signals[0]
    stream = np.concatenate([rec.signals[0][:2000], unseen])
    lines = b"".join(format_sample(s) for s in stream)
    monkeypatch.setattr(serial, "serial_for_url", lambda *a, **k: io.BytesIO(lines))
    capsys.readouterr()
    args = [
        "stream",
        "--model",
        str(tmp_path / "cl.onnx"),
        "--port",
        "test://",
        "--step",
        "400",
        "--max-windows",
        "13",
    ]
    assert main([*args, "--discover", "3"]) == 0
    printed = capsys.readouterr().out
    assert "new surface proposed: new surface 1" in printed
    lines = printed.splitlines()
    novel = [i for i, line in enumerate(lines) if line.startswith("  novel window")]
    assert len(novel) >= 3 and lines[novel[-1]] == "  novel window -> new surface 1"
    assert novel[0] > 5  # the first windows (a known surface) are not novel
