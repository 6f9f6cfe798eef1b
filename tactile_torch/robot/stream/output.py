"""Classify a stream's segments and give each result in a form a robot program can use.

:func:`classify_windows` turns the :class:`~tactile_torch.robot.stream.segments.Window` objects a stream
cuts into :class:`WindowResult` objects (label, name, scores,
latency, flags, and optionally a vote over the last windows); :func:`classify_touches` turns the
:class:`~tactile_torch.robot.stream.touch_segments.TouchSegment` objects of a touch stream into
:class:`TouchResult` objects (an ``"early"`` one when the early-decision rule fires during a touch, a
``"touch"`` one at its end, with the decision the robot got and when); :func:`classify_segments` does
either (the touches' are in :mod:`tactile_torch.robot.stream.touch_output`). :func:`result_record` gives a result as a dict, :func:`result_json` and :func:`result_text` as
one line. numpy and an exported bundle only: importing this module never imports torch.

A window the bundle does not classify (a sample beyond the sensor's range, no vibration at all, or
features far from the training data: :meth:`~tactile_torch.robot.runtime.OnnxPipeline.classify`) is
"unknown": ``label`` -1, ``name`` ``"unknown"``, the flag ``"unknown"`` and a one-line ``reason``.
A window whose scores are not all finite (its samples overflow the features) gets no label:
``label``, ``name`` and ``scores`` are ``None`` and its flags hold ``"non_finite_scores"``.

Examples
--------
>>> pipe = OnnxPipeline("vibration.onnx")                                   # doctest: +SKIP
>>> source = SerialSource(open_port, item_spec(pipe), idle_timeout_s=10)    # doctest: +SKIP
>>> for result in LiveStream(pipe, source, LiveOptions(step=400, vote=5)):  # doctest: +SKIP
...     print(result_json(result))
{"window": 0, "time": 1767225600.123, "label": 3, "name": "cork", ...}
"""

from __future__ import annotations

import json
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ...validation import check_count
from ..contract import NOT_FINITE, UNKNOWN
from ..runtime import OnnxPipeline
from .early_decision import EarlyRule
from .segments import Window
from .touch_output import TouchResult, classify_touches, json_number, touch_record, touch_text
from .touch_segments import TouchSegment

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
    vote: WindowVote | Mapping[str | None, WindowVote] | None = None,
    clock: Callable[[], float] = time.monotonic,
    range_g: float | None = None,
) -> Iterator[WindowResult]:
    """Yield the :class:`WindowResult` of each window, classified by an exported vibration bundle.

    Parameters
    ----------
    windows : iterable of Window
        From a :class:`~tactile_torch.robot.stream.segments.SlidingWindows` (through
        :class:`~tactile_torch.robot.stream.segments.Segments`; :class:`~tactile_torch.robot.stream.live.LiveStream`
        classifies with this).
    pipeline : OnnxPipeline
        A bundle taking ``(B, 3, W)`` windows.
    vote : WindowVote or mapping of sensor name to WindowVote, optional
        Adds the vote over the last windows to each result (cleared at gaps); one per sensor when the
        windows come from several (:attr:`Window.sensor`).
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
        if prediction.causes[0] == NOT_FINITE:
            label = name = row = None
            flags += ("non_finite_scores",)
        else:
            name = pipeline.label_name(label)
            row = row if np.isfinite(row).all() else None
            if label == UNKNOWN:
                flags += ("unknown",)
        latency_ms = (clock() - window.read_at) * 1e3
        voted = None
        sensor_vote = vote if vote is None or isinstance(vote, WindowVote) else vote[window.sensor]
        if sensor_vote is not None:
            if window.gaps:
                sensor_vote.reset()
            if label is not None and label != UNKNOWN:
                voted = sensor_vote.update(label, row)
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


def _window_record(result: WindowResult) -> dict:
    w = result.window
    scores = None if result.scores is None else [round(float(s), 6) for s in result.scores]
    record = {
        "event": "window",
        "window": w.index,
        "time": round(result.time, 6),
        "sample": w.end_sample,
        "t_start": json_number(w.t_start, 6),
        "t_end": json_number(w.t_end, 6),
        "rate_hz": json_number(w.rate_hz, 3),
        "label": result.label,
        "name": result.name,
        "score": None if scores is None or result.label == UNKNOWN else scores[result.label],
        "scores": scores,
        "latency_ms": round(result.latency_ms, 4),
        "skipped": w.skipped,
        "rejected": w.rejected,
        "gaps": w.gaps,
        "lost": w.lost,
        "flags": list(result.flags),
        "reason": result.reason,
        "vote": None,
        "sensor": w.sensor,
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
    sensor = "" if w.sensor is None else f"{w.sensor:<10} "
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
        for n, what in (
            (w.skipped, "skipped"),
            (w.rejected, "rejected"),
            (w.gaps, "gap(s)"),
            (w.lost, "lost"),
        )
        if n
    ]
    if extras:
        line += "  " + ", ".join(extras)
    if result.flags:
        line += "  [" + ",".join(result.flags) + "]"
    return sensor + line


def classify_segments(
    segments: Iterable[Window | TouchSegment],
    pipeline: OnnxPipeline,
    *,
    votes: WindowVote | Mapping[str | None, WindowVote] | None = None,
    rule: EarlyRule | None = None,
    clock: Callable[[], float] = time.monotonic,
    range_g: float | None = None,
    on_partial: str = "withhold",
) -> Iterator[WindowResult | TouchResult]:
    """Classify windows (:func:`classify_windows`) or touches (:func:`classify_touches`), whichever come."""
    iterator = iter(segments)
    first = next(iterator, None)
    if first is None:
        return
    import itertools

    chained = itertools.chain([first], iterator)
    if isinstance(first, TouchSegment):
        yield from classify_touches(
            chained, pipeline, rule=rule, clock=clock, range_g=range_g, on_partial=on_partial
        )
    else:
        yield from classify_windows(chained, pipeline, vote=votes, clock=clock, range_g=range_g)


__all__ = [
    "VOTE_METHODS",
    "VoteResult",
    "WindowResult",
    "WindowVote",
    "classify_segments",
    "classify_windows",
    "result_json",
    "result_record",
    "result_text",
]
