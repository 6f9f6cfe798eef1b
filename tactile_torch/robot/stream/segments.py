"""The middle of a live stream: continuity of ``t``, and segments (sliding windows, touches) cut from readings.

A :class:`~tactile_torch.robot.stream.source.Source` yields readings and breaks; :class:`Segments` runs
them through a :class:`Sequencer` (gaps in the sensor's ``t``, ``t`` going back, a sensor at another
rate) and a segmenter, and yields what the segmenter cuts:

* :class:`SlidingWindows`: a :class:`Window` of ``W`` consecutive items every ``step`` items, the
  samples of a vibration bundle (``(1, 3, W)``) or the frames of a frame bundle in continuous
  exploration (``(1, T, H, W)``, ``(1, T, 3, H, W)``); no window spans a break or a gap;
* :class:`TouchSegmenter`: touches of frames (:mod:`tactile_torch.robot.stream.touches`): a
  :class:`TouchSegment` at each early-decision checkpoint of a touch in progress and one at its end,
  each with the frames the bundle takes (:func:`~tactile_torch.robot.stream.touches.fit_frames`). A break
  or a gap ends the touch in progress (flag ``"cut"``): a touch is never merged across a pause.

The same classes cut the touches and windows of a recording offline (``tactile-torch predict``, with an
:class:`~tactile_torch.robot.stream.source.ArraySource`). numpy only.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from ..files.sample_times import GAP_TOLERANCE, RATE_TOLERANCE  # one rule for files and the live stream
from .port_lines import StreamEvent
from .source import FRAME, RECONNECT, SAMPLE, Break, EventEmitter, ItemSpec, Reading, Source
from .touches import END, SHORT, START, TouchLevels, TouchTracker, fit_frames

RATE_RUN = 16
"""Consecutive equal off-period steps of ``t`` after which the data's own rate is adopted for the gap checks."""

GAP = "gap"
"""What ended a segment: a gap in ``t`` (besides the :class:`~tactile_torch.robot.stream.source.Break` kinds)."""
RELEASE = "release"
"""What ended a touch: the activity fell below the release level (the touch's own end)."""
END_OF_INPUT = "end of input"
"""What ended a touch: the input ended (the end of a file, a stopped stream)."""


class Sequencer:
    """Check the continuity of the sensor's ``t``: gaps (lost items), ``t`` going back, another rate.

    Parameters
    ----------
    rate_hz : float, optional
        The expected rate; without it only ``t`` going back is a gap.
    item : str
        What an item is called in messages (``"sample"``, ``"frame"``).
    on_event, clock
        Events ``"gap"`` (rate-limited) and ``"rate"``.

    Attributes
    ----------
    gaps : int
        Gaps from ``t``, plus the breaks :class:`Segments` counts while a segment was open.
    lost : int
        Items known to be missing from the steps of ``t``.
    """

    def __init__(
        self,
        rate_hz: float | None = None,
        *,
        item: str = "sample",
        on_event: Callable[[StreamEvent], None] | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.rate_hz = rate_hz
        self.item = item
        self.gaps = self.lost = 0
        self._period = None if rate_hz is None else 1.0 / rate_hz
        self._prev_t: float | None = None
        self._odd_step, self._odd_run = 0.0, 0
        self._events = EventEmitter(on_event, clock)

    def reset(self) -> None:
        """Forget the previous ``t`` (after a break, the next step is not checked)."""
        self._prev_t = None

    def gap(self, t: float, in_segment: bool = True) -> bool:
        """Check the step from the previous ``t`` (seconds); return whether it is a gap.

        ``in_segment`` False: no segment is open (the first item after a reconnection, whose step from
        the last ``t`` before it counts the items lost meanwhile): the gap is not counted again.
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
            if ratio < 1.0 + GAP_TOLERANCE:  # faster than expected: nothing lost
                return False
            missing = max(1, round(ratio) - 1)
            self.lost += missing
            what = f"{missing} {self.item}(s) missing" + ("" if in_segment else " across the reconnection")
        else:
            what = "t went back (a spliced recording or a sensor reset)"
        self.gaps += in_segment
        self._events.emit("gap", f"gap in t from {prev:.6g} to {t:.6g} s: {what}", repeated=True)
        return True

    def _learn_rate(self, dt: float) -> None:
        # A run of equal steps off the expected period means the sensor runs at another rate (not a
        # burst of drops, which gives one long step): adopt it for the gap checks, and say so once.
        same = abs(dt - self._odd_step) <= 0.1 * self._odd_step
        self._odd_run = self._odd_run + 1 if same else 1
        if not same:
            self._odd_step = dt
        if self._odd_run < RATE_RUN:
            return
        step, expected = self._odd_step, self._period
        self._events.emit(
            "rate",
            f"t advances {step * 1e3:.4g} ms per {self.item} ({1 / step:.4g} Hz), not {expected * 1e3:.4g} ms "
            f"({1 / expected:.4g} Hz): gaps are now judged at {1 / step:.4g} Hz; results are flagged 'rate'",
        )
        self._period, self._odd_run = step, 0


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
    skipped, rejected, gaps : int
        Lines skipped, items rejected out of range and gaps since the previous window.
    flags : tuple of str
        ``"skipped"`` when a skipped line lies inside the window's span (without ``t`` a skipped line
        may have been an item, so the window may lack one); ``"rate"`` when ``rate_hz`` is off the
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

    kind = "window"


class _Totals:
    """Skipped lines, rejected items and gaps so far, and the counts at the previous result."""

    def __init__(self) -> None:
        self.counts = None
        self.sequencer = None
        self._last = (0, 0, 0)

    def now(self) -> tuple[int, int, int]:
        c = self.counts
        return (c.skipped, c.rejected, self.sequencer.gaps) if c is not None else (0, 0, 0)

    def since_last(self) -> tuple[int, int, int]:
        now = self.now()
        last, self._last = self._last, now
        return now[0] - last[0], now[1] - last[1], now[2] - last[2]


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
    """

    def __init__(self, spec: ItemSpec, size: int, step: int | None = None) -> None:
        self.spec, self.size = spec, int(size)
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
        self.totals = _Totals()

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
        skipped_n, rejected_n, gaps_n = self.totals.since_last()
        window = Window(
            data=self._input(ring[start : start + w]),
            index=self.windows,
            end_sample=self._items_read(),
            read_at=reading.read_at,
            t_start=None if t is None else self._ring_t[start],
            t_end=t,
            rate_hz=rate,
            skipped=skipped_n,
            rejected=rejected_n,
            gaps=gaps_n,
            flags=flags,
        )
        self.windows += 1
        return window

    def _items_read(self) -> int:
        counts = self.totals.counts
        return counts.items if counts is not None else self._items

    def finish(self, kind: str, at: float) -> None:
        """The input ended: a window in progress is dropped."""
        self.pending = 0


@dataclass(frozen=True)
class TouchSegment:
    """A touch, at one of its early-decision checkpoints (``kind="checkpoint"``) or at its end (``"end"``).

    Attributes
    ----------
    kind : {"checkpoint", "end"}
    touch : int
        0-based index of the touch in the stream.
    data : ndarray
        The bundle's input ``(1, T, H, W)`` (or ``(1, T, 3, H, W)``): the touch's frames so far brought to
        ``T`` (:func:`~tactile_torch.robot.stream.touches.fit_frames`).
    frames : int
        Frames of the touch (so far, at a checkpoint).
    frames_used : int
        Distinct frames in ``data``: ``min(frames, T)``.
    start_item : int
        Items read before the touch's first frame (its index in the stream).
    started_at, read_at : float
        Reader clock when the touch's first frame and its latest frame (the checkpoint's, or the last)
        were read.
    ended_at : float or None
        ``"end"`` segments: reader clock when the end became known (the release frame was read, or the
        break happened): where the end-of-touch result's latency starts.
    t_start, t_end : float or None
        The sensor's ``t`` of those frames (seconds).
    ended_by : str or None
        ``"end"`` segments: :data:`RELEASE` (the touch's own end), a break kind (``"silence"``,
        ``"reconnect"``, ``"rejected"``, ``"format"``), :data:`GAP`, or :data:`END_OF_INPUT`.
    rate_hz : float or None
        The rate the touch's ``t`` span gives.
    skipped, rejected, gaps : int
        Lines skipped, frames rejected and gaps since the previous touch's end.
    flags : tuple of str
        ``"cut"`` (ended by a break or a gap, not by a release), ``"after_cut"`` (started at the first
        frame after a break that cut a touch: the rest of a contact), ``"stretched"`` (fewer frames than
        the bundle takes, repeated evenly), ``"skipped"``, ``"rate"``.
    """

    kind: str
    touch: int
    data: np.ndarray
    frames: int
    frames_used: int
    start_item: int
    started_at: float
    read_at: float
    t_start: float | None
    t_end: float | None
    ended_by: str | None = None
    rate_hz: float | None = None
    skipped: int = 0
    rejected: int = 0
    gaps: int = 0
    flags: tuple[str, ...] = ()
    ended_at: float | None = None

    @property
    def duration_s(self) -> float:
        """From the touch's first frame to its latest one: sensor time when the frames carry ``t``, else the reader's clock."""
        if self.t_start is not None and self.t_end is not None:
            return self.t_end - self.t_start
        return self.read_at - self.started_at


class TouchSegmenter:
    """Cut touches from frames (:class:`~tactile_torch.robot.stream.touches.TouchTracker`), with their bundle input.

    Parameters
    ----------
    spec : ItemSpec
        A frame spec.
    levels : TouchLevels
    n_frames : int
        Frames the bundle takes (``T``).
    checkpoints : sequence of int
        Frame counts into a touch at which a ``"checkpoint"`` segment is given (early decisions).
    on_event, clock
        Event ``"short"`` (rate-limited) for contacts shorter than ``levels.min_frames``.

    Attributes
    ----------
    touches : int
        Touches ended (segments of kind ``"end"`` given).
    short : int
        Contacts shorter than ``min_frames`` (not touches).
    pending : int
        Frames of the touch in progress.
    """

    def __init__(
        self,
        spec: ItemSpec,
        levels: TouchLevels,
        n_frames: int,
        *,
        checkpoints: Sequence[int] = (),
        on_event: Callable[[StreamEvent], None] | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        if spec.kind != FRAME:
            raise ValueError(f"touches are cut from frames, got items of kind {spec.kind!r}")
        self.spec, self.levels, self.n_frames = spec, levels, int(n_frames)
        self.checkpoints = frozenset(int(c) for c in checkpoints if 1 <= int(c))
        self.rate_hz = spec.rate_hz
        self.touches = self.short = 0
        self._tracker = TouchTracker(levels)
        t = self.n_frames
        self._head = np.zeros((t, *spec.shape), dtype=np.float32)
        self._ring = np.zeros((2 * t, *spec.shape), dtype=np.float32)
        self._input = bundle_input(spec)
        self._events = EventEmitter(on_event, clock)
        self.totals = _Totals()
        self._started = None  # (start item, started_at, t_start, skipped at start, after_cut)
        self._last = None  # (read_at, t) of the latest frame of the touch
        self._after_cut = False

    @property
    def pending(self) -> int:
        return self._tracker.frames

    def _frames(self, n: int) -> np.ndarray:
        """The touch's frames brought to ``T``: the last ``T`` (n >= T), else the first ``n`` stretched."""
        t = self.n_frames
        if n >= t:
            s = n % t
            return fit_frames(self._ring[s : s + t], t)
        return fit_frames(self._head[:n], t)

    def _segment(
        self, kind: str, n: int, ended_by: str | None, ended_at: float | None = None
    ) -> TouchSegment:
        start_item, started_at, t_start, skipped_at_start, after_cut = self._started
        read_at, t_end = self._last
        flags: tuple[str, ...] = ()
        if ended_by is not None and ended_by != RELEASE:
            flags += ("cut",)
        if after_cut:
            flags += ("after_cut",)
        if n < self.n_frames:
            flags += ("stretched",)
        counts = self.totals.counts
        if counts is not None and counts.skipped > skipped_at_start:
            flags += ("skipped",)
        rate = None
        if t_start is not None and t_end is not None and n > 1 and t_end > t_start:
            rate = (n - 1) / (t_end - t_start)
            if self.rate_hz is not None and n >= 3 and abs(rate / self.rate_hz - 1) > RATE_TOLERANCE:
                flags += ("rate",)
        skipped = rejected = gaps = 0
        if kind == "end":
            skipped, rejected, gaps = self.totals.since_last()
        return TouchSegment(
            kind=kind,
            touch=self.touches,
            data=self._input(self._frames(n)),
            frames=n,
            frames_used=min(n, self.n_frames),
            start_item=start_item,
            started_at=started_at,
            read_at=read_at,
            t_start=t_start,
            t_end=t_end,
            ended_by=ended_by,
            rate_hz=rate,
            skipped=skipped,
            rejected=rejected,
            gaps=gaps,
            flags=flags,
            ended_at=ended_at,
        )

    def _end(self, code: int, n: int, ended_by: str, at: float) -> TouchSegment | None:
        if code == END:
            segment = self._segment("end", n, ended_by, at)
            self.touches += 1
            return segment
        if code == SHORT:
            self.short += 1
            self._events.emit(
                "short",
                f"a contact of {n} frame(s), shorter than a touch ({self.levels.min_frames} frames), was not "
                "classified",
                repeated=True,
            )
        return None

    def push(self, reading: Reading) -> TouchSegment | None:
        """Add one frame; return the checkpoint or the end of a touch it gives, if any."""
        frame = reading.values
        n_before = self._tracker.frames
        code = self._tracker.update(self.levels.activity(frame))
        if code == END or code == SHORT:
            self._after_cut = False
            return self._end(code, n_before, RELEASE, reading.read_at)
        if code == START:
            counts = self.totals.counts
            items = counts.items if counts is not None else 0
            skipped = counts.skipped if counts is not None else 0
            self._started = (items - 1, reading.read_at, reading.t, skipped, self._after_cut)
            self._after_cut = False
        if not self._tracker.touching:
            self._after_cut = False
            return None
        n = self._tracker.frames
        t = self.n_frames
        if n <= t:
            self._head[n - 1] = frame
        j = (n - 1) % t
        self._ring[j] = self._ring[j + t] = frame
        self._last = (reading.read_at, reading.t)
        if n in self.checkpoints:
            return self._segment("checkpoint", n, None)
        return None

    def cut(self, kind: str, at: float) -> TouchSegment | None:
        """A break or a gap: the touch in progress ends (flag ``"cut"``); return its segment."""
        n = self._tracker.frames
        code = self._tracker.cut()
        self._after_cut = code == END or code == SHORT
        return self._end(code, n, kind, at)

    def finish(self, kind: str, at: float) -> TouchSegment | None:
        """The input ended (or the stream was stopped): the touch in progress ends; return its segment."""
        n = self._tracker.frames
        return self._end(self._tracker.cut(), n, kind, at)


class Segments:
    """Run a source's readings through a :class:`Sequencer` and a segmenter; iterate over the segments.

    Parameters
    ----------
    source : Source
    segmenter : SlidingWindows or TouchSegmenter
    sequencer : Sequencer, optional
        Default: one at the source spec's rate.

    After the iteration (or when it was stopped), :meth:`finish` gives the touch in progress, if any.
    """

    def __init__(self, source: Source, segmenter, sequencer: Sequencer | None = None) -> None:
        self.source = source
        self.segmenter = segmenter
        self.sequencer = sequencer or Sequencer(source.spec.rate_hz, item=source.spec.kind)
        segmenter.totals.counts = source.counts
        segmenter.totals.sequencer = self.sequencer

    def __iter__(self) -> Iterator[Window | TouchSegment]:
        segmenter, sequencer = self.segmenter, self.sequencer
        push, gap = segmenter.push, sequencer.gap
        for reading in self.source.readings():
            if reading.__class__ is Break:
                if segmenter.pending:
                    sequencer.gaps += 1
                if reading.kind != RECONNECT:  # after a reconnection, t's next step counts what was lost
                    sequencer.reset()
                out = segmenter.cut(reading.kind, reading.at)
                if out is not None:
                    yield out
                continue
            t = reading.t
            if t is not None and gap(t, segmenter.pending > 0):
                out = segmenter.cut(GAP, reading.read_at)
                if out is not None:
                    yield out
            out = push(reading)
            if out is not None:
                yield out

    def finish(self, kind: str = END_OF_INPUT) -> Window | TouchSegment | None:
        """End the segment in progress (the end of input, a stop); return a touch it ends, if any."""
        return self.segmenter.finish(kind, time.monotonic())


__all__ = [
    "END_OF_INPUT",
    "GAP",
    "GAP_TOLERANCE",
    "RATE_RUN",
    "RATE_TOLERANCE",
    "RELEASE",
    "Segments",
    "Sequencer",
    "SlidingWindows",
    "TouchSegment",
    "TouchSegmenter",
    "Window",
    "bundle_input",
]
