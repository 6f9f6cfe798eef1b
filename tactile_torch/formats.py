"""Read and write every data file of tactile-torch with NumPy only (importable on the robot, no torch).

One home for the data formats (``docs/formats.md``); the loaders of :mod:`tactile_torch.data`, the
training (:func:`tactile_torch.training.load_features`), the command line and the runtime
(:meth:`tactile_torch.runtime.OnnxPipeline.read_npz`) all go through it.

=========================  =====================================================================
format                     contents
=========================  =====================================================================
image explorations .npz    ``frames`` uint8 ``(N, T, H, W, 3)`` RGB (or float pressure maps
                           ``(N, T, H, W)``), ``labels`` int ``(N,)``, ``class_names`` str ``(C,)``,
                           optional ``groups`` int ``(N,)``
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
>>> window_recordings(back.signals, 400, 200).windows.shape
(4, 3, 400)
"""

from __future__ import annotations

import io
import os
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputTypeError

PathLike = str | os.PathLike
NPZ_MAGIC = b"PK"
NPY_MAGIC = b"\x93NUMPY"
KINDS = ("image", "vibration", "features")
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
    """

    frames: np.ndarray | None
    pressure: np.ndarray | None
    labels: np.ndarray
    class_names: tuple[str, ...]
    groups: np.ndarray | None = None
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
    """

    signals: list[np.ndarray]
    labels: np.ndarray
    class_names: tuple[str, ...]
    rate_hz: float
    session: np.ndarray | None = None
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


@dataclass
class Windows:
    """Windows cut from recordings by :func:`window_recordings`.

    Attributes
    ----------
    windows : ndarray (N, 3, W) float32, C-contiguous (a copy)
    recording : ndarray (N,) int64, index of the source recording
    position : ndarray (N,) int64, index of the window within its recording (time order)
    """

    windows: np.ndarray
    recording: np.ndarray
    position: np.ndarray


# ------------------------------------------------------------------------------------ npz files
def _check_exists(path: Path) -> None:
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    if path.is_dir():
        raise ValueError(f"{path}: is a directory, expected a file")


# ------------------------------------------------------------------------------------ read limits
DEFAULT_MAX_READ_MB = 1024
"""Default bound (MiB) on what one data, model or bundle file may make the reader allocate."""
MAX_READ_ENV = "TACTILE_TORCH_MAX_READ_MB"
"""Environment variable that replaces :data:`DEFAULT_MAX_READ_MB` (``--max-read-mb`` sets it)."""
_MIB = 1 << 20
_CSV_EXPANSION = 4  # bytes of parsed table per byte of CSV text, at most ("0,0,0,0\n": 8 bytes, 4 float64)


def max_read_bytes(max_bytes: int | None = None) -> int:
    """Return the read bound in bytes: ``max_bytes`` if given, else ``$TACTILE_TORCH_MAX_READ_MB`` MiB, else 1 GiB.

    Every reader of this module checks what a file declares (the sizes in a zip's member headers,
    the shape and dtype in each ``.npy`` header, a CSV's size) against this bound before reading, so
    a crafted file (a zip bomb, a header declaring 10^12 samples) is refused in one line instead of
    exhausting the memory of a robot's computer.
    """
    if max_bytes is None:
        text = os.environ.get(MAX_READ_ENV, "")
        try:
            mib = float(text) if text else float(DEFAULT_MAX_READ_MB)
        except ValueError:
            mib = float("nan")
        if not (mib > 0 and np.isfinite(mib)):
            raise ValueError(f"{MAX_READ_ENV} must be a number of MiB > 0, got {text!r}")
        return int(mib * _MIB)
    if isinstance(max_bytes, bool) or not isinstance(max_bytes, int | np.integer) or max_bytes < 1:
        raise ValueError(f"max_bytes must be an int >= 1, got {max_bytes!r}")
    return int(max_bytes)


def _too_large(path: Path, what: str, size: int, limit: int) -> ValueError:
    return ValueError(
        f"{path}: {what} needs {size / _MIB:,.1f} MiB, more than the read limit of {limit / _MIB:,.0f} MiB "
        f"(raise it with {MAX_READ_ENV}=MB if the file is trusted)"
    )


def _npy_header(member, version: tuple[int, int]) -> tuple[tuple[int, ...], bool, np.dtype]:
    if version == (1, 0):
        return np.lib.format.read_array_header_1_0(member)
    if version == (2, 0):
        return np.lib.format.read_array_header_2_0(member)
    raise ValueError(f"unsupported .npy format version {version}")


def check_npz_size(path: PathLike, *, max_bytes: int | None = None, what: str = ".npz archive") -> int:
    """Check a ``.npz`` against the read bound without decompressing it; return the bytes its arrays need.

    Reads the zip's central directory (the declared uncompressed size of each member: ``zipfile``
    never inflates a member beyond it) and the header of each ``.npy`` member (shape and dtype,
    computed with Python integers: no overflow), and raises ``ValueError`` in one line when either
    total exceeds :func:`max_read_bytes`, or a member's shape needs more bytes than it holds.
    """
    path = Path(path)
    limit = max_read_bytes(max_bytes)
    try:
        with zipfile.ZipFile(path) as archive:
            members = archive.infolist()
            declared = sum(info.file_size for info in members)
            if declared > limit:
                raise _too_large(path, f"decompressing the {what}", declared, limit)
            needed = 0
            for info in members:
                with archive.open(info) as member:
                    try:
                        version = np.lib.format.read_magic(member)
                        shape, _, dtype = _npy_header(member, version)
                    except ValueError:
                        continue  # not a .npy member: read_npz names it
                if dtype.hasobject:
                    continue  # pickled: refused by read_npz unless allow_pickle
                size = dtype.itemsize
                for n in shape:
                    size *= int(n)
                if size > info.file_size:
                    raise ValueError(
                        f"{path}: {info.filename} declares shape {tuple(shape)} {dtype} ({size:,} bytes) but "
                        f"holds {info.file_size:,} bytes: a crafted or truncated {what}"
                    )
                needed += size
    except (zipfile.BadZipFile, EOFError, OSError) as err:
        raise ValueError(f"{path}: truncated or corrupt {what} ({err})") from None
    if needed > limit:
        raise _too_large(path, f"the {what}'s arrays", needed, limit)
    return needed


def read_npz(
    path: PathLike,
    *,
    allow_pickle: bool = False,
    what: str = ".npz archive",
    max_bytes: int | None = None,
) -> dict[str, np.ndarray]:
    """Return every array of a ``.npz`` file by name, or raise one ``ValueError`` naming the file.

    Empty, truncated or corrupt archives, files of another kind (a ``.npy``, an ONNX model, text) and
    pickled object arrays (unless ``allow_pickle``) are refused with a one-line reason; ``what``
    names the expected content in the messages (e.g. ``"tactile-torch model file"``). Before any
    array is read, the declared sizes are checked against ``max_bytes`` (default
    :func:`max_read_bytes`: 1 GiB, ``--max-read-mb``) by :func:`check_npz_size`.
    """
    path = Path(path)
    _check_exists(path)
    with path.open("rb") as f:
        head = f.read(8)
    if not head:
        raise ValueError(f"{path}: empty file (0 bytes), expected a {what}")
    if not head.startswith(NPZ_MAGIC):
        found = "a single .npy array" if head.startswith(NPY_MAGIC) else "not a zip archive"
        raise ValueError(f"{path}: expected a {what} (.npz), found {found}")
    check_npz_size(path, max_bytes=max_bytes, what=what)
    arrays: dict[str, np.ndarray] = {}
    try:
        with np.load(path, allow_pickle=allow_pickle) as npz:
            for key in npz.files:
                try:
                    value = npz[key]
                except ValueError as err:
                    if "allow_pickle" not in str(err):
                        raise
                    raise ValueError(
                        f"{path}: {key} is a pickled object array, which tactile-torch does not load by "
                        "default (unpickling can run code); re-save it as plain arrays (docs/formats.md), or "
                        "pass allow_pickle=True if you trust the file"
                    ) from None
                if not isinstance(value, np.ndarray):  # a zip member that is not a .npy array
                    raise ValueError(f"{path}: expected a {what} (.npz), found a zip archive holding {key!r}")
                arrays[key] = value
    except (zipfile.BadZipFile, EOFError, OSError) as err:
        raise ValueError(f"{path}: truncated or corrupt {what} ({err})") from None
    except ValueError as err:
        if str(err).startswith(str(path)):
            raise
        raise ValueError(f"{path}: unreadable {what} ({err})") from None
    return arrays


def write_npz(
    path: PathLike,
    arrays: dict[str, np.ndarray],
    *,
    compress: bool = True,
    inputs: Sequence[PathLike] = (),
) -> Path:
    """Write ``arrays`` to ``path`` exactly (no ``.npz`` appended), atomically; return the path.

    The archive is written to a temporary file next to ``path`` and renamed over it, so a crash or a
    full disk never leaves a truncated file under the final name; a directory, a device, a symbolic
    link or one of ``inputs`` (the files the caller read) at ``path`` is refused in one line
    (:func:`tactile_torch.safe_write.write_atomic`). Object arrays are refused.
    """
    from .safe_write import write_atomic

    for key, value in arrays.items():
        if np.asarray(value).dtype == object:
            raise InputTypeError(f"{key} must be a plain (non-object) array to be written without pickle")
    save = np.savez_compressed if compress else np.savez
    return write_atomic(path, lambda f: save(f, **arrays), inputs=inputs)


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
        value = np.char.decode(value, "utf-8")
    names = [str(c) for c in value]
    if not distinct:  # sessions repeat across classes (felt_3 and cork_3 are both session 3)
        check_class_names(sorted(set(names)), f"{path}: {name}")
        return tuple(names)
    return check_class_names(names, f"{path}: {name}")


def check_class_names(names: Sequence[str], where: str = "class_names") -> tuple[str, ...]:
    """Return ``names`` as a tuple if they can name classes, else raise ``ValueError`` starting with ``where``.

    A class name is printed in reports, one per line, and written into bundles: it must hold no
    control character (a newline would inject a line into a report), and no two may be equal (the
    labels would be ambiguous).
    """
    for i, name in enumerate(names):
        if any(ord(ch) < 32 or ord(ch) == 127 for ch in name):
            raise ValueError(
                f"{where} must hold no control characters (newline, tab, ...), got {name!r} at index {i}"
            )
    seen: dict[str, int] = {}
    for i, name in enumerate(names):
        if name in seen:
            raise ValueError(f"{where} must be distinct, got {name!r} at indices {seen[name]} and {i}")
        seen[name] = i
    return tuple(names)


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
        from .data.logs import integer_counts_message

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
    return ExplorationArrays(frames, pressure, labels, names, groups)


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
    :func:`tactile_torch.data.sources.read_source`); the checks are :func:`read_recordings`'s.
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
    signals = [np.ascontiguousarray(s, dtype=np.float32) for s in signals]
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
    return RecordingArrays(signals, labels, names, rate_hz, session)


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
    path = _data_path(path)
    _recordings(arrays, path)  # refuse to write what would not read back
    return write_npz(path, arrays)


def read_csv_recording(
    path: PathLike,
    *,
    columns: str | Sequence[str | int] | None = None,
    scale: float | None = None,
    units: str = "g",
    time_unit: str = "auto",
) -> tuple[np.ndarray, float]:
    """Read one CSV log of time and three accelerations; return ``(signal (n, 3) float32 in g, rate_hz)``.

    ``columns`` (names or indices of t, x, y, z), ``units`` (``"g"``, ``"m/s2"``), ``scale`` (units
    per count, required for integer counts) and ``time_unit`` (``"s"``, ``"ms"``, ``"us"``,
    ``"auto"``) are those of :func:`tactile_torch.data.logs.read_csv_log`, which reads the file
    (NumPy only). The rate is ``1 / median(dt)``.

    Raises
    ------
    ValueError
        If a column is missing, a value is not a finite number, there are fewer than 2 rows, the
        time stamps do not strictly increase, the rate is implausible for the time unit, or the
        accelerations are integer counts without a ``scale``.
    """
    from .data.logs import read_csv_log

    return read_csv_log(path, columns=columns, units=units, scale=scale, time_unit=time_unit)


def write_csv_recording(path: PathLike, signal: np.ndarray, rate_hz: float) -> Path:
    """Write one recording ``(n, 3)`` in g as a CSV log with the header ``t,x,y,z``; return the path.

    Times are ``i / rate_hz`` seconds; values keep float32 precision (9 significant digits), so
    :func:`read_csv_recording` gives the same samples and rate back.
    """
    signal = np.asarray(signal)
    if signal.ndim != 2 or signal.shape[1] != 3:
        raise ValueError(f"signal must have shape (n, 3), got {signal.shape}")
    if not rate_hz > 0:
        raise ValueError(f"rate_hz must be > 0, got {rate_hz!r}")
    table = np.column_stack([np.arange(len(signal)) / float(rate_hz), signal.astype(np.float64)])
    buffer = io.StringIO()
    np.savetxt(buffer, table, delimiter=",", fmt="%.9g", header="t,x,y,z", comments="")
    from .safe_write import write_atomic

    text = buffer.getvalue().encode("ascii")
    return write_atomic(path, lambda f: f.write(text))


def csv_class_name(path: PathLike) -> str:
    """Return the class a CSV log is named after (:func:`tactile_torch.data.logs.class_and_session`).

    >>> csv_class_name("logs/cork_12.csv"), csv_class_name("glass.csv")
    ('cork', 'glass')
    """
    from .data.logs import class_and_session

    return class_and_session(path)[0]


def read_csv_recordings(
    paths: Sequence[PathLike],
    *,
    class_names: Sequence[str] | None = None,
    sessions: Sequence[str] | None = None,
    index: PathLike | None = None,
    columns: str | Sequence[str | int] | None = None,
    scale: float | None = None,
    units: str = "g",
    time_unit: str = "auto",
) -> RecordingArrays:
    """Read CSV logs (one recording each) sharing one sample rate as :class:`RecordingArrays`.

    Each file's class and session come from ``class_names``/``sessions``, else an ``index`` CSV
    (``file,class[,session]``), else the naming rule (``felt_3.csv`` → class ``felt``, session
    ``3``; :func:`tactile_torch.data.logs.class_and_session`). Labels index the sorted distinct
    classes. ``columns``, ``scale``, ``units``, ``time_unit``: see :func:`read_csv_recording`. The
    files must share one sample rate within 0.1 %
    (:meth:`tactile_torch.data.VibrationRecordings.resample` converts).
    """
    from .data.logs import names_for

    paths = [Path(p) for p in paths]
    if not paths:
        raise ValueError("paths must name at least one CSV file, got none")
    names, session = names_for(paths, class_names=class_names, sessions=sessions, index=index)
    read = [
        read_csv_recording(p, columns=columns, scale=scale, units=units, time_unit=time_unit) for p in paths
    ]
    rates = np.array([r for _, r in read])
    if np.abs(rates / rates[0] - 1).max() > 1e-3:
        odd = int(np.argmax(np.abs(rates / rates[0] - 1)))
        raise ValueError(
            f"the files have different sample rates ({paths[0]}: {rates[0]:g} Hz, {paths[odd]}: "
            f"{rates[odd]:g} Hz); resample them to a common rate (load_vibration_csv(..., rate_hz=))"
        )
    classes = check_class_names(sorted(set(names)), "class names (of the CSV files)")
    return RecordingArrays(
        signals=[s for s, _ in read],
        labels=np.array([classes.index(n) for n in names], dtype=np.int64),
        class_names=classes,
        rate_hz=float(rates[0]),
        session=np.array(session),
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

    Parameters
    ----------
    paths : path or sequence of paths
        One ``.npz`` (image explorations, vibration recordings or a feature matrix, told apart by
        ``frames``, ``signals`` or ``features``), or one or more ``.csv`` logs (one recording each,
        class from the file name, see :func:`read_csv_recordings`).
    allow_pickle : bool
        Vibration files only: read the legacy pickled object array of a trusted file.
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


# ------------------------------------------------------------------------------------ windowing
def window_recordings(
    signals: Sequence[np.ndarray],
    size: int,
    step: int | None = None,
    *,
    max_per_recording: int | None = None,
) -> Windows:
    """Cut every recording ``(n_i, 3)`` into windows of ``size`` samples every ``step``.

    Window ``j`` of a recording holds its samples ``j * step ... j * step + size - 1``, transposed to
    ``(3, size)``; trailing samples that do not fill a window are dropped and recordings shorter
    than ``size`` give none. The same windows as :func:`tactile_torch.signal.sliding_windows`, as
    NumPy.

    Returns
    -------
    Windows
        ``windows`` ``(N, 3, size)`` float32, with the recording and position of each.

    Raises
    ------
    ValueError
        If ``size < 2``, ``step < 1``, or no recording holds ``size`` samples.
    """
    step = size if step is None else step
    for name, value in (("size", size), ("step", step)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
            raise ValueError(f"{name} must be an int >= 1, got {value!r}")
    if size < 2:
        raise ValueError(f"size must be >= 2 samples, got {size}")
    parts, recording, position = [], [], []
    for i, rec in enumerate(signals):
        rec = np.asarray(rec)
        if rec.ndim != 2 or rec.shape[1] != 3:
            raise ValueError(f"signals[{i}] must have shape (n, 3), got {rec.shape}")
        if len(rec) < size:
            continue
        view = np.lib.stride_tricks.sliding_window_view(rec, int(size), axis=0)[:: int(step)]  # (n_w, 3, W)
        if max_per_recording is not None:
            view = view[:max_per_recording]
        parts.append(view.astype(np.float32, copy=False))
        recording.append(np.full(len(view), i, dtype=np.int64))
        position.append(np.arange(len(view), dtype=np.int64))
    if not parts:
        longest = max((len(s) for s in signals), default=0)
        raise ValueError(f"no recording holds a window of {size} samples (longest: {longest} samples)")
    return Windows(
        np.ascontiguousarray(np.concatenate(parts)), np.concatenate(recording), np.concatenate(position)
    )


__all__ = [
    "DEFAULT_MAX_READ_MB",
    "KINDS",
    "MAX_READ_ENV",
    "ExplorationArrays",
    "FeatureArrays",
    "RecordingArrays",
    "Windows",
    "check_class_names",
    "check_npz_size",
    "csv_class_name",
    "data_kind",
    "data_name",
    "max_read_bytes",
    "read_csv_recording",
    "read_csv_recordings",
    "read_data",
    "read_explorations",
    "read_features",
    "read_npz",
    "read_recordings",
    "recordings_from_arrays",
    "window_recordings",
    "write_csv_recording",
    "write_explorations",
    "write_features",
    "write_npz",
    "write_recordings",
]
