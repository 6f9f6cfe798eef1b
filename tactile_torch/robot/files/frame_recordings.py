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

:func:`write_frame_recording` writes the first form. numpy only (bags need the ``ros`` extra).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .npz import PathLike, read_npz, write_npz

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
        """Frames per second: one over the median step of ``t``."""
        if len(self.t) < 2:
            return float("nan")
        return float(1.0 / np.median(np.diff(self.t)))

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


def _from_explorations(path: Path, recording: int | None, rate_hz: float, rest_s: float) -> FrameRecording:
    from .formats import read_explorations

    data = read_explorations(path)
    x = data.frames if data.frames is not None else data.pressure
    if recording is not None:
        if not 0 <= recording < len(x):
            raise ValueError(f"recording must be in 0..{len(x) - 1} ({path}), got {recording}")
        frames = x[recording]
        labels = np.full(len(frames), int(data.labels[recording]), dtype=np.int64)
    else:
        rest = np.full(x.shape[2:], 255, np.uint8) if x.ndim == 5 else x.min(axis=(0, 1))
        n_rest = max(1, round(rest_s * rate_hz))
        parts, labels = [], []
        for frames_i, label in zip(x, data.labels, strict=True):
            parts += [frames_i, np.broadcast_to(rest, (n_rest, *rest.shape))]
            labels += [int(label)] * len(frames_i) + [-1] * n_rest
        frames, labels = np.concatenate(parts), np.array(labels, dtype=np.int64)
    t = np.arange(len(frames)) / float(rate_hz)
    return FrameRecording(frames, t, labels, tuple(data.class_names), str(path))


def read_frame_recording(
    path: PathLike,
    *,
    recording: int | None = None,
    rate_hz: float = 10.0,
    rest_s: float = DEFAULT_REST_S,
    options=None,
) -> FrameRecording:
    """Read a frame recording, image explorations played as one, or a ROS 2 bag (module notes).

    Parameters
    ----------
    path : path
    recording : int, optional
        Explorations: play only this one (default: all, with rest between them).
    rate_hz : float
        Explorations: frames per second (default 10, the study's).
    rest_s : float
        Explorations: seconds of rest after each one.
    options : DataOptions, optional
        Bags: ``topic``, ``shape``, ``max_messages``.

    Raises
    ------
    ValueError
        One line naming the file: not a recording, vibration data, malformed fields.
    """
    if not rate_hz > 0 or not rest_s >= 0:
        raise ValueError(f"rate_hz must be > 0 and rest_s >= 0, got {rate_hz!r} and {rest_s!r}")
    from ..ros2.bags import is_bag

    path = Path(path)
    if is_bag(path):
        from .data_sources import DataOptions, read_bag_topic
        from .naming import names_for

        options = options or DataOptions()
        topic = read_bag_topic(path, options)
        if topic.kind != "frame":
            raise ValueError(
                f"{topic.name} holds {topic.msgtype}, not frames (Float32MultiArray, Image, TactileState, or a "
                "field= of numbers)"
            )
        classes, _ = names_for([path], index=getattr(options, "index", None))
        labels = np.zeros(len(topic.values), dtype=np.int64)
        return _check(FrameRecording(topic.values, topic.stamps_s, labels, (classes[0],), topic.name))
    arrays = read_npz(path, what="frame recording (.npz of frames and t)")
    if "signals" in arrays or "features" in arrays:
        raise ValueError(f"{path} holds vibration recordings or features, not frames")
    if "frames" not in arrays:
        raise ValueError(f"{path}: expected 'frames' (and 't' for a recording), found {sorted(arrays)}")
    if "t" not in arrays:
        return _check(_from_explorations(path, recording, float(rate_hz), float(rest_s)))
    if recording is not None:
        raise ValueError(f"recording: {path} is one frame recording (it has 't'); play it whole")
    names = None
    if "class_names" in arrays:
        from .formats import _names

        names = _names(arrays["class_names"], path)
    rec = FrameRecording(arrays["frames"], np.asarray(arrays["t"]), arrays.get("labels"), names, str(path))
    if rec.labels is not None and names is None:
        raise ValueError(f"{path}: labels need class_names")
    return _check(rec)


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
    "read_frame_recording",
    "touch_labels",
    "write_frame_recording",
]
