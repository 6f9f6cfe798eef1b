"""``simulate-sensor`` plays a day's files in order with their own stamps, waits for a reader, and needs no
torch for a synthetic surface (issue 42, point 6; issue 41's robot-install item)."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import serial

from tactile_torch.robot.stream.wire import parse_line
from tests.robot_data import surface_recordings

REPO = Path(__file__).resolve().parents[2]


def _epoch_log(path: Path, signal: np.ndarray, t0_ms: float) -> Path:
    """A logger's CSV: epoch milliseconds rounded to 0.1 ms at 800 Hz, accelerations in g."""
    t = np.round(t0_ms + np.arange(len(signal)) * 1.25, 1)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(path, np.column_stack([t, signal]), delimiter=",", header="timestamp_ms,x,y,z", comments="",
               fmt=["%.1f", "%.6f", "%.6f", "%.6f"])  # fmt: skip
    return path


def test_a_days_files_play_in_order_with_their_stamps_to_a_late_reader(tmp_path):
    rec = surface_recordings(2, 0.25)  # 200 samples each
    t0 = 1_762_430_000_000.0
    paths = [_epoch_log(tmp_path / "day2" / f"{name}.csv", s, t0 + 60_000 * i)
             for i, (name, s) in enumerate(zip(("cork", "felt"), rec.signals, strict=True))]  # fmt: skip
    sim = subprocess.Popen(
        [sys.executable, "-m", "tactile_torch.cli", "simulate-sensor", "--pty", "--data", *map(str, paths),
         "--columns", "timestamp_ms,x,y,z", "--time-unit", "ms"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO,
    )  # fmt: skip
    first = sim.stdout.readline()
    port_name = first.split()[2].rstrip(":")
    time.sleep(1.0)  # the stream starts late: nothing is written before it opens the port
    port = serial.Serial(port_name, timeout=5)
    port.reset_input_buffer()  # what pyserial's open does: anything written before the open is lost
    data = b""
    with pytest.raises(serial.SerialException):  # the sensor closes the port once all was read
        while chunk := port.read(port.in_waiting or 1):
            data += chunk
    port.close()
    out, err = sim.communicate(timeout=30)
    assert sim.returncode == 0, err
    assert f"writing 400 samples at 800 Hz ({paths[0]} and 1 more; their own t)" in out
    lines = [parse_line(line) for line in data.splitlines()]
    assert len(lines) == 400 and all(p is not None for p in lines)  # every sample, none lost at the start
    t = np.array([p[0] for p in lines])
    expected = np.concatenate([np.round(t0 + 60_000 * i + np.arange(200) * 1.25, 1) / 1e3 for i in (0, 1)])
    np.testing.assert_allclose(t, expected, rtol=0, atol=1e-5)  # the logs' epoch stamps, the jump kept
    np.testing.assert_allclose(np.array([p[1:] for p in lines]), np.concatenate(rec.signals), atol=2e-6)


def test_the_synthetic_surface_plays_without_torch(tmp_path):
    code = (
        "import sys\n"
        "for name in ('torch', 'scipy', 'sklearn', 'numba'):\n"
        "    sys.modules[name] = None  # the robot install: numpy, onnxruntime, pyserial\n"
        "from tactile_torch.cli import main\n"
        "sys.exit(main(['simulate-sensor', '--port', 'loop://', '--seconds', '0.2', '--fast']))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "writing 160 samples at 800 Hz (a synthetic surface; no t) to loop://" in done.stdout
    assert done.stdout.strip().endswith("160 samples written")


def test_explorations_without_a_frame_rate_need_one(tmp_path, capsys):
    from tactile_torch.cli import main

    path = tmp_path / "grasps.npz"
    np.savez(path, frames=np.zeros((2, 4, 3, 3), np.float32), labels=[0, 1], class_names=["a", "b"])
    assert main(["simulate-sensor", "--pty", "--data", str(path), "--fast"]) == 2
    err = capsys.readouterr().err
    assert err.strip().endswith(
        "holds explorations without 't' or 'frame_rate_hz', so their frame rate is unknown; give it"
    )
    assert err.count("\n") == 1 and "--rate:" in err
