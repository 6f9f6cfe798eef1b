"""Grasps replayed live through a pseudo-terminal at their recorded rate: the decisions at the end of each
touch equal ``tactile-torch predict`` on the same touches offline, nothing is lost or duplicated, and a
touch split by a pause of the sensor is reported as two, never merged. On the real taxel arrays of
``../shared/data`` (iCub fingertips, the Schunk hand's Drimus arrays) when present, and on the synthetic
frame generator always; then the CLI end to end (simulate-sensor, stream --json)."""

import json
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
import serial

from tactile_torch.cli import main
from tactile_torch.cli.simulate_sensor import MAX_SIMULATED_S
from tactile_torch.robot.files.frame_recordings import FrameRecording, write_frame_recording
from tactile_torch.robot.runtime import OnnxPipeline
from tactile_torch.robot.stream.live import LiveOptions, LiveStream, item_spec
from tactile_torch.robot.stream.output import result_record
from tactile_torch.robot.stream.serial_source import SerialSource
from tactile_torch.robot.stream.wire import simulate_frames
from tests.stream_helpers import PtySensor, template_bundle

PAUSE_S = 0.7  # the sensor stops this long inside the last touch (the stream's silence is 0.5 s)


def _grasps(source, shared_data):
    """``(training explorations, labels, class names, frame rate, replayed grasps)`` of one data source."""
    if source == "synthetic":
        from tactile_torch.data.images import make_explorations

        data = make_explorations(4, n_frames=12, frame_size=16, sensels=8, random_state=2, keep_pressure=True)
        x, y, rate = data.pressure.numpy(), data.labels.numpy(), 20.0
        return x, y, list(data.class_names), rate, [0, 1, 2]
    from tactile_torch.data.grasps import load_drimus_grasps, load_icub_grasps

    root = shared_data(source)
    if source == "icub_grasp":  # 5 fingertips x 12 taxels, the last 4 slices; no rate in the set: 10 Hz
        data, rate = load_icub_grasps(root, n_frames=4), 10.0
    else:  # the distal array of finger 1 (13 x 6), the last 30 frames of each grasp at ~15 frames/s
        data, rate = load_drimus_grasps(root, sensor="ts2_f1_distal", n_frames=30), 15.0
    y = data.labels.numpy()
    firsts = [int(np.flatnonzero(y == c)[0]) for c in np.unique(y)[:2]]  # two grasps of different objects
    return data.pressure.numpy(), y, list(data.class_names), rate, firsts


def _recording(x, y, names, rate, replay):
    """The replayed grasps one after another, each between resting frames (no pressure), with t."""
    rest = np.zeros((max(3, round(0.3 * rate)), *x.shape[2:]), np.float32)
    frames, labels = [rest], [-1] * len(rest)
    for i in replay:
        frames += [x[i].astype(np.float32), rest]
        labels += [int(y[i])] * x.shape[1] + [-1] * len(rest)
    frames = np.concatenate(frames)
    return FrameRecording(frames, np.arange(len(frames)) / rate, np.array(labels), tuple(names))


@pytest.mark.parametrize("source", ["synthetic", "icub_grasp", "drimus_sdh_tactile"])
def test_live_touches_equal_predict_on_the_same_touches(source, shared_data, tmp_path, capsys):
    x, y, names, rate, replay = _grasps(source, shared_data)
    bundle = template_bundle(tmp_path / "grasp.onnx", x, y, names, frame_rate_hz=rate)
    pipe = OnnxPipeline(bundle)
    recording = _recording(x, y, names, rate, replay)
    path = write_frame_recording(tmp_path / "rec.npz", recording)
    # offline: tactile-torch predict cuts the touches with the stream's own stages
    assert main(["predict", "--model", str(bundle), "--data", str(path), "--json"]) == 0
    offline = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert len(offline) == len(replay) and all(r["ended_by"] == "release" for r in offline)
    # live: the same frames over a pseudo-terminal at the recorded rate; the sensor pauses in the last touch
    last = offline[-1]
    cut = last["start"] + last["frames"] // 2
    sensor = PtySensor()
    try:
        port = serial.serial_for_url(sensor.path, timeout=0.05)
        source_ = SerialSource(port, item_spec(pipe), idle_timeout_s=5.0, silence_s=0.5)
        live = LiveStream(pipe, source_, LiveOptions(max_results=len(offline) + 1))

        def play():
            simulate_frames(sensor, recording.frames[:cut], t=recording.t[:cut], timestamps=True)
            time.sleep(PAUSE_S)  # the sensor pauses: its clock runs on
            simulate_frames(sensor, recording.frames[cut:], t=recording.t[cut:] + PAUSE_S, timestamps=True)

        writer = threading.Thread(target=play, daemon=True)
        writer.start()
        got = [result_record(r) for r in live]
        writer.join()
    finally:
        sensor.close()
    touches = [r for r in got if r["event"] == "touch"]
    keys = ("start", "frames", "frames_used", "label", "name", "ended_by")
    # every touch before the pause: the same touch, label and scores as predict
    assert [[r[k] for k in keys] for r in touches[:-2]] == [[r[k] for k in keys] for r in offline[:-1]]
    for a, b in zip(touches[:-2], offline[:-1], strict=True):
        assert np.allclose(a["scores"], b["scores"], atol=1e-5, rtol=0)
        assert (
            a["decision"]["label"] == b["decision"]["label"]
            and a["decision"]["frames"] == b["decision"]["frames"]
        )
    # the paused touch: reported as two, cut by the silence, never one merged touch
    first, second = touches[-2:]
    assert (first["start"], first["ended_by"], second["start"]) == (last["start"], "silence", cut)
    assert "cut" in first["flags"] and "after_cut" in second["flags"]
    assert first["frames"] + second["frames"] == last["frames"]
    # nothing lost or duplicated: every frame up to the last release read once, no line skipped, no gap in t
    assert source_.counts.items == second["start"] + second["frames"] + 1
    assert (source_.counts.skipped, source_.counts.rejected, live.sequencer.lost) == (0, 0, 0)
    assert live.sequencer.gaps == 1  # the pause


def test_stream_json_and_simulate_sensor_as_commands(tmp_path, capsys):
    """The commands as a robot runs them: ``stream --json`` in its own process reads frames sent once it says
    "reading" (one JSON line per touch, the same touches as ``predict``, SIGTERM ends it with status 0 and
    the summary); ``simulate-sensor`` plays the frame recording on a pty as frame lines."""
    import signal

    from tactile_torch.robot.stream.serial_source import parse_values

    x, y, names, rate, replay = _grasps("synthetic", None)
    bundle = template_bundle(tmp_path / "grasp.onnx", x, y, names, frame_rate_hz=rate)
    recording = _recording(x, y, names, rate, replay)
    path = write_frame_recording(tmp_path / "rec.npz", recording)
    sensor = PtySensor()
    try:
        proc = subprocess.Popen(
            [sys.executable, "-m", "tactile_torch.cli", "stream", "--model", str(bundle), "--port", sensor.path,
             "--json"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        assert "reading" in proc.stderr.readline()
        simulate_frames(sensor, recording.frames, t=recording.t, timestamps=True, realtime=False)
        sensor.drain()
        time.sleep(0.3)
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=30)
    finally:
        sensor.close()
    assert proc.returncode == 0, err
    touches = [json.loads(line) for line in out.splitlines()]
    assert main(["predict", "--model", str(bundle), "--data", str(path), "--json"]) == 0
    offline = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    keys = ("start", "frames", "name", "ended_by")
    assert [[r[k] for k in keys] for r in touches if r["event"] == "touch"] == [
        [r[k] for k in keys] for r in offline
    ]
    assert "stopped by SIGTERM" in err
    assert err.splitlines()[-1].startswith(f"{len(recording)} frames read, {len(replay)} touches")
    # simulate-sensor: the recording's frames as lines on a new pty
    sim = subprocess.Popen(
        [sys.executable, "-m", "tactile_torch.cli", "simulate-sensor", "--pty", "--data", str(path), "--timestamps",
         "--fast"],
        stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    port = serial.Serial(sim.stdout.readline().split()[2].rstrip(":"), timeout=5)
    data = b""
    with pytest.raises(serial.SerialException):  # the sensor closes the port once all was read
        while chunk := port.read(port.in_waiting or 1):
            data += chunk
    port.close()
    assert sim.wait(timeout=30) == 0 and sim.stdout.read().strip().endswith(
        f"{len(recording)} frames written"
    )
    lines = [parse_values(line, 64) for line in data.splitlines()[1:]]  # opening the port may cut the start
    t = np.array([p[0] for p in lines if p is not None])
    assert len(t) >= len(recording) // 2 and t[-1] == pytest.approx(recording.t[-1], abs=1e-6)
    assert np.array_equal(lines[-1][1].reshape(8, 8), recording.frames[-1])


def test_simulate_sensor_frame_options_are_checked(tmp_path, capsys):
    """A frame recording is played whole (``--recording`` names an exploration); one line, status 2."""
    x, y, names, rate, replay = _grasps("synthetic", None)
    path = write_frame_recording(tmp_path / "rec.npz", _recording(x, y, names, rate, replay[:1]))
    assert main(["simulate-sensor", "--pty", "--data", str(path), "--recording", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith("is one frame recording (it has 't'); play it whole") and err.count("\n") == 0
    with pytest.raises(SystemExit):  # argparse: one line, status 2
        main(["simulate-sensor", "--pty", "--seconds", str(MAX_SIMULATED_S + 1)])
    assert f"expected a finite number in (0, {MAX_SIMULATED_S}]" in capsys.readouterr().err
