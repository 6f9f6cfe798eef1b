"""The data of a trade-off study: one data file read through the package's loaders, cut into the raw
inputs the candidates take, with cross-validation folds that never put related samples on both sides.

Folds (every candidate of one raw input sees the same folds; made by :mod:`tactile_torch.model_selection`,
whose :func:`~tactile_torch.model_selection.sample_folds`, :func:`~tactile_torch.model_selection.window_folds`,
and :func:`~tactile_torch.model_selection.fold_units`):

* **Vibration windows** (non-overlapping, ``step = W``). When every class has at least two
  recordings (or sessions, when the file gives ``session``), folds are grouped by recording
  (scikit-learn's ``StratifiedGroupKFold``): a recording's windows are all on one side. Otherwise
  (e.g. one recording per surface) every recording is cut into ``n_folds`` consecutive time blocks,
  fold ``b`` tests block ``b`` of every recording, and the first window of every block but the first
  is dropped, so that no two neighbouring windows of a recording are on different sides.
* **Explorations and feature rows**: grouped by ``groups`` (object, subject, session) when the file
  has them and every class has at least two groups; stratified folds otherwise.

There are ``min(n_folds, smallest class count)`` folds (counted in groups or time blocks), at least
2; fewer raise ``ValueError`` naming the class.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..model_selection import cap_per_class, fold_units, group_ids, sample_folds, window_folds
from ..robot.contract import FEATURES_LAYOUT, FRAMES_LAYOUT, PRESSURE_LAYOUT, WINDOWS_LAYOUT
from ..validation import RandomState

WINDOW_SIZES = (200, 400, 800, 1600)
"""Window sizes the study tries (those the recordings allow), in samples."""

Fold = tuple[np.ndarray, np.ndarray]


@dataclass
class Samples:
    """One raw input of the study: what a candidate's ``features`` step takes, with labels and folds.

    Attributes
    ----------
    key : str
        ``"windows-<W>"``, ``"frames"``, ``"pressure"`` or ``"features"``.
    X : ndarray
        Raw input: windows ``(N, 3, W)`` float32, frames ``(N, T, 3, H, W)`` uint8, pressure maps
        ``(N, T, H, W)`` float32 or features ``(N, F)`` float64.
    y : ndarray of shape (N,), int64
    folds : list of (train, test) index arrays
    layout : str
        Names of the input dimensions (``"B,3,W"`` ...).
    acquisition_s : float
        Seconds of sensor data one sample needs (``W / rate``, ``T / frame rate``; 0 for features).
    split : str
        How the folds were made, in words.
    window : int or None
    index : ndarray or None
        Explorations and feature rows: the rows of the file kept (``max_per_class``).
    groups : ndarray or None
        What the folds keep on one side: recording (or session), a recording's time block, or the
        file's ``groups``; ``None`` for plain stratified folds. For further grouped sweeps of the same
        samples (e.g. breaking points).
    units : ndarray of shape (N,) or None
        The unit of the accuracy interval of each sample (:mod:`.selection`): its session or
        recording, the file's group, the time block (one recording per class), or the test fold
        (no groups at all).
    unit : str
        What a unit is, in words (``"session"``, ``"recording"``, ``"group"``, ``"time block"``, ``"fold"``).
    unit_names : tuple of str or None
        The name of each unit id, as the data name it (``"day1"``: a session of the file; ``"time block
        2"``, ``"fold 3"`` otherwise); see :meth:`unit_name`.
    """

    key: str
    X: np.ndarray
    y: np.ndarray
    folds: list[Fold]
    layout: str
    acquisition_s: float
    split: str
    window: int | None = None
    index: np.ndarray | None = None
    groups: np.ndarray | None = None
    units: np.ndarray | None = None
    unit: str = "fold"
    unit_names: tuple[str, ...] | None = None

    def unit_name(self, unit: int) -> str:
        """Return the name of unit id ``unit`` (the data's own name of a session or group, if it has one)."""
        if self.unit_names is not None and 0 <= int(unit) < len(self.unit_names):
            return self.unit_names[int(unit)]
        return f"{self.unit} {int(unit) + 1}"


def _names_of(values: np.ndarray) -> tuple[str, ...]:
    """The names of the ids :func:`group_ids` gives ``values``, in id order."""
    return tuple(str(v) for v in np.unique(np.asarray(values).astype(str)))


@dataclass
class TradeoffData:
    """A data file read for the trade-off study.

    Attributes
    ----------
    kind : {"vibration", "image", "pressure", "features"}
    class_names : tuple of str
    description : str
    recordings : RecordingArrays, VibrationRecordings or None
        Anything with ``signals``, ``labels``, ``class_names``, ``rate_hz`` and ``session``.
    raw : ndarray or None
        Frames, pressure maps or features (not vibration).
    labels, groups : ndarray or None
    rate_hz : float or None
        Sample rate (vibration) or frame rate (explorations).
    notes : list of str
        What the loader decided (e.g. the frame rate it assumed).
    precomputed : dict of str to (ndarray, float)
        Features of every sample already computed elsewhere, by feature-set name (e.g. ``"fused 12"``),
        with the seconds they took; used instead of computing them again (stateless steps only).
    touch_levels : TouchLevels or None
        Frame recordings: the levels their touches were cut at, which the deployed bundle records so that
        the live stream cuts the touches the study saw (:mod:`tactile_torch.robot.stream.recorded_touches`).
    """

    kind: str
    class_names: tuple[str, ...]
    description: str
    recordings: object | None = None
    raw: np.ndarray | None = None
    labels: np.ndarray | None = None
    groups: np.ndarray | None = None
    rate_hz: float | None = None
    notes: list[str] = field(default_factory=list)
    precomputed: dict[str, tuple[np.ndarray, float]] = field(default_factory=dict)
    touch_levels: object | None = None


def load_tradeoff_data(
    paths,
    *,
    frame_rate_hz: float | None = None,
    allow_pickle: bool = False,
    options=None,
    name: str | None = None,
) -> TradeoffData:
    """Read a data file (or CSV logs, ROS 2 bags) for :func:`~tactile_torch.tradeoff.run_tradeoff`, with
    :func:`tactile_torch.robot.files.data_sources.read_source` (docs/formats.md).

    Parameters
    ----------
    paths : path, sequence of paths, or arrays already read
        One ``.npz`` (image explorations ``frames``, raw pressure maps ``frames`` ``(N, T, H, W)``
        float, vibration recordings ``signals`` or a ``features`` matrix with ``labels``), vibration
        CSV logs ``t,x,y,z`` or ROS 2 bags (one recording per file, class and session from the file
        name: ``felt_3.csv`` → ``felt``, session ``3``); or what ``read_source`` returned.
    frame_rate_hz : float, optional
        Frames per second of explorations (default: the file's ``frame_rate_hz``; a file that states none
        needs it: the rate is never assumed). Frame recordings: from their ``t``.
    allow_pickle : bool
        Legacy vibration files that pickled recordings of different lengths (trusted files only).
    options : DataOptions, optional
        Columns, units, time unit, topic ... (:class:`tactile_torch.robot.files.data_sources.DataOptions`).
    name : str, optional
        How the description names the data (default: the file).

    Raises
    ------
    ValueError
        For an unknown file kind, a missing key or labels (one line naming the file).
    FileNotFoundError
        If a path does not exist.
    """
    from ..robot.files.formats import data_name

    if frame_rate_hz is not None and (
        isinstance(frame_rate_hz, bool)
        or not isinstance(frame_rate_hz, int | float | np.number)
        or not np.isfinite(frame_rate_hz)
        or frame_rate_hz <= 0
    ):
        raise ValueError(f"frame_rate_hz must be a finite number of frames/s > 0, got {frame_rate_hz!r}")
    if hasattr(paths, "kind"):
        data, where = paths, name or "data"
    else:
        from ..robot.files.data_sources import DataOptions, read_source

        data = read_source(paths, options or DataOptions(allow_pickle=allow_pickle))
        where = name or data_name(paths)
    name = Path(where).name
    if data.kind == "vibration":
        return vibration_data(data, name)
    notes, levels, what = [], None, "explorations"
    if data.kind == "frame recording":  # a hand's logs: the touches the live stream cuts from them
        from ..robot.stream.recorded_touches import recorded_touches

        touches = recorded_touches(data, n_frames=getattr(options, "frames", None))
        data, levels, notes, what = touches.explorations, touches.levels, list(touches.notes), "touches"
    if data.kind == "image":
        frame_rate_hz = frame_rate_hz or data.frame_rate_hz
        if frame_rate_hz is None:  # never assumed: the touch times, the shortest touch and the stream need it
            raise ValueError(
                f"frame_rate_hz: {where} holds explorations without 't' or 'frame_rate_hz', so their frame rate is "
                "unknown; give it (frame_rate_hz=)"
            )
        kind = "pressure" if data.frames is None else "image"
        raw = (
            data.pressure
            if kind == "pressure"
            else np.ascontiguousarray(data.frames.transpose(0, 1, 4, 2, 3))
        )
        pixels = "taxels (raw pressure maps)" if kind == "pressure" else "pixels (RGB)"
        return TradeoffData(
            kind=kind,
            class_names=tuple(data.class_names),
            description=f"{name}: {len(data)} {what} of {raw.shape[1]} frames of "
            f"{raw.shape[-2]} x {raw.shape[-1]} {pixels} at {frame_rate_hz:g} frames/s",
            raw=raw,
            labels=data.labels,
            groups=data.groups,
            rate_hz=float(frame_rate_hz),
            notes=notes,
            touch_levels=levels,
        )
    if data.labels is None:
        raise ValueError(f"{where}: a feature file needs 'labels' next to 'features' to compare models")
    return TradeoffData(
        kind="features",
        class_names=tuple(data.class_names),
        description=f"{name}: {data.features.shape[0]} samples x {data.features.shape[1]} features",
        raw=data.features,
        labels=data.labels,
        groups=getattr(data, "groups", None),
    )


def vibration_data(recordings: object, name: str) -> TradeoffData:
    """Wrap recordings (``signals``, ``labels``, ``class_names``, ``rate_hz``, ``session``) for the study."""
    lengths = [len(s) for s in recordings.signals]
    return TradeoffData(
        kind="vibration",
        class_names=tuple(recordings.class_names),
        description=f"{name}: {len(recordings.signals)} recordings of {min(lengths)}-{max(lengths)} samples at "
        f"{recordings.rate_hz:g} Hz, {len(recordings.class_names)} classes",
        recordings=recordings,
        rate_hz=float(recordings.rate_hz),
    )


def vibration_samples(
    recordings: object,
    window: int,
    *,
    n_folds: int,
    max_per_class: int | None = None,
    random_state: RandomState = None,
) -> Samples:
    """Cut ``recordings`` into non-overlapping windows of ``window`` samples with folds (module notes).

    Raises
    ------
    ValueError
        If ``window`` is longer than the recordings of a class, or leaves too few windows for the folds.
    """
    names = recordings.class_names
    lengths = np.array([len(s) for s in recordings.signals])
    for c, name in enumerate(names):
        longest = lengths[recordings.labels == c].max(initial=0)
        if longest < window:
            raise ValueError(
                f"window: {window} samples is longer than every recording of class {name!r} (longest "
                f"{longest} samples = {longest / recordings.rate_hz:g} s at {recordings.rate_hz:g} Hz); "
                "choose a shorter window (window=)"
            )
    from ..robot.stream.windows import window_recordings

    ds = window_recordings(recordings.signals, window, gaps=getattr(recordings, "gaps", None))
    X, recording, position = ds.windows, ds.recording, ds.position
    y = np.asarray(recordings.labels)[recording]
    rate = float(recordings.rate_hz)
    session = recordings.session if recordings.session is not None else np.arange(len(recordings))
    unit = "session" if recordings.session is not None else "recording"
    by_session = group_ids(np.asarray(session))[recording]
    grouped = all(len(np.unique(by_session[y == c])) >= 2 for c in np.unique(y))
    group, keep, folds, split = window_folds(
        recording,
        position,
        y,
        session,
        group_label=unit,
        n_folds=n_folds,
        names=names,
        window=window,
        max_per_class=max_per_class,
        random_state=random_state,
    )
    split = f"{len(keep)} windows; {split}"
    X, y, group = X[keep], y[keep], group[keep]
    if grouped:  # grouped by session (or recording): each is a unit
        units, unit_names = group, _names_of(session)
    else:  # time blocks: block b of every recording is one unit (it is fold b's test set)
        unit, units, unit_names = "time block", fold_units(folds, len(y)), None
    return Samples(
        f"windows-{window}",
        X,
        y,
        folds,
        WINDOWS_LAYOUT,
        window / rate,
        split,
        window,
        groups=group,
        units=units,
        unit=unit,
        unit_names=unit_names,
    )


def allowed_windows(
    recordings: object, candidates: Sequence[int], *, n_folds: int
) -> tuple[list[int], list[str]]:
    """Return the window sizes of ``candidates`` that leave enough windows for the folds, and why others do not."""
    allowed, reasons = [], []
    for w in sorted(set(int(c) for c in candidates)):
        try:
            vibration_samples(recordings, w, n_folds=n_folds, max_per_class=2 * n_folds)
        except ValueError as err:
            reasons.append(f"W = {w} left out: {err}")
            continue
        allowed.append(w)
    return allowed, reasons


def exploration_samples(
    data: TradeoffData, *, n_folds: int, max_per_class: int | None = None, random_state: RandomState = None
) -> Samples:
    """The explorations (frames or pressure maps) or feature rows of ``data`` with their folds."""
    keep = cap_per_class(data.labels, max_per_class)
    X, y = data.raw[keep], data.labels[keep]
    groups = None if data.groups is None else data.groups[keep]
    what = "samples" if data.kind == "features" else "explorations"
    folds, split = sample_folds(
        y, groups, n_folds=n_folds, names=data.class_names, what=what, random_state=random_state
    )
    layout = {"image": FRAMES_LAYOUT, "pressure": PRESSURE_LAYOUT, "features": FEATURES_LAYOUT}[data.kind]
    key = {"image": "frames", "pressure": "pressure", "features": "features"}[data.kind]
    acquisition = 0.0 if data.kind == "features" else X.shape[1] / float(data.rate_hz)
    grouped = groups is not None and "grouped" in split
    units = group_ids(groups) if grouped else fold_units(folds, len(y))
    split = f"{len(keep)} {what}; {split}"
    return Samples(
        key,
        X,
        y,
        folds,
        layout,
        acquisition,
        split,
        index=keep,
        groups=groups,
        units=units,
        unit="group" if grouped else "fold",
        unit_names=_names_of(groups) if grouped else None,
    )


__all__ = [
    "WINDOW_SIZES",
    "Samples",
    "TradeoffData",
    "allowed_windows",
    "exploration_samples",
    "load_tradeoff_data",
    "vibration_data",
    "vibration_samples",
]
