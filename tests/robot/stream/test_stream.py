"""The serial stream reader: windows, and every fault of a real line (docs/stream.md), over files,
pyserial's loop:// and a pseudo-terminal. The CLI over a pty is in tests/cli/test_stream.py."""

import io
import math
import re
import threading
import time
import tracemalloc

import numpy as np
import pytest
import serial
from numpy.lib.stride_tricks import sliding_window_view

from tactile_torch.robot.runtime import sensor_range_g
from tactile_torch.robot.stream.live import LiveOptions
from tactile_torch.robot.stream.port_lines import StreamDisconnected, StreamTimeout
from tactile_torch.robot.stream.serial_source import SerialSource
from tactile_torch.robot.stream.source import SAMPLE, ItemSpec
from tactile_torch.robot.stream.wire import format_sample, parse_line, parse_sample, simulate_sensor
from tests.stream_helpers import PtySensor, SerialWindows


def _recording(n, seed=0):
    rng = np.random.default_rng(seed)
    return np.round(rng.normal(0, 0.3, size=(n, 3)) / 0.0039) * 0.0039  # 3.9 mg steps


def _wire(rec):
    # (n, 3) float32: what the reader gets from the 5-decimal wire format
    return np.array([parse_sample(format_sample(s)) for s in rec], dtype=np.float32)


def _expected_windows(rec, w, step):
    # (n_windows, 3, w): the windows a batch sliding-window cut gives
    return sliding_window_view(_wire(rec), w, axis=0)[::step]


def _timed_lines(rec, t):
    return b"".join(format_sample(s, float(ti)) for s, ti in zip(rec, t, strict=True))


class _Clock:
    """A fake clock; ``sleep`` advances it and records the wait."""

    def __init__(self):
        self.now = 1000.0
        self.slept = []

    def __call__(self):
        return self.now

    def sleep(self, seconds):
        self.slept.append(seconds)
        self.now += seconds


class _ScriptedPort:
    """A port whose reads follow a script: bytes are read, ``(bytes, s)`` are read after s seconds (the
    time the sensor took to send them), a number is that many silent seconds (an empty read), an
    exception is raised. After the script, every read is 0.1 s of silence."""

    def __init__(self, script, clock):
        self.script = list(script)
        self.clock = clock
        self.closed = False

    def read(self, size):
        item = self.script.pop(0) if self.script else 0.1
        if isinstance(item, Exception):
            raise item
        if isinstance(item, float):
            self.clock.now += item
            return b""
        if isinstance(item, tuple):
            item, seconds = item
            self.clock.now += seconds
        return item

    def close(self):
        self.closed = True


def _reader(script, clock, **kwargs):
    port = _ScriptedPort(script, clock)
    events = []
    kwargs.setdefault("idle_timeout_s", 10.0)
    reader = SerialWindows(
        lambda: port, clock=clock, sleep=clock.sleep, on_event=events.append, name="/dev/imu", **kwargs
    )
    return reader, events, port


@pytest.mark.parametrize(("w", "step"), [(8, 8), (8, 3), (5, 1), (6, 10)])
def test_reader_yields_the_sliding_windows_of_the_stream(w, step):
    rec = _recording(47)
    port = serial.serial_for_url("loop://", timeout=0.05)
    simulate_sensor(port, rec, realtime=False)
    reader = SerialWindows(port, window_size=w, step=step)
    windows = list(reader)
    np.testing.assert_array_equal(
        np.concatenate([win.data for win in windows]), _expected_windows(rec, w, step)
    )
    assert [win.end_sample for win in windows] == list(range(w, 48, step))
    assert reader.samples == 47 and reader.skipped == reader.gaps == 0
    assert all(win.t_start is None and win.flags == () for win in windows)


def test_parse_line_reads_t_as_a_number_and_rejects_what_is_not_a_sample():
    assert parse_line(b"12.5,0,0,1\r\n") == (12.5, 0.0, 0.0, 1.0)
    assert parse_line(" 0.5, 0.25 ,1\n") == (None, 0.5, 0.25, 1.0)
    for bad in [
        b"ERR,0.1,0.2,0.3\n",
        b"0.1,nan,1",
        b"0,inf,0,1",
        b"1,2",
        b"1,2,3,4,5",
        b"\xff\xfe,1,2",
        b"",
        b"a,b,c",
    ]:
        assert parse_line(bad) is None, bad
    # a time stamp of any value is a time stamp: the sequencer judges it, the sample is kept
    assert parse_line(b"inf,0,0,1")[1:] == parse_line(b"nan,0,0,1")[1:] == (0.0, 0.0, 1.0)
    assert parse_sample(b"12.5,0,0,1") == (0.0, 0.0, 1.0)  # the t field is not returned
    assert parse_sample(b"ERR,0,0,1") is None


def test_garbage_is_skipped_counted_per_window_and_flags_the_windows_it_falls_in():
    rec = _recording(40)
    lines = [format_sample(s) for s in rec]
    garbage = {
        12: b"\xff\xfe\x00\x81\n",
        13: b"0.1,nan,1\n",
        27: b"1,2\n",
        28: b"1,2,3,4,5\n",
        29: b"0.12,-0.3",
    }
    # inserted before sample i (garbage lines are insertions: without t nothing says a sample is lost)
    stream = b"".join(garbage.get(i, b"") + line for i, line in enumerate(lines))
    reader = SerialWindows(io.BytesIO(stream), window_size=10, step=5)
    windows = list(reader)
    # "0.12,-0.3" runs into the next line: one line "0.12,-0.3<sample 29>" with 5 fields, skipped
    sent = np.delete(rec, 29, axis=0)
    np.testing.assert_array_equal(np.concatenate([w.data for w in windows]), _expected_windows(sent, 10, 5))
    assert reader.skipped == 5 and reader.samples == 39
    # windows end at samples 10, 15, ... 35: skipped lines counted in the window after them
    assert [w.skipped for w in windows] == [0, 2, 0, 0, 3, 0]
    # a window is flagged when a skipped line lies between its first and last sample
    spans = [(w.end_sample - 10, w.end_sample - 1) for w in windows]
    flagged = [any(a < i <= b for i in (12, 13, 27, 28, 29)) for a, b in spans]
    assert [("skipped" in w.flags) for w in windows] == flagged


def test_gaps_in_t_are_never_spanned_by_a_window():
    rate, w, step = 800.0, 8, 4
    rec = _recording(120)
    t = np.arange(120) / rate
    keep = np.ones(120, bool)
    keep[30:50] = False  # a burst of 20 dropped samples
    second = _recording(40, seed=5)  # a second recording spliced on: t starts again at 0
    stream = _timed_lines(rec[keep], t[keep]) + _timed_lines(second, np.arange(40) / rate)
    events = []
    reader = SerialWindows(io.BytesIO(stream), window_size=w, step=step, rate_hz=rate, on_event=events.append)
    windows = list(reader)
    segments = [_wire(rec[:30]), _wire(rec[50:]), _wire(second)]
    expected = np.concatenate([sliding_window_view(s, w, axis=0)[::step] for s in segments])
    np.testing.assert_array_equal(np.concatenate([win.data for win in windows]), expected)
    for win in windows:  # every window covers W consecutive sample periods
        assert win.t_end - win.t_start == pytest.approx((w - 1) / rate, abs=2e-6)
        assert win.rate_hz == pytest.approx(rate, rel=1e-3) and "rate" not in win.flags
    assert reader.gaps == 2 and reader.lost == 20
    gaps = [e.message for e in events if e.kind == "gap"]
    assert len(gaps) == 2 and "20 sample(s) missing" in gaps[0] and "t went back" in gaps[1]
    assert sum(win.gaps for win in windows) == 2


def test_a_sample_counter_works_as_t():
    rec = _recording(30)
    counter = np.r_[np.arange(10), np.arange(13, 33)]  # samples 10-12 lost
    stream = b"".join(f"{c},".encode() + format_sample(s) for c, s in zip(counter, rec, strict=True))
    reader = SerialWindows(io.BytesIO(stream), window_size=8, rate_hz=100.0, time_unit="samples")
    windows = list(reader)
    assert [w.end_sample for w in windows] == [8, 18, 26]  # a new segment at sample 10
    assert reader.lost == 3 and windows[0].t_start == 0.0 and windows[1].t_start == pytest.approx(0.13)


def test_a_stream_at_another_rate_is_flagged_not_silenced():
    # 100 Hz data for an 800 Hz model: every step of t looks like 7 lost samples until the reader
    # sees a steady rate, adopts it for the gap checks, says so once and flags the windows.
    rec = _recording(60)
    events = []
    reader = SerialWindows(
        io.BytesIO(_timed_lines(rec, np.arange(60) / 100.0)),
        window_size=8,
        rate_hz=800.0,
        on_event=events.append,
    )
    windows = list(reader)
    assert [e.kind for e in events if e.kind == "rate"] == ["rate"]
    assert "100 Hz" in next(e.message for e in events if e.kind == "rate")
    assert windows and all("rate" in w.flags and w.rate_hz == pytest.approx(100.0) for w in windows)


@pytest.mark.parametrize("bad", ["1e30,0,1", "3e19,0,1", "0,-5.5,1"])
def test_a_sample_out_of_range_is_rejected_and_ends_the_segment(bad):
    rec = _recording(40)
    lines = [format_sample(s) for s in rec]
    lines[20] = f"{bad}\n".encode()
    events = []
    reader = SerialWindows(io.BytesIO(b"".join(lines)), window_size=8, on_event=events.append)
    windows = list(reader)
    expected = np.concatenate(
        [sliding_window_view(_wire(rec[a:b]), 8, axis=0)[::8] for a, b in ((0, 20), (21, 40))]
    )
    np.testing.assert_array_equal(np.concatenate([w.data for w in windows]), expected)
    assert reader.rejected == 1 and reader.gaps == 1 and windows[2].rejected == 1
    assert [e.kind for e in events] == ["range"] and "±5 g" in events[0].message
    assert np.abs(np.concatenate([w.data for w in windows])).max() <= 5.0
    # the check is the range, not the parser: with no range the value passes
    assert SerialWindows(io.BytesIO(b"".join(lines)), window_size=8, range_g=math.inf).rejected == 0
    assert len(list(SerialWindows(io.BytesIO(b"".join(lines)), window_size=8, range_g=math.inf))) == 5


def test_sensor_range_comes_from_the_bundle_metadata():
    assert sensor_range_g({}) == 5.0
    assert sensor_range_g({"sensor_range_g": "16"}) == 16.0
    with pytest.raises(ValueError, match="sensor_range_g must be a number > 0, got '-2'"):
        sensor_range_g({"sensor_range_g": "-2"})


def test_a_timestamped_stream_skips_lines_without_t():
    rec = _recording(20)
    t = np.arange(20) / 800.0
    lines = [format_sample(s, ti) for s, ti in zip(rec, t, strict=True)]
    lines[9] = format_sample(rec[9])  # t lost in transmission: not a sample of this stream
    reader = SerialWindows(io.BytesIO(b"".join(lines)), window_size=5, rate_hz=800.0)
    windows = list(reader)
    assert reader.skipped == 1 and reader.lost == 1
    assert [w.end_sample for w in windows] == [5, 14, 19]  # sample 9 missing: a new segment at 10


def test_noise_without_newlines_is_dropped_with_bounded_memory():
    rec = _recording(16)
    noise = bytes(np.random.default_rng(0).integers(11, 256, 100_000, dtype=np.uint8))  # no b"\n"
    stream = (
        b"".join(format_sample(s) for s in rec[:8])
        + noise
        + b"\n"
        + b"".join(format_sample(s) for s in rec[8:])
    )

    class Chunked(io.RawIOBase):  # 4 kB reads, like a serial port's
        def __init__(self, data):
            self.data = io.BytesIO(data)

        def readable(self):
            return True

        def readinto(self, b):
            chunk = self.data.read(min(len(b), 4096))
            b[: len(chunk)] = chunk
            return len(chunk)

    reader = SerialWindows(Chunked(stream), window_size=8, max_line_bytes=256)
    windows = list(reader)
    assert reader.samples == 16 and reader.skipped == 1  # 100 kB of noise without a newline: one line
    np.testing.assert_array_equal(windows[1].data[0].T, _wire(rec[8:]))


def test_silence_is_reported_and_no_window_spans_it():
    clock = _Clock()
    rec = _recording(24)
    lines = [format_sample(s) for s in rec]
    script = [b"".join(lines[:12]), 0.3, 0.3, b"".join(lines[12:]), 0.1]
    reader, events, port = _reader(script, clock, window_size=8, max_windows=2, silence_s=0.5)
    windows = list(reader)
    assert [w.end_sample for w in windows] == [8, 20]  # samples 8-11 end with the silence
    np.testing.assert_array_equal(windows[1].data[0].T, _wire(rec[12:20]))
    assert [e.kind for e in events] == ["silence", "resumed"]
    assert (
        "no sample for 0.6 s after 12 samples" in events[0].message
        and "0.6 s of silence" in events[1].message
    )
    assert windows[1].gaps == 1 and port.closed


def test_waits_for_the_first_sample_then_gives_up():
    clock = _Clock()
    rec = _recording(8)
    script = [0.3, 0.3, 0.3, b"".join(format_sample(s) for s in rec)]
    reader, events, _ = _reader(script, clock, window_size=8, start_timeout_s=5.0, idle_timeout_s=1.0)
    windows = []
    with pytest.raises(
        StreamTimeout, match=r"^/dev/imu: no sample for 1\.\d s \(timeout 1 s\); 8 samples read"
    ):
        for window in reader:
            windows.append(window)
    assert len(windows) == 1
    assert [e.kind for e in events] == ["waiting", "first", "silence"]
    assert events[0].message == "no data yet on /dev/imu after 0.6 s (giving up after 5 s)"
    assert events[1].message == "first sample after 0.9 s"
    # nothing at all: the start timeout
    reader, events, _ = _reader([], clock, window_size=8, start_timeout_s=2.0)
    with pytest.raises(
        StreamTimeout, match=r"^/dev/imu: no data for 2\.\d s \(timeout 2 s\); 0 samples read"
    ):
        list(reader)


def test_a_failing_port_raises_one_clear_error():
    clock = _Clock()
    script = [b"0,0,1\n" * 5, serial.SerialException("device reports readiness to read but returned no data")]
    reader, _, port = _reader(script, clock, window_size=8)
    with pytest.raises(StreamDisconnected, match="/dev/imu disconnected after 5 samples: device reports"):
        list(reader)
    assert port.closed

    def unplugged():
        raise serial.SerialException("could not open port /dev/imu: No such file or directory")

    with pytest.raises(StreamDisconnected, match="could not open /dev/imu: could not open port"):
        list(SerialWindows(unplugged, window_size=8, name="/dev/imu"))


def test_reconnects_with_backoff_and_starts_a_new_window():
    clock = _Clock()
    rec = _recording(30)
    lines = [format_sample(s) for s in rec]
    ports = [
        _ScriptedPort([b"".join(lines[:12]), OSError(5, "Input/output error")], clock),
        _ScriptedPort([b"".join(lines[12:])], clock),
    ]
    failures = iter([OSError(2, "No such file"), OSError(2, "No such file"), OSError(2, "No such file")])

    def opener():
        if len(ports) == 2:
            return ports.pop(0)
        failure = next(failures, None)
        if failure is not None:
            raise failure
        return ports.pop(0)

    events = []
    reader = SerialWindows(
        opener,
        window_size=8,
        reconnect=True,
        idle_timeout_s=30.0,
        max_windows=3,
        clock=clock,
        sleep=clock.sleep,
        on_event=events.append,
        name="/dev/imu",
    )
    windows = list(reader)
    assert clock.slept == [0.5, 1.0, 2.0, 4.0]  # three failed attempts, the fourth opens
    # "disconnected" when the port fails, "reopened" when it opens again, "reconnected" at its first sample
    assert [e.kind for e in events] == ["disconnected", "reopened", "reconnected"]
    assert events[0].message == "/dev/imu disconnected ([Errno 5] Input/output error); reconnecting"
    assert "4 attempt(s)" in events[1].message and reader.reconnects == 1
    assert events[2].message == "/dev/imu: samples again 7.5 s after it failed"
    assert [w.end_sample for w in windows] == [8, 20, 28]  # a new segment after the reconnection
    np.testing.assert_array_equal(windows[1].data[0].T, _wire(rec[12:20]))


def test_reconnection_gives_up_after_the_idle_timeout():
    clock = _Clock()

    def opener():
        if not clock.slept:
            return _ScriptedPort([b"0,0,1\n" * 3, OSError(5, "Input/output error")], clock)
        raise OSError(2, "No such file")

    reader = SerialWindows(
        opener,
        window_size=8,
        reconnect=True,
        idle_timeout_s=5.0,
        clock=clock,
        sleep=clock.sleep,
        name="/dev/imu",
    )
    # waits 0.5, 1, 2 s, then the last wait is cut to 1.5 s: one attempt at the timeout itself
    with pytest.raises(StreamDisconnected, match=r"gave up reconnecting after 4 attempt\(s\), 5.0 s"):
        list(reader)
    assert clock.slept == [0.5, 1.0, 2.0, 1.5]


@pytest.mark.parametrize("first_read", [(), (0.05,)], ids=["data at once", "first read empty"])
def test_a_port_back_before_the_idle_timeout_is_reopened(first_read):
    """The issue's case: idle timeout 10 s, the port back after 8.5 s (the old backoff gave up at 7.5 s).
    Issue 34: the reopen lands on the timeout itself; when its first read was empty (the sensor's first
    line comes 50 ms later), the idle clock, still running from the last sample, ended the stream."""
    clock = _Clock()
    rec = _recording(24)
    lines = [format_sample(s) for s in rec]

    def opener():
        if not clock.slept:
            return _ScriptedPort([b"".join(lines[:8]), OSError(5, "Input/output error")], clock)
        if sum(clock.slept) < 8.5:
            raise OSError(2, "No such file")
        return _ScriptedPort([*first_read, b"".join(lines[8:])], clock)

    events = []
    reader = SerialWindows(
        opener,
        window_size=8,
        reconnect=True,
        idle_timeout_s=10.0,
        clock=clock,
        sleep=clock.sleep,
        name="/dev/imu",
        on_event=events.append,
    )
    windows = []
    with pytest.raises(StreamTimeout):  # the scripted port goes silent after its lines
        for window in reader:
            windows.append(window)
    assert reader.reconnects == 1 and len(windows) == 3
    assert clock.slept[:5] == [0.5, 1.0, 2.0, 4.0, 2.5]  # the attempt at 10 s finds it
    assert "open after 10.0 s (5 attempt(s))" in next(e.message for e in events if e.kind == "reopened")


def test_reader_over_a_pseudo_terminal_until_the_writer_closes_it():
    sensor = PtySensor()
    rec = _recording(64, seed=1)
    port = serial.Serial(sensor.path, timeout=0.1)
    reader = SerialWindows(port, window_size=16, idle_timeout_s=5.0)

    def write_then_close():
        sensor.write_samples(rec)
        # a pty drops what the reader has not read when the writer closes it (as an unplugged
        # adapter does): close once all has been read
        deadline = time.monotonic() + 10
        while reader.samples < len(rec) and time.monotonic() < deadline:
            time.sleep(0.01)
        sensor.close()

    writer = threading.Thread(target=write_then_close)
    writer.start()
    windows = []
    with pytest.raises(StreamDisconnected, match="disconnected after 64 samples"):
        for window in reader:
            windows.append(window.data)
    writer.join()
    port.close()
    np.testing.assert_array_equal(np.concatenate(windows), _expected_windows(rec, 16, 16))


def test_a_long_fast_stream_over_a_pty_loses_no_sample():
    # the functional version of bench/bench_stream.py: 30 s of 800 Hz, written as fast as the pty takes it
    n, rate, w = 24_000, 800.0, 800
    rec = _recording(n, seed=2)
    sensor = PtySensor()
    port = serial.Serial(sensor.path, timeout=0.1)
    writer = threading.Thread(target=lambda: sensor.write(_timed_lines(rec, np.arange(n) / rate)))
    writer.start()
    reader = SerialWindows(port, window_size=w, step=w // 2, rate_hz=rate, idle_timeout_s=5.0, max_windows=59)
    last = None
    for window in reader:
        last = window
    writer.join()
    sensor.close()
    port.close()
    assert reader.samples == n and reader.skipped == reader.gaps == reader.lost == 0
    assert reader.windows == (n - w) // (w // 2) + 1 == 59
    np.testing.assert_array_equal(last.data[0].T, _wire(rec[-w:]))


def test_memory_does_not_grow_with_the_stream():
    # tracemalloc's peak while reading 3x more samples stays the same (the ring, one window, one chunk)
    def peak(n):
        source = io.BytesIO(_timed_lines(_recording(n, seed=3), np.arange(n) / 800.0))
        tracemalloc.start()
        base = tracemalloc.get_traced_memory()[0]
        for _ in SerialWindows(source, window_size=800, step=400, rate_hz=800.0):
            pass
        used = tracemalloc.get_traced_memory()[1] - base
        tracemalloc.stop()
        return used

    small, large = peak(4_000), peak(12_000)
    assert large < small + 16_000, (small, large)  # one kept window would add 9.6 kB


@pytest.mark.parametrize(
    ("kwargs", "err", "match"),
    [
        ({"source": object()}, TypeError, r"source must have a read\(size\) method"),
        ({"time_unit": "h"}, ValueError, "time_unit must be one of"),
        ({"time_unit": "samples", "spec": ItemSpec(SAMPLE, (3,))}, ValueError, "needs rate_hz"),
        ({"silence_s": -1.0}, ValueError, "silence_s must be > 0"),
        ({"reconnect": True}, ValueError, "reconnect=True needs"),
        ({"backoff_s": (1,)}, ValueError, "backoff_s must be"),
        ({"units": "mg"}, ValueError, "units must be one of"),
    ],
)
def test_serial_source_bad_arguments(kwargs, err, match):
    spec = kwargs.pop("spec", ItemSpec(SAMPLE, (3,), -5.0, 5.0, 800.0, "g"))
    with pytest.raises(err, match=match):
        SerialSource(kwargs.pop("source", io.BytesIO()), spec, **kwargs)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"step": 1.5}, "step must be an int >= 1, got 1.5"),
        ({"step": 0}, "step must be an int >= 1, got 0"),
        ({"vote": 0}, "vote must be an int >= 1, got 0"),
        ({"max_results": 0}, "max_results must be an int >= 1, got 0"),
    ],
)
def test_live_options_bad_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        LiveOptions(**kwargs)


def test_simulate_sensor_paces_lines_at_the_rate():
    slept = []
    sink = io.BytesIO()
    simulate_sensor(sink, np.zeros((50, 3)), rate_hz=100.0, sleep=slept.append)
    # 50 samples at 100 Hz span 0.49 s of wall time; the fake sleep does not advance the clock, so
    # the requested lags add up to more than that, and each is at most one period late.
    assert sink.getvalue().count(b"\n") == 50
    assert len(slept) >= 45 and max(slept) <= 0.49 + 1e-3


def test_simulate_sensor_writes_t():
    sink = io.BytesIO()
    simulate_sensor(sink, np.ones((3, 3)), rate_hz=800.0, realtime=False, timestamps=True, t0=2.0)
    assert sink.getvalue().splitlines() == [
        b"2.000000,1.00000,1.00000,1.00000",
        b"2.001250,1.00000,1.00000,1.00000",
        b"2.002500,1.00000,1.00000,1.00000",
    ]


@pytest.mark.parametrize(
    ("rec", "kwargs", "match"),
    [
        (np.zeros((5, 2)), {}, r"recording must have shape \(n, 3\), got \(5, 2\)"),
        (np.full((5, 3), np.nan), {}, "recording must be finite"),
        (np.zeros((5, 3)), {"rate_hz": 0.0}, "rate_hz must be > 0"),
    ],
)
def test_simulate_sensor_bad_arguments(rec, kwargs, match):
    with pytest.raises(ValueError, match=match):
        simulate_sensor(io.BytesIO(), rec, **kwargs)


def test_floods_of_gap_events_are_counted_not_printed():
    # one sample dropped in every four, 20 times: 20 gaps; 5 are shown, the next one shown a second
    # later gives the count of the 15 left out
    rec = _recording(87)
    t = np.arange(84) / 800.0
    keep = np.ones(84, bool)
    keep[np.arange(20) * 4 + 1] = False
    clock = _Clock()
    script = [
        (_timed_lines(rec[:84][keep], t[keep]), 0.105),  # what the sensor sent in 0.105 s
        1.0,
        (_timed_lines(rec[84:], 0.2 + np.arange(3) / 800.0), 0.00375),  # after 76 more lost
    ]
    reader, events, _ = _reader(
        script, clock, window_size=8, rate_hz=800.0, silence_s=5.0, idle_timeout_s=2.0
    )
    with pytest.raises(StreamTimeout):
        list(reader)
    assert reader.gaps == 21 and reader.lost == 96 and [e.kind for e in events] == ["gap"] * 6
    assert events[0].message == "a 2.5 ms gap 0 ms into /dev/imu: 1 sample(s) missing"
    assert (
        events[5].message
        == "a 96.3 ms gap 0.104 s into /dev/imu: 76 sample(s) missing (and 15 more not shown before it)"
    )


def test_a_real_recording_with_its_own_time_column_streams_without_false_gaps(shared_data):
    # HapMat (real IMU, 100 Hz, t written as "0.01"-step text): the t steps of a real log are not exact
    # multiples of the period; the reader must find no gap and cut the offline sliding windows
    path = shared_data("hapmat_imu5") / "Wood_1.csv"
    table = np.loadtxt(path, delimiter=",", skiprows=1, usecols=(0, 1, 2, 3))
    lines = path.read_bytes().splitlines()[1:]
    stream = b"".join(b",".join(line.split(b",")[:4]) + b"\n" for line in lines if line)  # time,accel_x,y,z
    reader = SerialWindows(io.BytesIO(stream), window_size=100, step=50, rate_hz=100.0)
    windows = list(reader)
    assert reader.samples == len(table) and reader.gaps == reader.skipped == reader.lost == 0
    expected = sliding_window_view(table[:, 1:].astype(np.float32), 100, axis=0)[::50]
    np.testing.assert_array_equal(np.concatenate([w.data for w in windows]), expected)
    assert all(w.rate_hz == pytest.approx(100.0, rel=1e-3) and w.flags == () for w in windows)


# ---------------------------------------------------------------- issue 34: units, reconnects
G = 9.80665  # m/s^2 per g


def test_units_and_scale_convert_the_lines_to_g():
    rec = _recording(40)
    for units, scale, factor in (("m/s2", None, G), ("g", 0.0039, 1 / 0.0039)):
        lines = b"".join(format_sample(s) for s in rec * factor)  # m/s^2, or ADXL345 counts
        reader = SerialWindows(io.BytesIO(lines), window_size=8, units=units, scale=scale)
        got = np.concatenate([w.data[0].T for w in reader])
        wire = np.array([parse_sample(format_sample(s)) for s in rec * factor]) / factor
        np.testing.assert_allclose(got, wire.astype(np.float32), rtol=1e-6)
        assert reader.rejected == 0 and reader.samples == 40
    with pytest.raises(ValueError, match=r"units must be one of \['g', 'm/s2'\], got 'mg'"):
        SerialWindows(io.BytesIO(), window_size=8, units="mg")
    with pytest.raises(ValueError, match="scale must be > 0, got 0"):
        SerialWindows(io.BytesIO(), window_size=8, scale=0)


@pytest.mark.parametrize(
    ("gravity", "hint"),
    [
        (
            1.0,
            r"as g have a mean acceleration of (9|1\d)\.\d+ g over 64 samples .* look like m/s\^2: pass units='m/s2'",
        ),
        (0.0, r"\d+ of the last 64 samples were beyond ±5 g: .* units='m/s2' .* scale= .* range_g="),
    ],
    ids=["gravity", "no gravity"],
)
def test_samples_in_other_units_are_named_once(gravity, hint):
    # m/s^2 lines read as g: gravity reads 9.8 "g" (every sample rejected), or the vibration alone
    # (without gravity) throws most samples beyond the range; one line says what the data look like
    rec = (_recording(400) * (0.3 if gravity else 4) + np.array([0.0, 0.0, gravity])) * G
    clock = _Clock()
    script = [b"".join(format_sample(s) for s in rec), 0.3, 0.3, 0.3]
    reader, events, _ = _reader(script, clock, window_size=8, start_timeout_s=0.8, idle_timeout_s=0.8)
    with pytest.raises(
        StreamTimeout, match=r"no valid sample for 0\.\d s .* samples out of range; (these look|not g)"
    ):
        list(reader)
    units = [e.message for e in events if e.kind == "units"]
    assert len(units) == 1 and re.search(hint, units[0]), units
    # samples arrive: never "no data" (it was printed while samples were being rejected)
    assert not [e for e in events if "no data" in e.message]
    waiting = next(e.message for e in events if e.kind in ("waiting", "silence"))
    assert re.match(
        r"no valid sample (yet on /dev/imu )?(for |after )0\.\d s.*, \d+ samples out of range", waiting
    )


def test_samples_in_g_raise_no_units_line():
    rec = _recording(400) + np.array([0.0, 0.0, 1.0])  # gravity and vibration, in g
    events = []
    reader = SerialWindows(
        io.BytesIO(b"".join(format_sample(s) for s in rec)), window_size=8, on_event=events.append
    )
    assert len(list(reader)) == 50 and events == []


def test_samples_lost_across_a_reconnection_are_counted_from_t():
    clock = _Clock()
    rec = _recording(40)
    t = np.arange(40) / 800.0
    ports = [
        _ScriptedPort([_timed_lines(rec[:16], t[:16]), OSError(5, "Input/output error")], clock),
        _ScriptedPort([_timed_lines(rec[21:], t[21:])], clock),  # samples 16-20 sent while unplugged
    ]
    events = []
    reader = SerialWindows(
        lambda: ports.pop(0),
        window_size=8,
        rate_hz=800.0,
        reconnect=True,
        idle_timeout_s=1.0,
        clock=clock,
        sleep=clock.sleep,
        on_event=events.append,
        name="/dev/imu",
    )
    with pytest.raises(StreamTimeout):
        list(reader)
    # one gap: the reconnection (the step of t across it is the same gap, counted once); the silence at
    # the end is the stream's end, not a gap
    assert reader.lost == 5 and reader.gaps == 1 and reader.samples == 35
    gap = next(e.message for e in events if e.kind == "gap")
    assert gap == "a 7.5 ms gap 18.8 ms into /dev/imu: 5 sample(s) missing across the reconnection"
