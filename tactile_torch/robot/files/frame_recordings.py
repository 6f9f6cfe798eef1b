"""Frame recordings: a taxel array's frames in time order, as a stream plays them and ``predict`` cuts them.

A **frame recording** is what a hand's sensor sends: frames one after another, touches with rest in
between. Three files give one (:func:`read_frame_recording`):

==============================  ==========================================================================
file                            recording
==============================  ==========================================================================
frame recording ``.npz``        ``frames`` float ``(n, H, W)`` (pressure maps, any counts) or uint8
                                ``(n, H, W, 3)`` RGB, ``t`` float ``(n,)`` seconds (increasing; what marks
                                the file as a recording), optional ``labels`` int ``(n,)`` (the class of
                                each frame, -1 for none) and ``class_names`` str ``(C,)``
image explorations ``.npz``     ``frames`` ``(N, T, H, W)`` / ``(N, T, H, W, 3)`` (docs/formats.md): one
                                exploration (``recording=i``), or all of them in order, each followed by
                                ``rest_s`` seconds of resting frames (the per-taxel minimum of the file;
                                white for RGB), at ``rate_hz``; each frame labelled with its exploration's
                                class
ROS 2 bag                       a topic of frames (:mod:`tactile_torch.robot.ros2.bags`: ``Float32MultiArray``,
                                ``Image``, ``TactileState``, a ``field`` of any message), its header stamps
                                (else receive stamps) as ``t``; the class from the bag's name (docs/formats.md)
==============================  ==========================================================================

:func:`write_frame_recording` writes the first form. Several frame recordings read together for training
(:func:`read_frame_recordings`, what ``--data`` of frame recordings gives) are :class:`FrameRecordings`:
each frame's class from the files' ``labels``, or one class per file from the files' layout
(:func:`tactile_torch.robot.files.naming.recording_names`), and each file's session; the training side
cuts them into touches with the live stream's own stages (:mod:`tactile_torch.robot.stream.recorded_touches`).
The frame rate is the slope of ``t`` against the frame index (:func:`tactile_torch.robot.files.sample_times.time_base`,
the rule of the samples' time stamps); explorations (no ``t``) state theirs in ``frame_rate_hz``, or it is
given, never assumed. numpy only (bags need the ``ros`` extra).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .npz import PathLike, read_npz, write_npz
from .sample_times import rate_hz, time_base

DEFAULT_REST_S = 0.5
"""Seconds of resting frames after each exploration when a file of explorations is played as one recording."""


@dataclass
class FrameRecording:
    """A taxel array's frames in time order.

    Attributes
    ----------
    frames : ndarray
        ``(n, H, W)`` float32 pressure maps, or ``(n, H, W, 3)`` uint8 RGB frames.
    t : ndarray of shape (n,), float64
        Each frame's time in seconds, increasing.
    labels : ndarray of shape (n,), int64, or None
        The class of each frame (index into ``class_names``), -1 where there is none (rest).
    class_names : tuple of str or None
    name : str
        What messages call it.
    """

    frames: np.ndarray
    t: np.ndarray
    labels: np.ndarray | None = None
    class_names: tuple[str, ...] | None = None
    name: str = "recording"

    def __len__(self) -> int:
        return len(self.frames)

    @property
    def rate_hz(self) -> float:
        """Frames per second: the slope of ``t`` against the frame index between gaps (NaN below 2 frames).

        The rule of the samples' time stamps (:func:`tactile_torch.robot.files.sample_times.time_base`):
        stamps rounded or jittered by a logger, and gaps, do not bias it as a median step would.
        """
        if len(self.t) < 2:
            return float("nan")
        base = time_base(self.t - self.t[0])
        return rate_hz(base.period, base.period_error)

    @property
    def rgb(self) -> bool:
        """Whether the frames are RGB ``(n, H, W, 3)``."""
        return self.frames.ndim == 4


def _check(rec: FrameRecording) -> FrameRecording:
    f, t, where = rec.frames, rec.t, rec.name
    if f.ndim == 3 and np.issubdtype(f.dtype, np.number):
        if not np.isfinite(f).all():
            raise ValueError(f"{where}: frames must be finite, got NaN/inf values")
        rec.frames = f.astype(np.float32, copy=False)
    elif not (f.ndim == 4 and f.shape[-1] == 3 and f.dtype == np.uint8):
        raise ValueError(
            f"{where}: frames must be pressure maps (n, H, W) or uint8 RGB (n, H, W, 3), got {f.dtype} {f.shape}"
        )
    if len(f) == 0:
        raise ValueError(f"{where}: frames must hold at least one frame, got none")
    if t.shape != (len(f),) or not np.issubdtype(t.dtype, np.number) or not np.isfinite(t).all():
        raise ValueError(f"{where}: t must be {len(f)} finite times in seconds, got {t.dtype} {t.shape}")
    rec.t = t.astype(np.float64)
    if len(t) > 1 and (np.diff(rec.t) <= 0).any():
        raise ValueError(
            f"{where}: t must increase, frame {int(np.argmax(np.diff(rec.t) <= 0)) + 1} does not"
        )
    if rec.labels is not None:
        labels = np.asarray(rec.labels)
        if labels.shape != (len(f),) or not np.issubdtype(labels.dtype, np.integer):
            raise ValueError(
                f"{where}: labels must be integers of shape ({len(f)},), got {labels.dtype} {labels.shape}"
            )
        n = len(rec.class_names or ())
        if labels.max(initial=-1) >= n or labels.min(initial=-1) < -1:
            raise ValueError(f"{where}: labels must be -1 (none) or index class_names (0..{n - 1})")
        rec.labels = labels.astype(np.int64)
    return rec


def _from_explorations(
    path: Path, recording: int | None, frame_rate_hz: float | None, rest_s: float
) -> FrameRecording:
    from .formats import read_explorations

    data = read_explorations(path)
    frame_rate_hz = frame_rate_hz or data.frame_rate_hz
    if frame_rate_hz is None:
        raise ValueError(
            f"frame_rate_hz: {path} holds explorations without 't' or 'frame_rate_hz', so their frame rate is "
            "unknown; give it (frame_rate_hz=)"
        )
    x = data.frames if data.frames is not None else data.pressure
    if recording is not None:
        if not 0 <= recording < len(x):
            raise ValueError(f"recording must be in 0..{len(x) - 1} ({path}), got {recording}")
        frames = x[recording]
        labels = np.full(len(frames), int(data.labels[recording]), dtype=np.int64)
    else:
        rest = np.full(x.shape[2:], 255, np.uint8) if x.ndim == 5 else x.min(axis=(0, 1))
        n_rest = max(1, round(rest_s * frame_rate_hz))
        parts, labels = [], []
        for frames_i, label in zip(x, data.labels, strict=True):
            parts += [frames_i, np.broadcast_to(rest, (n_rest, *rest.shape))]
            labels += [int(label)] * len(frames_i) + [-1] * n_rest
        frames, labels = np.concatenate(parts), np.array(labels, dtype=np.int64)
    t = np.arange(len(frames)) / float(frame_rate_hz)
    return FrameRecording(frames, t, labels, tuple(data.class_names), str(path))


def read_frame_recording(
    path: PathLike,
    *,
    recording: int | None = None,
    frame_rate_hz: float | None = None,
    rest_s: float = DEFAULT_REST_S,
    options=None,
) -> FrameRecording:
    """Read a frame recording, image explorations played as one, or a ROS 2 bag (module notes).

    Parameters
    ----------
    path : path
    recording : int, optional
        Explorations: play only this one (default: all, with rest between them).
    frame_rate_hz : float, optional
        Explorations: frames per second (default: the file's ``frame_rate_hz``; one of them is needed).
    rest_s : float
        Explorations: seconds of rest after each one.
    options : DataOptions, optional
        Bags: ``topic``, ``shape``, ``max_messages``.

    Raises
    ------
    ValueError
        One line naming the file: not a recording, vibration data, malformed fields.
    """
    if not (frame_rate_hz is None or frame_rate_hz > 0) or not rest_s >= 0:
        raise ValueError(f"frame_rate_hz must be > 0 and rest_s >= 0, got {frame_rate_hz!r} and {rest_s!r}")
    from ..ros2.bags import is_bag

    path = Path(path)
    if is_bag(path):
        from ..ros2.bags import read_bag_topic
        from .naming import recording_names

        topic = read_bag_topic(path, options)
        if topic.kind != "frame":
            raise ValueError(
                f"{topic.name} holds {topic.msgtype}, not frames (Float32MultiArray, Image, TactileState, or a "
                "field= of numbers)"
            )
        classes = recording_names([path], index=getattr(options, "index", None)).classes
        labels = np.zeros(len(topic.values), dtype=np.int64)
        return _check(FrameRecording(topic.values, topic.stamps_s, labels, (classes[0],), topic.name))
    arrays = read_npz(path, what="frame recording (.npz of frames and t)")
    if "signals" in arrays or "features" in arrays:
        raise ValueError(f"{path} holds vibration recordings or features, not frames")
    if "frames" not in arrays:
        raise ValueError(f"{path}: expected 'frames' (and 't' for a recording), found {sorted(arrays)}")
    if "t" not in arrays:
        return _check(_from_explorations(path, recording, frame_rate_hz, float(rest_s)))
    if recording is not None:
        raise ValueError(f"recording: {path} is one frame recording (it has 't'); play it whole")
    return _from_arrays(arrays, path)


def _from_arrays(arrays: dict[str, np.ndarray], path: Path) -> FrameRecording:
    """The checked :class:`FrameRecording` of a frame recording file's arrays (``frames`` and ``t``)."""
    names = None
    if "class_names" in arrays:
        from .formats import _names

        names = _names(arrays["class_names"], path)
    rec = FrameRecording(arrays["frames"], np.asarray(arrays["t"]), arrays.get("labels"), names, str(path))
    if rec.labels is not None and names is None:
        raise ValueError(f"{path}: labels need class_names")
    return _check(rec)


@dataclass
class FrameRecordings:
    """Frame recordings read together (a hand's logs, the training data of a taxel array): what
    :func:`read_frame_recordings` and ``--data`` of frame recordings give.

    Attributes
    ----------
    recordings : list of FrameRecording
        In the order given; with per-frame ``labels`` that index ``class_names`` (the files' own, merged),
        or none.
    class_names : tuple of str
    file_labels : ndarray of shape (R,) int64, or None
        Each recording's class (index into ``class_names``) when the files carry no per-frame labels:
        from the files' layout (their names, folders, or an index CSV).
    session : ndarray of shape (R,) str
        Each recording's session (what held-out splits keep on one side).
    """

    recordings: list[FrameRecording]
    class_names: tuple[str, ...]
    file_labels: np.ndarray | None
    session: np.ndarray
    kind = "frame recording"

    def __len__(self) -> int:
        return len(self.recordings)


def labelled_recordings(paths) -> bool:
    """Whether every path is a frame recording ``.npz`` that labels its frames (``t`` and ``labels``), from the
    archives' member names (nothing is read)."""
    import zipfile

    try:
        for path in paths:
            with zipfile.ZipFile(path) as archive:
                if not {"frames.npy", "t.npy", "labels.npy"} <= set(archive.namelist()):
                    return False
    except (OSError, zipfile.BadZipFile):
        return False
    return bool(paths)


def recordings_layout(paths, options=None, *, labelled: bool):
    """Return the classes and sessions frame recordings get from their files (:class:`~.naming.RecordingNames`).

    Files that label their frames take only their sessions from the layout: their folder when they lie in
    several, else their name (``session_from`` or an index to say otherwise); the others take their class
    and session as any recording file (:func:`~.naming.recording_names`).
    """
    from .naming import FRAME_LABELS, RecordingNames, folder_names, recording_names

    index, class_from, session_from = (
        getattr(options, k, None) for k in ("index", "class_from", "session_from")
    )
    if not labelled:
        return recording_names(paths, index=index, class_from=class_from, session_from=session_from)
    several = folder_names(paths) is not None
    names = recording_names(
        paths,
        index=index,
        class_from=None if index else "file",
        session_from=None if index else session_from or ("folder" if several else "file"),
    )
    return RecordingNames(
        ("(their frames' labels)",) * len(paths),
        names.sessions,
        FRAME_LABELS,
        "the labels give the classes; "
        + ("the folders" if several and not index else "the index" if index else "the file names")
        + " the sessions",
    )


def read_frame_recordings(paths, options=None, *, arrays: list | None = None) -> FrameRecordings:
    """Read frame recording ``.npz`` files (``frames`` and ``t``) for training; return :class:`FrameRecordings`.

    Files that label their frames (``labels``, ``class_names``) keep them, their class names merged; files
    that do not get one class each, and every file a session, from the files' layout with ``options``'
    ``index``, ``class_from`` and ``session_from`` (:func:`tactile_torch.robot.files.naming.recording_names`;
    the sessions of labelled files from their folders, else their names). ``arrays``: the files' arrays
    when already read.

    Raises
    ------
    ValueError
        One line naming the file: not a frame recording, malformed fields, frames of different shapes,
        some files labelled and others not.
    """
    from .naming import check_class_names

    paths = [Path(p) for p in paths]
    arrays = arrays or [read_npz(p, what="frame recording (.npz of frames and t)") for p in paths]
    for path, a in zip(paths, arrays, strict=True):
        if "frames" not in a or "t" not in a:
            raise ValueError(
                f"{path}: a frame recording needs 'frames' and 't' (docs/formats.md), found {sorted(a)}"
            )
    recs = [_from_arrays(a, p) for a, p in zip(arrays, paths, strict=True)]
    shapes = {r.frames.shape[1:] for r in recs}
    if len(shapes) > 1:
        raise ValueError(
            f"the recordings hold frames of different shapes ({sorted(shapes)}); give those of one sensor"
        )
    labelled = [r.labels is not None for r in recs]
    if any(labelled) and not all(labelled):
        odd = paths[labelled.index(not labelled[0])]
        raise ValueError(
            f"{odd}: the frame recordings must all label their frames (labels, class_names) or none"
        )
    names = recordings_layout(paths, options, labelled=all(labelled))
    if all(labelled):
        classes = check_class_names(
            sorted({c for r in recs for c in r.class_names}), "class names (of the recordings)"
        )
        for r in recs:
            lookup = np.array([classes.index(c) for c in r.class_names] + [-1], dtype=np.int64)
            r.labels, r.class_names = lookup[r.labels], classes
        return FrameRecordings(recs, classes, None, np.array(names.sessions))
    classes = check_class_names(sorted(set(names.classes)), "class names (of the recordings)")
    file_labels = np.array([classes.index(c) for c in names.classes], dtype=np.int64)
    return FrameRecordings(recs, classes, file_labels, np.array(names.sessions))


def write_frame_recording(path: PathLike, recording: FrameRecording) -> Path:
    """Write ``recording`` as a frame recording ``.npz`` (module notes); return the path."""
    _check(recording)
    arrays = {"frames": recording.frames, "t": recording.t}
    if recording.labels is not None:
        arrays["labels"] = recording.labels
        arrays["class_names"] = np.array(recording.class_names or ())
    return write_npz(path, arrays)


def touch_labels(recording: FrameRecording, start: int, frames: int) -> int:
    """Return the class of frames ``start .. start + frames - 1``: their most frequent label (-1 if none)."""
    if recording.labels is None:
        return -1
    part = recording.labels[start : start + frames]
    part = part[part >= 0]
    if not len(part):
        return -1
    return int(np.bincount(part).argmax())


__all__ = [
    "DEFAULT_REST_S",
    "FrameRecording",
    "FrameRecordings",
    "labelled_recordings",
    "read_frame_recording",
    "read_frame_recordings",
    "recordings_layout",
    "touch_labels",
    "write_frame_recording",
]
