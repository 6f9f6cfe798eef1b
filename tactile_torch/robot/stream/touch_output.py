"""Classify the touches of a stream: an early decision when the bundle's rule is sure, one at every touch's end.

:func:`classify_touches` turns the :class:`~tactile_torch.robot.stream.touch_segments.TouchSegment`
objects of a touch stream into :class:`TouchResult` objects (an ``"early"`` one when the early-decision
rule fires during a touch, a ``"touch"`` one at its end, with the decision the robot got and when, or
withheld for an incomplete touch the rule is not sure of); :func:`touch_record` and :func:`touch_text`
give one as a dict and a line (:mod:`tactile_torch.robot.stream.output` gives windows and either).
numpy and an exported bundle only: importing this module never imports torch.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass

import numpy as np

from ..contract import NOT_FINITE, UNKNOWN
from ..runtime import OnnxPipeline
from .early_decision import EarlyRule, score_margins
from .touch_segments import TouchSegment


def json_number(value: float | None, digits: int) -> float | None:
    """``value`` rounded to ``digits`` for a JSON line; ``None`` for ``None``, NaN and infinities (strict JSON)."""
    return None if value is None or not math.isfinite(value) else round(float(value), digits)


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
    decision : Decision or None
        What the robot was told: the early decision when there was one, else this end-of-touch one;
        ``None`` when it was withheld (a partial touch the bundle cannot decide: ``withheld`` says why).
    reason : str or None
        Why the touch is unknown (label -1), one line.
    withheld : str or None
        Why the decision was withheld, one line (``None``: it was given).
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
    decision: Decision | None
    reason: str | None = None
    withheld: str | None = None

    @property
    def partial(self) -> bool:
        """Whether the bundle saw less than a whole touch (:attr:`TouchSegment.partial`)."""
        return self.segment.partial


def _classified(pipeline: OnnxPipeline, data: np.ndarray, range_g: float | None):
    """``(label, name, scores row, reason, margin, extra flags)`` of one bundle input."""
    prediction = pipeline.classify(data, range_g=range_g)
    label, reason, row = int(prediction.labels[0]), prediction.reasons[0], prediction.scores[0]
    if prediction.causes[0] == NOT_FINITE:
        return None, None, None, None, None, ("non_finite_scores",)
    name = pipeline.label_name(label)
    row = row if np.isfinite(row).all() else None
    if label == UNKNOWN:
        return label, name, row, reason, None, ("unknown",)
    margin = float(score_margins(row[None], np.array([label]))[0]) if row is not None else None
    return label, name, row, None, margin, ()


def _withheld(segment: TouchSegment, margin: float | None, rule: EarlyRule | None) -> str | None:
    """Why the end-of-touch decision of an incomplete touch is withheld (``None``: it is given).

    Incomplete: cut by a break or a gap, or the rest of a contact after such a cut. A touch that
    started and ended by itself is complete, however short (stretched to ``T``, as training selected
    its touches), and decided.
    """
    if "after_cut" in segment.flags:
        return (
            "partial: the rest of a contact cut before it (the bundle's rule is calibrated on first frames)"
        )
    if "cut" not in segment.flags:
        return None
    what = f"a touch cut by {segment.ended_by} after {segment.frames} frames"
    if rule is None or not rule.active:
        return f"partial: {what}; the bundle has no calibrated rule to decide a part by"
    if segment.frames < min(rule.checkpoints):
        return f"partial: {what}, fewer than the {min(rule.checkpoints)} its rule needs"
    if margin is None or margin < rule.threshold:
        shown = "none" if margin is None else f"{margin:.3g}"
        return f"partial: {what}; its margin {shown} is below the rule's {rule.threshold:.3g}"
    return None


def classify_touches(
    segments: Iterable[TouchSegment],
    pipeline: OnnxPipeline,
    *,
    rule: EarlyRule | None = None,
    clock: Callable[[], float] = time.monotonic,
    range_g: float | None = None,
    on_partial: str = "withhold",
) -> Iterator[TouchResult]:
    """Yield a :class:`TouchResult` when a touch is decided early and one at the end of every touch.

    Parameters
    ----------
    segments : iterable of TouchSegment
        From a :class:`~tactile_torch.robot.stream.touch_segments.TouchSegmenter` (through
        :class:`~tactile_torch.robot.stream.segments.Segments`); touches of several sensors may
        interleave (:attr:`TouchSegment.sensor`).
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
    on_partial : {"withhold", "decide"}
        The end-of-touch decision of an incomplete touch (cut by a break or a gap, or the rest of a
        contact after such a cut) not decided early: ``"withhold"`` gives it only when the early rule
        would (a touch's first frames, at least the rule's first checkpoint of them, and a margin that
        reaches its threshold), else ``decision`` is ``None`` and ``withheld`` says why; ``"decide"``
        gives it always. A touch that began and ended by itself is decided, however short.

    Early decisions are given for known labels only (a touch answered ``unknown`` at a checkpoint is
    not decided early). The end-of-touch result is given whatever was decided early, so that it can be
    compared with ``predict`` on the same touch.
    """
    early: dict[tuple[str | None, int], Decision] = {}
    active = rule is not None and rule.active
    for segment in segments:
        key = (segment.sensor, segment.touch)
        if segment.kind == "checkpoint":
            if not active or key in early or segment.frames not in rule.checkpoints:
                continue
            classified = _classified(pipeline, segment.data, range_g)
            label, name, _, _, margin, _ = classified
            if margin is None or margin < rule.threshold:
                continue
            latency_ms = (clock() - segment.read_at) * 1e3
            decision = Decision(label, name, True, segment.frames, segment.duration_s, latency_ms, margin)
            early[key] = decision
            yield _result(segment, "early", classified, latency_ms, decision)
            continue
        classified = _classified(pipeline, segment.data, range_g)
        label, name, _, _, margin, _ = classified
        known = segment.ended_at if segment.ended_at is not None else segment.read_at
        latency_ms = (clock() - known) * 1e3
        decision = early.pop(key, None)
        withheld = None
        if decision is None:
            withheld = _withheld(segment, margin, rule) if on_partial == "withhold" else None
            if withheld is None:
                decision = Decision(
                    label, name, False, segment.frames, segment.duration_s, latency_ms, margin
                )
        for older in [k for k in early if k[0] == segment.sensor]:  # a sensor's touches end in order
            del early[older]
        yield _result(segment, "touch", classified, latency_ms, decision, withheld)


def _result(
    segment: TouchSegment, kind: str, classified, latency_ms: float, decision, withheld=None
) -> TouchResult:
    """The :class:`TouchResult` of one classified touch (``classified``: :func:`_classified`'s tuple)."""
    label, name, row, reason, margin, flags = classified
    return TouchResult(
        segment, kind, label, name, row, latency_ms, time.time(), segment.flags + flags, margin, decision,
        reason if kind == "touch" else None, withheld,
    )  # fmt: skip


def touch_record(result: TouchResult) -> dict:
    """Return a touch result as a dict of JSON values.

    Keys: ``event`` (``"early"`` or ``"touch"``), ``sensor`` (its name when the source has several,
    else null), ``touch`` (index), ``time`` (wall clock, s), ``start`` (items read before the touch's
    first frame), ``frames`` (so far, for ``"early"``), ``frames_used`` (distinct frames given to the
    bundle), ``t_start``, ``t_end`` (sensor time, s, or null), ``duration_s``, ``ended_by``
    (``"release"``, ``"silence"``, ``"gap"``, ..., null for ``"early"``), ``label``, ``name``, ``score``,
    ``scores``, ``margin``, ``latency_ms``, ``skipped``, ``rejected``, ``gaps``, ``lost`` (since the
    previous touch), ``flags``, ``reason``, ``partial`` (the bundle saw less than a whole touch),
    ``decision`` (``label``, ``name``, ``early``, ``frames``, ``after_s`` into the touch, ``latency_ms``;
    null when withheld) and ``withheld`` (why, or null).
    """
    s = result.segment
    scores = None if result.scores is None else [round(float(v), 6) for v in result.scores]
    d = result.decision
    return {
        "event": result.kind,
        "sensor": s.sensor,
        "touch": s.touch,
        "time": round(result.time, 6),
        "start": s.start_item,
        "frames": s.frames,
        "frames_used": s.frames_used,
        "t_start": json_number(s.t_start, 6),
        "t_end": json_number(s.t_end, 6),
        "duration_s": json_number(s.duration_s, 6),
        "ended_by": s.ended_by,
        "label": result.label,
        "name": result.name,
        "score": None if scores is None or result.label in (None, UNKNOWN) else scores[result.label],
        "scores": scores,
        "margin": json_number(result.margin, 6),
        "latency_ms": round(result.latency_ms, 4),
        "skipped": s.skipped,
        "rejected": s.rejected,
        "gaps": s.gaps,
        "lost": s.lost,
        "flags": list(result.flags),
        "reason": result.reason,
        "partial": s.partial,
        "decision": None
        if d is None
        else {
            "label": d.label,
            "name": d.name,
            "early": d.early,
            "frames": d.frames,
            "after_s": json_number(d.after_s, 6),
            "latency_ms": round(d.latency_ms, 4),
        },
        "withheld": result.withheld,
    }


def touch_text(result: TouchResult) -> str:
    """Return a touch result as a line for a person."""
    s = result.segment
    sensor = "" if s.sensor is None else f"{s.sensor:<10} "
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
        if d is None:
            line += f"  withheld ({result.withheld})"
        elif d.early:
            line += f"  decided early at {d.frames} frames ({d.after_s:.2f} s): {d.name}"
    extras = [
        f"{n} {w}"
        for n, w in ((s.skipped, "skipped"), (s.rejected, "rejected"), (s.gaps, "gap(s)"), (s.lost, "lost"))
        if n
    ]
    if extras and result.kind == "touch":
        line += "  " + ", ".join(extras)
    if result.flags:
        line += "  [" + ",".join(result.flags) + "]"
    return sensor + line


__all__ = ["Decision", "TouchResult", "classify_touches", "json_number", "touch_record", "touch_text"]
