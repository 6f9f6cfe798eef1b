"""The serial source of a live stream: ASCII lines from a serial port, decoded into samples or frames.

:class:`SerialSource` is the :class:`~tactile_torch.robot.stream_source.Source` of ``tactile-torch stream
--port``: the port side (open, read, silence, timeouts, reconnection) is
:class:`~tactile_torch.robot.port_lines.PortLines`; this module decodes the lines.

Wire protocol: one ASCII line per item, ``\\n``-terminated (``\\r\\n`` accepted), comma-separated
numbers. A triaxial sample is ``x,y,z`` in g, or ``t,x,y,z``; a frame of an ``H x W`` taxel array is its
``H * W`` values in row-major order (``H * W * 3`` for RGB frames, pixel by pixel: ``r,g,b,r,g,b,...``),
optionally with ``t`` first. ``t`` is seconds by default (``time_unit``: ``ms``, ``us``, or ``samples``
for an item counter). A line with another number of fields is garbage (a line cut short, two lines run
together, a frame of another sensor): skipped and counted, never an item.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator

import numpy as np

from .port_lines import PortLines, ReadablePort, StreamEvent
from .stream_source import (
    FORMAT,
    RECONNECT,
    REJECTED,
    SAMPLE,
    SILENCE,
    Break,
    ItemSpec,
    Reading,
    SourceCounts,
)
from .wire import parse_line

TIME_UNITS = ("s", "ms", "us", "samples")
"""Units the ``t`` field may be in; ``"samples"`` is an item counter (one per sample or frame)."""
FORMAT_RUN = 16
"""Consecutive lines of the other format (with or without ``t``) after which the new format is followed."""
_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6}


def parse_values(line: bytes | str, size: int) -> tuple[float | None, np.ndarray] | None:
    """Return ``(t, values)`` of a line of ``size`` numbers (or ``t`` and ``size`` numbers), else ``None``.

    ``values`` is float64 ``(size,)``; ``t`` is ``None`` without a time field. ``None`` when the line is
    not ASCII, has another number of fields, or holds a field that is not a finite number.

    >>> parse_values(b"0.5,1,2,3,4\\r\\n", 4)
    (0.5, array([1., 2., 3., 4.]))
    >>> parse_values(b"1,2,3", 4) is None
    True
    """
    if isinstance(line, str):
        line = line.encode("ascii", "replace")
    fields = line.split(b",")
    n = len(fields)
    if n != size and n != size + 1:
        return None
    try:
        values = np.array(fields, dtype=np.float64)
    except (ValueError, UnicodeDecodeError):
        return None
    if not np.isfinite(values).all():
        return None
    if n == size:
        return None, values
    return float(values[0]), values[1:]


class _PortCounts:
    """:class:`~tactile_torch.robot.stream_source.SourceCounts` read live from a :class:`SerialSource`."""

    __slots__ = ("_source",)

    def __init__(self, source: SerialSource) -> None:
        self._source = source

    items = property(lambda self: self._source.samples)
    skipped = property(lambda self: self._source.skipped)
    rejected = property(lambda self: self._source.rejected)
    reconnects = property(lambda self: self._source.reconnects)
    format_switches = property(lambda self: self._source.format_switches)
    lost = property(lambda self: self._source.lost_on_reconnect)

    def snapshot(self) -> SourceCounts:
        """The counts now, as a plain :class:`SourceCounts`."""
        return SourceCounts(
            self.items, self.skipped, self.rejected, self.reconnects, self.format_switches, self.lost
        )


class SerialSource(PortLines):
    """Samples or frames from a serial line (a :class:`~tactile_torch.robot.stream_source.Source`).

    Parameters
    ----------
    source : readable object, or a callable with no argument that returns one
        A ``serial.Serial`` opened with a short ``timeout`` (0.1 s), a pyserial URL's port, a file;
        a callable is called to open (and to reopen) the port.
    spec : ItemSpec
        What a line holds: a sample ``(3,)`` or a frame ``(H, W)`` / ``(H, W, 3)``, and the range of
        accepted values (items with a value outside are rejected and end the segment).
    time_unit : {"s", "ms", "us", "samples"}
        Unit of the ``t`` field; ``"samples"`` reads it as an item counter (needs ``spec.rate_hz``).
    silence_s, idle_timeout_s, start_timeout_s, reconnect, backoff_s, on_event, on_open, name, clock, sleep
        As :class:`~tactile_torch.robot.port_lines.PortLines`.
    max_line_bytes : int, optional
        A partial line longer than this is dropped as skipped (default: room for the item's numbers,
        at least 256 bytes).

    Attributes
    ----------
    counts : SourceCounts
        Items, lines skipped, items rejected, reconnections, format switches (live).
    """

    def __init__(
        self,
        source: ReadablePort | Callable[[], ReadablePort],
        spec: ItemSpec,
        *,
        time_unit: str = "s",
        silence_s: float = 0.5,
        idle_timeout_s: float | None = None,
        start_timeout_s: float | None = None,
        reconnect: bool = False,
        backoff_s: tuple[float, float] = (0.5, 8.0),
        on_event: Callable[[StreamEvent], None] | None = None,
        on_open: Callable[[str], None] | None = None,
        max_line_bytes: int | None = None,
        name: str | None = None,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        if time_unit not in TIME_UNITS:
            raise ValueError(f"time_unit must be one of {TIME_UNITS}, got {time_unit!r}")
        if time_unit == "samples" and spec.rate_hz is None:
            raise ValueError("time_unit='samples' (a sample counter) needs rate_hz")
        if max_line_bytes is None:
            max_line_bytes = max(256, 24 * (spec.size + 1))
        super().__init__(
            source,
            silence_s=silence_s,
            idle_timeout_s=idle_timeout_s,
            start_timeout_s=start_timeout_s,
            reconnect=reconnect,
            backoff_s=backoff_s,
            on_event=on_event,
            on_open=on_open,
            max_line_bytes=max_line_bytes,
            name=name,
            clock=clock,
            sleep=sleep,
        )
        self.spec = spec
        self.time_unit = time_unit
        self.item = spec.kind
        self.skipped_name = "lines"
        self.rejected = self.format_switches = self.lost_on_reconnect = 0
        self.counts = _PortCounts(self)

    @property
    def name(self) -> str:
        """What messages call the port."""
        return self._name or "the port"

    def _decode(self):
        """Return the line decoder of frames: ``line -> (t, values) | None`` (samples: :func:`parse_line`)."""
        size, shape = self.spec.size, self.spec.shape

        def frame(line: bytes):
            parsed = parse_values(line, size)
            if parsed is None:
                return None
            return parsed[0], parsed[1].astype(np.float32).reshape(shape)

        return frame

    def readings(self) -> Iterator[Reading | Break]:
        """Yield a :class:`Reading` per accepted line and a :class:`Break` where continuity is lost."""
        spec = self.spec
        sample = spec.kind == SAMPLE
        decode = parse_line if sample else self._decode()
        lo, hi = spec.low, spec.high
        unit = _UNITS[self.time_unit] if self.time_unit in _UNITS else 1.0 / spec.rate_hz
        timed: bool | None = None  # whether the lines carry t (set by the first item of a connection)
        other_run = 0  # consecutive lines of the other format
        count = 0  # items since the connection (re)started, to spot a partial first line
        reconnects = self.reconnects
        check, in_range = spec.checks_range, spec.in_range
        self._last_sample_at, self._silent = self._clock(), False
        self._delay = self.backoff_s[0]
        for line, now in self._lines():
            if line is None:  # silence or reconnection: continuity lost, the format may change
                kind = RECONNECT if self.reconnects != reconnects else SILENCE
                reconnects = self.reconnects
                timed, other_run, count = None, 0, 0
                yield Break(kind, now)
                continue
            parsed = decode(line)
            if parsed is None:
                self.skipped += 1
                continue
            if sample:
                t, values = parsed[0], parsed[1:]
            else:
                t, values = parsed
            has_t = t is not None
            if timed is not None and has_t != timed and count <= 1:
                timed, count = (
                    None,
                    0,
                )  # the connection's first line was a partial one: the second sets the format
            if timed is not None and has_t != timed:
                # A line of the other format: one alone is garbage (a line cut short and merged with the
                # next); a run of them is the sensor switching formats.
                other_run += 1
                if other_run < FORMAT_RUN:
                    self.skipped += 1
                    continue
                fields = "x,y,z" if spec.kind == SAMPLE else f"{spec.size} values"
                new, old = (f"t,{fields}", fields) if not timed else (fields, f"t,{fields}")
                self.format_switches += 1
                self._emit(
                    "format",
                    f"the lines changed from {old} to {new} ({FORMAT_RUN} in a row) after {self.samples} "
                    f"{self.item}s; following the new format (the {FORMAT_RUN - 1} lines before this one "
                    "were skipped)",
                )
                timed, count = not timed, 0
                yield Break(FORMAT, now)
            other_run = 0
            if check and not (
                lo <= values[0] <= hi and lo <= values[1] <= hi and lo <= values[2] <= hi
                if sample
                else in_range(values)
            ):
                self.rejected += 1  # an item is known to be missing here: the segment ends
                self._emit(
                    "range",
                    f"a {self.item} out of the sensor's range {spec.describe_range()} was rejected: "
                    f"{spec.describe_item(values)}",
                    repeated=True,
                )
                count = 0
                yield Break(REJECTED, now)
                continue
            if self._silent or not self.samples:
                waited = now - self._last_sample_at
                if self._silent and self.samples:
                    self._emit("resumed", f"{self.item}s again after {waited:.1f} s of silence")
                elif waited >= self.silence_s:
                    self._emit("first", f"first {self.item} after {waited:.1f} s")
                self._silent = False
            self._last_sample_at = now
            if timed is None:
                timed = has_t
            if not count:  # a segment starts: the connection works, so the next failure waits little
                self._delay = self.backoff_s[0]
            count += 1
            self.samples += 1
            yield Reading(values, t * unit if has_t else None, now)


__all__ = ["FORMAT_RUN", "TIME_UNITS", "SerialSource", "parse_values"]
