"""Read a triaxial accelerometer from a serial line and cut it into windows, through the line's faults.

Runs on the robot's computer with numpy and pyserial only: importing this module never imports torch
(the classification of the windows is in :mod:`tactile_torch.robot.stream_output`).

Wire protocol (what :func:`simulate_sensor` writes and :class:`WindowReader` reads): one ASCII line
per sample, ``x,y,z`` in g, or ``t,x,y,z`` with ``t`` a number (seconds by default; milliseconds,
microseconds or a sample counter with ``time_unit``), terminated by ``\\n`` (``\\r\\n`` accepted). At
800 Hz a line of ~20 bytes needs about 16 kB/s, i.e. a baud rate of 230400 or more on a real UART.

What the reader does with a real line's faults (each is counted in an attribute and, where it changes
what is classified, reported through ``on_event``):

- a line that does not parse (a partial line at start-up, binary noise, NaN, 2 or 5 fields,
  ``ERR,x,y,z``, a 3-field line in a timestamped stream) is skipped and counted (:attr:`skipped`, and
  per window in :attr:`Window.skipped`); a window whose span holds one is flagged ``"skipped"``;
- a sample outside the sensor's range (``|value| > range_g``, ±5 g for the ADXL345 by default) is
  rejected (:attr:`rejected`) and, since a sample is then known to be missing, ends the segment;
- a gap: ``t`` not advancing by one sample period (more than 1.5 periods: samples dropped; zero or
  negative: a spliced recording or a sensor reset), a silence of ``silence_s`` seconds, a
  reconnection, or a rejected sample. No window ever spans a gap: the reader starts a new window
  after it, so the next window comes ``window_size`` samples later;
- silence is reported (``"silence"``, then ``"resumed"``) and ends the iteration with
  :class:`StreamTimeout` only after ``idle_timeout_s`` (``start_timeout_s`` before the first sample);
- a failing port (the writer closed it, the adapter was unplugged) raises :class:`StreamDisconnected`,
  or with ``reconnect=True`` is reopened with exponential backoff.

Memory is bounded: the reader keeps a ring of ``2 * window_size`` samples and at most one partial
line of ``max_line_bytes``.

Examples
--------
>>> import serial                                                  # doctest: +SKIP
>>> open_port = lambda: serial.Serial("/dev/ttyUSB0", 230400, timeout=0.1)  # doctest: +SKIP
>>> reader = WindowReader(open_port, window_size=800, step=400, rate_hz=800,
...                       idle_timeout_s=10, reconnect=True)      # doctest: +SKIP
>>> for window in reader:                                          # doctest: +SKIP
...     print(window.index, pipeline.predict_names(window.data))  # (1, 3, 800) float32
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from .checks import check_count, check_number
from .contract import DEFAULT_RANGE_G
from .csv_logs import STANDARD_GRAVITY, UNITS
from .data_sources import GRAVITY_BAND_G
from .port_lines import (
    PortLines,
    ReadablePort,
    StreamDisconnected,
    StreamEvent,
    StreamTimeout,
    open_serial_port,
)
from .runtime import sensor_range_g
from .sample_times import GAP_TOLERANCE, RATE_TOLERANCE
from .wire import format_sample, parse_line, parse_sample, pseudo_terminal, simulate_sensor

TIME_UNITS = ("s", "ms", "us", "samples")
"""Units the ``t`` field may be in; ``"samples"`` is a sample counter (one per sample)."""

_RATE_RUN = 16  # consecutive equal off-period steps of t after which the stream's own rate is adopted
_FORMAT_RUN = 16  # consecutive lines of the other format (x,y,z / t,x,y,z) after which it is followed
_UNITS_BLOCK = 64  # samples over which the units are judged (mean acceleration, share out of range)


@dataclass(frozen=True)
class Window:
    """One window cut from the stream, with what happened on the line since the previous window.

    Attributes
    ----------
    data : ndarray of shape (1, 3, W), float32
        The window in g, axes first (the bundles' input layout).
    index : int
        0-based count of windows yielded so far.
    end_sample : int
        Samples accepted so far; the window holds samples ``end_sample - W`` to ``end_sample - 1``.
    read_at : float
        Reader clock (``time.monotonic`` by default) when the window's last sample was read from the
        port: the start of the window's latency.
    t_start, t_end : float or None
        ``t`` of the first and last sample in seconds, ``None`` when the lines have no ``t``.
    rate_hz : float or None
        The rate the window's ``t`` span gives, ``None`` without ``t``.
    skipped, rejected, gaps : int
        Lines skipped, samples rejected out of range and gaps since the previous window.
    flags : tuple of str
        ``"skipped"`` when a skipped line lies inside the window's span (without ``t`` a skipped line
        may have been a sample, so the window may lack one); ``"rate"`` when ``rate_hz`` is off the
        expected rate by more than :data:`RATE_TOLERANCE`.
    """

    data: np.ndarray
    index: int
    end_sample: int
    read_at: float
    t_start: float | None = None
    t_end: float | None = None
    rate_hz: float | None = None
    skipped: int = 0
    rejected: int = 0
    gaps: int = 0
    flags: tuple[str, ...] = ()


class WindowReader(PortLines):
    """Iterate over :class:`Window` objects cut from a serial line stream, through its faults.

    The first window of a segment (the stream since its start or its last gap) is yielded once
    ``window_size`` samples have arrived, then one every ``step`` new samples (``step = window_size``:
    disjoint windows). See the module docstring for the faults handled and how.

    Parameters
    ----------
    source : readable object, or a callable with no argument that returns one
        Something with ``read(size) -> bytes``: a ``serial.Serial`` opened with a short ``timeout``
        (0.1 s), ``serial.serial_for_url("loop://")``, a file. A callable (e.g. a function that opens
        the port) is called when iteration starts and again to reconnect; the reader then closes the
        ports it opened.
    window_size : int
        Samples per window W (e.g. 800 = 1 s at 800 Hz), at least 2.
    step : int, optional
        Samples between window starts; defaults to ``window_size``.
    max_windows : int, optional
        Stop after this many windows.
    rate_hz : float, optional
        The sample rate the windows must have (the bundle's ``sample_rate_hz``). Needed to detect gaps
        from ``t``; without it, ``t`` is checked only for going back.
    time_unit : {"s", "ms", "us", "samples"}, default "s"
        Unit of the ``t`` field; ``"samples"`` reads it as a sample counter (needs ``rate_hz``).
    units : {"g", "m/s2"}, default "g"
        Units of the ``x,y,z`` values on the line (as ``tactile-torch train --units``); the windows
        are in g.
    scale : float, optional
        Units per count when the sensor sends integer counts (``0.0039`` for the ADXL345 at full
        resolution): a value is read as ``value * scale`` in ``units``.
    range_g : float, default 5.0
        Samples with a value beyond ``±range_g`` (in g, after ``units`` and ``scale``) are rejected
        (:func:`sensor_range_g` reads it from a bundle); ``math.inf`` turns the check off. Samples
        that look like other units (a mean of 7-12 g: gravity in m/s^2; or most of 64 samples out of
        range) are said so once (event ``"units"``, with the argument to set).
    silence_s : float, default 0.5
        Seconds without a sample after which a silence is reported and the segment ends.
    idle_timeout_s : float, optional
        Seconds without a sample after which iteration raises :class:`StreamTimeout` (``math.inf``:
        never). ``None`` (the default) ends iteration at the first empty read instead, as at the end
        of a file.
    start_timeout_s : float, optional
        The same before the first sample; defaults to ``idle_timeout_s``.
    reconnect : bool, default False
        Reopen a failed port (``source`` must be a callable) with exponential backoff, until
        ``idle_timeout_s`` has passed without a sample; otherwise raise :class:`StreamDisconnected`.
        A reopened port gets ``idle_timeout_s`` anew for its first sample. With ``t``, the samples
        lost while the port was away are counted (:attr:`lost`) from the step of ``t`` across the
        reconnection; a ``source`` that reopens with :func:`open_serial_port` ``(keep_input=True)``
        keeps what the sensor sent during the wait (pyserial's ``open`` flushes it).
    backoff_s : tuple of float, default (0.5, 8.0)
        First and longest wait between reconnection attempts; the wait doubles after each failure.
    on_event : callable, optional
        Called with each :class:`StreamEvent`.
    on_open : callable, optional
        Called with the port's name once it is open at the start (opening a serial port discards
        what it had buffered: a sensor should be started after this, not before).
    max_line_bytes : int, default 256
        A partial line longer than this (binary noise with no newline) is dropped as skipped.
    name : str, optional
        What to call the port in messages (default: the port's ``name`` or ``port`` attribute).
    clock, sleep : callable
        Time source and sleep function (``time.monotonic``, ``time.sleep``); tests replace them.

    Attributes
    ----------
    samples : int
        Samples accepted.
    skipped : int
        Lines skipped (did not parse).
    rejected : int
        Samples rejected out of range.
    gaps : int
        Gaps (from ``t``, silences, reconnections and rejected samples).
    lost : int
        Samples known to be missing (from the steps of ``t``).
    windows : int
        Windows yielded.
    reconnects : int
        Successful reconnections.
    format_switches : int
        Switches between the ``x,y,z`` and ``t,x,y,z`` line formats that were followed.
    """

    def __init__(
        self,
        source: ReadablePort | Callable[[], ReadablePort],
        *,
        window_size: int,
        step: int | None = None,
        max_windows: int | None = None,
        rate_hz: float | None = None,
        time_unit: str = "s",
        units: str = "g",
        scale: float | None = None,
        range_g: float = DEFAULT_RANGE_G,
        silence_s: float = 0.5,
        idle_timeout_s: float | None = None,
        start_timeout_s: float | None = None,
        reconnect: bool = False,
        backoff_s: tuple[float, float] = (0.5, 8.0),
        on_event: Callable[[StreamEvent], None] | None = None,
        on_open: Callable[[str], None] | None = None,
        max_line_bytes: int = 256,
        name: str | None = None,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        window_size = check_count(window_size, "window_size", 2)
        self.step = window_size if step is None else check_count(step, "step", 1)
        self.max_windows = None if max_windows is None else check_count(max_windows, "max_windows", 1)
        if time_unit not in TIME_UNITS:
            raise ValueError(f"time_unit must be one of {TIME_UNITS}, got {time_unit!r}")
        if time_unit == "samples" and rate_hz is None:
            raise ValueError("time_unit='samples' (a sample counter) needs rate_hz")
        self.rate_hz = None if rate_hz is None else check_number(rate_hz, "rate_hz")
        self.range_g = check_number(range_g, "range_g")
        if units not in UNITS:
            raise ValueError(f"units must be one of {list(UNITS)}, got {units!r}")
        self.units, self.scale = units, None if scale is None else check_number(scale, "scale")
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
        self.window_size = window_size
        self.time_unit = time_unit
        self.rejected = self.gaps = self.lost = 0
        self.windows = self.format_switches = 0

    def _time_gap(self, t: float, in_segment: bool = True) -> bool:
        """Check the step from the previous ``t`` (seconds); return whether it is a gap.

        ``in_segment`` False: no segment is open (the first sample after a reconnection, whose step
        from the last ``t`` before it counts the samples lost meanwhile): the gap breaks nothing new.
        """
        prev, self._prev_t = self._prev_t, t
        if prev is None:
            return False
        dt = t - prev
        if dt > 0.0:
            if self._period is None:
                return False
            ratio = dt / self._period
            if 1.0 - GAP_TOLERANCE <= ratio <= 1.0 + GAP_TOLERANCE:
                self._odd_run = 0
                return False
            self._learn_rate(dt)
            if ratio < 1.0 + GAP_TOLERANCE:  # faster than expected: no sample lost
                return False
            missing = max(1, round(ratio) - 1)
            self.lost += missing
            what = f"{missing} sample(s) missing" + ("" if in_segment else " across the reconnection")
        else:
            what = "t went back (a spliced recording or a sensor reset)"
        self.gaps += in_segment
        self._emit("gap", f"gap in t from {prev:.6g} to {t:.6g} s: {what}", repeated=True)
        return True

    def _learn_rate(self, dt: float) -> None:
        # A run of equal steps off the expected period means the sensor runs at another rate (not a
        # burst of drops, which gives one long step): adopt it for the gap checks, and say so once.
        same = abs(dt - self._odd_step) <= 0.1 * self._odd_step
        self._odd_run = self._odd_run + 1 if same else 1
        if not same:
            self._odd_step = dt
        if self._odd_run < _RATE_RUN:
            return
        step, expected = self._odd_step, self._period
        self._emit(
            "rate",
            f"t advances {step * 1e3:.4g} ms per sample ({1 / step:.4g} Hz), not {expected * 1e3:.4g} ms "
            f"({1 / expected:.4g} Hz): gaps are now judged at {1 / step:.4g} Hz; windows are flagged 'rate'",
        )
        self._period, self._odd_run = step, 0

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
                f"{rejected} of the last {n} samples were beyond ±{self.range_g:g} g: samples in other units than "
                f"{self.units}{'' if self.scale is None else f' x {self.scale:g}'}? declare them with units='m/s2' "
                "(m/s^2) or scale= (units per count of a sensor that sends counts), or the sensor's range with "
                "range_g="
            )
        else:
            return False
        self._units_hint = hint
        self._emit("units", message)
        return True

    def __iter__(self) -> Iterator[Window]:
        w, step, range_g = self.window_size, self.step, self.range_g
        factor = UNITS[self.units] * (1.0 if self.scale is None else self.scale)
        # the units are judged over blocks of samples until they are found wrong (said once)
        judge, block, block_x, block_y, block_z, block_rejected = (
            self._units_hint is None,
            0,
            0.0,
            0.0,
            0.0,
            0,
        )
        units = {"s": 1.0, "ms": 1e-3, "us": 1e-6}
        unit = units[self.time_unit] if self.time_unit in units else 1.0 / self.rate_hz
        self._period = None if self.rate_hz is None else 1.0 / self.rate_hz
        self._prev_t, self._odd_step, self._odd_run = None, 0.0, 0
        self._last_sample_at, self._silent = self._clock(), False
        self._delay = self.backoff_s[0]
        # Ring of 2W samples written twice (at i and i + W) so that the last W samples are always one
        # contiguous slice: no copy per sample, one per window. Beside it, per sample, its t and the
        # count of lines skipped before it (to flag windows whose span holds a skipped line).
        ring = np.zeros((2 * w, 3), dtype=np.float32)
        ring_t = [0.0] * w
        ring_skipped = [0] * w
        count = since_window = 0  # samples in the current segment, samples since the last window
        timed: bool | None = None  # whether the lines carry t (set by the first sample of a connection)
        other_run = 0  # consecutive lines of the other format
        at_window = (0, 0, 0)  # skipped, rejected, gaps at the previous window
        for line, now in self._lines():
            if line is None:  # silence or reconnection: a gap (if a segment was open), the format may change
                self.gaps += count > 0
                count, timed, other_run = 0, None, 0
                if not self._reconnected:  # a silence: the sensor may have paused, t may jump
                    self._prev_t = None
                self._reconnected = False  # a reconnection: t's next step counts what was lost meanwhile
                continue
            parsed = parse_line(line)
            if parsed is None:
                self.skipped += 1
                continue
            if timed is not None and (parsed[0] is not None) != timed and count <= 1:
                # the connection's first line was a partial one: the second sets the format
                timed, count, self._prev_t = None, 0, None
            if timed is not None and (parsed[0] is not None) != timed:
                # A line of the other format: one alone is garbage (a line cut short and merged with
                # the next gives four numbers); a run of them is the sensor switching formats.
                other_run += 1
                if other_run < _FORMAT_RUN:
                    self.skipped += 1
                    continue
                new, old = ("t,x,y,z", "x,y,z") if not timed else ("x,y,z", "t,x,y,z")
                self.format_switches += 1
                self._emit(
                    "format",
                    f"the lines changed from {old} to {new} ({_FORMAT_RUN} in a row) after {self.samples} "
                    f"samples; following the new format (the {_FORMAT_RUN - 1} lines before this one were "
                    "skipped)",
                )
                self.gaps += count > 0
                timed, count, self._prev_t = not timed, 0, None
            other_run = 0
            t, x, y, z = parsed
            if factor != 1.0:
                x, y, z = x * factor, y * factor, z * factor
            if judge:
                block, block_x, block_y, block_z = block + 1, block_x + x, block_y + y, block_z + z
                if block == _UNITS_BLOCK:
                    mean = (block_x / block, block_y / block, block_z / block)
                    judge = not self._judge_units(mean, block, self.rejected - block_rejected)
                    block, block_x, block_y, block_z, block_rejected = 0, 0.0, 0.0, 0.0, self.rejected
            if not (-range_g <= x <= range_g and -range_g <= y <= range_g and -range_g <= z <= range_g):
                # a sample is known to be missing here: end the segment
                self.rejected += 1
                self.gaps += count > 0
                count, self._prev_t = 0, None
                self._emit(
                    "range",
                    f"a sample out of the sensor's range ±{range_g:g} g was rejected: ({x:g}, {y:g}, {z:g})",
                    repeated=True,
                )
                continue
            if self._silent or not self.samples:
                waited = now - self._last_sample_at
                if self._silent and self.samples:
                    self._emit("resumed", f"samples again after {waited:.1f} s of silence")
                elif waited >= self.silence_s:
                    self._emit("first", f"first sample after {waited:.1f} s")
                self._silent = False
            self._last_sample_at = now
            if timed is None:  # the first sample of a connection sets the line format
                timed = t is not None
            if t is not None:
                t *= unit
                if self._time_gap(t, count > 0):
                    count = 0
            if not count:  # a segment starts: the connection works, so the next failure waits little
                self._delay = self.backoff_s[0]
            i = self.samples % w
            ring[i] = ring[i + w] = (x, y, z)
            ring_t[i] = t or 0.0
            ring_skipped[i] = self.skipped
            self.samples += 1
            count += 1
            since_window += 1
            if count < w or (count > w and since_window < step):
                continue
            since_window = 0
            start = self.samples % w
            flags = ("skipped",) if self.skipped > ring_skipped[start] else ()
            rate = None if t is None else (w - 1) / (t - ring_t[start])
            if (
                rate is not None
                and self.rate_hz is not None
                and abs(rate / self.rate_hz - 1) > RATE_TOLERANCE
            ):
                flags += ("rate",)
            totals = (self.skipped, self.rejected, self.gaps)
            window = Window(
                data=np.ascontiguousarray(ring[start : start + w].T)[None],
                index=self.windows,
                end_sample=self.samples,
                read_at=now,
                t_start=None if t is None else ring_t[start],
                t_end=t,
                rate_hz=rate,
                skipped=totals[0] - at_window[0],
                rejected=totals[1] - at_window[1],
                gaps=totals[2] - at_window[2],
                flags=flags,
            )
            at_window = totals
            self.windows += 1
            yield window
            if self.max_windows is not None and self.windows >= self.max_windows:
                return


__all__ = [
    "StreamDisconnected",
    "StreamEvent",
    "StreamTimeout",
    "Window",
    "WindowReader",
    "format_sample",
    "open_serial_port",
    "parse_line",
    "parse_sample",
    "pseudo_terminal",
    "sensor_range_g",
    "simulate_sensor",
]
