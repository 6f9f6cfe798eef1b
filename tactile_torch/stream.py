"""Stream a triaxial accelerometer over a serial line, cut it into windows, classify them live.

Runs on the robot's computer with numpy, pyserial and onnxruntime only: importing this module never
imports torch.

Wire protocol (what :func:`simulate_sensor` writes and :class:`WindowReader` reads): one ASCII line
per sample, ``x,y,z`` in g (or ``t,x,y,z``, the first field ignored), terminated by ``\\n`` (``\\r\\n``
accepted). At 800 Hz a line of ~20 bytes needs about 16 kB/s, i.e. a baud rate of 230400 or more on
a real UART. Lines that do not parse (a partial line at start-up, a glitch) or that hold NaN/inf are
skipped and counted in :attr:`WindowReader.skipped`, never passed on.

Examples
--------
>>> import serial                                          # doctest: +SKIP
>>> port = serial.Serial("/dev/ttyUSB0", 230400, timeout=1)  # doctest: +SKIP
>>> reader = WindowReader(port, window_size=800, step=400)  # doctest: +SKIP
>>> for window in reader:                                   # (1, 3, 800) float32   doctest: +SKIP
...     print(pipeline.predict_names(window))               # doctest: +SKIP
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from typing import Protocol

import numpy as np


class _LineSource(Protocol):
    def readline(self) -> bytes: ...


class _LineSink(Protocol):
    def write(self, data: bytes) -> int | None: ...


def parse_sample(line: bytes | str) -> tuple[float, float, float] | None:
    """Return the ``(x, y, z)`` sample of one protocol line, or ``None`` if it is not a finite sample.

    >>> parse_sample(b"0.01,-0.02,1.0\\r\\n")
    (0.01, -0.02, 1.0)
    >>> parse_sample(b"12.5,0,0,1")          # t,x,y,z: the time is ignored
    (0.0, 0.0, 1.0)
    >>> parse_sample(b"0.1,nan,1") is None
    True
    """
    if isinstance(line, bytes):
        try:
            line = line.decode("ascii")
        except UnicodeDecodeError:
            return None
    fields = line.strip().split(",")
    if len(fields) not in (3, 4):
        return None
    try:
        x, y, z = (float(v) for v in fields[-3:])
    except ValueError:
        return None
    if not all(np.isfinite((x, y, z))):
        return None
    return x, y, z


def format_sample(sample: np.ndarray) -> bytes:
    """Return the protocol line of one ``(3,)`` sample in g (5 decimals: finer than the 3.9 mg LSB)."""
    return f"{sample[0]:.5f},{sample[1]:.5f},{sample[2]:.5f}\n".encode("ascii")


class WindowReader:
    """Iterate over windows ``(1, 3, window_size)`` float32 cut from a serial line stream.

    The first window is yielded once ``window_size`` samples have arrived, then one every ``step``
    new samples (``step = window_size``: disjoint windows). Iteration ends when the source returns an
    empty line (a timeout on a serial port, or the end of a stream), or after ``max_windows``.

    Parameters
    ----------
    source : object with ``readline() -> bytes``
        A ``serial.Serial`` (set a ``timeout``), ``serial.serial_for_url("loop://")`` or a file.
    window_size : int
        Samples per window W (e.g. 800 = 1 s at 800 Hz).
    step : int, optional
        Samples between window starts; defaults to ``window_size``.
    max_windows : int, optional
        Stop after this many windows.

    Attributes
    ----------
    samples : int
        Samples accepted so far.
    skipped : int
        Lines skipped because they did not parse or were not finite.
    """

    def __init__(
        self,
        source: _LineSource,
        *,
        window_size: int,
        step: int | None = None,
        max_windows: int | None = None,
    ) -> None:
        if not hasattr(source, "readline"):
            raise TypeError(
                f"source must have a readline() method (e.g. serial.Serial), got {type(source).__name__}"
            )
        step = window_size if step is None else step
        for name, value in (("window_size", window_size), ("step", step)):
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
                raise ValueError(f"{name} must be an int >= 1, got {value!r}")
        if window_size < 2:
            raise ValueError(f"window_size must be >= 2 samples, got {window_size}")
        self.source = source
        self.window_size = int(window_size)
        self.step = int(step)
        self.max_windows = max_windows
        self.samples = 0
        self.skipped = 0

    def __iter__(self) -> Iterator[np.ndarray]:
        w = self.window_size
        # Ring of 2W samples written twice (at i and i + W) so that the last W samples are always one
        # contiguous slice: no copy per sample, one copy per window.
        ring = np.zeros((2 * w, 3), dtype=np.float32)
        emitted = 0
        since_last = 0
        while self.max_windows is None or emitted < self.max_windows:
            line = self.source.readline()
            if not line:
                return
            sample = parse_sample(line)
            if sample is None:
                self.skipped += 1
                continue
            i = self.samples % w
            ring[i] = ring[i + w] = sample
            self.samples += 1
            since_last += 1
            if self.samples >= w and (self.samples == w or since_last >= self.step):
                since_last = 0
                start = self.samples % w
                emitted += 1
                yield np.ascontiguousarray(ring[start : start + w].T)[None]


def simulate_sensor(
    sink: _LineSink,
    recording: np.ndarray,
    *,
    rate_hz: float = 800.0,
    realtime: bool = True,
    sleep: Callable[[float], None] = time.sleep,
) -> int:
    """Write a recording ``(n, 3)`` in g to ``sink`` as protocol lines; return the number of samples.

    With ``realtime=True`` the lines are paced at ``rate_hz`` against a monotonic clock (no drift
    accumulates); otherwise they are written as fast as the sink takes them.
    """
    recording = np.asarray(recording)
    if recording.ndim != 2 or recording.shape[1] != 3:
        raise ValueError(f"recording must have shape (n, 3), got {recording.shape}")
    if not np.isfinite(recording).all():
        raise ValueError("recording must be finite, got NaN or inf samples")
    if not rate_hz > 0:
        raise ValueError(f"rate_hz must be > 0, got {rate_hz}")
    start = time.perf_counter()
    for i, sample in enumerate(recording):
        if realtime:
            lag = start + i / rate_hz - time.perf_counter()
            if lag > 0:
                sleep(lag)
        sink.write(format_sample(sample))
    return len(recording)


__all__ = ["WindowReader", "format_sample", "parse_sample", "simulate_sensor"]
