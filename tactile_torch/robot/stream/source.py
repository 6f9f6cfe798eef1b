"""The pluggable source of a live stream: what a transport (a serial line, a DDS topic) hands the stream.

A live stream has five stages; this module is the contract between the first and the rest:

1. **source** (:class:`Source`): a transport that yields timestamped :class:`Reading` objects (one
   3-axis sample or one frame each) and :class:`Break` markers, and reports its faults (late start,
   silence, disconnection and reconnection, garbage, values out of range) as :class:`StreamEvent`
   objects and its exceptions :class:`StreamTimeout` / :class:`StreamDisconnected`;
   :class:`tactile_torch.robot.stream.serial_source.SerialSource` reads lines from a serial port,
   :class:`ArraySource` replays arrays (``predict`` offline, tests, benchmarks);
2. **continuity** (:class:`tactile_torch.robot.stream.segments.Sequencer`): gaps in the sensor's ``t``,
   ``t`` going back, a sensor at another rate;
3. **segmenter** (:mod:`tactile_torch.robot.stream.segments`): sliding windows of samples or frames,
   or touches of frames (:mod:`tactile_torch.robot.stream.touches`);
4. **classifier** (:mod:`tactile_torch.robot.stream.output`): the bundle, with the early-decision rule
   (:mod:`tactile_torch.robot.stream.early_decision`);
5. **outputs**: one text or JSON line per result, and any number of hooks called with each result
   (:class:`tactile_torch.robot.stream.live.LiveStream`).

What a source must do (the serial one is the model): yield a :class:`Reading` for every item it
accepted, with ``values`` of shape :attr:`ItemSpec.shape` (in the bundle's units) and ``t`` in seconds
(or ``None``); count what it refused in :attr:`Source.counts` (``skipped``: could not be decoded, e.g.
a line or message of the wrong length; ``rejected``: values outside :attr:`ItemSpec.low` /
:attr:`ItemSpec.high`, checked with :meth:`ItemSpec.in_range`); yield a :class:`Break` whenever
continuity is lost (a silence of ``silence_s``, a reconnection, a rejected item, a change of format),
so that no window or touch spans it; raise :class:`StreamTimeout` when nothing valid arrived for the
start or idle timeout and :class:`StreamDisconnected` when the transport failed for good; call
``on_event`` with one :class:`StreamEvent` per thing a person should hear about (through an
:class:`EventEmitter`, which limits floods), and ``on_open(name)`` once it is ready to receive.
numpy only (no torch).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import NamedTuple, Protocol

import numpy as np

from .port_lines import StreamDisconnected, StreamEvent, StreamTimeout

SAMPLE = "sample"
""":attr:`ItemSpec.kind` of a triaxial accelerometer sample ``(3,)`` in g."""
FRAME = "frame"
""":attr:`ItemSpec.kind` of a taxel frame ``(H, W)`` (pressure) or ``(H, W, 3)`` (RGB, 0-255)."""

SILENCE = "silence"
""":attr:`Break.kind`: nothing valid arrived for the source's ``silence_s``."""
RECONNECT = "reconnect"
""":attr:`Break.kind`: the transport failed and was reopened (or the publisher came back)."""
REJECTED = "rejected"
""":attr:`Break.kind`: an item with a value outside the range was refused: one is known to be missing."""
FORMAT = "format"
""":attr:`Break.kind`: the items changed format (e.g. ``x,y,z`` lines became ``t,x,y,z``)."""
LOST = "lost"
""":attr:`Break.kind`: the transport reported items lost here (a DDS reader's full queue, samples lost on the wire)."""

_EVENT_INTERVAL_S = 1.0  # repeated events beyond _EVENTS_PER_INTERVAL in this interval are counted, not shown
_EVENTS_PER_INTERVAL = 5


@dataclass(frozen=True)
class ItemSpec:
    """What one item of the stream is: its kind, shape, accepted range and rate (from the bundle).

    Attributes
    ----------
    kind : {"sample", "frame"}
    shape : tuple of int
        ``(3,)`` for a sample (x, y, z in g); ``(H, W)`` for a pressure frame; ``(H, W, 3)`` for an
        RGB frame (channels last, as image files and the ``.npz`` explorations store them).
    low, high : float
        Accepted values, inclusive (``-inf``, ``inf``: no check). An item with a value outside is
        rejected (:attr:`SourceCounts.rejected`).
    rate_hz : float or None
        Items per second the bundle was trained at (``None``: unknown).
    units : str
        What the values are, for messages (``"g"``, ``"counts"``, ``"0-255"``).
    """

    kind: str
    shape: tuple[int, ...]
    low: float = -math.inf
    high: float = math.inf
    rate_hz: float | None = None
    units: str = ""

    @property
    def size(self) -> int:
        """Number of values in one item (``H * W`` for a pressure frame)."""
        return int(np.prod(self.shape))

    @property
    def checks_range(self) -> bool:
        """Whether values are checked against ``low`` / ``high`` at all."""
        return math.isfinite(self.low) or math.isfinite(self.high)

    def in_range(self, values: np.ndarray | Sequence[float]) -> bool:
        """Return whether every value lies in ``[low, high]`` (NaN never does)."""
        if not self.checks_range:
            return True
        if not isinstance(values, np.ndarray):  # a sample (x, y, z): no array round trip
            return all(self.low <= v <= self.high for v in values)
        return bool(values.min() >= self.low and values.max() <= self.high)

    def describe_range(self) -> str:
        """The accepted range in words, e.g. ``"±5 g"`` or ``"[0, 4095] counts"``."""
        if not self.checks_range:
            return "no range check"
        if self.low == -self.high:
            return f"±{self.high:g} {self.units}".rstrip()
        return f"[{self.low:g}, {self.high:g}] {self.units}".rstrip()

    def describe_item(self, values: np.ndarray | Sequence[float]) -> str:
        """A short description of an item's values for an event line (the sample, or a frame's extremes)."""
        if not isinstance(values, np.ndarray) or (values.ndim == 1 and len(values) <= 3):
            return "(" + ", ".join(f"{v:g}" for v in values) + ")"
        flat = np.asarray(values).reshape(-1)
        return f"a frame with values in [{float(flat.min()):g}, {float(flat.max()):g}]"


class Reading(NamedTuple):
    """One item a source accepted (a named tuple: one is made per item).

    Attributes
    ----------
    values : ndarray or tuple of float
        The item, of shape :attr:`ItemSpec.shape` (a sample may be a tuple ``(x, y, z)``).
    t : float or None
        The sensor's time of the item in seconds (a header stamp, a ``t`` field), ``None`` when the
        transport carries none. Its steps say whether items were lost (the sequencer's rule).
    read_at : float
        The source's clock (``time.monotonic`` by default) when the item was read: where a result's
        latency starts.
    sent_at : float or None
        When the sender wrote the item by its own clock (seconds; a DDS sample's source timestamp),
        ``None`` when the transport does not say. Without ``t`` it is the item's time for silences
        and durations (never for losses: a publisher's write times are no sensor clock).
    sensor : int
        Which sensor of the source the item is from (0 for a source of one sensor;
        :attr:`Source.sensors` names them).
    """

    values: object
    t: float | None
    read_at: float
    sent_at: float | None = None
    sensor: int = 0

    @property
    def clock(self) -> float | None:
        """The sender's time of the item: ``t``, else ``sent_at`` (``None``: only the reader's clock)."""
        return self.t if self.t is not None else self.sent_at


class Break(NamedTuple):
    """Continuity was lost before the next reading: no window or touch may span this point.

    Attributes
    ----------
    kind : str
        :data:`SILENCE`, :data:`RECONNECT`, :data:`REJECTED`, :data:`FORMAT` or :data:`LOST`.
    at : float
        The source's clock when it happened.
    sensor : int or None
        The sensor it concerns (a rejected item of one sensor of a hand); ``None``: every sensor.
    """

    kind: str
    at: float
    sensor: int | None = None


@dataclass
class SourceCounts:
    """What a source counted since it started (read by the summary line and the JSON results).

    Attributes
    ----------
    items : int
        Items accepted (samples or frames yielded as readings).
    skipped : int
        Lines or messages that could not be decoded (garbage, wrong length, wrong format).
    rejected : int
        Items refused because a value lay outside the spec's range.
    reconnects : int
        Successful reconnections.
    format_switches : int
        Format changes followed (e.g. ``x,y,z`` to ``t,x,y,z`` lines).
    lost : int
        Items the transport knows it lost (e.g. dropped while reconnecting), besides those the
        sensor's ``t`` shows (counted by the sequencer).
    """

    items: int = 0
    skipped: int = 0
    rejected: int = 0
    reconnects: int = 0
    format_switches: int = 0
    lost: int = 0


class Source(Protocol):
    """A transport that yields the items of a stream (the first stage; see the module notes).

    Attributes
    ----------
    name : str
        What messages call it (the port, the topic).
    spec : ItemSpec
        What an item is; the source decodes its lines or messages into this shape.
    counts : SourceCounts
        Kept up to date while :meth:`readings` runs.
    skipped_name : str, optional
        What the summary calls what ``counts.skipped`` counts (``"lines"``, ``"messages"``: the default).
    """

    name: str
    spec: ItemSpec
    counts: SourceCounts

    def readings(self) -> Iterator[Reading | Break]:
        """Yield readings and breaks until the end of input; raise ``StreamTimeout`` / ``StreamDisconnected``."""
        ...


class EventEmitter:
    """Send :class:`StreamEvent` objects to a callback, limiting floods of repeated kinds.

    ``emit(kind, message, repeated=True)`` shows at most 5 events of a kind per second; the next
    one shown says how many were left out before it. Sources and the sequencer share one emitter.
    """

    def __init__(
        self, on_event: Callable[[StreamEvent], None] | None, clock: Callable[[], float] = time.monotonic
    ) -> None:
        self.on_event = on_event
        self._clock = clock
        self._window: dict[str, tuple[float, int]] = {}
        self._held: dict[str, int] = {}

    def emit(self, kind: str, message: str, *, repeated: bool = False) -> None:
        """Send one event (``repeated``: one that can come in floods, such as gaps and rejections)."""
        if self.on_event is None:
            return
        if repeated:
            now = self._clock()
            start, shown = self._window.get(kind, (-math.inf, 0))
            if now - start >= _EVENT_INTERVAL_S:
                start, shown = now, 0
            if shown >= _EVENTS_PER_INTERVAL:
                self._held[kind] = self._held.get(kind, 0) + 1
                return
            self._window[kind] = (start, shown + 1)
            held = self._held.pop(kind, 0)
            if held:
                message += f" (and {held} more not shown before it)"
        self.on_event(StreamEvent(kind, message))


class ArraySource:
    """A :class:`Source` that replays arrays: the stream's stages on a recording, without a transport.

    What ``tactile-torch predict`` runs touches and windows of a recording through (the same
    sequencer, segmenters and classifier as the live stream), and what tests and benchmarks feed the
    stages with. Values outside the spec's range are rejected as a live source rejects them (a
    :class:`Break` follows).

    Parameters
    ----------
    values : ndarray of shape (n, *spec.shape)
    spec : ItemSpec
    t : ndarray of shape (n,), optional
        Each item's time in seconds.
    clock : callable, default time.monotonic
        Gives each reading's ``read_at``.
    name : str
    """

    def __init__(
        self,
        values: np.ndarray,
        spec: ItemSpec,
        *,
        t: np.ndarray | None = None,
        clock: Callable[[], float] = time.monotonic,
        name: str = "array",
        on_event: Callable[[StreamEvent], None] | None = None,
    ) -> None:
        values = np.asarray(values)
        if values.shape[1:] != tuple(spec.shape):
            raise ValueError(
                f"values must have shape (n, {', '.join(map(str, spec.shape))}), got {values.shape}"
            )
        if t is not None:
            t = np.asarray(t, dtype=np.float64)
            if t.shape != (len(values),):
                raise ValueError(f"t must have shape ({len(values)},), got {t.shape}")
        self.values, self.t, self.spec, self.name = values, t, spec, name
        self.counts = SourceCounts()
        self.skipped_name = "items"
        self._clock = clock
        self._events = EventEmitter(on_event, clock)

    def readings(self) -> Iterator[Reading | Break]:
        values, t, spec, counts, clock = self.values, self.t, self.spec, self.counts, self._clock
        for i in range(len(values)):
            item = values[i]
            if not spec.in_range(item):
                counts.rejected += 1
                self._events.emit(
                    "range",
                    f"{self.name}: item {i} has a value outside {spec.describe_range()}: "
                    f"{spec.describe_item(item)}; rejected",
                    repeated=True,
                )
                yield Break(REJECTED, clock())
                continue
            counts.items += 1
            yield Reading(item, None if t is None else float(t[i]), clock())


__all__ = [
    "FORMAT",
    "FRAME",
    "RECONNECT",
    "REJECTED",
    "SAMPLE",
    "SILENCE",
    "ArraySource",
    "Break",
    "EventEmitter",
    "ItemSpec",
    "Reading",
    "Source",
    "SourceCounts",
    "StreamDisconnected",
    "StreamEvent",
    "StreamTimeout",
]
