"""The features of a data file: what ``tactile-torch train`` and the trade-off's feature files learn from.

:func:`load_features` reads a data file of ``docs/formats.md`` through :mod:`tactile_torch.robot.files.formats`
(image explorations: ``frames``; a hand's frame recordings: ``frames`` and ``t``, cut into touches by the
live stream's own stages, :mod:`tactile_torch.robot.stream.recorded_touches`; vibration recordings:
``signals`` or CSV logs; a ready ``features`` matrix) and computes its features (the image features
:func:`tactile_torch.image.exploration_features`, fused or per frame; the per-taxel time-series features
:class:`~tactile_torch.features.transformers.TaxelFeatures`; windows and
:func:`tactile_torch.signal.window_features`) as a :class:`FeatureSet`, with what held-out splits need
(groups, recordings, positions) and what the live stream needs (frame rate, touch levels, value range).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

FRAME_FEATURES = ("fused", "per-frame", "per-taxel")
"""Feature sets of frames (explorations and touches): the 12 image features of the fused edges, 12 per frame,
or the 7 time-series features of every taxel (the trade-off's winners on small taxel arrays)."""


@dataclass
class FeatureSet:
    """Features of one data file.

    Attributes
    ----------
    X : ndarray of shape (N, F), float64
    y : ndarray of shape (N,), int64
        Class index of each row.
    class_names : tuple of str
    source : dict
        How the features were made (``kind`` = ``"image"``, ``"vibration"`` or ``"features"``, plus
        the window size, step and sample rate, or the fusion flag and the frame shape ``(T, 3, H, W)``,
        or the number of features).
    groups : ndarray of shape (N,), optional
        What must stay on one side of a held-out split: each window's recording session (the file's
        ``session``, else its recording), or an exploration's ``groups``; ``None``: independent rows.
    recording, position : ndarray of shape (N,), optional
        Vibration windows: the recording each comes from and its index in it (time order).
    raw : ndarray, optional
        Frames: the explorations (or touches) the features were made from, ``(N, T, H, W)`` pressure or
        ``(N, T, H, W, 3)`` RGB, for the early-decision rule's prefixes of each touch.
    notes : list of str
        What was decided on the way (the touches cut from recordings, the frame rate), one line each.
    group_label : str
        What ``groups`` are, in words (``"session"`` for the touches of a hand's recordings).
    """

    X: np.ndarray
    y: np.ndarray
    class_names: tuple[str, ...]
    source: dict = field(default_factory=dict)
    groups: np.ndarray | None = None
    recording: np.ndarray | None = None
    position: np.ndarray | None = None
    raw: np.ndarray | None = field(default=None, repr=False)
    notes: list[str] = field(default_factory=list)
    group_label: str = "the file's groups"


def load_features(
    path,
    *,
    window: int = 800,
    step: int | None = None,
    features: str | None = None,
    frame_rate_hz: float | None = None,
    allow_pickle: bool = False,
    options=None,
    name: str | None = None,
) -> FeatureSet:
    """Read a data file (:func:`tactile_torch.robot.files.data_sources.read_source`) and return its features.

    Parameters
    ----------
    path : path, sequence of paths, or arrays already read
        Image explorations (``frames``), vibration recordings (``signals``) or a feature matrix
        (``features``) in one ``.npz``, each with ``labels`` (and ``class_names``); CSV logs
        (one recording each); ROS 2 bags. Class and session of logs and bags come from the naming
        rule (``felt_3.csv``: class ``felt``, session ``3``) or an index. See ``docs/formats.md``.
        Or what :func:`~tactile_torch.robot.files.data_sources.read_source` returned.
    window, step : int
        Vibration windows: length and hop in samples (default hop: ``window``, no overlap).
    features : {"fused", "per-frame", "per-taxel"}, optional
        Frames: the feature set (:data:`FRAME_FEATURES`). Default: per-taxel for pressure maps of at most
        :data:`~tactile_torch.features.transformers.MAX_TAXELS` taxels (a hand's array), else fused.
    frame_rate_hz : float, optional
        Explorations: frames per second, for the live stream (default: the file's ``frame_rate_hz``; frame
        recordings: from ``t``). Without one the model records none (the stream then needs ``--onset``).
    allow_pickle : bool
        Only for vibration files written by tactile-torch 0.1 with recordings of different lengths
        (a pickled object array): allow it only for files you trust.
    options : DataOptions, optional
        Columns, units, time unit, topic ... (:class:`tactile_torch.robot.files.data_sources.DataOptions`).
    name : str, optional
        How messages name the data (default: the file, or ``"data"`` for arrays already read).

    Returns
    -------
    FeatureSet
        With ``groups`` (and, for windows, ``recording`` and ``position``) for held-out splits.

    Raises
    ------
    FileNotFoundError, ValueError
        One line naming the file and the field (see :mod:`tactile_torch.robot.files.formats`), or the
        recording and sample that the declared units make implausible; labels are required here.
    """
    from ..robot.files.formats import data_name

    if hasattr(path, "kind"):
        data, where = path, name or "data"
    else:
        from ..robot.files.data_sources import DataOptions, read_source

        data = read_source(path, options or DataOptions(allow_pickle=allow_pickle))
        where = name or data_name(path)
    if data.kind == "features":
        if data.labels is None:
            raise ValueError(f"{where}: missing 'labels'; training needs labels (N,) next to 'features'")
        source = {"kind": "features", "n_features": data.features.shape[1]}
        return FeatureSet(data.features, data.labels, data.class_names, source)
    if data.kind in ("image", "frame recording"):
        return _frame_features(data, features, frame_rate_hz, options, where)
    import torch

    from ..robot.stream.windows import check_window, window_recordings
    from ..signal import window_features

    window = check_window(window)
    gaps = getattr(data, "gaps", None)
    _check_lengths(data, window, where)
    try:
        cut = window_recordings(data.signals, window, step, gaps=gaps)
    except ValueError as err:
        raise ValueError(f"{where}: {err}; pass a smaller window (window=)") from None
    X = window_features(torch.from_numpy(cut.windows)).double().numpy()
    overflow = ~np.isfinite(X).all(axis=1)
    if overflow.any():  # e.g. a corrupted 1e30 sample: say so, rather than "X must be finite" later
        first = int(np.argmax(overflow))
        peak = float(np.abs(cut.windows[first]).max())
        raise ValueError(
            f"{where}: {int(overflow.sum())} window(s) hold samples out of range (window {first} of recording "
            f"{int(cut.recording[first])} reaches {peak:.3g} g), whose features overflow; remove or clip them"
        )
    source = {"kind": "vibration", "window": window, "step": step or window, "rate_hz": data.rate_hz}
    return FeatureSet(
        X,
        data.labels[cut.recording],
        data.class_names,
        source,
        groups=None if data.session is None else np.asarray(data.session)[cut.recording],
        recording=cut.recording,
        position=cut.position,
    )


def _check_lengths(data, window: int, where: str) -> None:
    """Refuse a class none of whose recordings (or stretches between gaps) holds a window; warn about
    recordings that give none (they are left out)."""
    import warnings
    from itertools import pairwise

    gaps = getattr(data, "gaps", None)
    longest = []
    for i, signal in enumerate(data.signals):
        bounds = [0, *(() if gaps is None else gaps[i].tolist()), len(signal)]
        longest.append(max(b - a for a, b in pairwise(bounds)))
    longest = np.array(longest)
    short = np.flatnonzero(longest < window)
    if not short.size:
        return
    files = getattr(data, "sources", None)

    def name(i: int) -> str:
        what = f"recording {i}" if files is None else files[i].removeprefix(f"{where}: ")
        between = " between gaps" if gaps is not None and len(gaps[i]) else ""
        return f"{what}, has {longest[i]} samples{between}"

    labels = np.asarray(data.labels)
    for c, class_name in enumerate(data.class_names):
        mine = np.flatnonzero(labels == c)
        if mine.size and (longest[mine] < window).all():
            i = int(mine[np.argmax(longest[mine])])
            raise ValueError(
                f"{where}: every recording of class {class_name!r} is shorter than one window of {window} samples "
                f"({window / data.rate_hz:.3g} s at {data.rate_hz:g} Hz); the longest, {name(i)}: pass a smaller "
                "window (window=) or longer recordings"
            )
    warnings.warn(
        f"{where}: {short.size} of {len(longest)} recordings are shorter than one window of {window} samples "
        f"and give none; e.g. {name(int(short[0]))}",
        stacklevel=3,
    )


def frame_features(raw: np.ndarray, features: str) -> np.ndarray:
    """Return the features ``(N, F)`` float64 of frames ``raw``: pressure maps ``(N, T, H, W)`` or RGB ``(N, T, H, W, 3)``.

    ``features`` (:data:`FRAME_FEATURES`): ``"per-taxel"`` (:class:`~tactile_torch.features.transformers.TaxelFeatures`),
    ``"fused"`` or ``"per-frame"`` (:func:`tactile_torch.image.exploration_features` of the frames as the
    display shows them: pressure maps rendered by :func:`tactile_torch.data.images.render_pressure`). What
    :func:`load_features` computes, and ``train``'s early rule on the first frames of each touch.
    """
    import torch

    rgb = raw.ndim == 5
    with torch.no_grad():
        if features == "per-taxel":
            from .transformers import TaxelFeatures

            x = torch.from_numpy(np.ascontiguousarray(raw.transpose(0, 1, 4, 2, 3)) if rgb else raw)
            return TaxelFeatures(rgb)(x).double().numpy()
        from ..data.images import render_pressure
        from ..image import exploration_features

        if rgb:
            frames = torch.from_numpy(np.ascontiguousarray(raw.transpose(0, 1, 4, 2, 3)))
        else:
            frames = render_pressure(torch.from_numpy(np.ascontiguousarray(raw, dtype=np.float32)))
        return exploration_features(frames, fuse=features == "fused").double().numpy()


def _frame_features(
    data, features: str | None, frame_rate_hz: float | None, options, where: str
) -> FeatureSet:
    """The features of explorations or of frame recordings' touches, and the live stream's part of the source."""
    from ..robot.stream.touches import frame_metadata
    from .transformers import MAX_TAXELS

    notes, levels, unit = [], None, "the file's groups"
    if data.kind == "frame recording":
        from ..robot.stream.recorded_touches import recorded_touches

        touches = recorded_touches(data, n_frames=getattr(options, "frames", None))
        data, levels, notes, unit = touches.explorations, touches.levels, list(touches.notes), "session"
    rgb = data.frames is not None
    raw = data.frames if rgb else data.pressure
    taxels = raw.shape[2] * raw.shape[3]
    features = features or (
        "per-taxel" if not rgb and taxels <= MAX_TAXELS and raw.shape[1] >= 2 else "fused"
    )
    if features not in FRAME_FEATURES:
        raise ValueError(f"features must be one of {FRAME_FEATURES}, got {features!r}")
    if features == "per-taxel" and (taxels > MAX_TAXELS or raw.shape[1] < 2):
        raise ValueError(
            f"features: per-taxel features need frames of at most {MAX_TAXELS} taxels and T >= 2 frames, got "
            f"{raw.shape[1]} frames of {raw.shape[2]} x {raw.shape[3]} ({where})"
        )
    rate = frame_rate_hz or data.frame_rate_hz
    X = frame_features(raw, features)
    if features == "per-taxel":
        shape = [int(raw.shape[1]), 3, *raw.shape[2:4]] if rgb else [int(s) for s in raw.shape[1:]]
        source = {"kind": "image" if rgb else "pressure", "features": "per-taxel", "frame_shape": shape}
        if rgb:
            source["fuse"] = True  # read by older tools; the per-taxel features ignore it
        live, note = frame_metadata(raw, frame_rate_hz=rate, rgb=rgb, levels=levels)
    else:  # the image pipeline (pressure maps rendered as the display shows them)
        from ..data.images import explorations_from_arrays

        frames = explorations_from_arrays(data).frames
        source = {"kind": "image", "fuse": features == "fused", "frame_shape": list(frames.shape[1:])}
        live, note = frame_metadata(frames.numpy(), frame_rate_hz=rate, rgb=True, levels=levels)
        live.pop("value_range", None)  # RGB frames are 0-255 by their type
    source.update(live)
    if rate is None:
        notes.append(
            "no frame rate (the explorations state none: frame_rate_hz=): the model records none, so the live "
            "stream's shortest touch is 2 frames"
        )
    notes += [note] if note else []
    return FeatureSet(
        X, data.labels, data.class_names, source, groups=data.groups, raw=raw, notes=notes, group_label=unit
    )


__all__ = ["FRAME_FEATURES", "FeatureSet", "frame_features", "load_features"]
