"""Read and write every data file of tactile-torch with NumPy only (importable on the robot, no torch).

One home for the data formats (``docs/formats.md``); the loaders of :mod:`tactile_torch.data`, the
training (:func:`tactile_torch.features.files.load_features`), the command line and the runtime
(:meth:`tactile_torch.robot.runtime.OnnxPipeline.read_npz`) all go through it. The archives are read
within the read bound by :mod:`tactile_torch.robot.files.npz`, CSV logs by
:mod:`tactile_torch.robot.files.csv_logs`, and recordings are cut into windows by
:mod:`tactile_torch.robot.stream.windows`.

=========================  =====================================================================
format                     contents
=========================  =====================================================================
image explorations .npz    ``frames`` uint8 ``(N, T, H, W, 3)`` RGB (or float pressure maps
                           ``(N, T, H, W)``), ``labels`` int ``(N,)``, ``class_names`` str ``(C,)``,
                           optional ``groups`` int ``(N,)`` and ``frame_rate_hz`` float
vibration recordings .npz  ``signals`` float in g: ``(R, n, 3)`` when the recordings are equally
                           long, else all samples concatenated ``(sum n_i, 3)`` with ``lengths``
                           int ``(R,)``; ``labels`` int ``(R,)``, ``class_names`` str ``(C,)``,
                           ``rate_hz`` float, optional ``session`` str ``(R,)``
feature matrix .npz        ``features`` float ``(N, F)``, optional ``labels`` ``(N,)`` and
                           ``class_names`` str ``(C,)``
CSV log                    one recording per file: a time column in seconds and ``x, y, z`` in g
=========================  =====================================================================

No file is unpickled unless the caller passes ``allow_pickle=True`` (only old vibration files that
stored recordings of different lengths as a pickled object array need it). Every error is a
``ValueError`` (``FileNotFoundError`` for a missing file) whose message starts with the file and names
the field, what was expected and what was found.

Examples
--------
>>> import numpy as np, tempfile, os
>>> path = os.path.join(tempfile.mkdtemp(), "rec.npz")
>>> rec = RecordingArrays([np.zeros((900, 3)), np.zeros((500, 3))], np.array([0, 1]), ("cork", "felt"), 800.0)
>>> _ = write_recordings(path, rec)
>>> back = read_recordings(path)          # ragged: concatenated samples + lengths, no pickle
>>> [s.shape for s in back.signals]
[(900, 3), (500, 3)]
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...validation import saturate_float32
from .csv_logs import integer_counts_message, read_csv_log
from .naming import check_class_names, recording_names
from .npz import PathLike, read_npz, write_npz
from .sample_times import describe_timing

DATA_KINDS = ("image", "vibration", "features")
"""The kinds of data file, by the array that marks them: ``frames``, ``signals``, ``features``."""
_MARKER = {"frames": "image", "signals": "vibration", "features": "features"}


# ------------------------------------------------------------------------------------ containers
@dataclass
class ExplorationArrays:
    """Image explorations as read from a file (NumPy arrays, channels last as stored).

    Attributes
    ----------
    frames : ndarray (N, T, H, W, 3) uint8, or None when the file holds pressure maps
    pressure : ndarray (N, T, H, W) float32, or None
    labels : ndarray (N,) int64
    class_names : tuple of str
    groups : ndarray (N,) int64, or None
    frame_rate_hz : float or None (frames per second, when the file states it; never assumed)
    """

    frames: np.ndarray | None
    pressure: np.ndarray | None
    labels: np.ndarray
    class_names: tuple[str, ...]
    groups: np.ndarray | None = None
    frame_rate_hz: float | None = None
    kind = "image"

    def __len__(self) -> int:
        return len(self.labels)


@dataclass
class RecordingArrays:
    """Triaxial vibration recordings as read from a file.

    Attributes
    ----------
    signals : list of ndarray (n_i, 3) float32, in g
    labels : ndarray (R,) int64
    class_names : tuple of str
    rate_hz : float
    session : ndarray (R,) str, or None
    gaps : list of ndarray (K_i,) int64, or None
        Per recording, the samples that start a new stretch after a gap in its time stamps
        (increasing, in ``1 .. n_i - 1``); no window spans a gap. ``None``: no gaps.
    sources : list of str, or None
        How messages name each recording (its CSV file or bag; set by
        :func:`~tactile_torch.robot.files.data_sources.read_source`).
    """

    signals: list[np.ndarray]
    labels: np.ndarray
    class_names: tuple[str, ...]
    rate_hz: float
    session: np.ndarray | None = None
    gaps: list[np.ndarray] | None = None
    sources: list[str] | None = None
    kind = "vibration"

    def __len__(self) -> int:
        return len(self.signals)


@dataclass
class FeatureArrays:
    """A feature matrix as read from a file.

    Attributes
    ----------
    features : ndarray (N, F) float64
    labels : ndarray (N,) int64, or None (class indices into ``class_names``)
    class_names : tuple of str, or None
    """

    features: np.ndarray
    labels: np.ndarray | None
    class_names: tuple[str, ...] | None
    kind = "features"

    def __len__(self) -> int:
        return len(self.features)


def _data_path(path: PathLike) -> Path:
    # Data files keep numpy.savez's convention (".npz" appended when missing); model files do not.
    path = Path(path)
    return path if path.suffix == ".npz" else path.with_name(path.name + ".npz")


def data_kind(arrays: dict[str, np.ndarray], path: PathLike) -> str:
    """Return ``"image"``, ``"vibration"`` or ``"features"`` from the keys of a data file."""
    kinds = [kind for key, kind in _MARKER.items() if key in arrays]
    if len(kinds) != 1:
        found = f"keys {sorted(arrays)}" if arrays else "no array"
        more = " (only one of them)" if kinds else ""
        raise ValueError(
            f"{path}: expected image explorations ('frames'), vibration recordings ('signals') or a "
            f"feature matrix ('features'){more}, found {found}"
        )
    return kinds[0]


# ------------------------------------------------------------------------------------ field checks
def _require(arrays: dict, path: Path, keys: Sequence[str], kind: str) -> None:
    missing = [k for k in keys if k not in arrays]
    if missing:
        raise ValueError(
            f"{path}: missing {', '.join(repr(k) for k in missing)}; {kind} need "
            f"{', '.join(keys)} (docs/formats.md), found {sorted(arrays)}"
        )


def _int_vector(value: np.ndarray, path: Path, name: str, n: int) -> np.ndarray:
    if value.shape != (n,) or not np.issubdtype(value.dtype, np.integer):
        raise ValueError(f"{path}: {name} must be integers of shape ({n},), got {value.dtype} {value.shape}")
    return value.astype(np.int64)


def _names(
    value: np.ndarray, path: Path, name: str = "class_names", *, distinct: bool = True
) -> tuple[str, ...]:
    if value.ndim != 1 or value.dtype.kind not in "US":
        raise ValueError(f"{path}: {name} must be a 1-D array of strings, got {value.dtype} {value.shape}")
    if value.dtype.kind == "S":
        for i, raw in enumerate(value.tolist()):
            try:
                raw.decode("utf-8")
            except UnicodeDecodeError as err:
                raise ValueError(
                    f"{path}: {name} must be UTF-8 text, got {raw!r} at index {i} (byte 0x{raw[err.start]:02x} "
                    f"at position {err.start} is not UTF-8)"
                ) from None
        value = np.char.decode(value, "utf-8")
    names = [str(c) for c in value]
    if not distinct:  # sessions repeat across classes (felt_3 and cork_3 are both session 3)
        check_class_names(sorted(set(names)), f"{path}: {name}")
        return tuple(names)
    return check_class_names(names, f"{path}: {name}")


def _labels(value: np.ndarray, path: Path, n: int, names: tuple[str, ...]) -> np.ndarray:
    labels = _int_vector(value, path, "labels", n)
    if n and (labels.min() < 0 or labels.max() >= len(names)):
        raise ValueError(
            f"{path}: labels must index class_names (0..{len(names) - 1}), "
            f"got values {labels.min()}..{labels.max()}"
        )
    return labels


def _check_finite(value: np.ndarray, path: Path, name: str) -> None:
    bad = ~np.isfinite(value)
    if bad.any():
        where = np.unravel_index(int(np.argmax(bad)), value.shape)
        raise ValueError(
            f"{path}: {name} must be finite, got {int(bad.sum())} NaN/inf value(s) (first at index "
            f"{tuple(int(i) for i in where)})"
        )


def _float_signals(value: np.ndarray, path: Path) -> None:
    if np.issubdtype(value.dtype, np.integer):
        raise ValueError(integer_counts_message(f"{path}: signals", f"{value.dtype}"))
    if not np.issubdtype(value.dtype, np.floating):
        raise ValueError(f"{path}: signals must be float accelerations in g, got dtype {value.dtype}")


# ------------------------------------------------------------------------------------ images
def read_explorations(path: PathLike) -> ExplorationArrays:
    """Read an image-exploration ``.npz``; see the module docstring for the fields.

    Raises ``ValueError`` naming the file and the field for a missing key, a wrong shape or dtype,
    labels outside ``class_names`` and non-finite pressure maps.
    """
    path = Path(path)
    arrays = read_npz(path)
    return _explorations(arrays, path)


def _explorations(arrays: dict[str, np.ndarray], path: Path) -> ExplorationArrays:
    _require(arrays, path, ("frames", "labels", "class_names"), "image explorations")
    raw = arrays["frames"]
    frames = pressure = None
    if raw.ndim == 5 and raw.shape[-1] == 3 and raw.dtype == np.uint8:
        frames = raw
    elif raw.ndim == 4 and np.issubdtype(raw.dtype, np.floating):
        _check_finite(raw, path, "frames")
        pressure = raw.astype(np.float32, copy=False)
    else:
        raise ValueError(
            f"{path}: frames must be uint8 RGB (N, T, H, W, 3) or float pressure maps (N, T, H, W), "
            f"got {raw.dtype} {raw.shape}"
        )
    n = raw.shape[0]
    if n == 0:
        raise ValueError(f"{path}: frames must hold at least one exploration, got shape {raw.shape}")
    names = _names(arrays["class_names"], path)
    labels = _labels(arrays["labels"], path, n, names)
    groups = arrays.get("groups")
    if groups is not None:
        groups = _int_vector(groups, path, "groups", n)
    rate = arrays.get("frame_rate_hz")
    if rate is not None and not (rate.shape == () and rate.dtype.kind in "fiu" and 0 < rate < np.inf):
        raise ValueError(f"{path}: frame_rate_hz must be a number of frames/s > 0, got {rate!r}")
    return ExplorationArrays(frames, pressure, labels, names, groups, None if rate is None else float(rate))


def write_explorations(path: PathLike, data: ExplorationArrays) -> Path:
    """Write image explorations (``frames`` channels last, or ``pressure``) to ``path``; return it.

    ``.npz`` is appended to a path without it (as :func:`numpy.savez` does); the returned path is
    the file written.
    """
    raw = data.frames if data.frames is not None else data.pressure
    if raw is None:
        raise ValueError("data must hold frames or pressure maps, got neither")
    arrays = {
        "frames": np.asarray(raw),
        "labels": np.asarray(data.labels, dtype=np.int64),
        "class_names": np.asarray(data.class_names, dtype=str),
    }
    if data.groups is not None:
        arrays["groups"] = np.asarray(data.groups, dtype=np.int64)
    if data.frame_rate_hz is not None:
        arrays["frame_rate_hz"] = np.float64(data.frame_rate_hz)
    path = _data_path(path)
    _explorations(arrays, path)  # refuse to write what would not read back
    return write_npz(path, arrays)


# ------------------------------------------------------------------------------------ vibration
def read_recordings(
    path: PathLike, *, allow_pickle: bool = False, default_rate_hz: float | None = None
) -> RecordingArrays:
    """Read a vibration-recordings ``.npz``; see the module docstring for the fields.

    Reads the three layouts of ``signals``: ``(R, n, 3)``; concatenated ``(sum n_i, 3)`` with
    ``lengths``; and, only with ``allow_pickle=True`` (a trusted file), the object array of
    ``(n_i, 3)`` recordings that tactile-torch 0.1 wrote for recordings of different lengths.
    ``default_rate_hz`` stands in for a missing ``rate_hz`` (a file written by another tool).

    Raises ``ValueError`` naming the file and the field for a missing key, a wrong shape, integer
    signals (raw counts where g are expected), NaN/inf, labels outside ``class_names`` or a
    non-positive ``rate_hz``.
    """
    path = Path(path)
    arrays = read_npz(path, allow_pickle=allow_pickle)
    if default_rate_hz is not None:
        arrays.setdefault("rate_hz", np.float64(default_rate_hz))
    return _recordings(arrays, path)


def recordings_from_arrays(arrays: dict[str, np.ndarray], path: PathLike) -> RecordingArrays:
    """Validate the arrays of a vibration ``.npz`` (as :func:`read_npz` returns them); return the recordings.

    For readers that convert ``signals`` first (declared units or a scale for integer counts,
    :func:`tactile_torch.robot.files.data_sources.read_source`); the checks are :func:`read_recordings`'s.
    """
    return _recordings(arrays, Path(path))


def _recordings(arrays: dict[str, np.ndarray], path: Path) -> RecordingArrays:
    _require(arrays, path, ("signals", "labels", "class_names", "rate_hz"), "vibration recordings")
    raw = arrays["signals"]
    if raw.dtype == object:  # the legacy pickled layout, read only when the caller allowed pickle
        signals = [np.asarray(s) for s in raw.ravel()]
        for i, s in enumerate(signals):
            if s.ndim != 2 or s.shape[1] != 3:
                raise ValueError(f"{path}: signals[{i}] must have shape (n, 3), got {s.shape}")
            _float_signals(s, path)
            _check_finite(s, path, f"signals[{i}]")
    elif "lengths" in arrays:
        if raw.ndim != 2 or raw.shape[1] != 3:
            raise ValueError(
                f"{path}: signals stored with lengths must be the concatenated samples (sum n_i, 3), "
                f"got {raw.shape}"
            )
        _float_signals(raw, path)
        lengths = arrays["lengths"]
        if lengths.ndim != 1 or not np.issubdtype(lengths.dtype, np.integer) or (lengths < 1).any():
            raise ValueError(
                f"{path}: lengths must be integers >= 1 of shape (R,), got {lengths.dtype} {lengths}"
            )
        if int(lengths.sum()) != raw.shape[0]:
            raise ValueError(
                f"{path}: lengths must add up to the {raw.shape[0]} samples of signals, got {int(lengths.sum())}"
            )
        _check_finite(raw, path, "signals")
        signals = np.split(raw, np.cumsum(lengths)[:-1])
    else:
        if raw.ndim != 3 or raw.shape[2] != 3:
            raise ValueError(
                f"{path}: signals must have shape (R, n, 3) (or (sum n_i, 3) with 'lengths'), got {raw.shape}"
            )
        _float_signals(raw, path)
        _check_finite(raw, path, "signals")
        signals = list(raw)
    if not signals or not all(len(s) for s in signals):
        raise ValueError(f"{path}: signals must hold at least one recording of at least one sample")
    signals = [np.ascontiguousarray(saturate_float32(s)) for s in signals]
    names = _names(arrays["class_names"], path)
    labels = _labels(arrays["labels"], path, len(signals), names)
    rate = arrays["rate_hz"]
    if rate.size != 1 or not np.issubdtype(rate.dtype, np.number) or not float(rate.ravel()[0]) > 0:
        raise ValueError(f"{path}: rate_hz must be one number > 0 (samples per second), got {rate!r}")
    rate_hz = float(rate.ravel()[0])
    if not np.isfinite(rate_hz):
        raise ValueError(f"{path}: rate_hz must be finite, got {rate_hz}")
    session = arrays.get("session")
    if session is not None:
        session = np.asarray(_names(session, path, "session", distinct=False))
        if session.shape != (len(signals),):
            raise ValueError(f"{path}: session must have shape ({len(signals)},), got {session.shape}")
    gaps = _gaps(arrays.get("gaps"), path, [len(s) for s in signals])
    return RecordingArrays(signals, labels, names, rate_hz, session, gaps)


def _gaps(value: np.ndarray | None, path: Path, lengths: list[int]) -> list[np.ndarray] | None:
    """The optional ``gaps`` array ``(K, 2)`` (recording, sample), checked, as a list per recording."""
    if value is None:
        return None
    if value.ndim != 2 or value.shape[1] != 2 or not np.issubdtype(value.dtype, np.integer):
        raise ValueError(
            f"{path}: gaps must be integers of shape (K, 2) (recording, sample), got {value.dtype} {value.shape}"
        )
    recording, sample = value[:, 0].astype(np.int64), value[:, 1].astype(np.int64)
    if len(value) and (recording.min() < 0 or recording.max() >= len(lengths)):
        raise ValueError(
            f"{path}: gaps must name recordings 0..{len(lengths) - 1}, got {recording.min()}..{recording.max()}"
        )
    per_recording = []
    for r, n in enumerate(lengths):
        mine = np.sort(sample[recording == r])
        if mine.size and (mine[0] < 1 or mine[-1] > n - 1 or (np.diff(mine) <= 0).any()):
            raise ValueError(
                f"{path}: gaps of recording {r} must be distinct samples in 1..{n - 1}, got {mine.tolist()[:5]}"
            )
        per_recording.append(mine)
    return per_recording


def write_recordings(path: PathLike, data: RecordingArrays) -> Path:
    """Write vibration recordings to ``path`` without pickle; return it.

    Equally long recordings are stored as ``signals`` ``(R, n, 3)`` float32; recordings of different
    lengths as their samples concatenated ``(sum n_i, 3)`` and ``lengths`` ``(R,)``.
    """
    signals = [np.asarray(s, dtype=np.float32) for s in data.signals]
    if len({len(s) for s in signals}) == 1:
        arrays = {"signals": np.stack(signals)}
    else:
        arrays = {
            "signals": np.concatenate(signals) if signals else np.zeros((0, 3), np.float32),
            "lengths": np.array([len(s) for s in signals], dtype=np.int64),
        }
    arrays.update(
        labels=np.asarray(data.labels, dtype=np.int64),
        class_names=np.asarray(data.class_names, dtype=str),
        rate_hz=np.float64(data.rate_hz),
    )
    if data.session is not None:
        arrays["session"] = np.asarray(data.session, dtype=str)
    if data.gaps is not None and any(len(g) for g in data.gaps):
        arrays["gaps"] = np.array(
            [(r, int(i)) for r, g in enumerate(data.gaps) for i in g], dtype=np.int64
        ).reshape(-1, 2)
    path = _data_path(path)
    _recordings(arrays, path)  # refuse to write what would not read back
    return write_npz(path, arrays)


def read_csv_recordings(
    paths: Sequence[PathLike],
    *,
    class_names: Sequence[str] | None = None,
    sessions: Sequence[str] | None = None,
    index: PathLike | None = None,
    class_from: str | None = None,
    session_from: str | None = None,
    columns: str | Sequence[str | int] | None = None,
    scale: float | None = None,
    units: str = "g",
    time_unit: str = "auto",
    sample_rate_hz: float | None = None,
) -> RecordingArrays:
    """Read CSV logs (one recording each) sharing one sample rate as :class:`RecordingArrays`.

    The one reader of several CSV logs (every ``--data``, the data sets' loaders, Python). Classes and
    sessions: ``class_names``/``sessions``, an ``index`` CSV, or the files' layout with ``class_from`` /
    ``session_from`` (:func:`tactile_torch.robot.files.naming.recording_names`); labels index the sorted
    classes. ``columns`` ... ``sample_rate_hz``: :func:`~tactile_torch.robot.files.csv_logs.read_csv_log`.
    One sample rate within 0.1 % (resample others alone: ``VibrationRecordings.resample``); gaps kept in
    ``gaps``; one warning per finding for all the files (``sample_times.describe_timing``).
    """
    import warnings

    paths = [Path(p) for p in paths]
    if not paths:
        raise ValueError("paths must name at least one CSV file, got none")
    names = recording_names(
        paths,
        class_names=class_names,
        sessions=sessions,
        index=index,
        class_from=class_from,
        session_from=session_from,
    )
    logs = [
        read_csv_log(
            p, columns=columns, scale=scale, units=units, time_unit=time_unit, sample_rate_hz=sample_rate_hz
        )
        for p in paths
    ]
    rates = np.array([log.rate_hz for log in logs])
    if np.abs(rates / rates[0] - 1).max() > 1e-3:
        odd = int(np.argmax(np.abs(rates / rates[0] - 1)))
        raise ValueError(
            f"the files have different sample rates ({paths[0]}: {rates[0]:g} Hz, {paths[odd]}: "
            f"{rates[odd]:g} Hz); resample them to a common rate first (each file read alone, "
            "tactile_torch.data.VibrationRecordings.resample)"
        )
    for line in describe_timing(
        [(str(p), log.timing, log.seconds) for p, log in zip(paths, logs, strict=True)]
    ):
        warnings.warn(line, stacklevel=2)
    classes = check_class_names(sorted(set(names.classes)), "class names (of the CSV files)")
    return RecordingArrays(
        signals=[log.signal for log in logs],
        labels=np.array([classes.index(n) for n in names.classes], dtype=np.int64),
        class_names=classes,
        rate_hz=float(rates[0]),
        session=np.array(names.sessions),
        gaps=[log.gaps for log in logs] if any(log.gaps.size for log in logs) else None,
    )


# ------------------------------------------------------------------------------------ features
def read_features(path: PathLike, *, require_labels: bool = False) -> FeatureArrays:
    """Read a feature-matrix ``.npz``: ``features`` ``(N, F)``, optional ``labels`` and ``class_names``.

    Labels without ``class_names`` may be any integers or strings: the class names are then their
    sorted distinct values and the labels index them. Raises ``ValueError`` naming the file and the
    field (``require_labels``: labels must be present).
    """
    path = Path(path)
    return _features(read_npz(path), path, require_labels=require_labels)


def _features(arrays: dict[str, np.ndarray], path: Path, *, require_labels: bool = False) -> FeatureArrays:
    _require(arrays, path, ("features", "labels") if require_labels else ("features",), "feature files")
    X = arrays["features"]
    if X.ndim != 2 or X.shape[0] == 0 or X.shape[1] == 0:
        raise ValueError(f"{path}: features must have shape (N, F) with N, F >= 1, got {X.shape}")
    if not (np.issubdtype(X.dtype, np.floating) or np.issubdtype(X.dtype, np.integer)):
        raise ValueError(f"{path}: features must be numbers (float), got dtype {X.dtype}")
    X = X.astype(np.float64)
    _check_finite(X, path, "features")
    labels, names = arrays.get("labels"), None
    if "class_names" in arrays:
        names = _names(arrays["class_names"], path)
        if labels is not None:
            labels = _labels(labels, path, X.shape[0], names)
    elif labels is not None:
        if labels.shape != (X.shape[0],) or labels.dtype.kind not in "iuUS":
            raise ValueError(
                f"{path}: labels must be integers or strings of shape ({X.shape[0]},), "
                f"got {labels.dtype} {labels.shape}"
            )
        uniq, labels = np.unique(labels, return_inverse=True)
        names = tuple(str(c) for c in uniq)
        labels = labels.astype(np.int64)
    return FeatureArrays(X, labels, names)


def write_features(path: PathLike, data: FeatureArrays) -> Path:
    """Write a feature matrix (and its labels and class names when given) to ``path``; return it."""
    arrays = {"features": np.asarray(data.features, dtype=np.float64)}
    if data.labels is not None:
        arrays["labels"] = np.asarray(data.labels, dtype=np.int64)
    if data.class_names is not None:
        arrays["class_names"] = np.asarray(data.class_names, dtype=str)
    path = _data_path(path)
    _features(arrays, path)  # refuse to write what would not read back
    return write_npz(path, arrays)


# ------------------------------------------------------------------------------------ any data file
def data_name(paths: PathLike | Sequence[PathLike]) -> str:
    """Return how messages name a data argument: the file, or the first of several files."""
    if isinstance(paths, str | os.PathLike):
        return str(paths)
    names = [str(p) for p in paths]
    if len(names) == 1:
        return names[0]
    return f"{names[0]} (and {len(names) - 1} more)" if names else "no file"


def read_data(
    paths: PathLike | Sequence[PathLike], *, allow_pickle: bool = False
) -> ExplorationArrays | RecordingArrays | FeatureArrays:
    """Read one data file of any kind, or CSV logs; return its arrays (``.kind`` says which).

    ``paths``: one ``.npz`` (explorations, recordings or features: ``frames``, ``signals``, ``features``), or
    ``.csv`` logs (:func:`read_csv_recordings`). ``allow_pickle``: a trusted legacy vibration file only.
    """
    paths = [Path(paths)] if isinstance(paths, str | os.PathLike) else [Path(p) for p in paths]
    if not paths:
        raise ValueError("data must name a .npz file or CSV logs, got none")
    if all(p.suffix.lower() == ".csv" for p in paths):
        return read_csv_recordings(paths)
    if len(paths) > 1:
        raise ValueError(
            f"data must be one .npz file or one or more .csv logs, got {[str(p) for p in paths]}"
        )
    path = paths[0]
    arrays = read_npz(path, allow_pickle=allow_pickle, what="data file (.npz of docs/formats.md)")
    kind = data_kind(arrays, path)
    if kind == "image":
        return _explorations(arrays, path)
    if kind == "vibration":
        return _recordings(arrays, path)
    return _features(arrays, path)


__all__ = [
    "DATA_KINDS",
    "ExplorationArrays",
    "FeatureArrays",
    "RecordingArrays",
    "check_class_names",
    "data_kind",
    "data_name",
    "read_csv_recordings",
    "read_data",
    "read_explorations",
    "read_features",
    "read_npz",
    "read_recordings",
    "recordings_from_arrays",
    "write_explorations",
    "write_features",
    "write_recordings",
]
