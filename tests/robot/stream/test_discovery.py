"""Tests of novelty discovery (tactile_torch.robot.stream.discovery.SurfaceDiscovery) and ``tactile-torch stream --discover``."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_torch.robot.stream.discovery import SurfaceDiscovery
from tests.robot_data import prebuilt

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


@pytest.fixture(scope="module")
def clustering_bundle(tmp_path_factory):
    """An exported clustering of three stylus surfaces (glass, cork, rubber), their recordings, and one
    of a surface it never saw: built here, or beforehand on the robot install (tests.robot_data)."""
    path = prebuilt("discovery", tmp_path_factory.mktemp("discovery"))
    with np.load(path / "rec.npz") as rec:
        signals = rec["signals"]
    return path / "cl.onnx", signals, np.load(path / "unseen.npy")


def _stream_discover(bundle, stream, n_windows, monkeypatch, capsys):
    """Run ``tactile-torch stream --discover 3`` on ``stream`` (samples, 3) over a fake port; return its stdout."""
    import io

    import serial

    from tactile_torch.cli import main
    from tactile_torch.robot.stream.wire import format_sample

    lines = b"".join(format_sample(s) for s in stream)
    monkeypatch.setattr(serial, "serial_for_url", lambda *a, **k: io.BytesIO(lines))
    capsys.readouterr()
    args = ["stream", "--model", str(bundle), "--port", "test://", "--step", "400"]
    assert main([*args, "--max-windows", str(n_windows), "--discover", "3"]) == 0
    return capsys.readouterr().out


def test_cli_stream_discover_proposes_a_surface_the_clustering_never_saw(
    clustering_bundle, monkeypatch, capsys
):
    bundle, signals, unseen = clustering_bundle
    # the stream: a known surface, then one the clustering never saw (the coarsest sandpaper)
    stream = np.concatenate([signals[0][:2000], unseen])
    printed = _stream_discover(bundle, stream, 13, monkeypatch, capsys)
    assert "new surface proposed: new surface 1" in printed
    lines = printed.splitlines()
    novel = [i for i, line in enumerate(lines) if line.startswith("  novel window")]
    assert len(novel) >= 3 and lines[novel[-1]] == "  novel window -> new surface 1"
    assert novel[0] > 5  # the first windows (a known surface) are not novel


def test_cli_stream_discover_skips_a_stuck_sensor(clustering_bundle, monkeypatch, capsys):
    """A stuck sensor (constant on every axis) gives unknown windows (label -1): never a new surface."""
    bundle, signals, _ = clustering_bundle
    stuck = np.tile(np.array([[0.02, -0.01, 1.0]], dtype=np.float32), (3200, 1))
    # a stuck stretch between two stretches of a known surface, then stuck to the end
    stream = np.concatenate([signals[0][:1200], stuck, signals[0][1200:2400], stuck])
    printed = _stream_discover(bundle, stream, 22, monkeypatch, capsys)
    lines = printed.splitlines()
    unknown = [line for line in lines if "no vibration: every axis is constant" in line]
    assert len(unknown) == 16  # the runtime marks the stuck windows unknown ...
    assert "new surface proposed" not in printed  # ... and discovery skips them
    assert not [line for line in lines if line.startswith("  novel window")]
