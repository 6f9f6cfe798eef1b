"""The port under a serial stream: open it, read lines, report silence, time out, reconnect.

:class:`PortLines` is the port side of :class:`tactile_torch.robot.stream.serial_source.SerialSource` (which parses
the lines into samples or frames); the events and errors it reports are :class:`StreamEvent`,
:class:`StreamTimeout` and :class:`StreamDisconnected`. Runs on the robot (no torch).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Protocol

from ...exceptions import InputTypeError
from ...validation import check_count, check_number
from ..files.sample_times import describe_duration

_EVENT_INTERVAL_S = (
    1.0  # gap/range events beyond _EVENTS_PER_INTERVAL in this interval are counted, not shown
)
_EVENTS_PER_INTERVAL = 5


class ReadablePort(Protocol):
    """Anything with ``read(size) -> bytes``: a ``serial.Serial``, a pseudo-terminal, a file."""

    def read(self, size: int = ...) -> bytes: ...


class StreamTimeout(TimeoutError):
    """No sample arrived for longer than the reader's idle timeout (or start timeout)."""


class StreamDisconnected(ConnectionError):
    """The port failed (writer closed it, adapter unplugged) and reconnection is off or gave up."""


@dataclass(frozen=True)
class StreamEvent:
    """Something a user should hear about while the stream runs (not a window).

    Attributes
    ----------
    kind : str
        ``"waiting"`` (no data yet), ``"first"`` (first sample), ``"silence"``, ``"resumed"``, ``"gap"``,
        ``"range"`` (a sample out of range), ``"units"`` (the samples look like other units than
        declared, once), ``"rate"`` (``t`` runs at another rate than expected), ``"format"`` (the lines
        switched between ``x,y,z`` and ``t,x,y,z``), ``"disconnected"`` (the port failed),
        ``"reopened"`` (open again), ``"reconnected"`` (its first sample: back).
    message : str
        One line for a person.
    """

    kind: str
    message: str


def open_serial_port(
    url: str, *, baudrate: int = 230400, timeout: float = 0.1, keep_input: bool = False
) -> ReadablePort:
    """Return the serial port ``url`` opened with pyserial (``serial.serial_for_url``).

    pyserial's ``open()`` discards what the OS had buffered for the port (``tcflush`` on POSIX). That is
    what a stream wants when it first opens the port (stale bytes from before it started), not when
    it reopens one after a failure: the sensor may already have sent samples during the wait.
    ``keep_input=True`` opens without that flush where pyserial has one (its POSIX ports), so that
    nothing is lost silently.
    """
    import serial

    if not keep_input:
        return serial.serial_for_url(url, baudrate=baudrate, timeout=timeout)
    port = serial.serial_for_url(url, baudrate=baudrate, timeout=timeout, do_not_open=True)
    flushes = hasattr(port, "_reset_input_buffer")  # called by serialposix.Serial.open (pyserial 3.x)
    if flushes:
        port._reset_input_buffer = lambda: None  # this instance only, during open()
    try:
        port.open()
    finally:
        if flushes:
            del port._reset_input_buffer
    return port


def _giving_up(limit: float) -> str:
    return "no time limit" if math.isinf(limit) else f"giving up after {limit:g} s"


class PortLines:
    """The port side of :class:`~tactile_torch.robot.stream.serial_source.SerialSource`: open, read lines, time out, reconnect.

    Owns the port: opens it (or takes an open one), reads what has arrived and splits it into lines
    (keeping at most one partial line of ``max_line_bytes``), reports silence and ends with
    :class:`StreamTimeout` after the idle or start timeout, raises :class:`StreamDisconnected` when the
    port fails, or reopens it with exponential backoff (``reconnect``). Every parameter is
    :class:`~tactile_torch.robot.stream.serial_source.SerialSource`'s of the same name. The subclass parses the
    lines, counts accepted ``samples``, ``skipped`` lines and ``rejected`` samples, and keeps
    ``_last_sample_at`` (the clock at the last valid sample), ``_silent``, ``_delay`` (the next
    reconnection wait) and ``_units_hint`` (what the samples look like, when not the declared units)
    up to date, which the timeouts and the backoff here read.

    Attributes
    ----------
    samples : int
        Samples accepted (counted by the subclass).
    skipped : int
        Lines skipped (did not parse, or partial lines longer than ``max_line_bytes``).
    rejected : int
        Samples rejected (counted by the subclass).
    reconnects : int
        Reconnections: a port that failed, reopened and gave a sample again (counted at that sample).
    """

    def __init__(
        self,
        source: ReadablePort | Callable[[], ReadablePort],
        *,
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
        opens = callable(source) and not hasattr(source, "read")
        if not opens and not hasattr(source, "read"):
            raise InputTypeError(
                "source must have a read(size) method (e.g. serial.Serial) or be a callable that "
                f"opens one, got {type(source).__name__}"
            )
        if reconnect and not opens:
            raise ValueError("reconnect=True needs source to be a callable that opens the port")
        self.silence_s = check_number(silence_s, "silence_s")
        self.idle_timeout_s = (
            None if idle_timeout_s is None else check_number(idle_timeout_s, "idle_timeout_s")
        )
        start = idle_timeout_s if start_timeout_s is None else start_timeout_s
        self.start_timeout_s = None if start is None else check_number(start, "start_timeout_s")
        if len(backoff_s) != 2:
            raise ValueError(f"backoff_s must be (first, longest) seconds, got {backoff_s!r}")
        first, longest = (check_number(b, "backoff_s") for b in backoff_s)
        self.backoff_s = (first, max(first, longest))
        self.max_line_bytes = check_count(max_line_bytes, "max_line_bytes", 16)
        self.reconnect = bool(reconnect)
        self.on_event = on_event
        self.on_open = on_open
        self._source = source
        self._opens = opens
        self._name = name
        self._clock = clock
        self._sleep = sleep
        self.samples = self.skipped = self.rejected = self.reconnects = 0
        self.item = "sample"  # what an item is called in messages ("frame" for a frame stream)
        self._units_hint: str | None = None
        self._event_window: dict[str, tuple[float, int]] = {}
        self._held_events: dict[str, int] = {}
        self._last_sample_at, self._silent = clock(), False
        self._first_sample_at: float | None = (
            None  # the clock at the stream's first valid sample (set by the subclass)
        )
        self._delay = self.backoff_s[0]
        self._reconnected = False  # set with the break that a reconnection yields, cleared by the subclass
        self._back_pending = False  # a port reopened after a failure: its first sample is "back"
        self._failed_at: float | None = None
        self.opened_at: float | None = (
            None  # when a live port first opened: the sensor's losses are bounded by it
        )

    # -- events ---------------------------------------------------------------------------------

    def _emit(self, kind: str, message: str, *, repeated: bool = False) -> None:
        if self.on_event is None:
            return
        if repeated:  # gaps and rejections can come in floods: a few lines per interval, then a count
            now = self._clock()
            start, shown = self._event_window.get(kind, (-math.inf, 0))
            if now - start >= _EVENT_INTERVAL_S:
                start, shown = now, 0
            if shown >= _EVENTS_PER_INTERVAL:
                self._held_events[kind] = self._held_events.get(kind, 0) + 1
                return
            self._event_window[kind] = (start, shown + 1)
            held = self._held_events.pop(kind, 0)
            if held:
                message += f" (and {held} more not shown before it)"
        self.on_event(StreamEvent(kind, message))

    def _port_name(self, port: object) -> str:
        if self._name:
            return self._name
        name = getattr(port, "port", None) or getattr(port, "name", None)
        return str(name) if name else type(port).__name__

    # -- the port -------------------------------------------------------------------------------

    def _open(self) -> ReadablePort:
        port = self._source() if self._opens else self._source
        if not hasattr(port, "read"):
            raise InputTypeError(f"source() must return a port with read(size), got {type(port).__name__}")
        return port

    def _close(self, port: object) -> None:
        if self._opens and port is not None:
            try:
                port.close()
            except OSError:
                pass

    @staticmethod
    def _reader_of(port: ReadablePort) -> Callable[[], bytes]:
        # Read what has arrived, without waiting for more: a serial port says how much is waiting
        # (read(1) then blocks up to the port's timeout); raw files and pipes return what they have.
        if hasattr(type(port), "in_waiting"):  # on the class: the property itself fails on a dead port
            return lambda: port.read(port.in_waiting or 1)
        read = getattr(port, "read1", None) or port.read
        return lambda: read(65536)

    def _reopen(self, error: Exception | None) -> ReadablePort:
        """Open the port: at the start (``error`` None) or after ``error``, with exponential backoff.

        Without ``reconnect`` only one attempt is made. The wait doubles after each failure and is
        reset only when a sample arrives, so a port that opens but fails at once is not retried in a
        tight loop. Gives up with :class:`StreamDisconnected` once the idle (or start) timeout has
        passed without a sample.
        """
        name = self._name or "the port"
        reopening = error is not None
        if reopening:
            self._failed_at = self._clock()
            self._emit("disconnected", f"{name} disconnected ({error}); reconnecting")
        started, attempts = self._clock(), 0
        while True:
            if error is not None:
                limit = self.idle_timeout_s if self.samples else self.start_timeout_s
                waited = self._clock() - self._last_sample_at
                if limit is not None and waited >= limit:
                    raise StreamDisconnected(
                        f"{name}: gave up reconnecting after {attempts} attempt(s), {waited:.1f} s without a "
                        f"{self.item} (idle timeout {limit:g} s): {error}"
                    )
                # the last wait is cut short so that one attempt is made at the timeout itself
                self._sleep(self._delay if limit is None else min(self._delay, limit - waited))
                self._delay = min(2 * self._delay, self.backoff_s[1])
            attempts += 1
            try:
                port = self._open()
            except OSError as err:
                if not self.reconnect:
                    raise StreamDisconnected(f"could not open {name}: {err}") from err
                error = err
                continue
            if reopening or attempts > 1:
                self._back_pending = reopening  # counted as a reconnection at its first sample ("back")
                self._emit(
                    "reopened",
                    f"{self._port_name(port)} open after {self._clock() - started:.1f} s ({attempts} attempt(s))",
                )
            return port

    # -- iteration ------------------------------------------------------------------------------

    def _lines(self) -> Iterator[tuple[bytes | None, float]]:  # noqa: PLR0915
        """Yield ``(line, read time)`` from the port; ``(None, time)`` marks a break (silence, reconnection).

        Owns the port: reads what has arrived, keeps the partial line, reports silence, raises
        :class:`StreamTimeout` and :class:`StreamDisconnected`, and reconnects.
        """
        clock = self._clock
        port = None
        partial = b""
        overlong = False  # within a line longer than max_line_bytes, already counted
        try:
            port = self._reopen(None) if self._opens else self._open()
            name = self._port_name(port)
            read = self._reader_of(port)
            # the clocks start once the port is open (opening may take a while, and flushes it)
            self._last_sample_at = opened_at = clock()
            if self.idle_timeout_s is not None:  # a live port (not a file read to its end)
                self.opened_at = opened_at
            if self.on_open is not None:
                self.on_open(name)
            while True:
                before = clock()
                try:
                    chunk = read()
                except OSError as err:
                    if not self.reconnect:
                        raise StreamDisconnected(
                            f"{name} disconnected after {self.samples} {self.item}s: {err}"
                        ) from err
                    self._close(port)
                    port = self._reopen(err)
                    read = self._reader_of(port)
                    partial, overlong = b"", False
                    # A port reopened late (at the idle timeout itself) gets the idle timeout anew for its
                    # first sample: its first read may well be empty. _reopen still gives up once the
                    # timeout has passed since the last sample, so a port that fails at once is not
                    # retried for ever.
                    opened_at = clock()
                    self._reconnected = True
                    yield None, opened_at
                    continue
                now = clock()
                if chunk:
                    if overlong:  # the rest of a line already dropped: up to its newline, it counts nothing
                        end = chunk.find(b"\n")
                        chunk, overlong = (b"", True) if end < 0 else (chunk[end + 1 :], False)
                    lines = (partial + chunk).split(b"\n")
                    partial = lines.pop()
                    if (
                        len(partial) > self.max_line_bytes
                    ):  # noise without newlines: one line skipped, whatever its length
                        self.skipped += 1
                        partial, overlong = b"", True
                    for line in lines:
                        yield line, now
                    if self.idle_timeout_s is None:
                        continue
                    now = clock()
                elif self.idle_timeout_s is None:  # end of input; the last line may lack its newline
                    if partial:
                        yield partial, now
                    return
                elif now - before < 1e-3:  # a port without a read timeout, or a file at its end: do not spin
                    self._sleep(0.01)
                    now = clock()
                # Time counts since the last VALID sample: bytes that never parse (garbage, a sensor at
                # the wrong baud rate, a line format the stream refuses) do not keep the stream alive.
                waited = now - max(self._last_sample_at, opened_at)
                limit = self.idle_timeout_s if self.samples else self.start_timeout_s
                invalid = self.skipped or self.rejected  # lines arrive, none is a valid sample
                item = self.item
                what = f"no valid {item}" if invalid else "no data" if not self.samples else f"no {item}"
                skipped = ", ".join(
                    [f"{self.skipped} lines skipped"] * bool(self.skipped)
                    + [f"{self.rejected} {item}s out of range"] * bool(self.rejected)
                )
                skipped = f", {skipped}" if skipped else ""
                if waited >= limit:
                    raise StreamTimeout(
                        f"{name}: {what} for {waited:.1f} s (timeout {limit:g} s); {self.samples} {item}s "
                        f"read, {self.skipped} lines skipped"
                        + (f", {self.rejected} {item}s out of range" if self.rejected else "")
                        + (f"; {self._units_hint}" if self._units_hint else "")
                    )
                if waited >= self.silence_s and not self._silent:
                    self._silent = True
                    if self.samples:
                        into = (
                            ""
                            if self._first_sample_at is None
                            else (
                                f", {describe_duration(self._last_sample_at - self._first_sample_at)} into the stream"
                            )
                        )
                        self._emit(
                            "silence",
                            f"{what} for {describe_duration(waited)} after {self.samples} {item}s{into}{skipped}; "
                            f"waiting ({_giving_up(limit)})",
                        )
                        yield None, now
                    else:
                        self._emit(
                            "waiting",
                            f"{what} yet on {name} after {waited:.1f} s{skipped} ({_giving_up(limit)})",
                        )
        finally:
            self._close(port)


__all__ = [
    "PortLines",
    "ReadablePort",
    "StreamDisconnected",
    "StreamEvent",
    "StreamTimeout",
    "open_serial_port",
]
