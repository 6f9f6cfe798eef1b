"""The features of a data file: what ``tactile-torch train`` and the trade-off's feature files learn from.

:func:`load_features` reads a data file of ``docs/formats.md`` through :mod:`tactile_torch.robot.files.formats`
(image explorations: ``frames``; vibration recordings: ``signals`` or CSV logs; a ready ``features``
matrix) and computes its features (:func:`tactile_torch.image.exploration_features`, or windows and
:func:`tactile_torch.signal.window_features`) as a :class:`FeatureSet`, with what held-out splits need
(groups, recordings, positions).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


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
    """

    X: np.ndarray
    y: np.ndarray
    class_names: tuple[str, ...]
    source: dict = field(default_factory=dict)
    groups: np.ndarray | None = None
    recording: np.ndarray | None = None
    position: np.ndarray | None = None


def load_features(
    path,
    *,
    window: int = 800,
    step: int | None = None,
    fuse: bool = True,
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
    fuse : bool
        Image explorations: fused (12) or per-frame (T x 12) features.
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
    if data.kind == "image":
        from ..data.images import explorations_from_arrays
        from ..image import exploration_features

        images = explorations_from_arrays(data)
        X = exploration_features(images.frames, fuse=fuse).double().numpy()
        source = {"kind": "image", "fuse": fuse, "frame_shape": list(images.frames.shape[1:])}
        source.update(_live_source(images.frames.numpy()))
        return FeatureSet(X, data.labels, data.class_names, source, groups=data.groups)
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


def _live_source(frames: np.ndarray) -> dict:
    """What a model file of RGB explorations keeps for the live stream: the frame rate and touch levels."""
    from ..image import DEFAULT_FRAME_RATE_HZ
    from ..robot.stream.touches import touch_levels

    live = {"frame_rate_hz": DEFAULT_FRAME_RATE_HZ}
    try:
        live["touch_levels"] = touch_levels(
            frames, frame_rate_hz=DEFAULT_FRAME_RATE_HZ, rgb=True
        ).to_metadata()
    except ValueError:  # no pressure in the frames at all: the stream will need --onset
        pass
    return live


__all__ = ["FeatureSet", "load_features"]
