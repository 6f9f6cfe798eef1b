"""The serial source of a live stream: ASCII lines from a serial port, decoded into samples or frames.

:class:`SerialSource` is the :class:`~tactile_torch.robot.stream.source.Source` of ``tactile-torch stream
--port``: the port side (open, read, silence, timeouts, reconnection) is
:class:`~tactile_torch.robot.stream.port_lines.PortLines`; this module decodes the lines.

Wire protocol: one ASCII line per item, ``\\n``-terminated (``\\r\\n`` accepted), comma-separated
numbers. A triaxial sample is ``x,y,z`` in g, or ``t,x,y,z``; a frame of an ``H x W`` taxel array is its
``H * W`` values in row-major order (``H * W * 3`` for RGB frames, pixel by pixel: ``r,g,b,r,g,b,...``),
optionally with ``t`` first. ``t`` is seconds by default (``time_unit``: ``ms``, ``us``, or ``samples``
for an item counter). A line with another number of fields is garbage (a line cut short, two lines run
together, a frame of another sensor): skipped and counted, never an item.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator

import numpy as np

from ...validation import check_number, saturate_float32
from ..files.csv_logs import STANDARD_GRAVITY, UNITS
from ..files.data_sources import GRAVITY_BAND_G
from ..files.sample_times import describe_duration
from .port_lines import PortLines, ReadablePort, StreamEvent
from .source import FORMAT, RECONNECT, REJECTED, SAMPLE, SILENCE, Break, ItemSpec, Reading
from .wire import parse_line

TIME_UNITS = ("s", "ms", "us", "samples")
"""Units the ``t`` field may be in; ``"samples"`` is an item counter (one per sample or frame)."""
FORMAT_RUN = 16
"""Consecutive lines of the other format (with or without ``t``) after which the new format is followed."""
UNITS_BLOCK = 64
"""Samples over which the units of a sample stream are judged (mean acceleration, share out of range)."""
_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6}


def parse_values(line: bytes | str, size: int) -> tuple[float | None, np.ndarray] | None:
    """Return ``(t, values)`` of a line of ``size`` numbers (or ``t`` and ``size`` numbers), else ``None``.

    ``values`` is float64 ``(size,)``; ``t`` is ``None`` without a time field. ``None`` when the line is
    not ASCII, has another number of fields, or holds a field that is not a number, or a value that is
    not finite (``t`` may be any number: the stream's sequencer judges it).

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
    if n == size:
        return (None, values) if np.isfinite(values).all() else None
    if not np.isfinite(values[1:]).all():
        return None
    return float(values[0]), values[1:]


class _PortCounts:
    """:class:`~tactile_torch.robot.stream.source.SourceCounts` read live from a :class:`SerialSource`."""

    __slots__ = ("_source",)

    def __init__(self, source: SerialSource) -> None:
        self._source = source

    items = property(lambda self: self._source.samples)
    skipped = property(lambda self: self._source.skipped)
    rejected = property(lambda self: self._source.rejected)
    reconnects = property(lambda self: self._source.reconnects)
    format_switches = property(lambda self: self._source.format_switches)
    lost = property(lambda self: self._source.lost_on_reconnect)


class SerialSource(PortLines):
    """Samples or frames from a serial line (a :class:`~tactile_torch.robot.stream.source.Source`).

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
    units : {"g", "m/s2"}, default "g"
        Samples: units of the ``x,y,z`` values on the line (as ``tactile-torch train --units``); the
        readings are in g.
    scale : float, optional
        Samples: units per count when the sensor sends integer counts (``0.0039`` for the ADXL345 at
        full resolution): a value is read as ``value * scale`` in ``units``. Samples that look like
        other units (a mean of 7-12 g over 64 samples: gravity in m/s^2; or most of 64 samples out of
        range) are said so once (event ``"units"``, with the argument to set).
    silence_s, idle_timeout_s, start_timeout_s, reconnect, backoff_s, on_event, on_open, name, clock, sleep
        As :class:`~tactile_torch.robot.stream.port_lines.PortLines`.
    max_line_bytes : int, optional
        A partial line longer than this is dropped as skipped, once however long (default: room for the
        item's numbers, at least 256 bytes).
    all_sensors : bool, default False
        Frames: a line holds the frames of several sensors, one after the other (``v1,...,vHW`` each,
        ``t`` first if any), as many as the connection's first line holds: each is a reading of its
        own sensor (:attr:`sensors`: ``"0"``, ``"1"``, ...), cut into touches on its own.

    Attributes
    ----------
    counts : SourceCounts
        Items, lines skipped, items rejected, reconnections, format switches (live).
    sensors : list of str
        With ``all_sensors``: the sensors' names once the first line has said how many there are.
    """

    def __init__(  # noqa: PLR0913
        self,
        source: ReadablePort | Callable[[], ReadablePort],
        spec: ItemSpec,
        *,
        time_unit: str = "s",
        units: str = "g",
        scale: float | None = None,
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
        all_sensors: bool = False,
    ) -> None:
        if time_unit not in TIME_UNITS:
            raise ValueError(f"time_unit must be one of {TIME_UNITS}, got {time_unit!r}")
        if time_unit == "samples" and spec.rate_hz is None:
            raise ValueError("time_unit='samples' (a sample counter) needs rate_hz")
        if units not in UNITS:
            raise ValueError(f"units must be one of {list(UNITS)}, got {units!r}")
        if spec.kind != SAMPLE and (units != "g" or scale is not None):
            raise ValueError("units and scale apply to accelerometer samples, not to frames")
        if all_sensors and spec.kind == SAMPLE:
            raise ValueError("all_sensors reads the frames of several taxel arrays on one line, not samples")
        self.all_sensors = bool(all_sensors)
        self.sensors: list[str] = []
        self.units, self.scale = units, None if scale is None else check_number(scale, "scale")
        if max_line_bytes is None:
            max_line_bytes = max(256, 24 * (spec.size * (64 if all_sensors else 1) + 1))
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

    def _judge_units(self, mean: tuple[float, float, float], n: int, rejected: int) -> bool:
        """Say once what a block of ``n`` samples (mean in g, ``rejected`` out of range) looks like; return whether it did."""
        norm = math.sqrt(sum(m * m for m in mean))
        declared = "g" if self.units == "g" and self.scale is None else None
        if declared and GRAVITY_BAND_G[0] <= norm <= GRAVITY_BAND_G[1]:
            hint = "these look like m/s^2: pass units='m/s2'"
            message = (
                f"the samples read as g have a mean acceleration of {norm:.3g} g over {n} samples (x, y, z = "
                f"{', '.join(f'{m:.3g}' for m in mean)}): gravity reads 1 g, so {hint} ({STANDARD_GRAVITY} m/s^2 "
                "= 1 g)"
            )
        elif 2 * rejected >= n:
            hint = "not g? declare units='m/s2', scale= or range_g="
            message = (
                f"{rejected} of the last {n} samples were beyond {self.spec.describe_range()}: samples in other "
                f"units than {self.units}{'' if self.scale is None else f' x {self.scale:g}'}? declare them with "
                "units='m/s2' (m/s^2) or scale= (units per count of a sensor that sends counts), or the sensor's "
                "range with range_g="
            )
        else:
            return False
        self._units_hint = hint
        self._emit("units", message)
        return True

    @property
    def name(self) -> str:
        """What messages call the port."""
        return self._name or "the port"

    def _decode(self):
        """Return the line decoder of frames: ``line -> (t, values) | None`` (samples: :func:`parse_line`).

        ``values`` is a frame ``spec.shape``, or with ``all_sensors`` the frames ``(k, *spec.shape)`` of the
        ``k`` sensors the first line held (a line with another number of values is garbage).
        """
        size, shape = self.spec.size, self.spec.shape

        def frame(line: bytes):
            parsed = parse_values(line, size)
            if parsed is None:
                return None
            # beyond float32 (1e308) reads as float32's largest, then as out of range: never inf, never a warning
            return parsed[0], saturate_float32(parsed[1]).reshape(shape)

        def frames(line: bytes):
            n = line.count(b",") + 1
            k = len(self.sensors) or (n // size if n % size == 0 else (n - 1) // size)
            parsed = parse_values(line, k * size) if k else None
            if parsed is None:
                return None
            if not self.sensors:  # the first line says how many sensors the line carries
                self.sensors.extend(str(i) for i in range(k))
            return parsed[0], saturate_float32(parsed[1]).reshape(k, *shape)

        return frames if self.all_sensors else frame

    def readings(self) -> Iterator[Reading | Break]:  # noqa: C901, PLR0915
        """Yield a :class:`Reading` per accepted line and a :class:`Break` where continuity is lost."""
        spec = self.spec
        sample = spec.kind == SAMPLE
        decode = parse_line if sample else self._decode()
        lo, hi = spec.low, spec.high
        factor = UNITS[self.units] * (1.0 if self.scale is None else self.scale)
        # the units of samples are judged over blocks until they are found wrong (said once)
        judge = sample and self._units_hint is None
        block, block_x, block_y, block_z, block_rejected = 0, 0.0, 0.0, 0.0, 0
        unit = _UNITS[self.time_unit] if self.time_unit in _UNITS else 1.0 / spec.rate_hz
        timed: bool | None = None  # whether the lines carry t (set by the first item of a connection)
        other_run = 0  # consecutive lines of the other format
        count = 0  # items since the connection (re)started, to spot a partial first line
        check, in_range = spec.checks_range, spec.in_range
        self._last_sample_at, self._silent = self._clock(), False
        self._delay = self.backoff_s[0]
        for line, now in self._lines():
            if line is None:  # silence or reconnection: continuity lost, the format may change
                kind = RECONNECT if self._reconnected else SILENCE  # after a reconnection t counts the loss
                self._reconnected = False
                timed, other_run, count = None, 0, 0
                yield Break(kind, now)
                continue
            parsed = decode(line)
            if parsed is None:
                self.skipped += 1
                continue
            if sample:
                t, x, y, z = parsed
                if factor != 1.0:
                    x, y, z = x * factor, y * factor, z * factor
                values = (x, y, z)
                if judge:
                    block, block_x, block_y, block_z = block + 1, block_x + x, block_y + y, block_z + z
                    if block == UNITS_BLOCK:
                        mean = (block_x / block, block_y / block, block_z / block)
                        judge = not self._judge_units(mean, block, self.rejected - block_rejected)
                        block, block_x, block_y, block_z, block_rejected = 0, 0.0, 0.0, 0.0, self.rejected
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
            if self.all_sensors:
                good = yield from self._check_sensors(values, now)
            elif check and not (
                lo <= values[0] <= hi and lo <= values[1] <= hi and lo <= values[2] <= hi
                if sample
                else in_range(values)
            ):
                self._reject(values, now)
                yield Break(REJECTED, now)
                good = ()
            else:
                good = None
            if good is not None and not good:
                count = 0
                continue
            if self._back_pending:  # the first sample of a reopened port: the sensor is back
                self._back_pending = False
                self.reconnects += 1
                self._emit(
                    "reconnected",
                    f"{self.name}: {self.item}s again {now - self._failed_at:.1f} s after it failed",
                )
                self._silent = False
            elif self._silent or not self.samples:
                waited = now - self._last_sample_at
                if self._first_sample_at is None:
                    self._first_sample_at = now
                if self._silent and self.samples:
                    self._emit("resumed", f"{self.item}s again after {describe_duration(waited)} of silence")
                elif waited >= self.silence_s:
                    self._emit("first", f"first {self.item} after {waited:.1f} s")
                self._silent = False
            self._last_sample_at = now
            if timed is None:
                timed = has_t
            if not count:  # a segment starts: the connection works, so the next failure waits little
                self._delay = self.backoff_s[0]
            count += 1
            stamp = t * unit if has_t else None
            if good is None:
                self.samples += 1
                yield Reading(values, stamp, now)
                continue
            for index in good:
                self.samples += 1
                yield Reading(values[index], stamp, now, None, index)

    def _reject(self, item, now: float, sensor: str = "") -> None:
        self.rejected += 1  # an item is known to be missing here: the segment ends
        self._emit(
            "range",
            f"a {self.item}{sensor} out of the sensor's range {self.spec.describe_range()} was rejected: "
            f"{self.spec.describe_item(item)}",
            repeated=True,
        )

    def _check_sensors(self, frames: np.ndarray, now: float):
        """Yield a break for each sensor's frame out of range; return the indices of the others."""
        good = []
        for index, frame in enumerate(frames):
            if self.spec.in_range(frame):
                good.append(index)
            else:
                self._reject(frame, now, f" of sensor {self.sensors[index]}")
                yield Break(REJECTED, now, index)
        return good


__all__ = ["FORMAT_RUN", "TIME_UNITS", "SerialSource", "parse_values"]
