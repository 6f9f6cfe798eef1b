"""Touches cut from a stream of frames: a segment at each early-decision checkpoint and at each touch's end.

:class:`TouchSegmenter` is the segmenter of frame bundles in touch mode (the other is
:class:`~tactile_torch.robot.stream.segments.SlidingWindows`): it follows a
:class:`~tactile_torch.robot.stream.touches.TouchTracker` over the frames and gives a
:class:`TouchSegment` with the frames the bundle takes (:func:`~tactile_torch.robot.stream.touches.fit_frames`)
at each checkpoint of a touch in progress and at its end. A break or a gap ends the touch in progress
(flag ``"cut"``): a touch is never merged across a pause. numpy only.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..files.sample_times import RATE_TOLERANCE
from .port_lines import StreamEvent
from .segments import RELEASE, Totals, bundle_input
from .source import FRAME, EventEmitter, ItemSpec, Reading
from .touches import END, SHORT, START, TouchLevels, TouchTracker, fit_frames


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
    skipped, rejected, gaps, lost : int
        Lines skipped, frames rejected, gaps and frames known lost since the previous touch's end.
    flags : tuple of str
        ``"cut"`` (ended by a break or a gap, not by a release), ``"after_cut"`` (started at the first
        frame after a break that cut a touch: the rest of a contact), ``"stretched"`` (fewer frames than
        the bundle takes, repeated evenly), ``"skipped"``, ``"rate"``.
    sensor : str or None
        The name of the sensor it was cut from, when the source has several (``None``: one sensor).
    sent_start, sent_end : float or None
        The sender's clock of the first and latest frame (``t``, else the transport's send time, e.g.
        a DDS source timestamp): what :attr:`duration_s` is measured with when there is no ``t``.
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
    lost: int = 0
    sensor: str | None = None
    sent_start: float | None = None
    sent_end: float | None = None

    @property
    def duration_s(self) -> float:
        """From the touch's first frame to its latest one, by the sender's clock (``t``, else its send time),
        else by the reader's."""
        if self.sent_start is not None and self.sent_end is not None:
            return self.sent_end - self.sent_start
        return self.read_at - self.started_at

    @property
    def partial(self) -> bool:
        """Whether the bundle saw less than a whole touch of ``T`` frames: cut, the rest of a cut contact, or stretched."""
        return any(f in self.flags for f in ("cut", "after_cut", "stretched"))


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
    sensor : str, optional
        The name of the sensor whose frames it cuts (its touches say so), when the source has several.

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
        sensor: str | None = None,
    ) -> None:
        if spec.kind != FRAME:
            raise ValueError(f"touches are cut from frames, got items of kind {spec.kind!r}")
        self.spec, self.levels, self.n_frames, self.sensor = spec, levels, int(n_frames), sensor
        self._items = 0  # frames pushed
        self.checkpoints = frozenset(int(c) for c in checkpoints if 1 <= int(c))
        self.rate_hz = spec.rate_hz
        self.touches = self.short = 0
        self._tracker = TouchTracker(levels)
        t = self.n_frames
        self._head = np.zeros((t, *spec.shape), dtype=np.float32)
        self._ring = np.zeros((2 * t, *spec.shape), dtype=np.float32)
        self._input = bundle_input(spec)
        self._events = EventEmitter(on_event, clock)
        self.totals = Totals()
        self._started = None  # (start item, started_at, t_start, skipped at start, after_cut, sent_start)
        self._last = None  # (read_at, t, sent) of the latest frame of the touch
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
        start_item, started_at, t_start, skipped_at_start, after_cut, sent_start = self._started
        read_at, t_end, sent_end = self._last
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
        skipped = rejected = gaps = lost = 0
        if kind == "end":
            skipped, rejected, gaps, lost = self.totals.since_last()
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
            lost=lost,
            sensor=self.sensor,
            sent_start=sent_start,
            sent_end=sent_end,
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
        index = self._items
        self._items += 1
        code = self._tracker.update(self.levels.activity(frame))
        if code == END or code == SHORT:
            self._after_cut = False
            return self._end(code, n_before, RELEASE, reading.read_at)
        if code == START:
            counts = self.totals.counts
            skipped = counts.skipped if counts is not None else 0
            sent = reading.t if reading.t is not None else reading.sent_at
            self._started = (index, reading.read_at, reading.t, skipped, self._after_cut, sent)
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
        self._last = (reading.read_at, reading.t, reading.t if reading.t is not None else reading.sent_at)
        if n in self.checkpoints:
            return self._segment("checkpoint", n, None)
        return None

    def cut(self, kind: str, at: float) -> TouchSegment | None:
        """A break or a gap: the touch in progress ends (flag ``"cut"``); return its segment."""
        n = self._tracker.frames
        code = self._tracker.cut()
        if n:  # a break with no touch in progress leaves the rest of one cut before as it was
            self._after_cut = code == END or code == SHORT
        return self._end(code, n, kind, at)

    def finish(self, kind: str, at: float) -> TouchSegment | None:
        """The input ended (or the stream was stopped): the touch in progress ends; return its segment."""
        n = self._tracker.frames
        return self._end(self._tracker.cut(), n, kind, at)


__all__ = ["TouchSegment", "TouchSegmenter"]
