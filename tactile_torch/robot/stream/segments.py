"""The middle of a live stream: continuity of ``t``, and segments (sliding windows, touches) cut from readings.

A :class:`~tactile_torch.robot.stream.source.Source` yields readings and breaks; :class:`Segments` runs
them through a :class:`Sequencer` (gaps in the sensor's ``t``, ``t`` going back, a sensor at another
rate) and a segmenter, and yields what the segmenter cuts:

* :class:`SlidingWindows`: a :class:`Window` of ``W`` consecutive items every ``step`` items, the
  samples of a vibration bundle (``(1, 3, W)``) or the frames of a frame bundle in continuous
  exploration (``(1, T, H, W)``, ``(1, T, 3, H, W)``); no window spans a break or a gap;
* :class:`~tactile_torch.robot.stream.touch_segments.TouchSegmenter`: touches of frames (:mod:`tactile_torch.robot.stream.touches`): a
  ``TouchSegment`` at each early-decision checkpoint of a touch in progress and one at its end,
  each with the frames the bundle takes (:func:`~tactile_torch.robot.stream.touches.fit_frames`). A break
  or a gap ends the touch in progress (flag ``"cut"``): a touch is never merged across a pause.

The same classes cut the touches and windows of a recording offline (``tactile-torch predict``, with an
:class:`~tactile_torch.robot.stream.source.ArraySource`). numpy only.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from ..files.sample_times import GAP_TOLERANCE, RATE_TOLERANCE  # one rule for files and the live stream
from .sequencer import Sequencer
from .source import SAMPLE, SILENCE, Break, ItemSpec, Reading, Source

GAP = "gap"
"""What ended a segment: a gap in ``t`` (besides the :class:`~tactile_torch.robot.stream.source.Break` kinds)."""
RELEASE = "release"
"""What ended a touch: the activity fell below the release level (the touch's own end)."""
END_OF_INPUT = "end of input"
"""What ended a touch: the input ended (the end of a file, a stopped stream)."""


def bundle_input(spec: ItemSpec) -> Callable[[np.ndarray], np.ndarray]:
    """Return the function that turns ``W`` consecutive items ``(W, *spec.shape)`` into the bundle's input.

    Samples ``(W, 3)`` → windows ``(1, 3, W)``; pressure frames ``(T, H, W)`` → ``(1, T, H, W)``; RGB
    frames ``(T, H, W, 3)`` (0-255) → uint8 ``(1, T, 3, H, W)``, as the image bundles take them. Always a
    new contiguous array.
    """
    if spec.kind == SAMPLE:
        return lambda block: np.ascontiguousarray(block.T)[None]
    if len(spec.shape) == 3:
        return lambda block: np.ascontiguousarray(
            np.rint(np.clip(block, 0, 255)).astype(np.uint8).transpose(0, 3, 1, 2)
        )[None]
    return lambda block: np.array(block)[None]


@dataclass(frozen=True)
class Window:
    """One window cut from the stream, with what happened since the previous window.

    Attributes
    ----------
    data : ndarray
        The bundle's input: ``(1, 3, W)`` float32 samples in g, or ``(1, T, H, W)`` / ``(1, T, 3, H, W)``
        float32 frames.
    index : int
        0-based count of windows yielded so far.
    end_sample : int
        Items (samples or frames) accepted so far; the window holds items ``end_sample - W`` to ``end_sample - 1``.
    read_at : float
        Reader clock (``time.monotonic`` by default) when the window's last item was read from the
        port: the start of the window's latency.
    t_start, t_end : float or None
        ``t`` of the first and last item in seconds, ``None`` when the lines have no ``t``.
    rate_hz : float or None
        The rate the window's ``t`` span gives, ``None`` without ``t``.
    skipped, rejected, gaps, lost : int
        Lines skipped, items rejected out of range, gaps, and items known lost (from ``t`` and from
        the transport) since the previous window.
    flags : tuple of str
        ``"skipped"`` when a skipped line lies inside the window's span (without ``t`` a skipped line
        may have been an item, so the window may lack one); ``"rate"`` when ``rate_hz`` is off the
        expected rate by more than :data:`RATE_TOLERANCE`.
    sensor : str or None
        The name of the sensor it was cut from, when the source has several (``None``: one sensor).
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
    lost: int = 0
    sensor: str | None = None

    kind = "window"


class Totals:
    """Skipped lines, rejected items, gaps and items lost so far, and the counts at the previous result (a segmenter's)."""

    def __init__(self) -> None:
        self.counts = None
        self.sequencer = None
        self._last = (0, 0, 0, 0)

    def now(self) -> tuple[int, int, int, int]:
        c, q = self.counts, self.sequencer
        if c is None:
            return (0, 0, 0, 0)
        return (c.skipped, c.rejected, q.gaps, q.lost + c.lost)

    def since_last(self) -> tuple[int, int, int, int]:
        now = self.now()
        last, self._last = self._last, now
        return tuple(a - b for a, b in zip(now, last, strict=True))


class SlidingWindows:
    """Cut windows of ``size`` consecutive items, one every ``step`` items, never across a break or gap.

    The first window of a segment (the stream since its start or its last break) comes once ``size``
    items have arrived, then one every ``step`` new items. Memory: a ring of ``2 * size`` items
    written twice, so that the last ``size`` items are always one contiguous slice.

    Parameters
    ----------
    spec : ItemSpec
    size : int
        Items per window (``W`` samples, ``T`` frames), at least 1.
    step : int, optional
        Items between window starts (default ``size``).
    sensor : str, optional
        The name of the sensor whose items it cuts (its windows say so), when the source has several.
    """

    def __init__(
        self, spec: ItemSpec, size: int, step: int | None = None, *, sensor: str | None = None
    ) -> None:
        self.spec, self.size, self.sensor = spec, int(size), sensor
        self.step = self.size if step is None else int(step)
        self.rate_hz = spec.rate_hz
        self.windows = 0
        self.pending = 0  # items in the current segment
        self._since_window = 0
        self._items = 0
        self._ring = np.zeros((2 * self.size, *spec.shape), dtype=np.float32)
        self._ring_t = [0.0] * self.size
        self._ring_skipped = [0] * self.size
        self._input = bundle_input(spec)
        self.totals = Totals()

    def cut(self, kind: str, at: float) -> None:
        """A break or gap: the window in progress is dropped."""
        self.pending = 0

    def push(self, reading: Reading) -> Window | None:
        """Add one reading; return the window it completes, if any."""
        w = self.size
        i = self._items % w
        ring = self._ring
        ring[i] = ring[i + w] = reading.values
        t = reading.t
        self._ring_t[i] = t or 0.0
        counts = self.totals.counts
        skipped = counts.skipped if counts is not None else 0
        self._ring_skipped[i] = skipped
        self._items += 1
        self.pending += 1
        self._since_window += 1
        if self.pending < w or (self.pending > w and self._since_window < self.step):
            return None
        self._since_window = 0
        start = self._items % w
        flags = ("skipped",) if skipped > self._ring_skipped[start] else ()
        rate = None
        if t is not None:
            span = t - self._ring_t[start]
            rate = (w - 1) / span if span > 0 else None
        if rate is not None and self.rate_hz is not None and abs(rate / self.rate_hz - 1) > RATE_TOLERANCE:
            flags += ("rate",)
        skipped_n, rejected_n, gaps_n, lost_n = self.totals.since_last()
        window = Window(
            data=self._input(ring[start : start + w]),
            index=self.windows,
            end_sample=self._items,
            read_at=reading.read_at,
            t_start=None if t is None else self._ring_t[start],
            t_end=t,
            rate_hz=rate,
            skipped=skipped_n,
            rejected=rejected_n,
            gaps=gaps_n,
            flags=flags,
            lost=lost_n,
            sensor=self.sensor,
        )
        self.windows += 1
        return window

    def finish(self, kind: str, at: float) -> None:
        """The input ended: a window in progress is dropped."""
        self.pending = 0


class _Channel:
    """One sensor's stages: its sequencer and segmenter, its latest reading, and a silence awaiting its clock."""

    __slots__ = ("broken", "last", "segmenter", "sequencer", "silence")

    def __init__(self, segmenter, sequencer: Sequencer) -> None:
        self.segmenter, self.sequencer = segmenter, sequencer
        self.last: Reading | None = None
        self.silence: float | None = None
        self.broken = False  # a break cut a segment: a gap once items follow (the end of the input is none)


class Segments:
    """Run a source's readings through a :class:`Sequencer` and a segmenter per sensor; iterate over the segments.

    Parameters
    ----------
    source : Source
    segmenter : SlidingWindows or TouchSegmenter, or a sequence of them
        (:class:`~tactile_torch.robot.stream.touch_segments.TouchSegmenter`)
        One per sensor of the source (a reading goes to ``segmenter[reading.sensor]``).
    sequencer : Sequencer or sequence of Sequencer, optional
        One per segmenter. Default: one each at the source spec's rate.
    channel : callable, optional
        ``channel(i) -> (segmenter, sequencer)`` for a sensor ``i`` the source names later (a hand's
        sensors appear with the first message); without it such readings are an error.

    A silence the source reports (a :class:`~tactile_torch.robot.stream.source.Break` of kind
    ``"silence"``, from the reader's clock) ends a segment only when the **sensor's clock** agrees:
    when the readings carry one (``t``, else the sender's ``sent_at``), the cut waits for the next
    reading, and is made if its clock advanced by the source's ``silence_s`` or more; otherwise the
    reader (a loaded CPU, a slow transport) was late, not the sensor, and nothing is cut. Without a
    sender's clock the silence cuts at once. A live source's opening time (``opened_at``) bounds
    the losses each sequencer counts. After the iteration (or when it was stopped), :meth:`finish`
    gives the touches in progress.
    """

    def __init__(self, source: Source, segmenter, sequencer=None, *, channel=None) -> None:
        self.source = source
        self._new_channel = channel
        segmenters = list(segmenter) if isinstance(segmenter, list | tuple) else [segmenter]
        if sequencer is None:
            sequencers = [
                Sequencer(source.spec.rate_hz, item=source.spec.kind, name=source.name) for _ in segmenters
            ]
        else:
            sequencers = list(sequencer) if isinstance(sequencer, list | tuple) else [sequencer]
        if len(sequencers) != len(segmenters):
            raise ValueError(f"one sequencer per segmenter: got {len(sequencers)} for {len(segmenters)}")
        self._channels: list[_Channel] = []
        for g, q in zip(segmenters, sequencers, strict=True):
            self._add(g, q)
        self.segmenter, self.sequencer = segmenters[0], sequencers[0]
        self.silence_s = getattr(source, "silence_s", None)

    def _add(self, segmenter, sequencer: Sequencer) -> _Channel:
        segmenter.totals.counts = self.source.counts
        segmenter.totals.sequencer = sequencer
        self._channels.append(_Channel(segmenter, sequencer))
        return self._channels[-1]

    def _channel_of(self, index: int) -> _Channel:
        """The channel of sensor ``index``, made (with those before it) the first time it is read from."""
        while len(self._channels) <= index:
            segmenter, sequencer = self._new_channel(len(self._channels))
            sequencer.origin = self._channels[0].sequencer.origin
            self._add(segmenter, sequencer)
        return self._channels[index]

    @property
    def segmenters(self) -> list:
        return [c.segmenter for c in self._channels]

    @property
    def sequencers(self) -> list[Sequencer]:
        return [c.sequencer for c in self._channels]

    def __iter__(self) -> Iterator:
        channels, source = self._channels, self.source
        started = False
        for reading in source.readings():
            if not started:  # the source is open once it yields: its opening time bounds the losses
                started = True
                origin = getattr(source, "opened_at", None)
                for c in channels:
                    c.sequencer.origin = origin
                names = getattr(source, "sensors", None)
                if names:  # a hand's sensors are named by its first message
                    channels[0].segmenter.sensor = names[0]
            if reading.__class__ is Break:
                for c in channels if reading.sensor is None else (self._channel_of(reading.sensor),):
                    yield from self._break(c, reading.kind, reading.at)
                continue
            c = (
                channels[reading.sensor]
                if reading.sensor < len(channels)
                else self._channel_of(reading.sensor)
            )
            if c.silence is not None:
                yield from self._resume(c, reading)
            if c.broken:
                c.sequencer.gaps += 1
                c.broken = False
            released = c.sequencer.push(reading)
            c.last = reading
            if released is None:
                out = c.segmenter.push(reading)
                if out is not None:
                    yield out
            else:
                yield from self._released(c, released)

    def _released(self, c: _Channel, released) -> Iterator:
        segmenter = c.segmenter
        for cut, reading in released:
            if cut:
                if segmenter.pending:
                    c.sequencer.gaps += 1
                out = segmenter.cut(GAP, reading.read_at)
                if out is not None:
                    yield out
            out = segmenter.push(reading)
            if out is not None:
                yield out

    def _cut(self, c: _Channel, kind: str, at: float) -> Iterator:
        yield from self._released(c, c.sequencer.reset(kind))
        c.broken = c.broken or c.segmenter.pending > 0
        out = c.segmenter.cut(kind, at)
        if out is not None:
            yield out

    def _break(self, c: _Channel, kind: str, at: float) -> Iterator:
        if kind == SILENCE and self.silence_s is not None and c.last is not None and c.last.clock is not None:
            if c.silence is None:
                c.silence = at  # the sensor's clock decides, at the next reading
            return
        if c.silence is not None:
            at_silence, c.silence = c.silence, None
            yield from self._cut(c, SILENCE, at_silence)
        yield from self._cut(c, kind, at)

    def _resume(self, c: _Channel, reading: Reading) -> Iterator:
        """The first reading after a silence of the reader's clock: cut if the sensor's clock paused too."""
        at, c.silence = c.silence, None
        now, before = reading.clock, c.last.clock
        if now is None or now - before >= self.silence_s:
            yield from self._cut(c, SILENCE, at)
        else:
            c.sequencer.note(
                "late",
                f"the silence was the reader's, not the sensor's (its clock advanced {now - before:.3g} s across "
                "it): nothing cut",
            )

    def finish(self, kind: str = END_OF_INPUT) -> list:
        """End the segments in progress (the end of input, a stop); return the touches they end."""
        out: list = []
        now = time.monotonic()
        for c in self._channels:
            if c.silence is not None:  # nothing came after the silence: it ended the touch
                kind_c, c.silence = SILENCE, None
            else:
                kind_c = kind
            out += list(self._released(c, c.sequencer.reset(None)))
            last = c.segmenter.finish(kind_c, now)
            if last is not None:
                out.append(last)
        return out


__all__ = [
    "END_OF_INPUT",
    "GAP",
    "GAP_TOLERANCE",
    "RATE_TOLERANCE",
    "RELEASE",
    "Segments",
    "SlidingWindows",
    "Window",
    "bundle_input",
]
