"""A hand's frame recordings as training touches, cut by the live stream's own stages (numpy only).

A hand logs its taxel frames continuously; a model trains on explorations of ``T`` frames and the live
stream classifies touches. So that what trains is what the hand will classify, :func:`recorded_touches`
runs every recording through the stream's own stages (:class:`~.segments.Segments` over an
:class:`~.source.ArraySource`: the :class:`~.segments.Sequencer`'s gap rule, the
:class:`~.segments.TouchSegmenter` and its :class:`~.touches.TouchTracker`) at the levels the bundle
will carry, and brings each touch to ``T`` frames with :func:`~.touches.fit_frames`, exactly as the
stream brings a touch at its end:

1. **Frame rate**: the slope of ``t`` against the frame index
   (:func:`~tactile_torch.robot.files.sample_times.time_base`, the rule of the samples' time stamps),
   shared by the recordings within 1 %.
2. **Levels** (:func:`recording_levels`): the contacts are the runs of labelled frames (per-frame
   ``labels``), else the runs of frames whose pressure above each taxel's rest stands
   :data:`~.touches.NOISE_CONTACT` noise deviations out; :func:`~.touches.touch_levels` sets the onset
   and release from them, above each taxel's resting level over all the frames. The deployed bundle
   records these levels (``touch_levels``), so the stream cuts the touches training saw.
3. **Touches**: a touch ended by its release trains; the pieces of a contact cut by a gap, a silence or
   the end of its recording (before and after the cut) do not, nor a touch whose frames carry no label:
   counted in the notes.
4. **T**: the median touch's frames (``n_frames`` to choose).
5. **Labels and groups**: a touch's most frequent frame label, else its recording's class (one label
   per file); its recording's session as its group, so that held-out splits keep a session apart.

Examples
--------
>>> import numpy as np
>>> from tactile_torch.robot.files.frame_recordings import FrameRecording, FrameRecordings
>>> frames = np.full((300, 2, 2), 10.0, np.float32)
>>> labels = np.full(300, -1)
>>> for start in (20, 120, 220):  # three presses of 50 frames
...     frames[start : start + 50] += 40.0
...     labels[start : start + 50] = 0
>>> rec = FrameRecording(frames, np.arange(300) / 50.0, labels, ("cork",))
>>> touches = recorded_touches(FrameRecordings([rec], ("cork",), None, np.array(["day1"])))
>>> touches.explorations.pressure.shape, touches.rate_hz
((3, 50, 2, 2), 50.0)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..files.formats import ExplorationArrays
from ..files.frame_recordings import FrameRecording, touch_labels
from ..files.sample_times import rate_hz, time_base
from .segments import RELEASE, Segments
from .sequencer import Sequencer
from .source import FRAME, ArraySource, ItemSpec
from .touch_segments import TouchSegment, TouchSegmenter
from .touches import (
    DEAD_BAND,
    GRAY,
    NOISE_CONTACT,
    TouchLevels,
    contact_sign,
    fit_frames,
    reading_noise,
    resting_level,
    touch_levels,
)

RATE_AGREEMENT = 0.01
"""Frame recordings trained together must agree on their frame rate within this share."""


@dataclass
class RecordedTouches:
    """The touches of frame recordings, as the training side takes them (:func:`recorded_touches`).

    Attributes
    ----------
    explorations : ExplorationArrays
        One exploration of ``n_frames`` frames per touch (``pressure`` ``(N, T, H, W)``, or RGB
        ``frames`` ``(N, T, H, W, 3)``), its label, the class names, each touch's session as ``groups``
        (``None`` when the recordings are one session) and the frame rate.
    levels : TouchLevels
        The levels the touches were cut at (what the bundle records for the stream).
    rate_hz : float
        Frames per second, from ``t``.
    n_frames : int
        ``T``, the frames of each exploration.
    segments : list of TouchSegment
        The end segment of each touch kept (its ``start_item`` and ``frames`` in its recording).
    recording : ndarray of shape (N,) int64
        The recording each touch comes from.
    notes : list of str
        What was decided and left out, one line each.
    """

    explorations: ExplorationArrays
    levels: TouchLevels
    rate_hz: float
    n_frames: int
    segments: list[TouchSegment]
    recording: np.ndarray
    notes: list[str] = field(default_factory=list)


def frame_rate(recordings: list[FrameRecording]) -> float:
    """Return the frames per second of ``recordings`` from their ``t`` (the slope rule); they must agree within 1 %.

    Raises ``ValueError`` naming two recordings of different rates, or one of fewer than 2 frames.
    """
    rates = []
    for rec in recordings:
        if len(rec.t) < 2:
            raise ValueError(
                f"{rec.name}: t must hold at least 2 frames to give the frame rate, got {len(rec.t)}"
            )
        base = time_base(rec.t - rec.t[0])
        rates.append(rate_hz(base.period, base.period_error))
    rates = np.array(rates)
    odd = int(np.argmax(np.abs(rates / rates[0] - 1)))
    if abs(rates[odd] / rates[0] - 1) > RATE_AGREEMENT:
        raise ValueError(
            f"the recordings have different frame rates ({recordings[0].name}: {rates[0]:g} frames/s, "
            f"{recordings[odd].name}: {rates[odd]:g} frames/s); resample them to one rate"
        )
    return float(rates[0])


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``(start, stop)`` of every run of True in ``mask``."""
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(np.int8), 0]))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True))


def _pressure(frames: np.ndarray) -> np.ndarray:
    """Pressure-like readings of frames: pressure maps as they are, RGB as ``1 - gray`` (white: no pressure)."""
    if frames.ndim == 4:
        return 1.0 - (frames[..., 0] * GRAY[0] + frames[..., 1] * GRAY[1] + frames[..., 2] * GRAY[2]) / 255.0
    return frames


def recording_levels(
    recordings: list[FrameRecording], rate: float, *, contact: str = "raises"
) -> TouchLevels:
    """Return the touch levels of recordings: :func:`~.touches.touch_levels` of their contacts (module notes, 2).

    Raises ``ValueError`` naming the first recording when no contact stands out of the frames' rest.
    """
    rgb = recordings[0].rgb
    pressure = [_pressure(rec.frames) for rec in recordings]
    sign = 1.0 if rgb else contact_sign(np.concatenate(pressure), contact)[0]
    rest = resting_level(sign * np.concatenate(pressure))
    noise = float(np.median([reading_noise(p[None]) for p in pressure]))
    contacts = []
    for rec, p in zip(recordings, pressure, strict=True):
        if rec.labels is not None:
            mask = rec.labels >= 0
        else:
            above = np.maximum(sign * p - rest - DEAD_BAND * noise, 0.0).reshape(len(p), -1).sum(axis=1)
            mask = above > NOISE_CONTACT * max(noise, np.finfo(np.float32).eps)
        contacts += [rec.frames[a:b] for a, b in _runs(mask) if b - a >= 2]
    if not contacts:
        raise ValueError(
            f"{recordings[0].name}: no touch stands out of the frames' rest (no contact {NOISE_CONTACT:g} noise "
            "deviations above each taxel's resting level); give the touch levels (onset=, release=)"
        )
    length = int(np.median([len(c) for c in contacts]))
    explorations = np.stack([fit_frames(c, length) for c in contacts])
    try:
        return touch_levels(explorations, frame_rate_hz=rate, sign=sign, rest=None if rgb else rest, rgb=rgb)
    except ValueError as err:
        raise ValueError(f"{recordings[0].name}: no touch stands out of the frames' rest ({err})") from None


def _touches(rec: FrameRecording, levels: TouchLevels, rate: float) -> tuple[list[TouchSegment], int]:
    """The end segments of every touch the live stream cuts from ``rec``, and the contacts too short to be one."""
    spec = ItemSpec(FRAME, rec.frames.shape[1:], rate_hz=rate)
    segmenter = TouchSegmenter(spec, levels, 1)
    segments = Segments(
        ArraySource(rec.frames, spec, t=rec.t, name=rec.name),
        segmenter,
        Sequencer(rate, item=FRAME, name=rec.name),
    )
    return list(segments) + segments.finish(), segmenter.short


def recorded_touches(
    data,
    *,
    n_frames: int | None = None,
    levels: TouchLevels | None = None,
    contact: str = "raises",
) -> RecordedTouches:
    """Return the touches of frame recordings as explorations for training (module notes).

    Parameters
    ----------
    data : FrameRecordings
        :func:`tactile_torch.robot.files.frame_recordings.read_frame_recordings` (``--data`` of frame recordings).
    n_frames : int >= 2, optional
        ``T``: the frames each touch is brought to (default: the median touch's).
    levels : TouchLevels, optional
        Cut at these levels instead of the recordings' own (:func:`recording_levels`).
    contact : {"raises", "lowers", "auto"}
        Pressure maps: how contact changes a reading.

    Raises
    ------
    ValueError
        One line: recordings of different frame rates, no contact above rest, no touch ended by its release,
        ``n_frames`` below 2.
    """
    recs = data.recordings
    rate = frame_rate(recs)
    levels = recording_levels(recs, rate, contact=contact) if levels is None else levels
    kept, cut, unlabelled, short = [], {}, 0, 0
    for i, rec in enumerate(recs):
        ends, n_short = _touches(rec, levels, rate)
        short += n_short
        for s in ends:
            if s.ended_by != RELEASE or "after_cut" in s.flags:  # a piece of a contact, before or after a cut
                why = s.ended_by if s.ended_by != RELEASE else "its release after a cut"
                cut[why] = cut.get(why, 0) + 1
                continue
            label = (
                touch_labels(rec, s.start_item, s.frames)
                if rec.labels is not None
                else int(data.file_labels[i])
            )
            if label < 0:
                unlabelled += 1
                continue
            kept.append((i, s, label))
    if not kept:
        raise ValueError(
            f"{recs[0].name}: no touch ended by its release in the recordings ({sum(cut.values())} cut, {unlabelled} "
            "without a label); check the touch levels (onset=, release=) or the labels"
        )
    lengths = np.array([s.frames for _, s, _ in kept])
    t = int(np.median(lengths)) if n_frames is None else int(n_frames)
    if t < 2:
        raise ValueError(f"n_frames must be at least 2 (a touch's time series), got {t}")
    x = np.stack([fit_frames(recs[i].frames[s.start_item : s.start_item + s.frames], t) for i, s, _ in kept])
    recording = np.array([i for i, _, _ in kept], dtype=np.int64)
    _, session_ids = np.unique(np.asarray(data.session).astype(str), return_inverse=True)
    explorations = ExplorationArrays(
        x if recs[0].rgb else None,
        None if recs[0].rgb else x.astype(np.float32, copy=False),
        np.array([label for _, _, label in kept], dtype=np.int64),
        tuple(data.class_names),
        session_ids[recording].astype(np.int64)
        if session_ids.max(initial=0) > 0
        else None,  # one session: none
        rate,
    )
    notes = [
        f"{len(kept)} touches of {len(recs)} recording(s) at {rate:g} frames/s (from t), cut by the live stream at "
        f"onset {levels.onset:.4g} / release {levels.release:.4g} ({levels.source}); each brought to {t} frames "
        f"({'the median touch' if n_frames is None else 'as asked'}; touches of {lengths.min()}-{lengths.max()} frames)"
    ]
    left = [f"{n} ended by {why}" for why, n in sorted(cut.items())] + [
        f"{unlabelled} without a label"
    ] * bool(unlabelled)
    left += [f"{short} contact(s) shorter than a touch"] * bool(short)
    if left:
        notes.append(f"left out of training: {', '.join(left)} (pieces of contacts, or rest)")
    return RecordedTouches(explorations, levels, rate, t, [s for _, s, _ in kept], recording, notes)


__all__ = ["RATE_AGREEMENT", "RecordedTouches", "frame_rate", "recorded_touches", "recording_levels"]
