import io
import os
import threading

import numpy as np
import pytest
import serial
from numpy.lib.stride_tricks import sliding_window_view

from tactile_torch.stream import WindowReader, format_sample, parse_sample, simulate_sensor


def _recording(n, seed=0):
    rng = np.random.default_rng(seed)
    return np.round(rng.normal(0, 0.3, size=(n, 3)) / 0.0039) * 0.0039  # 3.9 mg steps


def _expected_windows(rec, w, step):
    # (n_windows, 3, w): the windows a batch sliding-window cut gives, in float32 after the 5-decimal wire format
    wire = np.array([[float(v) for v in format_sample(s).decode().split(",")] for s in rec], dtype=np.float32)
    return sliding_window_view(wire, w, axis=0)[::step]


@pytest.mark.parametrize(("w", "step"), [(8, 8), (8, 3), (5, 1), (6, 10)])
def test_reader_yields_the_sliding_windows_of_the_stream(w, step):
    rec = _recording(47)
    port = serial.serial_for_url("loop://", timeout=0.05)
    simulate_sensor(port, rec, realtime=False)
    reader = WindowReader(port, window_size=w, step=step)
    got = np.concatenate(list(reader))
    np.testing.assert_array_equal(got, _expected_windows(rec, w, step))
    assert reader.samples == 47 and reader.skipped == 0


def test_reader_skips_garbage_lines_and_counts_them():
    rec = _recording(20)
    lines = [format_sample(s) for s in rec]
    stream = b"".join([b"2.3,0.1\n", b"\xff\xfe,1,2\n", *lines[:10], b"0.1,inf,1\n", b"a,b,c\n", *lines[10:]])
    reader = WindowReader(io.BytesIO(stream), window_size=10)
    got = np.concatenate(list(reader))
    np.testing.assert_array_equal(got, _expected_windows(rec, 10, 10))
    assert reader.skipped == 4


def test_reader_stops_after_max_windows():
    reader = WindowReader(io.BytesIO(b"0,0,1\n" * 100), window_size=4, step=2, max_windows=3)
    assert len(list(reader)) == 3 and reader.samples == 8


def test_simulate_sensor_paces_lines_at_the_rate():
    slept = []
    sink = io.BytesIO()
    simulate_sensor(sink, np.zeros((50, 3)), rate_hz=100.0, sleep=slept.append)
    # 50 samples at 100 Hz span 0.49 s of wall time; the fake sleep does not advance the clock, so
    # the requested lags add up to more than that, and each is at most one period late.
    assert sink.getvalue().count(b"\n") == 50
    assert len(slept) >= 45 and max(slept) <= 0.49 + 1e-3


def test_reader_over_a_pseudo_terminal():
    master, slave = os.openpty()
    rec = _recording(64, seed=1)
    port = serial.Serial(os.ttyname(slave), timeout=0.5)
    writer = threading.Thread(
        target=simulate_sensor, args=(io.FileIO(master, "wb", closefd=False), rec), kwargs={"realtime": False}
    )
    writer.start()
    windows = list(WindowReader(port, window_size=16, max_windows=4))
    writer.join()
    port.close()
    os.close(master)
    np.testing.assert_array_equal(np.concatenate(windows), _expected_windows(rec, 16, 16))


@pytest.mark.parametrize(
    ("kwargs", "err", "match"),
    [
        ({"source": object(), "window_size": 8}, TypeError, "source must have a readline"),
        ({"source": io.BytesIO(), "window_size": 0}, ValueError, "window_size must be an int >= 1, got 0"),
        ({"source": io.BytesIO(), "window_size": 1}, ValueError, "window_size must be >= 2"),
        ({"source": io.BytesIO(), "window_size": 8, "step": 1.5}, ValueError, "step must be an int >= 1"),
    ],
)
def test_reader_bad_arguments(kwargs, err, match):
    with pytest.raises(err, match=match):
        WindowReader(**kwargs)


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


def test_parse_sample_rejects_wrong_field_counts():
    assert parse_sample("1,2") is None and parse_sample("1,2,3,4,5") is None
    assert parse_sample("0.5, 0.25 ,1\r\n") == (0.5, 0.25, 1.0)
