"""Classify a stream's segments and give each result in a form a robot program can use.

:func:`classify_windows` turns the :class:`~tactile_torch.robot.stream.segments.Window` objects of a
:class:`~tactile_torch.robot.stream.window_reader.WindowReader` into :class:`WindowResult` objects (label, name, scores,
latency, flags, and optionally a vote over the last windows); :func:`classify_touches` turns the
:class:`~tactile_torch.robot.stream.segments.TouchSegment` objects of a touch stream into
:class:`TouchResult` objects (an ``"early"`` one when the early-decision rule fires during a touch, a
``"touch"`` one at its end, with the decision the robot got and when); :func:`classify_segments` does
either. :func:`result_record` gives a result as a dict, :func:`result_json` and :func:`result_text` as
one line. numpy and an exported bundle only: importing this module never imports torch.

A window the bundle does not classify (a sample beyond the sensor's range, no vibration at all, or
features far from the training data: :meth:`~tactile_torch.robot.runtime.OnnxPipeline.classify`) is
"unknown": ``label`` -1, ``name`` ``"unknown"``, the flag ``"unknown"`` and a one-line ``reason``.
A window whose scores are not all finite (its samples overflow the features) gets no label:
``label``, ``name`` and ``scores`` are ``None`` and its flags hold ``"non_finite_scores"``.

Examples
--------
>>> pipe = OnnxPipeline("vibration.onnx")                                   # doctest: +SKIP
>>> reader = WindowReader(open_port, window_size=800, step=400, rate_hz=800)  # doctest: +SKIP
>>> for result in classify_windows(reader, pipe, vote=WindowVote(5)):       # doctest: +SKIP
...     print(result_json(result))
{"window": 0, "time": 1767225600.123, "label": 3, "name": "cork", ...}
"""

from __future__ import annotations

import json
import math
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from ...validation import check_count
from ..contract import UNKNOWN
from ..runtime import OnnxPipeline
from .early_decision import EarlyRule, score_margins
from .segments import TouchSegment, Window

VOTE_METHODS = ("majority", "mean")
"""How :class:`WindowVote` combines windows: majority of the labels, or argmax of the mean scores."""


@dataclass(frozen=True)
class VoteResult:
    """The vote over the last windows.

    Attributes
    ----------
    label : int
    name : str
    support : float
        ``"majority"``: the share of the voting windows that gave ``label``; ``"mean"``: the mean score
        of ``label``.
    windows : int
        Windows in the vote (fewer than the vote's ``n`` after the start or a gap).
    """

    label: int
    name: str
    support: float
    windows: int


@dataclass(frozen=True)
class WindowResult:
    """The classification of one window, with what the line did since the previous window.

    Attributes
    ----------
    window : Window
        The window (data, sample count, ``t`` span, line counts).
    label : int or None
        ``-1`` when unknown (see ``reason``); ``None`` when the scores were not finite.
    name : str or None
        The label's class name (the label as a string when the bundle has none).
    scores : ndarray of shape (C,) or None
        The bundle's scores for the window.
    latency_ms : float
        From reading the window's last sample to having its result, in milliseconds.
    time : float
        Wall-clock time (``time.time()``) when the result was ready.
    flags : tuple of str
        The window's flags (``"skipped"``, ``"rate"``), ``"unknown"`` and ``"non_finite_scores"``.
    vote : VoteResult or None
        The vote including this window, when voting.
    reason : str or None
        Why the window is unknown (label -1), one line; ``None`` otherwise.
    """

    window: Window
    label: int | None
    name: str | None
    scores: np.ndarray | None
    latency_ms: float
    time: float
    flags: tuple[str, ...]
    vote: VoteResult | None = None
    reason: str | None = None


class WindowVote:
    """Combine the last ``n`` classified windows into one decision.

    Jamali and Sammut classify a material from several touches and take the majority vote of the
    per-touch decisions; here the "touches" are the last ``n`` windows of the stream. The history is
    cleared at a gap (silence, reconnection, dropped samples, a rejected sample): windows on either
    side may come from different contacts. Windows without a label (non-finite scores) do not vote.

    Parameters
    ----------
    n : int
        Windows in the vote (>= 1).
    method : {"majority", "mean"}, default "majority"
        ``"majority"``: the most frequent label, a tie going to the most recent of the tied labels;
        ``"mean"``: the argmax of the mean of the windows' scores (for the mixture bundles, whose
        scores are log responsibilities, this multiplies the windows' posteriors).
    class_names : sequence of str, optional
        Names of the labels.

    References
    ----------
    N. Jamali and C. Sammut, "Majority voting: material classification by tactile sensing using
    surface texture," IEEE Transactions on Robotics 27(3), 508-521, 2011.
    """

    def __init__(self, n: int, method: str = "majority", class_names: Sequence[str] = ()) -> None:
        n = check_count(n, "n", 1)
        if method not in VOTE_METHODS:
            raise ValueError(f"method must be one of {VOTE_METHODS}, got {method!r}")
        self.n = int(n)
        self.method = method
        self.class_names = list(class_names)
        self._history: deque[tuple[int, np.ndarray]] = deque(maxlen=self.n)

    def reset(self) -> None:
        """Forget the windows seen so far."""
        self._history.clear()

    def update(self, label: int, scores: np.ndarray) -> VoteResult:
        """Add one window's label and scores ``(C,)``; return the vote over the last ``n`` windows."""
        self._history.append((int(label), np.asarray(scores, dtype=np.float64)))
        if self.method == "mean":
            mean = np.mean([s for _, s in self._history], axis=0)
            winner = int(np.argmax(mean))
            support = float(mean[winner])
        else:
            labels = [lab for lab, _ in self._history]
            counts: dict[int, int] = {}
            for lab in labels:
                counts[lab] = counts.get(lab, 0) + 1
            top = max(counts.values())
            winner = next(lab for lab in reversed(labels) if counts[lab] == top)
            support = top / len(labels)
        name = self.class_names[winner] if winner < len(self.class_names) else str(winner)
        return VoteResult(winner, name, support, len(self._history))


def classify_windows(
    windows: Iterable[Window],
    pipeline: OnnxPipeline,
    *,
    vote: WindowVote | None = None,
    clock: Callable[[], float] = time.monotonic,
    range_g: float | None = None,
) -> Iterator[WindowResult]:
    """Yield the :class:`WindowResult` of each window, classified by an exported vibration bundle.

    Parameters
    ----------
    windows : iterable of Window
        Typically a :class:`~tactile_torch.robot.stream.window_reader.WindowReader`.
    pipeline : OnnxPipeline
        A bundle taking ``(B, 3, W)`` windows.
    vote : WindowVote, optional
        Adds the vote over the last windows to each result (cleared at gaps).
    clock : callable, default time.monotonic
        The clock of the reader (``Window.read_at``), for the latency.
    range_g : float, optional
        Windows holding a value beyond ``±range_g`` are unknown (default: the bundle's range; pass
        the reader's ``range_g`` when it was set otherwise, ``math.inf`` for none).

    A window the bundle does not classify (beyond the range, constant, or out of distribution:
    :meth:`~tactile_torch.robot.runtime.OnnxPipeline.classify`) gets label ``-1``, name ``"unknown"``, the
    flag ``"unknown"`` and its ``reason``; it does not vote.
    """
    for window in windows:
        flags = window.flags
        prediction = pipeline.classify(window.data, range_g=range_g)
        label, reason, row = int(prediction.labels[0]), prediction.reasons[0], prediction.scores[0]
        if reason is not None and reason.startswith("scores not finite"):
            label = name = row = None
            flags += ("non_finite_scores",)
        else:
            name = pipeline.label_name(label)
            row = row if np.isfinite(row).all() else None
            if label == UNKNOWN:
                flags += ("unknown",)
        latency_ms = (clock() - window.read_at) * 1e3
        voted = None
        if vote is not None:
            if window.gaps:
                vote.reset()
            if label is not None and label != UNKNOWN:
                voted = vote.update(label, row)
        yield WindowResult(
            window,
            label,
            name,
            row,
            latency_ms,
            time.time(),
            flags,
            voted,
            reason if label is not None else None,
        )


def _number(value: float | None, digits: int) -> float | None:
    return None if value is None or not math.isfinite(value) else round(float(value), digits)


def _window_record(result: WindowResult) -> dict:
    w = result.window
    scores = None if result.scores is None else [round(float(s), 6) for s in result.scores]
    record = {
        "event": "window",
        "window": w.index,
        "time": round(result.time, 6),
        "sample": w.end_sample,
        "t_start": _number(w.t_start, 6),
        "t_end": _number(w.t_end, 6),
        "rate_hz": _number(w.rate_hz, 3),
        "label": result.label,
        "name": result.name,
        "score": None if scores is None or result.label == UNKNOWN else scores[result.label],
        "scores": scores,
        "latency_ms": round(result.latency_ms, 4),
        "skipped": w.skipped,
        "rejected": w.rejected,
        "gaps": w.gaps,
        "flags": list(result.flags),
        "reason": result.reason,
        "vote": None,
    }
    if result.vote is not None:
        v = result.vote
        record["vote"] = {
            "label": v.label,
            "name": v.name,
            "support": round(v.support, 6),
            "windows": v.windows,
        }
    return record


def result_record(result: WindowResult | TouchResult) -> dict:
    """Return a result as a dict of JSON values (what :func:`result_json` writes; what an output hook may publish).

    ``event`` says what it is: ``"window"``, ``"early"`` (a touch decided before its end) or ``"touch"``
    (a touch's end). Keys of windows: see :func:`result_json`; of touches: see :func:`touch_record`.
    """
    if isinstance(result, TouchResult):
        return touch_record(result)
    return _window_record(result)


def result_json(result: WindowResult | TouchResult) -> str:
    """Return one result as one line of JSON (no NaN: strict JSON that any parser reads).

    Keys of a window: ``event`` (``"window"``), ``window`` (index), ``time`` (wall clock, s), ``sample``
    (samples read so far), ``t_start`` and ``t_end`` (the sensor's ``t`` in s, or null), ``label``,
    ``name``, ``score`` (the label's score), ``scores`` (list), ``latency_ms``, ``skipped``,
    ``rejected``, ``gaps`` (since the previous window), ``flags`` (list), ``vote`` (null, or
    ``label``, ``name``, ``support``, ``windows``). Touches: :func:`touch_record`.
    """
    return json.dumps(result_record(result), allow_nan=False)


def result_text(result: WindowResult | TouchResult) -> str:
    """Return one result as a line for a person: index, samples read, name, score, latency, extras."""
    if isinstance(result, TouchResult):
        return touch_text(result)
    w = result.window
    if result.label is None:
        line = f"{w.index:>6} {w.end_sample:>9} {'-':<24} no label: scores not finite"
    elif result.label == UNKNOWN:
        line = (
            f"{w.index:>6} {w.end_sample:>9} {result.name:<24} {result.reason} ({result.latency_ms:.2f} ms)"
        )
    else:
        score = float(result.scores[result.label])
        line = f"{w.index:>6} {w.end_sample:>9} {result.name:<24} score {score:+.3f} ({result.latency_ms:.2f} ms)"
    if result.vote is not None:
        v = result.vote
        line += f"  vote {v.name} ({v.support:.2f} of {v.windows})"
    extras = [
        f"{n} {what}"
        for n, what in ((w.skipped, "skipped"), (w.rejected, "rejected"), (w.gaps, "gap(s)"))
        if n
    ]
    if extras:
        line += "  " + ", ".join(extras)
    if result.flags:
        line += "  [" + ",".join(result.flags) + "]"
    return line


# ---------------------------------------------------------------------------------------------- touches
@dataclass(frozen=True)
class Decision:
    """The decision a touch got: early (the rule fired at a checkpoint) or at its end.

    Attributes
    ----------
    label : int or None
        ``-1`` unknown, ``None`` when the scores were not finite.
    name : str or None
    early : bool
    frames : int
        Frames into the touch when it was decided.
    after_s : float
        From the touch's first frame to the frame it was decided at: sensor time when the frames carry
        ``t``, else the reader's clock (the latency comes on top).
    latency_ms : float
        From reading that frame (at the end of a touch: from reading the frame, or the break, that ended
        it) to having the decision.
    margin : float or None
        The score margin at the decision (:func:`~tactile_torch.robot.stream.early_decision.score_margins`).
    """

    label: int | None
    name: str | None
    early: bool
    frames: int
    after_s: float
    latency_ms: float
    margin: float | None = None


@dataclass(frozen=True)
class TouchResult:
    """The classification of a touch at an early-decision checkpoint (``kind="early"``) or at its end (``"touch"``).

    Attributes
    ----------
    segment : TouchSegment
        The touch (frames, start, duration, what ended it, line counts, flags).
    kind : {"early", "touch"}
    label, name, scores, latency_ms, time, flags, reason
        As :class:`WindowResult`, for the touch's frames so far (``"early"``) or all of them (``"touch"``).
    margin : float or None
        The label's score minus the best other score.
    decision : Decision
        What the robot was told: the early decision when there was one, else this end-of-touch one.
    """

    segment: TouchSegment
    kind: str
    label: int | None
    name: str | None
    scores: np.ndarray | None
    latency_ms: float
    time: float
    flags: tuple[str, ...]
    margin: float | None
    decision: Decision
    reason: str | None = None


def _classified(pipeline: OnnxPipeline, data: np.ndarray, range_g: float | None):
    """``(label, name, scores row, reason, margin, extra flags)`` of one bundle input."""
    prediction = pipeline.classify(data, range_g=range_g)
    label, reason, row = int(prediction.labels[0]), prediction.reasons[0], prediction.scores[0]
    if reason is not None and reason.startswith("scores not finite"):
        return None, None, None, None, None, ("non_finite_scores",)
    name = pipeline.label_name(label)
    row = row if np.isfinite(row).all() else None
    if label == UNKNOWN:
        return label, name, row, reason, None, ("unknown",)
    margin = float(score_margins(row[None], np.array([label]))[0]) if row is not None else None
    return label, name, row, None, margin, ()


def classify_touches(
    segments: Iterable[TouchSegment],
    pipeline: OnnxPipeline,
    *,
    rule: EarlyRule | None = None,
    clock: Callable[[], float] = time.monotonic,
    range_g: float | None = None,
) -> Iterator[TouchResult]:
    """Yield a :class:`TouchResult` when a touch is decided early and one at the end of every touch.

    Parameters
    ----------
    segments : iterable of TouchSegment
        From a :class:`~tactile_torch.robot.stream.segments.TouchSegmenter` (through
        :class:`~tactile_torch.robot.stream.segments.Segments`).
    pipeline : OnnxPipeline
        A bundle taking frames ``(B, T, H, W)`` or ``(B, T, 3, H, W)``.
    rule : EarlyRule, optional
        Classify the touch at its checkpoints and decide early when the margin reaches the
        threshold (once per touch); without it, checkpoints are ignored and every decision comes at
        the end of the touch.
    clock : callable
        The clock of the reader (``read_at``), for the latency.
    range_g : float, optional
        As :meth:`~tactile_torch.robot.runtime.OnnxPipeline.classify` (frames: ``inf``).

    Early decisions are given for known labels only (a touch answered ``unknown`` at a checkpoint is
    not decided early). The end-of-touch result is given whatever was decided early, so that it can be
    compared with ``predict`` on the same touch.
    """
    early: dict[int, Decision] = {}
    active = rule is not None and rule.active
    for segment in segments:
        if segment.kind == "checkpoint":
            if not active or segment.touch in early or segment.frames not in rule.checkpoints:
                continue
            label, name, row, reason, margin, flags = _classified(pipeline, segment.data, range_g)
            if margin is None or margin < rule.threshold:
                continue
            latency_ms = (clock() - segment.read_at) * 1e3
            decision = Decision(label, name, True, segment.frames, segment.duration_s, latency_ms, margin)
            early[segment.touch] = decision
            yield TouchResult(
                segment,
                "early",
                label,
                name,
                row,
                latency_ms,
                time.time(),
                segment.flags + flags,
                margin,
                decision,
            )
            continue
        label, name, row, reason, margin, flags = _classified(pipeline, segment.data, range_g)
        known = segment.ended_at if segment.ended_at is not None else segment.read_at
        latency_ms = (clock() - known) * 1e3
        decision = early.pop(segment.touch, None) or Decision(
            label, name, False, segment.frames, segment.duration_s, latency_ms, margin
        )
        early.clear()  # touches end in order: nothing older is still open
        yield TouchResult(
            segment,
            "touch",
            label,
            name,
            row,
            latency_ms,
            time.time(),
            segment.flags + flags,
            margin,
            decision,
            reason,
        )


def classify_segments(
    segments: Iterable[Window | TouchSegment],
    pipeline: OnnxPipeline,
    *,
    vote: WindowVote | None = None,
    rule: EarlyRule | None = None,
    clock: Callable[[], float] = time.monotonic,
    range_g: float | None = None,
) -> Iterator[WindowResult | TouchResult]:
    """Classify windows (:func:`classify_windows`) or touches (:func:`classify_touches`), whichever come."""
    iterator = iter(segments)
    first = next(iterator, None)
    if first is None:
        return
    import itertools

    chained = itertools.chain([first], iterator)
    if isinstance(first, TouchSegment):
        yield from classify_touches(chained, pipeline, rule=rule, clock=clock, range_g=range_g)
    else:
        yield from classify_windows(chained, pipeline, vote=vote, clock=clock, range_g=range_g)


def touch_record(result: TouchResult) -> dict:
    """Return a touch result as a dict of JSON values.

    Keys: ``event`` (``"early"`` or ``"touch"``), ``touch`` (index), ``time`` (wall clock, s), ``start``
    (items read before the touch's first frame), ``frames`` (so far, for ``"early"``), ``frames_used``
    (distinct frames given to the bundle), ``t_start``, ``t_end`` (sensor time, s, or null),
    ``duration_s``, ``ended_by`` (``"release"``, ``"silence"``, ``"gap"``, ..., null for ``"early"``),
    ``label``, ``name``, ``score``, ``scores``, ``margin``, ``latency_ms``, ``skipped``, ``rejected``,
    ``gaps`` (since the previous touch), ``flags``, ``reason``, and ``decision``: ``label``, ``name``,
    ``early``, ``frames``, ``after_s`` (into the touch), ``latency_ms``.
    """
    s = result.segment
    scores = None if result.scores is None else [round(float(v), 6) for v in result.scores]
    d = result.decision
    return {
        "event": result.kind,
        "touch": s.touch,
        "time": round(result.time, 6),
        "start": s.start_item,
        "frames": s.frames,
        "frames_used": s.frames_used,
        "t_start": _number(s.t_start, 6),
        "t_end": _number(s.t_end, 6),
        "duration_s": _number(s.duration_s, 6),
        "ended_by": s.ended_by,
        "label": result.label,
        "name": result.name,
        "score": None if scores is None or result.label in (None, UNKNOWN) else scores[result.label],
        "scores": scores,
        "margin": _number(result.margin, 6),
        "latency_ms": round(result.latency_ms, 4),
        "skipped": s.skipped,
        "rejected": s.rejected,
        "gaps": s.gaps,
        "flags": list(result.flags),
        "reason": result.reason,
        "decision": {
            "label": d.label,
            "name": d.name,
            "early": d.early,
            "frames": d.frames,
            "after_s": _number(d.after_s, 6),
            "latency_ms": round(d.latency_ms, 4),
        },
    }


def touch_text(result: TouchResult) -> str:
    """Return a touch result as a line for a person."""
    s = result.segment
    if result.label is None:
        what = f"{'-':<20} no label: scores not finite"
    elif result.label == UNKNOWN:
        what = f"{result.name:<20} {result.reason}"
    else:
        margin = "" if result.margin is None else f" margin {result.margin:.3g}"
        what = f"{result.name:<20} score {float(result.scores[result.label]):+.3f}{margin}"
    if result.kind == "early":
        line = f"early {s.touch:>5} after {s.frames} frames ({s.duration_s:.2f} s)  {what} ({result.latency_ms:.2f} ms)"
    else:
        line = (
            f"touch {s.touch:>5} frames {s.start_item}+{s.frames} ({s.duration_s:.2f} s, ended by {s.ended_by})  "
            f"{what} ({result.latency_ms:.2f} ms)"
        )
        d = result.decision
        if d.early:
            line += f"  decided early at {d.frames} frames ({d.after_s:.2f} s): {d.name}"
    extras = [
        f"{n} {w}" for n, w in ((s.skipped, "skipped"), (s.rejected, "rejected"), (s.gaps, "gap(s)")) if n
    ]
    if extras and result.kind == "touch":
        line += "  " + ", ".join(extras)
    if result.flags:
        line += "  [" + ",".join(result.flags) + "]"
    return line


__all__ = [
    "VOTE_METHODS",
    "Decision",
    "TouchResult",
    "VoteResult",
    "WindowResult",
    "WindowVote",
    "classify_segments",
    "classify_touches",
    "classify_windows",
    "result_json",
    "result_record",
    "result_text",
    "touch_record",
    "touch_text",
]
