"""Read a triaxial accelerometer from a serial line and cut it into windows, through the line's faults.

Runs on the robot's computer with numpy and pyserial only: importing this module never imports torch
(the classification of the windows is in :mod:`tactile_torch.robot.stream.output`).

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

:class:`WindowReader` is the vibration stream assembled from the stream's stages (the serial
:class:`~tactile_torch.robot.stream.serial_source.SerialSource`, the :class:`~tactile_torch.robot.stream.segments.Sequencer`
and :class:`~tactile_torch.robot.stream.segments.SlidingWindows`; :mod:`tactile_torch.robot.stream.source`
describes them); frames and touches go through the same stages (:class:`tactile_torch.robot.stream.live.LiveStream`).

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

import time
from collections.abc import Callable, Iterator

from ...validation import check_count, check_number
from ..contract import DEFAULT_RANGE_G
from .port_lines import ReadablePort, StreamEvent
from .segments import Segments, Sequencer, SlidingWindows, Window
from .serial_source import SerialSource
from .source import SAMPLE, ItemSpec


class WindowReader:
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
        self.rate_hz = (
            None if rate_hz is None else check_number(rate_hz, "rate_hz")
        )  # time_unit: SerialSource
        self.range_g = check_number(range_g, "range_g")
        spec = ItemSpec(SAMPLE, (3,), -self.range_g, self.range_g, self.rate_hz, "g")
        self.source = SerialSource(
            source,
            spec,
            time_unit=time_unit,
            units=units,
            scale=scale,
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
        self.units, self.scale = self.source.units, self.source.scale
        self.sequencer = Sequencer(self.rate_hz, item="sample", on_event=on_event, clock=clock)
        self.segmenter = SlidingWindows(spec, window_size, self.step)

    # what the reader counted, from its stages
    samples = property(lambda self: self.source.samples)
    skipped = property(lambda self: self.source.skipped)
    rejected = property(lambda self: self.source.rejected)
    reconnects = property(lambda self: self.source.reconnects)
    format_switches = property(lambda self: self.source.format_switches)
    gaps = property(lambda self: self.sequencer.gaps)
    lost = property(lambda self: self.sequencer.lost)
    windows = property(lambda self: self.segmenter.windows)

    def __iter__(self) -> Iterator[Window]:
        for window in Segments(self.source, self.segmenter, self.sequencer):
            yield window
            if self.max_windows is not None and self.segmenter.windows >= self.max_windows:
                return


__all__ = ["WindowReader"]
