"""Triaxial vibration recordings in memory and on disk (the ``.npz`` format; CSV logs: ``read_csv_recordings``).

:class:`VibrationRecordings` holds recordings in the vibration format of docs/formats.md (``signals`` in g,
``labels``, ``class_names``, ``rate_hz``, optional ``session``); :meth:`~VibrationRecordings.windows`
cuts them into the ``(N, 3, W)`` windows of :func:`tactile_torch.signal.window_features`. The
seeded stylus simulator lives in :mod:`tactile_torch.data.stylus`. Files are read and written by :mod:`tactile_torch.robot.files.formats` (NumPy only; ``docs/formats.md``);
the functions here turn them into :class:`VibrationRecordings`.

Examples
--------
>>> import numpy as np
>>> rec = VibrationRecordings([np.zeros((1600, 3))], np.array([0]), ("glass",), 800.0)
>>> rec.windows(400).windows.shape
torch.Size([4, 3, 400])
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..exceptions import InputTypeError
from ..validation import check_positive

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
    """Triaxial recordings with labels: the vibration format of docs/formats.md, in memory.

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
    gaps : list of ndarray, optional
        Per recording, the samples that start a new stretch after a gap in its time stamps (CSV logs
        and bags, :attr:`tactile_torch.robot.files.formats.RecordingArrays.gaps`): no window spans a gap.
    """

    signals: list[np.ndarray]
    labels: np.ndarray
    class_names: tuple[str, ...]
    rate_hz: float
    session: np.ndarray | None = None
    gaps: list[np.ndarray] | None = None

    def __post_init__(self) -> None:
        checked = []
        for i, s in enumerate(self.signals):
            s = np.asarray(s)
            if s.ndim != 2 or s.shape[1] != 3:
                raise ValueError(f"signals[{i}] must have shape (n, 3), got {s.shape}")
            if not np.issubdtype(s.dtype, np.number):
                raise InputTypeError(f"signals[{i}] must be numeric, got dtype {s.dtype}")
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
            raise InputTypeError(f"labels must be integers, got dtype {labels.dtype}")
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
        if self.gaps is not None:
            self.gaps = [np.asarray(g, dtype=np.int64) for g in self.gaps]
            if len(self.gaps) != len(checked):
                raise ValueError(
                    f"gaps must give one array per recording ({len(checked)}), got {len(self.gaps)}"
                )

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
            Recordings shorter than ``size`` give no window; no window spans a gap (``gaps``).

        Raises
        ------
        ValueError
            If no recording is at least ``size`` samples long.
        """
        import torch

        from ..robot.stream.windows import window_recordings

        check_positive(size, "size", integer=True)
        cut = window_recordings(self.signals, size, step, max_per_recording=max_per_recording, gaps=self.gaps)
        return VibrationWindows(
            windows=torch.from_numpy(cut.windows),
            labels=torch.from_numpy(self.labels[cut.recording]),
            recording=torch.from_numpy(cut.recording),
            position=torch.from_numpy(cut.position),
            class_names=self.class_names,
            rate_hz=self.rate_hz,
        )

    @classmethod
    def from_arrays(cls, arrays: object) -> VibrationRecordings:
        """Return the recordings a reader of :mod:`tactile_torch.robot.files.formats` gave (``RecordingArrays``:
        a vibration ``.npz``, CSV logs read by ``read_csv_recordings``, ROS 2 bags)."""
        return cls(
            arrays.signals, arrays.labels, arrays.class_names, arrays.rate_hz, arrays.session, arrays.gaps
        )

    def resample(self, rate_hz: float) -> VibrationRecordings:
        """Return the recordings resampled to ``rate_hz`` with ``scipy.signal.resample_poly``.

        The ratio is approximated by a fraction with denominator <= 1000; resample_poly low-pass
        filters (Kaiser window) before decimating, and pads the ends with zeros, so the first and last
        few dozen samples are attenuated. Resampling does not add information: 100 Hz data upsampled
        to 800 Hz still holds nothing above 50 Hz. The stretches between ``gaps`` are resampled one by
        one (no filter reaches across a gap).
        """
        from scipy.signal import resample_poly

        check_positive(rate_hz, "rate_hz")
        ratio = Fraction(float(rate_hz) / self.rate_hz).limit_denominator(1000)
        if ratio == 1:
            return replace(self, signals=[s.copy() for s in self.signals])
        up, down = ratio.numerator, ratio.denominator
        signals, gaps = [], []
        for i, s in enumerate(self.signals):
            cuts = [] if self.gaps is None else self.gaps[i].tolist()
            parts = [
                resample_poly(part.astype(np.float64), up, down, axis=0).astype(np.float32)
                for part in np.split(s, cuts)
            ]
            signals.append(np.concatenate(parts))
            gaps.append(np.cumsum([len(p) for p in parts[:-1]]).astype(np.int64))
        return replace(
            self, signals=signals, rate_hz=self.rate_hz * up / down, gaps=None if self.gaps is None else gaps
        )

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
    """Write ``recordings`` to a ``.npz`` file in the vibration format; return the path written.

    Equal-length recordings are stored as one float32 array ``signals`` ``(R, n, 3)``; recordings of
    different lengths as their samples concatenated ``(sum n_i, 3)`` plus ``lengths`` ``(R,)``: no
    pickle either way (:func:`tactile_torch.robot.files.formats.write_recordings`, ``docs/formats.md``).
    """
    from ..robot.files.formats import RecordingArrays, write_recordings

    arrays = RecordingArrays(
        recordings.signals,
        recordings.labels,
        recordings.class_names,
        recordings.rate_hz,
        recordings.session,
        recordings.gaps,
    )
    return write_recordings(path, arrays)


def load_vibration_npz(path: str | Path, *, allow_pickle: bool = False) -> VibrationRecordings:
    """Read a vibration ``.npz`` (``signals``, ``labels``, ``class_names``, ``rate_hz``[, ``lengths``, ``session``]).

    ``signals`` is float ``(R, n, 3)`` in g, or the concatenated samples ``(sum n_i, 3)`` of
    recordings of different lengths with ``lengths`` ``(R,)``. Files written by tactile-torch 0.1
    stored the latter as a pickled object array: those load only with ``allow_pickle=True`` (only for
    files you trust: unpickling can run arbitrary code); re-save them to drop the pickle.

    Raises
    ------
    ValueError
        One line naming the file and the field: a missing key, a wrong shape or dtype (integer
        counts where g are expected), NaN/inf, or a pickled array read without ``allow_pickle``
        (:func:`tactile_torch.robot.files.formats.read_recordings`).
    """
    from ..robot.files.formats import read_recordings

    return VibrationRecordings.from_arrays(read_recordings(path, allow_pickle=allow_pickle))


__all__ = [
    "QUANTUM_G",
    "RANGE_G",
    "SAMPLE_RATE_HZ",
    "STANDARD_GRAVITY",
    "VibrationRecordings",
    "VibrationWindows",
    "load_vibration_npz",
    "save_vibration_npz",
]
