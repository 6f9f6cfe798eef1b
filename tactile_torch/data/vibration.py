"""Triaxial vibration recordings in memory and on disk: the ``.npz`` format and CSV logs.

:class:`VibrationRecordings` holds recordings in the vibration format of DESIGN.md (``signals`` in g,
``labels``, ``class_names``, ``rate_hz``, optional ``session``); :meth:`~VibrationRecordings.windows`
cuts them into the ``(N, 3, W)`` windows of :func:`tactile_torch.signal.window_features`. The
seeded stylus simulator lives in :mod:`tactile_torch.data.stylus` (its names stay importable from
here too).

Examples
--------
>>> import numpy as np
>>> rec = VibrationRecordings([np.zeros((1600, 3))], np.array([0]), ("glass",), 800.0)
>>> rec.windows(400).windows.shape
torch.Size([4, 3, 400])
"""

from __future__ import annotations

import csv
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, replace
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._checks import check_positive

if TYPE_CHECKING:
    import torch

STANDARD_GRAVITY = 9.80665  # m/s^2 per g
SAMPLE_RATE_HZ = 800.0  # ADXL345 output data rate of the study
QUANTUM_G = 0.0039  # ADXL345 full-resolution scale factor, 3.9 mg/LSB
RANGE_G = 5.0  # the study's ±5 g; the largest code is floor(5 / 0.0039) = 1282 → 4.9998 g


# ----------------------------------------------------------------------------------------------
# Container and file formats
# ----------------------------------------------------------------------------------------------


@dataclass
class VibrationRecordings:
    """Triaxial recordings with labels: the vibration format of DESIGN.md, in memory.

    Parameters
    ----------
    signals : list of ndarray, each ``(n_i, 3)``
        Recordings in g, axes x, y, z; float32 (converted). Lengths may differ.
    labels : ndarray ``(R,)``
        Class index of each recording, in ``0 .. C-1``; int64.
    class_names : sequence of str ``(C,)``
    rate_hz : float
        Sample rate shared by all recordings.
    session : ndarray ``(R,)`` of str, optional
        Session (or source file) of each recording, for grouped splits.
    """

    signals: list[np.ndarray]
    labels: np.ndarray
    class_names: tuple[str, ...]
    rate_hz: float
    session: np.ndarray | None = None

    def __post_init__(self) -> None:
        checked = []
        for i, s in enumerate(self.signals):
            s = np.asarray(s)
            if s.ndim != 2 or s.shape[1] != 3:
                raise ValueError(f"signals[{i}] must have shape (n, 3), got {s.shape}")
            if not np.issubdtype(s.dtype, np.number):
                raise TypeError(f"signals[{i}] must be numeric, got dtype {s.dtype}")
            if not np.isfinite(s).all():
                raise ValueError(
                    f"signals[{i}] must be finite, got {int((~np.isfinite(s)).sum())} NaN/inf value(s)"
                )
            checked.append(np.ascontiguousarray(s, dtype=np.float32))
        self.signals = checked
        self.class_names = tuple(str(c) for c in self.class_names)
        labels = np.asarray(self.labels)
        if labels.shape != (len(checked),):
            raise ValueError(
                f"labels must have shape ({len(checked)},) (one per recording), got {labels.shape}"
            )
        if labels.size and not np.issubdtype(labels.dtype, np.integer):
            raise TypeError(f"labels must be integers, got dtype {labels.dtype}")
        if labels.size and (labels.min() < 0 or labels.max() >= len(self.class_names)):
            raise ValueError(
                f"labels must lie in 0..{len(self.class_names) - 1} (one per class name), "
                f"got {labels.min()}..{labels.max()}"
            )
        self.labels = labels.astype(np.int64)
        check_positive(float(self.rate_hz), "rate_hz")
        self.rate_hz = float(self.rate_hz)
        if self.session is not None:
            session = np.asarray(self.session).astype(str)
            if session.shape != (len(checked),):
                raise ValueError(f"session must have shape ({len(checked)},), got {session.shape}")
            self.session = session

    def __len__(self) -> int:
        return len(self.signals)

    @property
    def durations_s(self) -> np.ndarray:
        """Duration of each recording in seconds, ``(R,)``."""
        return np.array([len(s) / self.rate_hz for s in self.signals])

    def windows(
        self, size: int, step: int | None = None, *, max_per_recording: int | None = None
    ) -> VibrationWindows:
        """Return the windows of every recording, with their labels and positions.

        Parameters
        ----------
        size : int
            Window length ``W`` in samples.
        step : int, optional
            Hop between windows; default ``size`` (non-overlapping).
        max_per_recording : int, optional
            Keep only the first windows of each recording.

        Returns
        -------
        VibrationWindows
            float32 windows ``(N, 3, W)`` (a copy), recordings in order, windows in time order.
            Recordings shorter than ``size`` give no window.

        Raises
        ------
        ValueError
            If no recording is at least ``size`` samples long.
        """
        import torch

        from ..signal import sliding_windows

        check_positive(size, "size", integer=True)
        parts, labels, recording, position = [], [], [], []
        for i, s in enumerate(self.signals):  # recordings differ in length: one unfold each
            if len(s) < size:
                continue
            w = sliding_windows(torch.from_numpy(s), size, step)
            if max_per_recording is not None:
                w = w[:max_per_recording]
            parts.append(w)
            labels.append(np.full(len(w), self.labels[i]))
            recording.append(np.full(len(w), i))
            position.append(np.arange(len(w)))
        if not parts:
            raise ValueError(
                f"no recording has size={size} samples (longest: {max(map(len, self.signals), default=0)})"
            )

        def as_long(parts: list[np.ndarray]) -> torch.Tensor:
            return torch.from_numpy(np.concatenate(parts).astype(np.int64))

        return VibrationWindows(
            windows=torch.cat(parts).contiguous(),
            labels=as_long(labels),
            recording=as_long(recording),
            position=as_long(position),
            class_names=self.class_names,
            rate_hz=self.rate_hz,
        )

    def resample(self, rate_hz: float) -> VibrationRecordings:
        """Return the recordings resampled to ``rate_hz`` with ``scipy.signal.resample_poly``.

        The ratio is approximated by a fraction with denominator <= 1000; resample_poly low-pass
        filters (Kaiser window) before decimating, and pads the ends with zeros, so the first and last
        few dozen samples are attenuated. Resampling does not add information: 100 Hz data upsampled
        to 800 Hz still holds nothing above 50 Hz.
        """
        from scipy.signal import resample_poly

        check_positive(rate_hz, "rate_hz")
        ratio = Fraction(float(rate_hz) / self.rate_hz).limit_denominator(1000)
        if ratio == 1:
            return replace(self, signals=[s.copy() for s in self.signals])
        signals = [
            resample_poly(s.astype(np.float64), ratio.numerator, ratio.denominator, axis=0).astype(np.float32)
            for s in self.signals
        ]
        return replace(self, signals=signals, rate_hz=self.rate_hz * ratio.numerator / ratio.denominator)

    def save(self, path: str | Path) -> Path:
        """Write the recordings to ``path`` (``.npz``); see :func:`save_vibration_npz`."""
        return save_vibration_npz(path, self)


@dataclass
class VibrationWindows:
    """Windows cut from labelled recordings, ready for :func:`tactile_torch.signal.window_features`.

    Attributes
    ----------
    windows : Tensor ``(N, 3, W)`` float32, in g
    labels : Tensor ``(N,)`` int64, class index
    recording : Tensor ``(N,)`` int64, index of the source recording
    position : Tensor ``(N,)`` int64, index of the window within its recording (time order); the
        study's odd/even split is ``position % 2``
    class_names : tuple of str
    rate_hz : float
    """

    windows: torch.Tensor
    labels: torch.Tensor
    recording: torch.Tensor
    position: torch.Tensor
    class_names: tuple[str, ...]
    rate_hz: float

    def __len__(self) -> int:
        return len(self.labels)


def save_vibration_npz(path: str | Path, recordings: VibrationRecordings) -> Path:
    """Write ``recordings`` to a ``.npz`` file in the vibration format of DESIGN.md; return the path.

    Equal-length recordings are stored as one float32 array ``signals`` ``(R, n, 3)``; recordings of
    different lengths as an object array of ``(n_i, 3)`` arrays (which needs ``allow_pickle=True``
    to load).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    lengths = {len(s) for s in recordings.signals}
    if len(lengths) <= 1 and recordings.signals:
        signals = np.stack(recordings.signals)
    else:
        signals = np.empty(len(recordings.signals), dtype=object)
        signals[:] = recordings.signals
    arrays = {
        "signals": signals,
        "labels": recordings.labels,
        "class_names": np.array(recordings.class_names, dtype=str),
        "rate_hz": np.float64(recordings.rate_hz),
    }
    if recordings.session is not None:
        arrays["session"] = recordings.session
    np.savez_compressed(path, **arrays)
    return path if path.suffix == ".npz" else path.with_name(path.name + ".npz")


def load_vibration_npz(path: str | Path, *, allow_pickle: bool = False) -> VibrationRecordings:
    """Read a vibration ``.npz`` (``signals``, ``labels``, ``class_names``, ``rate_hz``[, ``session``]).

    ``signals`` is float ``(R, n, 3)`` in g, or an object array of ``(n_i, 3)`` recordings; the latter
    is pickled, so it loads only with ``allow_pickle=True`` (only for files you trust: unpickling can
    run arbitrary code).

    Raises
    ------
    ValueError
        If a key is missing, a shape is wrong, or ragged signals are read without ``allow_pickle``.
    """
    with np.load(path, allow_pickle=allow_pickle) as data:
        missing = sorted({"signals", "labels", "class_names", "rate_hz"} - set(data.files))
        if missing:
            raise ValueError(f"{path} must hold signals, labels, class_names and rate_hz; missing {missing}")
        try:
            signals = data["signals"]
        except ValueError as err:
            raise ValueError(
                f"{path} stores recordings of different lengths as an object array; load it with "
                "allow_pickle=True if you trust the file"
            ) from err
        if signals.dtype != object and signals.ndim != 3:
            raise ValueError(f"signals in {path} must have shape (R, n, 3), got {signals.shape}")
        return VibrationRecordings(
            signals=list(signals),
            labels=data["labels"],
            class_names=tuple(data["class_names"].tolist()),
            rate_hz=float(data["rate_hz"]),
            session=data["session"] if "session" in data.files else None,
        )


def read_csv_recording(
    path: str | Path, *, columns: Sequence[str] | None = None, scale: float = 1.0
) -> tuple[np.ndarray, float]:
    """Read one CSV log of time and three accelerations; return ``(signal (n, 3) float32, rate_hz)``.

    The file has a time column in seconds and x, y, z accelerations, comma-separated. With a header
    line, the columns are found by name: ``columns`` (4 names: time, x, y, z) if given, else ``t``
    or ``time`` and ``x``, ``y``, ``z`` (case-insensitive); without one, the first four columns are
    taken in that order. Accelerations are multiplied by ``scale`` (e.g. ``1 / 9.80665`` for m/s^2
    → g). The rate is ``1 / median(dt)``; samples are taken as uniformly spaced (a warning says when
    a step deviates from the median by more than 5 %).

    Raises
    ------
    ValueError
        If a column is missing, a value is not a finite number, there are fewer than 2 rows, or the
        time stamps do not strictly increase.
    """
    path = Path(path)
    with path.open(newline="") as f:
        first = next(csv.reader(f), None)
    if first is None:
        raise ValueError(f"{path} is empty")
    try:
        [float(v) for v in first]
        header = None
    except ValueError:
        header = [h.strip().lower() for h in first]
    if header is None:
        if columns is not None:
            raise ValueError(f"{path} has no header line, so columns={list(columns)} cannot be found")
        index = [0, 1, 2, 3]
    else:
        wanted = [c.lower() for c in columns] if columns is not None else None
        if wanted is not None and len(wanted) != 4:
            raise ValueError(f"columns must name 4 columns (time, x, y, z), got {list(columns)}")
        if wanted is None:
            wanted = ["time" if "time" in header else "t", "x", "y", "z"]
        absent = [c for c in wanted if c not in header]
        if absent:
            raise ValueError(f"{path} must have columns {wanted}, missing {absent} (header: {header})")
        index = [header.index(c) for c in wanted]
    try:
        table = np.loadtxt(path, delimiter=",", skiprows=0 if header is None else 1, usecols=index, ndmin=2)
    except ValueError as err:
        raise ValueError(f"{path}: every value of columns {index} must be a number ({err})") from err
    if len(table) < 2:
        raise ValueError(f"{path} must hold at least 2 samples, got {len(table)}")
    if not np.isfinite(table).all():
        raise ValueError(f"{path} must hold finite values, got {int((~np.isfinite(table)).sum())} NaN/inf")
    dt = np.diff(table[:, 0])
    if (dt <= 0).any():
        raise ValueError(
            f"{path}: time stamps must strictly increase, row {int(np.argmax(dt <= 0)) + 1} does not"
        )
    step = float(np.median(dt))
    rate = float(f"{1.0 / step:.9g}")  # 0.01 s steps written as text give 100.00000000000213 Hz
    if np.abs(dt - step).max() > 0.05 * step:
        warnings.warn(
            f"{path}: time steps vary by up to {np.abs(dt - step).max() / step:.0%} of the median; "
            "the samples are taken as uniformly spaced",
            stacklevel=2,
        )
    return (table[:, 1:] * scale).astype(np.float32), rate


def load_vibration_csv(
    paths: str | Path | Sequence[str | Path],
    *,
    class_names: Sequence[str] | None = None,
    columns: Sequence[str] | None = None,
    scale: float = 1.0,
    rate_hz: float | None = None,
) -> VibrationRecordings:
    """Load CSV logs ``t,x,y,z`` (one recording per file) as :class:`VibrationRecordings`.

    Parameters
    ----------
    paths : path or sequence of paths
    class_names : sequence of str, optional
        Class of each file (same length as ``paths``); default the file name without extension.
        Labels index the sorted distinct names; ``session`` is the file name.
    columns, scale
        See :func:`read_csv_recording`.
    rate_hz : float, optional
        Resample every file to this rate. Without it, all files must share one rate (within 0.1 %).

    Examples
    --------
    >>> rec = load_vibration_csv(["cork_1.csv", "cork_2.csv"], class_names=["cork", "cork"])  # doctest: +SKIP
    """
    paths = [paths] if isinstance(paths, str | Path) else list(paths)
    if not paths:
        raise ValueError("paths must name at least one CSV file, got none")
    names = [Path(p).stem for p in paths] if class_names is None else [str(c) for c in class_names]
    if len(names) != len(paths):
        raise ValueError(f"class_names must give one class per file ({len(paths)}), got {len(names)}")
    read = [read_csv_recording(p, columns=columns, scale=scale) for p in paths]
    classes = tuple(sorted(set(names)))
    rates = np.array([r for _, r in read])
    signals = [s for s, _ in read]
    if rate_hz is None:
        if np.abs(rates / rates[0] - 1).max() > 1e-3:
            raise ValueError(
                f"the files have different sample rates ({sorted(set(np.round(rates, 3)))} Hz); "
                "pass rate_hz= to resample them to a common rate"
            )
        common = float(rates[0])
    else:
        check_positive(rate_hz, "rate_hz")
        common = float(rate_hz)
        signals = [
            VibrationRecordings([s], np.zeros(1, np.int64), ("_",), r).resample(common).signals[0]
            for s, r in zip(signals, rates, strict=True)
        ]
    return VibrationRecordings(
        signals=signals,
        labels=np.array([classes.index(n) for n in names]),
        class_names=classes,
        rate_hz=common,
        session=np.array([Path(p).stem for p in paths]),
    )


# The simulator's names, importable from here as before the split (loaded on first use: the
# simulator imports this module).
_SIMULATOR_NAMES = (
    "SPEED_M_S",
    "SURFACES",
    "Surface",
    "make_vibration_dataset",
    "make_vibration_recordings",
    "surface_table",
)


def __getattr__(name: str):
    if name in _SIMULATOR_NAMES:
        from . import stylus

        return getattr(stylus, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "QUANTUM_G",
    "RANGE_G",
    "SAMPLE_RATE_HZ",
    "STANDARD_GRAVITY",
    "VibrationRecordings",
    "VibrationWindows",
    "load_vibration_csv",
    "load_vibration_npz",
    "read_csv_recording",
    "save_vibration_npz",
    *_SIMULATOR_NAMES,
]
