"""A live stream assembled: any source, a bundle, windows or touches, early decisions, output hooks.

:class:`LiveStream` runs the stages of :mod:`tactile_torch.robot.stream.source` for one bundle: the
items the bundle takes (:func:`item_spec`: samples of a vibration bundle, frames of a taxel-array
bundle, with the range and rate from its metadata), a :class:`~tactile_torch.robot.stream.segments.Sequencer`,
a segmenter (sliding windows; or, for frame bundles, touches cut with the bundle's levels,
:func:`touch_setup`), the classifier with the bundle's early-decision rule, and every output hook
(a callable taking each result: printing, a JSON line, a ROS 2 publisher). ``tactile-torch stream``
is this with a serial (or DDS) source; ``tactile-torch predict --touches`` runs the same stages on a
recording through an :class:`~tactile_torch.robot.stream.source.ArraySource`. numpy and onnxruntime
only.

Examples
--------
>>> pipe = OnnxPipeline("grasp.onnx")                                      # doctest: +SKIP
>>> spec = item_spec(pipe)  # frames (H, W)                                  # doctest: +SKIP
>>> source = SerialSource(open_port, spec, idle_timeout_s=10)              # doctest: +SKIP
>>> live = LiveStream(pipe, source, LiveOptions(segment="touches"))        # doctest: +SKIP
>>> live.run([lambda result: print(result_json(result))])                  # doctest: +SKIP
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass

import numpy as np

from ..contract import (
    EARLY_RULE_KEY,
    FRAME_RATE_KEY,
    FRAMES_LAYOUT,
    PRESSURE_LAYOUT,
    SAMPLE_RATE_KEY,
    TOUCH_LEVELS_KEY,
    VALUE_RANGE_KEY,
    WINDOW_SIZE_KEY,
    WINDOWS_LAYOUT,
)
from ..runtime import OnnxPipeline, sensor_range_g
from .early_decision import EarlyRule
from .output import VOTE_METHODS, WindowResult, WindowVote, classify_segments
from .port_lines import StreamEvent
from .segments import END_OF_INPUT, Segments, SlidingWindows
from .sequencer import Sequencer
from .source import FRAME, SAMPLE, ItemSpec, Source
from .touch_output import TouchResult
from .touch_segments import TouchSegmenter
from .touches import SIGNALS, TouchLevels

SEGMENTS = ("auto", "windows", "touches")
"""How a stream is cut: ``touches`` (frame bundles' default), ``windows`` (sliding windows), ``auto``."""
ON_PARTIAL = ("withhold", "decide")
"""What the robot is told of a partial touch (cut, the rest of a cut contact, or stretched): see :class:`LiveOptions`."""
Output = Callable[[WindowResult | TouchResult], None]
"""An output hook: called with every result, in order."""


def frame_bundle(pipe: OnnxPipeline) -> bool:
    """Return whether ``pipe`` takes frames (pressure maps or RGB explorations) rather than windows or features."""
    return pipe.input_layout in (PRESSURE_LAYOUT, FRAMES_LAYOUT)


def item_spec(
    pipe: OnnxPipeline,
    *,
    range_g: float | None = None,
    value_range: tuple[float, float] | None = None,
) -> ItemSpec:
    """Return the :class:`ItemSpec` of the items ``pipe`` takes, with the accepted range and the rate.

    Vibration bundles: samples ``(3,)`` in g within ``±range_g`` (default: the bundle's
    ``sensor_range_g``, else 5 g) at ``sample_rate_hz``. Pressure-map bundles ``(B, T, H, W)``: frames
    ``(H, W)`` within ``value_range`` (default: the bundle's ``value_range`` metadata, else no check)
    at ``frame_rate_hz``. RGB bundles ``(B, T, 3, H, W)``: frames ``(H, W, 3)`` in [0, 255].
    ``ValueError`` for a bundle that takes features.
    """
    meta = pipe.metadata
    if pipe.input_layout == WINDOWS_LAYOUT:
        limit = sensor_range_g(meta) if range_g is None else float(range_g)
        rate = float(meta[SAMPLE_RATE_KEY]) if SAMPLE_RATE_KEY in meta else None
        return ItemSpec(SAMPLE, (3,), -limit, limit, rate, "g")
    if not frame_bundle(pipe):
        raise ValueError(
            f"{pipe.path}: a {pipe.pipeline} bundle takes {pipe.input_layout} input, not a stream of samples "
            "or frames"
        )
    rate = float(meta[FRAME_RATE_KEY]) if FRAME_RATE_KEY in meta else None
    h, w = pipe.input_shape[-2], pipe.input_shape[-1]
    if pipe.input_layout == FRAMES_LAYOUT:
        low, high = (0.0, 255.0) if value_range is None else value_range
        return ItemSpec(FRAME, (h, w, 3), low, high, rate, "0-255")
    if value_range is None and VALUE_RANGE_KEY in meta:
        try:
            low, high = (float(v) for v in json.loads(meta[VALUE_RANGE_KEY]))
        except (ValueError, TypeError) as err:
            raise ValueError(
                f"{pipe.path}: metadata {VALUE_RANGE_KEY} must be [low, high], got {meta[VALUE_RANGE_KEY]!r:.60}: {err}"
            ) from None
        value_range = (low, high)
    low, high = value_range if value_range is not None else (-math.inf, math.inf)
    return ItemSpec(FRAME, (h, w), float(low), float(high), rate, "counts")


@dataclass(frozen=True)
class LiveOptions:
    """How a live stream is cut and decided (the ``stream`` options, in the same names).

    Attributes
    ----------
    segment : {"auto", "windows", "touches"}
        ``auto``: touches for frame bundles, windows for vibration bundles.
    step : int, optional
        Windows: items between window starts (default: half a window).
    max_results : int, optional
        Stop after this many windows or touches.
    vote, vote_method
        Windows: the vote over the last ``vote`` windows (``1``: none).
    early : bool
        Touches: use the bundle's early-decision rule (when it has one).
    onset, release, min_frames, touch_signal
        Touches: replace the bundle's levels (:class:`~tactile_torch.robot.stream.touches.TouchLevels`).
    on_partial : {"withhold", "decide"}
        Touches: the decision of an incomplete touch (cut by a break or a gap, or the rest of a contact
        after such a cut): ``"withhold"`` (the default) gives it only when the bundle's early rule would
        have at that many frames (its margin reaches the calibrated threshold, and the frames are a
        touch's first ones), else ``decision`` is ``None``; ``"decide"`` gives every one. Either way
        the result says ``partial`` (as it does for a complete touch shorter than the bundle's ``T``,
        which is decided: the bundle's training touches were selected the same way).
    """

    segment: str = "auto"
    step: int | None = None
    max_results: int | None = None
    vote: int = 1
    vote_method: str = "majority"
    early: bool = True
    onset: float | None = None
    release: float | None = None
    min_frames: int | None = None
    touch_signal: str | None = None
    on_partial: str = "withhold"

    def __post_init__(self) -> None:
        if self.segment not in SEGMENTS:
            raise ValueError(f"segment must be one of {SEGMENTS}, got {self.segment!r}")
        if self.on_partial not in ON_PARTIAL:
            raise ValueError(f"on_partial must be one of {ON_PARTIAL}, got {self.on_partial!r}")
        for name, value in (("step", self.step), ("vote", self.vote), ("max_results", self.max_results)):
            if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value < 1):
                raise ValueError(f"{name} must be an int >= 1, got {value!r}")
        if self.vote_method not in VOTE_METHODS:
            raise ValueError(f"vote_method must be one of {VOTE_METHODS}, got {self.vote_method!r}")
        if self.touch_signal is not None and self.touch_signal not in SIGNALS:
            raise ValueError(f"touch_signal must be one of {SIGNALS}, got {self.touch_signal!r}")
        for name in ("onset", "release"):
            value = getattr(self, name)
            if value is not None and not (isinstance(value, int | float) and math.isfinite(value)):
                raise ValueError(f"{name} must be a finite number, got {value!r}")


def touch_setup(
    pipe: OnnxPipeline, options: LiveOptions = LiveOptions()
) -> tuple[TouchLevels, EarlyRule | None]:
    """Return the touch levels (the bundle's, with ``options``' overrides) and the early rule of a frame bundle.

    ``ValueError`` when the bundle records no levels and ``options`` give no onset (name them with
    ``onset=``), or when its metadata are malformed.
    """
    meta = pipe.metadata
    shape = tuple(pipe.input_shape[-2:])
    if TOUCH_LEVELS_KEY in meta:
        levels = TouchLevels.from_metadata(meta[TOUCH_LEVELS_KEY], shape)
    elif options.onset is not None:
        levels = TouchLevels(
            onset=float(options.onset),
            release=float(options.onset / 2 if options.release is None else options.release),
            rgb=pipe.input_layout == FRAMES_LAYOUT,
            source="given",
        )
    else:
        raise ValueError(
            f"onset: {pipe.path} records no touch levels (a bundle exported before they existed); give the "
            "onset level (onset=, release=) or cut sliding windows instead (segment='windows')"
        )
    levels = levels.with_overrides(
        onset=options.onset,
        release=options.release,
        min_frames=options.min_frames,
        signal=options.touch_signal,
    )
    rule = None
    if options.early and EARLY_RULE_KEY in meta:
        rule = EarlyRule.from_metadata(meta[EARLY_RULE_KEY])
    return levels, rule


class LiveStream:
    """Classify a source's items with a bundle: windows or touches, early decisions, output hooks.

    The one assembly of a live stream (and of ``predict --touches`` on a recording): the stages of
    :mod:`tactile_torch.robot.stream.source` for every source. A source of several sensors (a hand's
    ``TactileState``, a serial line of several arrays: :attr:`Source.sensors`) gets one sequencer and
    one segmenter per sensor (each sensor its own touches) and one classifier.

    Parameters
    ----------
    pipe : OnnxPipeline
    source : Source
        Its ``spec`` must be :func:`item_spec` of ``pipe`` (the serial source, a DDS source, an
        :class:`~tactile_torch.robot.stream.source.ArraySource`).
    options : LiveOptions
    on_event : callable, optional
        Events of the sequencer and the segmenter (gaps, stamps, rate, short contacts).
    clock : callable
        The source's clock (for latencies).

    Attributes
    ----------
    sensors : tuple of str
        The source's sensor names (``()`` for a source of one sensor).
    segmenters : list of SlidingWindows or TouchSegmenter
        One per sensor; ``segmenter`` is the first.
    sequencers : list of Sequencer
        One per sensor; ``sequencer`` is the first.
    levels : TouchLevels or None
    rule : EarlyRule or None
    results : int
        Windows or touches classified (early decisions not counted).
    unknown : int
        Of them, answered unknown.
    early : int
        Touches decided early.
    withheld : int
        Incomplete touches whose decision was withheld (``on_partial="withhold"``).
    """

    def __init__(
        self,
        pipe: OnnxPipeline,
        source: Source,
        options: LiveOptions = LiveOptions(),
        *,
        on_event: Callable[[StreamEvent], None] | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.pipe, self.source, self.options, self._clock = pipe, source, options, clock
        spec = source.spec
        frames = spec.kind == FRAME
        segment = options.segment if options.segment != "auto" else ("touches" if frames else "windows")
        if segment == "touches" and not frames:
            raise ValueError(f"segment: touches are cut from frames; {pipe.path} takes vibration windows")
        self.segment = segment
        self._on_event = on_event
        self.levels, self.rule = None, None
        self.size = (
            int(pipe.input_shape[1])
            if frames
            else int(pipe.metadata.get(WINDOW_SIZE_KEY, pipe.input_shape[-1]))
        )
        if segment == "touches":
            self.levels, self.rule = touch_setup(pipe, options)
        self.step = options.step if options.step is not None else max(self.size // 2, 1)
        self.votes = {} if segment == "windows" and options.vote > 1 else None
        first = self._channel(0)
        self.segments = Segments(source, first[0], first[1], channel=self._channel)
        self.results = self.unknown = self.early = self.withheld = 0

    def _channel(self, index: int):
        """The segmenter and sequencer of the source's sensor ``index`` (each sensor is cut on its own)."""
        spec, clock, on_event = self.source.spec, self._clock, self._on_event
        names = getattr(self.source, "sensors", None) or ()
        name = names[index] if index < len(names) else None
        sequencer = Sequencer(
            spec.rate_hz, item=spec.kind, name=self.source.name, on_event=on_event, clock=clock
        )
        if self.segment == "touches":
            checkpoints = self.rule.checkpoints if self.rule is not None and self.rule.active else ()
            segmenter = TouchSegmenter(
                spec,
                self.levels,
                self.size,
                checkpoints=checkpoints,
                on_event=on_event,
                clock=clock,
                sensor=name,
            )
        else:
            segmenter = SlidingWindows(spec, self.size, self.step, sensor=name)
        if self.votes is not None:
            self.votes[name] = WindowVote(self.options.vote, self.options.vote_method, self.pipe.class_names)
        return segmenter, sequencer

    @property
    def sensors(self) -> tuple[str, ...]:
        """The source's sensor names (``()`` for a source of one sensor)."""
        return tuple(getattr(self.source, "sensors", None) or ())

    @property
    def segmenters(self) -> list:
        """One segmenter per sensor read so far (:attr:`segmenter` is the first)."""
        return self.segments.segmenters

    @property
    def sequencers(self) -> list:
        """One sequencer per sensor read so far (:attr:`sequencer` is the first)."""
        return self.segments.sequencers

    @property
    def segmenter(self):
        """The first sensor's segmenter (the only one of a source of one sensor)."""
        return self.segments.segmenter

    @property
    def sequencer(self):
        """The first sensor's sequencer."""
        return self.segments.sequencer

    def warm_up(self) -> None:
        """Run the bundle once on a plausible input: its first call allocates (do it before opening a port)."""
        shape = (1, *(int(d) for d in self.pipe.input_shape[1:]))
        if self.pipe.input_layout == WINDOWS_LAYOUT:
            warm = np.linspace(-0.5, 0.5, int(np.prod(shape)), dtype=np.float32).reshape(shape)
        else:
            warm = np.zeros(shape, dtype=np.float32)
        self.pipe.classify(warm)

    def _classified(self, segments: Iterable) -> Iterator[WindowResult | TouchResult]:
        range_g = self.source.spec.high if self.source.spec.kind == SAMPLE else math.inf
        for result in classify_segments(
            segments,
            self.pipe,
            votes=self.votes,
            rule=self.rule,
            clock=self._clock,
            range_g=range_g,
            on_partial=self.options.on_partial,
        ):
            if result.__class__ is TouchResult and result.kind == "early":
                self.early += 1
            else:
                self.results += 1
                self.unknown += result.label == -1
                self.withheld += result.__class__ is TouchResult and result.decision is None
            yield result

    def __iter__(self) -> Iterator[WindowResult | TouchResult]:
        """Yield every result until the source ends (raises what the source raises), or ``max_results``."""
        limit = self.options.max_results
        for result in self._classified(self.segments):
            yield result
            if (
                limit is not None
                and self.results >= limit
                and not (result.__class__ is TouchResult and result.kind == "early")
            ):
                return

    def finish(self, why: str = END_OF_INPUT) -> Iterator[WindowResult | TouchResult]:
        """Yield the results of the touches in progress when the stream ends or is stopped (flag ``"cut"``)."""
        segments = self.segments.finish(why)
        if segments:
            yield from self._classified(segments)

    def run(self, outputs: Iterable[Output] = ()) -> None:
        """Call every output hook with every result, then with the touches in progress at the end of input."""
        outputs = list(outputs)
        for result in self:
            for output in outputs:
                output(result)
        for result in self.finish():
            for output in outputs:
                output(result)

    @property
    def lost(self) -> int:
        """Items known lost: from the sensor's ``t`` (every sequencer) and from the transport."""
        return sum(q.lost for q in self.sequencers) + self.source.counts.lost

    def summary(self) -> str:
        """One line: what was read, cut and classified, and the line's faults."""
        c, q = self.source.counts, self.sequencers
        item = self.source.spec.kind
        short = sum(g.short for g in self.segmenters) if self.segment == "touches" else 0
        cut = (
            f"{self.results} touches ({self.early} decided early, {self.withheld} partial withheld, {short} contacts "
            "too short)"
            if self.segment == "touches"
            else f"{self.results} windows"
        )
        if self.sensors:
            cut += f" of {len(self.sensors)} sensors"
        what = f"{getattr(self.source, 'skipped_name', 'messages')} skipped"
        gaps, corrected = sum(s.gaps for s in q), sum(s.corrected for s in q)
        return (
            f"{c.items} {item}s read, {cut}, {c.skipped} {what}, {c.rejected} {item}s out of range, {gaps} gaps "
            f"({self.lost} {item}s known lost), {corrected} time stamps corrected, {c.reconnects} reconnections, "
            f"{self.unknown} {self.segment} unknown, {c.format_switches} line-format switches"
        )


def classify_recording(
    pipe: OnnxPipeline,
    recording,
    options: LiveOptions = LiveOptions(),
    *,
    value_range: tuple[float, float] | None = None,
    on_event: Callable[[StreamEvent], None] | None = None,
) -> tuple[list[WindowResult | TouchResult], LiveStream]:
    """Run a :class:`~tactile_torch.robot.files.frame_recordings.FrameRecording` through the live stream's stages.

    The frames go through an :class:`~tactile_torch.robot.stream.source.ArraySource` with their ``t``,
    then the same sequencer, segmenter (touches by default) and classifier as ``tactile-torch stream``:
    the touches and decisions a live stream of the same frames gives (``tactile-torch predict
    --touches``). Returns every result, the touch in progress at the end included, and the stream
    (its counts and summary).
    """
    from .source import ArraySource

    spec = item_spec(pipe, value_range=value_range)
    frames = recording.frames
    if frames.shape[1:] != spec.shape:
        raise ValueError(
            f"{recording.name}: frames of shape {frames.shape[1:]} do not fit this {pipe.pipeline} bundle, "
            f"which takes frames of {spec.shape}"
        )
    source = ArraySource(frames, spec, t=recording.t, name=recording.name, on_event=on_event)
    live = LiveStream(pipe, source, options, on_event=on_event)
    results = list(live)
    results += list(live.finish())
    return results, live


__all__ = [
    "SEGMENTS",
    "LiveOptions",
    "LiveStream",
    "Output",
    "classify_recording",
    "frame_bundle",
    "item_spec",
    "touch_setup",
]
