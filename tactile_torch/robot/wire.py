"""The sensor's line protocol: parse and format ``x,y,z`` / ``t,x,y,z`` lines; a simulated sensor.

One ASCII line per sample, ``x,y,z`` in g, or ``t,x,y,z`` with ``t`` a number (seconds unless the
reader is told otherwise), terminated by ``\\n`` (``\\r\\n`` accepted). numpy only: this module runs on
the robot (through :mod:`tactile_torch.robot.stream`, which re-exports these names) and on the bench
(``tactile-torch simulate-sensor``).
"""

from __future__ import annotations

import array
import contextlib
import math
import time
from collections.abc import Callable, Iterator
from typing import BinaryIO, Protocol

import numpy as np


class _Sink(Protocol):
    def write(self, data: bytes) -> int | None: ...


def parse_line(line: bytes | str) -> tuple[float | None, float, float, float] | None:
    """Return ``(t, x, y, z)`` of one protocol line (``t`` is ``None`` for ``x,y,z``), or ``None``.

    ``None`` when the line is not ASCII, has other than 3 or 4 fields, a field is not a number, or a
    value is NaN or infinite.

    >>> parse_line(b"12.5,0,0,1\\r\\n")
    (12.5, 0.0, 0.0, 1.0)
    >>> parse_line(b"0.01,-0.02,1.0\\n")
    (None, 0.01, -0.02, 1.0)
    >>> parse_line(b"ERR,0,0,1") is None
    True
    """
    if isinstance(line, bytes):
        try:
            line = line.decode("ascii")
        except UnicodeDecodeError:
            return None
    fields = line.split(",")
    n = len(fields)
    if n != 3 and n != 4:
        return None
    try:
        values = [float(v) for v in fields]
    except ValueError:
        return None
    for v in values:
        if not math.isfinite(v):
            return None
    if n == 3:
        return None, values[0], values[1], values[2]
    return values[0], values[1], values[2], values[3]


def parse_sample(line: bytes | str) -> tuple[float, float, float] | None:
    """Return the ``(x, y, z)`` sample of one protocol line, or ``None`` if it is not a finite sample.

    The ``t`` of a ``t,x,y,z`` line must be a finite number too, but is not returned
    (:func:`parse_line` returns it).

    >>> parse_sample(b"0.01,-0.02,1.0\\r\\n")
    (0.01, -0.02, 1.0)
    >>> parse_sample(b"12.5,0,0,1")
    (0.0, 0.0, 1.0)
    >>> parse_sample(b"0.1,nan,1") is None
    True
    """
    parsed = parse_line(line)
    return None if parsed is None else parsed[1:]


def format_sample(sample: np.ndarray, t: float | None = None) -> bytes:
    """Return the protocol line of one ``(3,)`` sample in g (5 decimals: finer than the 3.9 mg LSB).

    With ``t`` (seconds) the line is ``t,x,y,z`` with ``t`` to the microsecond.
    """
    xyz = f"{sample[0]:.5f},{sample[1]:.5f},{sample[2]:.5f}\n"
    return (xyz if t is None else f"{t:.6f},{xyz}").encode("ascii")


@contextlib.contextmanager
def pseudo_terminal(*, drain_timeout_s: float = 10.0) -> Iterator[tuple[BinaryIO, str]]:
    """Open a pseudo-terminal pair (POSIX); yield ``(sink, path)``: what is written to ``sink`` is read at ``path``.

    ``path`` (e.g. ``/dev/pts/3``) is the port a reader opens as it would open ``/dev/ttyUSB0``; the
    terminal is raw (no echo, no line editing). On exit, waits up to ``drain_timeout_s`` for the
    reader to take what was written (closing a pseudo-terminal drops unread input), then closes it:
    the reader's next read fails, as when a sensor's adapter is unplugged.
    """
    import fcntl
    import os
    import termios
    import tty

    master, slave = os.openpty()
    try:
        tty.setraw(slave)
        with open(master, "wb", buffering=0, closefd=False) as sink:
            yield sink, os.ttyname(slave)
        # Written bytes pass through the kernel's flip buffer before the reader's queue counts them:
        # wait for the queue to stay empty a while, not just to be empty once.
        unread = array.array("i", [0])
        deadline, empty_since = time.monotonic() + drain_timeout_s, None
        while (now := time.monotonic()) < deadline:
            fcntl.ioctl(slave, termios.FIONREAD, unread)
            empty_since = (empty_since or now) if not unread[0] else None
            if empty_since is not None and now - empty_since >= 0.05:
                break
            time.sleep(0.01)
    finally:
        os.close(master)
        os.close(slave)


def simulate_sensor(
    sink: _Sink,
    recording: np.ndarray,
    *,
    rate_hz: float = 800.0,
    realtime: bool = True,
    timestamps: bool = False,
    t0: float = 0.0,
    sleep: Callable[[float], None] = time.sleep,
) -> int:
    """Write a recording ``(n, 3)`` in g to ``sink`` as protocol lines; return the number of samples.

    With ``realtime=True`` the lines are paced at ``rate_hz`` against a monotonic clock (no drift
    accumulates); otherwise they are written as fast as the sink takes them. With ``timestamps=True``
    each line is ``t,x,y,z`` with ``t = t0 + i / rate_hz`` seconds.
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
        sink.write(format_sample(sample, t0 + i / rate_hz if timestamps else None))
    return len(recording)


__all__ = ["format_sample", "parse_line", "parse_sample", "pseudo_terminal", "simulate_sensor"]
