"""The sensor's line protocol: parse and format ``x,y,z`` / ``t,x,y,z`` lines and frame lines; a simulated sensor.

One ASCII line per sample, ``x,y,z`` in g, or ``t,x,y,z`` with ``t`` a number (seconds unless the
reader is told otherwise), terminated by ``\\n`` (``\\r\\n`` accepted); a frame of a taxel array is
one line of its values in row-major order, optionally with ``t`` first (:func:`format_frame`). numpy only: this module runs on
the robot (:class:`~tactile_torch.robot.stream.serial_source.SerialSource` reads these lines) and on the bench
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

    ``None`` when the line is not ASCII, has other than 3 or 4 fields, a field is not a number, or
    ``x``, ``y`` or ``z`` is NaN or infinite. ``t`` may be any number, ``inf`` and ``nan`` included:
    the stream's sequencer judges it (a stamp off schedule is corrected, the sample kept).

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
    for v in values[n - 3 :]:
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


def format_frame(frame: np.ndarray, t: float | None = None) -> bytes:
    """Return the protocol line of one frame: its values in row-major order, ``t`` (seconds) first if given.

    Integer-valued frames (raw counts, uint8 RGB) are written as integers; others with 9 significant
    digits, which float32 values survive exactly.

    >>> format_frame(np.array([[0, 12], [3, 4]]), t=0.5)
    b'0.500000,0,12,3,4\\n'
    """
    flat = np.asarray(frame).reshape(-1)
    if flat.dtype.kind in "iub" or (
        np.abs(flat).max(initial=0) < 2**53 and np.array_equal(flat, np.round(flat))
    ):
        body = ",".join(map(str, flat.astype(np.int64).tolist()))
    else:
        body = ",".join(f"{v:.9g}" for v in flat.astype(np.float32).tolist())
    return (body + "\n" if t is None else f"{t:.6f},{body}\n").encode("ascii")


@contextlib.contextmanager
def pseudo_terminal(*, drain_timeout_s: float = 10.0) -> Iterator[tuple[BinaryIO, str]]:
    """Open a pseudo-terminal pair (POSIX); yield ``(sink, path)``: what is written to ``sink`` is read at ``path``.

    ``path`` (e.g. ``/dev/pts/3``) is the port a reader opens as it would open ``/dev/ttyUSB0``; the
    terminal is raw (no echo, no line editing). This side keeps no handle on ``path``, so
    :func:`wait_for_reader` sees when a reader opens it. On exit, waits up to ``drain_timeout_s`` for
    the reader to take what was written (closing a pseudo-terminal drops unread input), then closes it:
    the reader's next read fails, as when a sensor's adapter is unplugged.
    """
    import fcntl
    import os
    import termios
    import tty

    master, slave = os.openpty()
    path = os.ttyname(slave)
    try:
        tty.setraw(slave)  # the settings stay with the terminal, for whoever opens it
        os.close(slave)
        slave = -1
        with open(master, "wb", buffering=0, closefd=False) as sink:
            yield sink, path
        if not reader_attached(master):
            return
        slave = os.open(path, os.O_RDONLY | os.O_NOCTTY | os.O_NONBLOCK)  # to count what is still unread
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
        if slave >= 0:
            os.close(slave)


def reader_attached(sink: BinaryIO | int) -> bool:
    """Return whether a reader holds the terminal side of a :func:`pseudo_terminal` open (its ``sink`` or fd)."""
    import select

    poll = select.poll()
    poll.register(sink, select.POLLHUP)
    return not any(event & select.POLLHUP for _, event in poll.poll(0))


def wait_for_reader(
    sink: BinaryIO | int,
    timeout_s: float | None = None,
    *,
    settle_s: float = 0.3,
    sleep: Callable[[float], None] = time.sleep,
) -> bool:
    """Wait until a reader opens the terminal side of a :func:`pseudo_terminal`; return whether one did.

    A reader that opens a serial port discards what was buffered before (pyserial's ``open`` flushes
    the input, as ``tactile-torch stream`` relies on): writing before the reader is there, or in the
    moment it opens, loses the first lines. So this waits for the open, then ``settle_s`` more for the
    reader's flush, before the caller writes. ``timeout_s`` ``None``: wait as long as it takes.
    """
    deadline = None if timeout_s is None else time.monotonic() + float(timeout_s)
    while not reader_attached(sink):
        if deadline is not None and time.monotonic() >= deadline:
            return False
        sleep(0.01)
    sleep(settle_s)
    return True


def _play(
    sink: _Sink,
    line: Callable[[int, float | None], bytes],
    n: int,
    *,
    rate_hz: float,
    t: np.ndarray | None,
    pace: np.ndarray | None,
    timestamps: bool,
    realtime: bool,
    sleep: Callable[[float], None],
    t0: float = 0.0,
) -> int:
    """Write ``line(i, stamp)`` for ``i`` in ``0 .. n-1``; return ``n`` (:func:`simulate_sensor`, :func:`simulate_frames`).

    The stamps are ``t`` (the recording's own), else ``t0 + i / rate_hz``; written only with
    ``timestamps``. Item ``i`` goes out ``pace[i]`` seconds after the first (default: its stamp's offset).
    """
    if t is not None:
        t = np.asarray(t, dtype=np.float64)
        if t.shape != (n,) or not np.isfinite(t).all():
            raise ValueError(f"t must hold {n} finite times in seconds, got shape {t.shape}")
    elif not rate_hz > 0:
        raise ValueError(f"rate_hz must be > 0, got {rate_hz}")
    own = t if t is not None else t0 + np.arange(n) / float(rate_hz)
    pace = own - own[0] if pace is None and n else own if pace is None else np.asarray(pace, dtype=np.float64)
    if pace.shape != (n,):
        raise ValueError(f"pace must hold {n} times in seconds, got shape {pace.shape}")
    start = time.perf_counter()
    for i in range(n):
        if realtime:
            lag = start + pace[i] - time.perf_counter()
            if lag > 0:
                sleep(lag)
        sink.write(line(i, float(own[i]) if timestamps else None))
    return n


def simulate_sensor(
    sink: _Sink,
    recording: np.ndarray,
    *,
    rate_hz: float = 800.0,
    realtime: bool = True,
    timestamps: bool = False,
    t0: float = 0.0,
    t: np.ndarray | None = None,
    pace: np.ndarray | None = None,
    sleep: Callable[[float], None] = time.sleep,
) -> int:
    """Write a recording ``(n, 3)`` in g to ``sink`` as protocol lines; return the number of samples.

    With ``realtime=True`` the lines are paced against a monotonic clock (no drift accumulates): at
    ``rate_hz``, or at the recording's own times ``t`` (seconds, ``(n,)``: a logger's stamps, gaps
    included), or at ``pace`` (seconds since the first line, when it differs from ``t``: several
    recordings played one after another); otherwise they are written as fast as the sink takes them.
    With ``timestamps=True`` each line is ``t,x,y,z``: ``t`` the recording's own stamps when given,
    else ``t0 + i / rate_hz`` seconds.
    """
    recording = np.asarray(recording)
    if recording.ndim != 2 or recording.shape[1] != 3:
        raise ValueError(f"recording must have shape (n, 3), got {recording.shape}")
    if not np.isfinite(recording).all():
        raise ValueError("recording must be finite, got NaN or inf samples")
    fmt = format_sample
    return _play(sink, lambda i, ti: fmt(recording[i], ti), len(recording), rate_hz=rate_hz, t=t, pace=pace,
                 timestamps=timestamps, realtime=realtime, sleep=sleep, t0=t0)  # fmt: skip


def simulate_frames(
    sink: _Sink,
    frames: np.ndarray,
    *,
    t: np.ndarray | None = None,
    rate_hz: float = 10.0,
    realtime: bool = True,
    timestamps: bool = False,
    pace: np.ndarray | None = None,
    sleep: Callable[[float], None] = time.sleep,
) -> int:
    """Write frames ``(n, H, W)`` (or ``(n, H, W, 3)`` RGB) to ``sink`` as frame lines; return the number written.

    With ``t`` (seconds, ``(n,)``) the frames are paced at their recorded times (pauses included; or at
    ``pace``, seconds since the first frame) and ``timestamps=True`` writes that ``t``; without it they
    are paced at ``rate_hz`` and ``t = i / rate_hz``. ``realtime=False`` writes as fast as the sink takes them.
    """
    frames = np.asarray(frames)
    if frames.ndim not in (3, 4) or len(frames) == 0:
        raise ValueError(f"frames must have shape (n, H, W) or (n, H, W, 3) with n >= 1, got {frames.shape}")
    if not np.isfinite(frames).all():
        raise ValueError("frames must be finite, got NaN or inf values")
    fmt = format_frame
    return _play(sink, lambda i, ti: fmt(frames[i], ti), len(frames), rate_hz=rate_hz, t=t, pace=pace,
                 timestamps=timestamps, realtime=realtime, sleep=sleep)  # fmt: skip


__all__ = [
    "format_frame",
    "format_sample",
    "parse_line",
    "parse_sample",
    "pseudo_terminal",
    "reader_attached",
    "simulate_frames",
    "simulate_sensor",
    "wait_for_reader",
]
