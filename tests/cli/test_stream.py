"""`tactile-torch stream` and `simulate-sensor` over a pseudo-terminal, through every fault of a real
line: a sensor starting late or pausing, the writer closing the port (with and without --reconnect),
a sample of 1e30, dropped samples and spliced recordings, garbage and ERR lines; --json and --vote, read
by another process as docs/stream.md shows."""

import json
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import serial

from tactile_torch.cli import STREAM_DISCONNECTED_EXIT, STREAM_NO_DATA_EXIT, STREAM_OUTPUT_CLOSED_EXIT, main
from tactile_torch.robot.stream.wire import format_sample, parse_line
from tests.conftest import _NO_TORCH
from tests.stream_helpers import PtySensor, axis_recording, energy_bundle, expected_axis

W, RATE = 16, 800.0
DOCS = Path(__file__).resolve().parents[2] / "docs" / "stream.md"


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    return str(energy_bundle(tmp_path_factory.mktemp("bundle") / "energy.onnx", window=W, rate_hz=RATE))


@pytest.fixture
def opened(monkeypatch):
    """Count the ports the stream opens; ``opened(n)`` waits until it has opened ``n``."""
    real = serial.serial_for_url
    done = threading.Condition()
    count = [0]

    def serial_for_url(url, **kwargs):
        port = real(url, **kwargs)
        with done:
            count[0] += 1
            done.notify_all()
        return port

    monkeypatch.setattr(serial, "serial_for_url", serial_for_url)

    def wait(n):
        with done:
            assert done.wait_for(lambda: count[0] >= n, timeout=30), (
                f"the stream did not open the port {n} time(s)"
            )

    return wait


class _Writer(threading.Thread):
    """Run the sensor's script in a thread; re-raise its error in the test."""

    def __init__(self, script):
        super().__init__(daemon=True)
        self.script, self.error = script, None
        self.start()

    def run(self):
        try:
            self.script()
        except BaseException as err:  # handed to the test
            self.error = err

    def finish(self):
        self.join(30)
        if self.error is not None:
            raise self.error


def _stream(model, sensor, *args, json_lines=True):
    return main(
        ["stream", "--model", model, "--port", sensor.path, *(["--json"] if json_lines else []), *args]
    )


def _records(out):
    return [json.loads(line) for line in out.splitlines()]


def _t(start, n):
    return (start + np.arange(n)) / RATE


def _check_windows(records, sent):
    """Every window is W consecutive samples of what was sent (by t), labelled as the bundle does."""
    for r in records:
        assert r["t_end"] - r["t_start"] == pytest.approx((W - 1) / RATE, abs=2e-6)
        i = round(r["t_start"] * RATE)
        assert r["name"] == expected_axis(sent[i : i + W].T)


def test_late_sensor_and_pause_are_waited_for_and_reported(model, sensor_pty, opened, capsys):
    rec, _ = axis_recording("xy", 40)

    def sensor():
        opened(1)
        time.sleep(1.0)  # the stream started before the sensor
        sensor_pty.write_samples(rec[:40], _t(0, 40))
        time.sleep(2.0)  # the sensor pauses: its clock runs on
        sensor_pty.write_samples(rec[40:], _t(40 + 2 * RATE, 40))

    writer = _Writer(sensor)
    status = _stream(model, sensor_pty, "--max-windows", "8", "--idle-timeout", "10")
    writer.finish()
    out, err = capsys.readouterr()
    assert status == 0
    records = _records(out)
    # two segments of 40 samples: windows at 16, 24, 32, 40 samples of each, none across the pause
    assert [r["sample"] for r in records] == [16, 24, 32, 40, 56, 64, 72, 80]
    _check_windows(records, np.concatenate([rec[:40], np.zeros((2 * int(RATE), 3)), rec[40:]]))
    assert [r["gaps"] for r in records] == [0, 0, 0, 0, 1, 0, 0, 0]
    messages = [line for line in err.splitlines() if line.startswith("tactile-torch stream: ")]
    assert re.search(r"no data yet on \S+ after 0\.\d s \(giving up after 60 s\)", messages[0])
    assert re.search(r"first sample after 1\.\d s", messages[1])
    assert re.search(
        r"no sample for 0\.\d+ s after 40 samples, \d+ ms into the stream; waiting \(giving up after 10 s\)",
        messages[2],
    )
    assert re.search(r"samples again after [12](\.\d+)? s of silence", messages[3])  # the 2 s pause
    assert "80 samples read, 8 windows, 0 lines skipped" in err.splitlines()[-1]


def test_silence_ends_with_a_non_zero_status(model, sensor_pty, opened, capsys):
    assert _stream(model, sensor_pty, "--start-timeout", "1") == STREAM_NO_DATA_EXIT
    err = capsys.readouterr().err.splitlines()
    assert re.search(r": no data for 1\.\d s \(timeout 1 s\); 0 samples read, 0 lines skipped$", err[-2])
    rec, _ = axis_recording("z", 20)
    writer = _Writer(lambda: (opened(2), sensor_pty.write_samples(rec)))
    assert _stream(model, sensor_pty, "--idle-timeout", "1") == STREAM_NO_DATA_EXIT
    writer.finish()
    out, err = capsys.readouterr()
    assert [r["name"] for r in _records(out)] == ["z"]
    assert re.search(r": no sample for 1\.\d s \(timeout 1 s\); 20 samples read", err)


def test_writer_closing_the_port_is_one_line_and_a_non_zero_status(model, sensor_pty, opened, capsys):
    rec, _ = axis_recording("y", 24)

    def sensor():
        opened(1)
        sensor_pty.write_samples(rec)
        sensor_pty.drain()
        sensor_pty.close()

    writer = _Writer(sensor)
    status = _stream(model, sensor_pty)
    writer.finish()
    out, err = capsys.readouterr()
    assert status == STREAM_DISCONNECTED_EXIT
    assert [r["sample"] for r in _records(out)] == [16, 24]
    lines = err.splitlines()
    assert len(lines) == 3 and "Traceback" not in err  # header, the disconnection, the summary
    assert re.fullmatch(r"tactile-torch stream: \S+ disconnected after 24 samples: .+", lines[1])


def test_reconnect_reopens_the_port_with_backoff(model, tmp_path, opened, capsys):
    sensor = PtySensor(link=tmp_path / "imu")  # a stable name, as /dev/serial/by-id/... gives
    rec, _ = axis_recording("xz", 24)

    def script():
        opened(1)
        sensor.write_samples(rec[:24], _t(0, 24))
        sensor.drain()
        sensor.replug()  # unplugged and plugged in again: a new pty behind the same name
        opened(2)
        sensor.write_samples(rec[24:], _t(100, 24))

    writer = _Writer(script)
    status = _stream(model, sensor, "--reconnect", "--max-windows", "4")
    writer.finish()
    sensor.close()
    out, err = capsys.readouterr()
    assert status == 0
    assert [(r["sample"], r["name"], r["gaps"]) for r in _records(out)] == [
        (16, "x", 0),
        (24, "x", 0),
        (40, "z", 1),
        (48, "z", 0),
    ]
    assert re.search(r"stream: \S+/imu disconnected \(.+\); reconnecting", err)
    assert re.search(r"stream: \S+/imu open after \d+\.\d s \(\d attempt\(s\)\)", err)
    assert "1 reconnections" in err


def test_a_reopened_port_keeps_what_arrived_before_the_open(model, tmp_path, opened, capsys):
    """Issue 34: every reconnection lost what the sensor sent during the backoff wait (opening the port
    flushed it), uncounted. Now a reopen keeps it, and what was lost while unplugged is counted from t."""
    sensor = PtySensor(link=tmp_path / "imu")
    rec, _ = axis_recording("xz", 24)

    def script():
        opened(1)
        sensor.write_samples(rec[:24], _t(0, 24))
        sensor.drain()
        sensor.replug()  # plugged in again: the sensor sends at once, while the stream waits to reopen
        sensor.write_samples(rec[29:], _t(29, 19))  # samples 24-28 were sent while it was unplugged

    writer = _Writer(script)
    status = _stream(model, sensor, "--reconnect", "--max-windows", "3", "--idle-timeout", "5")
    writer.finish()
    sensor.close()
    out, err = capsys.readouterr()
    assert status == 0, err
    assert [(r["sample"], round(r["t_start"] * RATE)) for r in _records(out)] == [(16, 0), (24, 8), (40, 29)]
    assert f"a 7.5 ms gap 28.8 ms into {tmp_path / 'imu'}: 5 sample(s) missing across the reconnection" in err
    assert "40 samples read, 3 windows" in err.splitlines()[-1] and "(5 samples known lost)" in err


def test_data_faults_never_reach_a_window(model, sensor_pty, opened, capsys):
    # one session through the data rows of the table: a 1e30 sample, a burst of 30 dropped samples,
    # a spliced recording (t starts again), garbage of every kind, ERR lines and a line without t
    rec, _ = axis_recording("xyz", 60)
    lines = [format_sample(s, t) for s, t in zip(rec, _t(0, 180), strict=True)]
    lines[20] = b"0.025000,1e30,0,1\n"
    lines[45] = b"ERR,0.1,0.2,0.3\n"  # a sample replaced by an error report: also a gap in t
    del lines[70:100]  # dropped samples
    garbage = [
        b"\xff\xfe\x00\x81\n",  # binary noise
        b"0.1,nan,1,2\n",
        b"1,2\n",
        b"1,2,3,4,5\n",
        b"0.12,-0.3",  # a partial line, run into the next one
        b"0.130,0.2,0.3,0.4\n",
        b"0.4,0.5,0.6\n",  # no t in a timestamped stream
    ]
    second, _ = axis_recording("zx", 30, random_state=1)
    splice = [format_sample(s, t) for s, t in zip(second, _t(0, 60), strict=True)]

    def sensor():  # each part once the sensor has had the time to send it (lost samples included)
        opened(1)
        for part, n in ((lines[:60] + garbage, 60), (lines[60:], 120), (splice, 60)):
            time.sleep(n / RATE)
            sensor_pty.write(b"".join(part))

    writer = _Writer(sensor)
    status = _stream(model, sensor_pty, "--idle-timeout", "1")
    writer.finish()
    out, err = capsys.readouterr()
    assert status == STREAM_NO_DATA_EXIT and "nan" not in out.lower() and "inf" not in out.lower()
    records = _records(out)
    first, spliced = records[:-6], records[-6:]
    _check_windows(first, rec)
    _check_windows(spliced, second)
    # segments of the first recording: [0, 20) [21, 45) [46, 70) [100, 180); no window spans a boundary
    starts = [round(r["t_start"] * RATE) for r in first]
    assert starts == [0, 21, 29, 46, 54, *range(100, 165, 8)]
    assert [round(r["t_start"] * RATE) for r in spliced] == list(range(0, 45, 8))
    # the ERR line (between samples 44 and 46) and the 6 garbage lines (between 59 and 60), counted
    # with the window after them
    assert [r["skipped"] for r in first] == [0, 0, 0, 7] + [0] * 10
    assert [r["rejected"] for r in first] == [0, 1] + [0] * 12
    # the garbage fell inside the spans of windows 3 (samples 46-61) and 4 (54-69); the ERR line before both
    assert [r["flags"] for r in first] == [[]] * 3 + [["skipped"]] * 2 + [[]] * 9
    assert "out of the sensor's range ±5 g was rejected: (1e+30, 0, 1)" in err
    assert "a 2.5 ms gap 55 ms into " in err and ": 1 sample(s) missing" in err  # the ERR line's sample
    assert "a 38.8 ms gap 86.2 ms into " in err and ": 30 sample(s) missing" in err
    assert "0.224 s into " in err and ", t went back by 0.224 s: a spliced recording or a sensor reset" in err
    assert "208 samples read, 20 windows, 7 lines skipped, 1 samples out of range" in err.splitlines()[-1]


def test_an_out_of_range_sample_without_the_range_check_gets_no_label(model, sensor_pty, opened, capsys):
    rec, _ = axis_recording("x", 32)
    lines = [format_sample(s) for s in rec]
    lines[3] = b"1e30,0,1\n"
    writer = _Writer(lambda: (opened(1), sensor_pty.write(b"".join(lines))))
    status = _stream(model, sensor_pty, "--range", "inf", "--max-windows", "3", json_lines=False)
    writer.finish()
    out = capsys.readouterr().out.splitlines()  # the decisions only: the status lines are on stderr
    assert status == 0 and len(out) == 3
    assert out[0].split()[:3] == ["0", "16", "-"] and "no label: scores not finite" in out[0]
    assert out[0].endswith("[non_finite_scores]") and "nan" not in out[0] and "inf" not in out[0]
    assert out[1].split()[2] == "x" and out[2].split()[2] == "x"  # windows 8-23, 16-31 are clean


def test_garbage_is_reported_with_each_window_not_only_at_the_end(model, sensor_pty, opened, capsys):
    rec, _ = axis_recording("y", 48)
    lines = [format_sample(s) for s in rec]
    for i in (5, 30):
        lines.insert(i, b"#noise\n")

    writer = _Writer(lambda: (opened(1), sensor_pty.write(b"".join(lines))))
    status = _stream(model, sensor_pty, "--step", "16", "--max-windows", "3", json_lines=False)
    writer.finish()
    out = capsys.readouterr().out.splitlines()
    assert status == 0 and len(out) == 3
    assert out[0].rstrip().endswith("1 skipped  [skipped]")
    assert out[1].rstrip().endswith("1 skipped  [skipped]")
    assert "skipped" not in out[2]


def test_json_and_vote_lines_are_read_by_another_process(model, tmp_path):
    # docs/stream.md's example consumer, run as its own process, reads `stream --json --vote 3` run
    # where torch cannot be imported
    example = re.search(r"```python\n(# robot_consumer\.py.*?)```", DOCS.read_text(), re.S).group(1)
    consumer_py = tmp_path / "robot_consumer.py"
    consumer_py.write_text(example)
    sensor = PtySensor()
    rec, _ = axis_recording("xxy", 30)
    args = ["stream", "--model", model, "--port", sensor.path, "--json", "--vote", "3", "--max-windows", "10"]
    robot = _NO_TORCH + f"from tactile_torch.cli import main\nsys.exit(main({args!r}))"  # as on the robot
    stream = subprocess.Popen([sys.executable, "-c", robot], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    consumer = subprocess.Popen(
        [sys.executable, str(consumer_py)], stdin=stream.stdout, stdout=subprocess.PIPE, text=True
    )
    stream.stdout.close()
    first = stream.stderr.readline().decode()
    waiting = stream.stderr.readline().decode()  # printed once the port is open and silent
    assert "no data yet" in waiting, first + waiting
    sensor.write_samples(rec, _t(0, 90))
    got, _ = consumer.communicate(timeout=60)
    assert stream.wait(timeout=60) == 0, stream.stderr.read().decode()
    sensor.close()
    decided = [line.split() for line in got.splitlines()]
    # windows start at 0, 8, ... 72; the vote is the majority of the last 3 (a tie: the latest)
    names = [expected_axis(rec[s : s + W].T) for s in range(0, 73, 8)]
    votes = []
    for i in range(10):
        last = names[max(0, i - 2) : i + 1]
        top = max(last.count(n) for n in last)
        votes.append(next(n for n in reversed(last) if last.count(n) == top))
    assert [d[0] for d in decided] == [str(i) for i in range(10)]
    assert [d[1] for d in decided] == names and names[0] == "x" and names[-1] == "y"
    assert [d[2] for d in decided] == votes


def test_simulate_sensor_plays_a_recording_on_a_pty(tmp_path):
    rec, _ = axis_recording("z", 400)
    data = tmp_path / "rec.npz"
    np.savez(data, signals=rec[None].astype(np.float32), labels=[0], class_names=["z"], rate_hz=RATE)
    proc = subprocess.Popen(
        [sys.executable, "-m", "tactile_torch.cli", "simulate-sensor", "--pty", "--data", str(data), "--timestamps"],
        stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    path = re.match(r"sensor on (\S+):", proc.stdout.readline()).group(1)
    port = serial.Serial(path, timeout=5)
    data = b""
    with pytest.raises(serial.SerialException):  # the sensor closes the port once all was read
        while chunk := port.read(port.in_waiting or 1):
            data += chunk
    port.close()
    assert proc.wait(timeout=30) == 0 and proc.stdout.read().strip().endswith("400 samples written")
    t = np.array([p[0] for p in map(parse_line, data.splitlines()) if p is not None])
    assert len(t) >= 300 and t[-1] == pytest.approx(399 / RATE)  # opening the port may cut the start
    np.testing.assert_allclose(np.diff(t), 1 / RATE, atol=2e-6)


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["--vote", "0"], "argument --vote: expected a whole number >= 1, got '0'"),
        (["--silence", "-1"], "argument --silence: expected a finite number >= 0.01, got '-1'"),
        (
            ["--idle-timeout", "soon"],
            "argument --idle-timeout/--timeout: expected a finite number >= 0, got 'soon'",
        ),
        (["--step", "1.5"], "argument --step: expected a whole number >= 1, got '1.5'"),
        (["--step", "0"], "argument --step: expected a whole number >= 1, got '0'"),
    ],
)
def test_stream_bad_options_are_one_usage_error(model, args, match, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["stream", "--model", model, "--port", "/dev/null", *args])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and err.count("\n") == 1 and err.startswith("tactile-torch stream: ")
    assert err.strip().endswith(match)


def test_stream_refuses_a_bundle_that_takes_no_windows(tmp_path, capsys):
    model = energy_bundle(tmp_path / "features.onnx", drop=("window_size",))
    assert main(["stream", "--model", str(model), "--port", "/dev/null"]) == 2
    assert (
        capsys.readouterr().err.strip()
        == f"tactile-torch stream: {model} does not take vibration windows or taxel frames"
    )


def test_simulate_sensor_needs_a_port_or_a_pty(capsys):
    assert main(["simulate-sensor"]) == 2
    assert (
        capsys.readouterr().err.strip()
        == "tactile-torch simulate-sensor: give one of --port PORT, --pty or --ros2-topic TOPIC"
    )
    assert main(["stream", "--model", "m.onnx"]) == 2  # a stream reads a port or a ROS 2 topic
    assert "give either --port PORT (a serial sensor) or --ros2-topic TOPIC" in capsys.readouterr().err


@pytest.fixture
def sensor_pty():
    sensor = PtySensor()
    yield sensor
    sensor.close()


# ---------------------------------------------------------------- issue 23: a stream a robot can supervise
def test_a_merged_line_in_an_xyz_stream_does_not_stall_it(model, sensor_pty, opened, capsys):
    """A line cut after its first comma merges with the next into four numbers: skipped, not a format."""
    rec, _ = axis_recording("xyz", 200)  # 600 samples = 37 windows of 16 (+ 8)
    lines = [format_sample(s) for s in rec]
    cut = lines[20].split(b",")[0] + b","  # "x," then the next line: "x,x,y,z"
    sent = b"".join(lines[:20]) + cut + b"".join(lines[21:])

    def sensor():
        opened(1)
        sensor_pty.write(sent)
        sensor_pty.drain()

    writer = _Writer(sensor)
    status = _stream(model, sensor_pty, "--step", "16", "--idle-timeout", "1")
    writer.finish()
    out, err = capsys.readouterr()
    records = _records(out)
    assert status == STREAM_NO_DATA_EXIT  # the sensor stopped: the idle timeout, not a stall
    # 599 samples were sent intact but one (merged into the skipped line): 37 windows of 16, none lost
    assert len(records) == 37 and records[-1]["sample"] == 592, (len(records), err)
    assert "changed from" not in err and "0 line-format switches" in err.splitlines()[-1]
    assert "598 samples read, 37 windows, 1 lines skipped" in err.splitlines()[-1]


def test_a_real_switch_of_line_format_is_reported_once_and_followed(model, sensor_pty, opened, capsys):
    rec, _ = axis_recording("xz", 64)
    sent = b"".join(format_sample(s) for s in rec[:64]) + b"".join(
        format_sample(s, t) for s, t in zip(rec[64:], _t(64, 64), strict=True)
    )

    def sensor():
        opened(1)
        sensor_pty.write(sent)
        sensor_pty.drain()

    writer = _Writer(sensor)
    status = _stream(model, sensor_pty, "--step", "16", "--idle-timeout", "1")
    writer.finish()
    out, err = capsys.readouterr()
    records = _records(out)
    events = [line for line in err.splitlines() if "changed from x,y,z to t,x,y,z" in line]
    assert status == STREAM_NO_DATA_EXIT and len(events) == 1, err
    # 4 windows before; 15 timed lines skipped, the 16th confirms the switch: 49 samples, 3 windows
    assert [r["sample"] for r in records] == [16, 32, 48, 64, 80, 96, 112], err
    assert all(r["t_start"] is not None for r in records[4:]) and records[4]["gaps"] == 1
    assert "113 samples read, 7 windows, 15 lines skipped" in err.splitlines()[-1]
    assert "1 line-format switches" in err.splitlines()[-1]


def test_garbage_at_the_wrong_baud_rate_times_out_like_silence(model, sensor_pty, opened, capsys):
    """Bytes that never parse do not keep the stream alive: --timeout counts time without a valid sample."""
    stop = threading.Event()
    rng = np.random.default_rng(0)

    def sensor():
        opened(1)
        while not stop.is_set():  # what a 9600-baud sensor looks like on a 230400-baud port
            sensor_pty.write(bytes(rng.integers(0, 256, 200, dtype=np.uint8)) + b"\n")
            time.sleep(0.02)

    writer = _Writer(sensor)
    started = time.monotonic()
    status = _stream(model, sensor_pty, "--timeout", "1", "--start-timeout", "1.5")
    elapsed = time.monotonic() - started
    stop.set()
    writer.finish()
    err = capsys.readouterr().err.splitlines()
    assert status == STREAM_NO_DATA_EXIT and elapsed < 10, (elapsed, err)
    assert re.search(
        r": no valid sample for 1\.\d s \(timeout 1\.5 s\); 0 samples read, \d+ lines skipped$", err[-2]
    )
    assert re.search(r"no valid sample yet on \S+ after 0\.\d s, \d+ lines skipped", "\n".join(err))


def test_m_s2_lines_are_named_and_read_with_units(model, sensor_pty, opened, capsys):
    """Issue 34: m/s^2 lines were rejected sample by sample with no hint, and "no data yet" was printed."""
    rec, _ = axis_recording("xz", 32)
    still = rec * 0.05 + [0.0, 0.0, 1.0]  # a sensor at rest: gravity on z
    lines = b"".join(format_sample(s) for s in np.concatenate([still, rec]) * 9.80665)  # in m/s^2
    writer = _Writer(lambda: (opened(1), sensor_pty.write(lines)))
    assert _stream(model, sensor_pty, "--start-timeout", "1", "--idle-timeout", "1") == STREAM_NO_DATA_EXIT
    writer.finish()
    out, err = capsys.readouterr()
    hints = [line for line in err.splitlines() if "gravity reads 1 g" in line]
    assert len(hints) == 1 and hints[0].endswith("pass --units m/s2 (9.80665 m/s^2 = 1 g)"), err
    assert "no data" not in err and err.splitlines()[-2].endswith("these look like m/s^2: pass --units m/s2")
    writer = _Writer(lambda: (opened(2), sensor_pty.write(lines)))
    status = _stream(model, sensor_pty, "--units", "m/s2", "--step", "16", "--max-windows", "8")
    writer.finish()
    out, err = capsys.readouterr()
    assert status == 0 and "m/s^2" not in err and "0 samples out of range" in err.splitlines()[-1]
    records = _records(out)
    # windows of the recording after the still part, in g, labelled as the bundle labels g windows
    assert [r["name"] for r in records[4:]] == [expected_axis(rec[i : i + W].T) for i in range(0, 64, 16)]


def _default_sigint() -> None:
    """In the child: SIGINT to its default. A test run started in the background of a non-interactive shell
    inherits SIGINT ignored, and Python then keeps ignoring it (no KeyboardInterrupt), as the shell meant."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _start_stream(model, port, *args):
    """``tactile-torch stream`` in its own process (as systemd runs it); returns it once it says "reading"."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "tactile_torch.cli", "stream", "--model", model, "--port", port, *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=_default_sigint,  # the test process may run with SIGINT ignored
    )
    header = proc.stderr.readline()  # status lines go to stderr, in text mode as in --json
    assert "reading" in header, (header, proc.stdout.read() if proc.poll() is not None else "")
    return proc


def test_samples_sent_right_after_reading_are_all_counted(model, sensor_pty):
    """'reading' comes once the port is open and the model warm: nothing the sensor sends then is lost."""
    rec, _ = axis_recording("xy", 80)
    proc = _start_stream(model, sensor_pty.path, "--step", "16", "--max-windows", "10")
    sensor_pty.write_samples(rec[:160], _t(0, 160))  # at once: 10 windows
    out, err = proc.communicate(timeout=60)
    lines = out.splitlines()
    assert proc.returncode == 0, err
    # stdout holds the decisions only (one line per window); the summary is the last line of stderr
    assert [line.split()[1] for line in lines] == [str(16 * (i + 1)) for i in range(10)], out
    assert "160 samples read, 10 windows, 0 lines skipped" in err.splitlines()[-1]


@pytest.mark.parametrize("how", ["SIGTERM", "SIGINT"])
def test_sigterm_and_sigint_end_with_the_summary_and_status_0(model, sensor_pty, how):
    import signal

    rec, _ = axis_recording("z", 64)
    proc = _start_stream(model, sensor_pty.path, "--step", "16")
    sensor_pty.write_samples(rec, _t(0, 64))
    sensor_pty.drain()
    deadline = time.monotonic() + 30
    seen = []
    while len(seen) < 4 and time.monotonic() < deadline:  # the 4 windows of 16 samples
        seen.append(proc.stdout.readline())
    proc.send_signal(getattr(signal, how))
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
    assert len(seen + out.splitlines()) == 4, out  # stdout: the 4 windows, nothing else
    assert err.splitlines()[-1].startswith("64 samples read, 4 windows, 0 lines skipped"), err
    assert f"stopped by {how}" in err and "Traceback" not in err


def test_a_closed_stdout_ends_the_stream_at_once(model, sensor_pty):
    """The consumer of the decisions dies while the sensor goes on: the stream stops at its next window
    (text lines go through the same print, show(), as the JSON lines tested here)."""
    rec, _ = axis_recording("xy", 8)
    stop = threading.Event()

    def sensor():  # a sensor that never stops (100 windows a second)
        i = 0
        while not stop.is_set():
            sensor_pty.write_samples(rec, _t(i, 16))
            i += 16
            time.sleep(0.01)

    proc = _start_stream(model, sensor_pty.path, "--step", "16", "--idle-timeout", "30", "--json")
    writer = _Writer(sensor)
    try:
        assert proc.stdout.readline()  # a first decision, then the reader goes away
        proc.stdout.close()
        status = proc.wait(timeout=20)  # before: it classified into nothing until the sensor stopped
    finally:
        stop.set()
        proc.kill()
        writer.finish()
    err = proc.stderr.read().splitlines()
    assert status == STREAM_OUTPUT_CLOSED_EXIT, err
    assert re.fullmatch(
        r"tactile-torch stream: stdout closed \(its reader went away\) after \d+ windows; stopping", err[-2]
    )
    assert re.match(
        r"\d+ samples read, \d+ windows, 0 lines skipped", err[-1]
    ) and "Traceback" not in "".join(err)


@pytest.mark.slow
def test_a_five_minute_real_time_stream_loses_and_mislabels_nothing(model, sensor_pty, tmp_path):
    """The issue's soak: 800 Hz in real time for 5 minutes, then SIGTERM; every window sent is reported."""
    import signal

    seconds = 300
    rec, _ = axis_recording("xyz", int(RATE) * seconds // 3, random_state=5)
    out_path = tmp_path / "windows.jsonl"
    with out_path.open("w") as out:
        proc = subprocess.Popen(
            [sys.executable, "-m", "tactile_torch.cli", "stream", "--model", model, "--port", sensor_pty.path,
             "--step", str(W), "--json"],
            stdout=out, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        assert "reading" in proc.stderr.readline()
        start = time.perf_counter()
        for i in range(0, len(rec), 80):  # 100 ms of samples at a time, paced against the clock
            time.sleep(max(0.0, start + i / RATE - time.perf_counter()))
            sensor_pty.write_samples(rec[i : i + 80], _t(i, len(rec[i : i + 80])))
        sensor_pty.drain()
        time.sleep(0.5)
        proc.send_signal(signal.SIGTERM)
        err = proc.communicate(timeout=60)[1]
    records = _records(out_path.read_text())
    assert proc.returncode == 0, err
    assert len(records) == len(rec) // W  # windows sent == windows reported
    _check_windows(records, rec)
    assert err.splitlines()[-1].startswith(
        f"{len(rec)} samples read, {len(rec) // W} windows, 0 lines skipped"
    )
