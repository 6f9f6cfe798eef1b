"""Cut vibration recordings into windows with NumPy (the robot's and the training's one windowing).

Window ``j`` of a recording holds its samples ``j * step ... j * step + size - 1``, transposed to
``(3, size)``: the windows of :func:`tactile_torch.signal.sliding_windows`, as NumPy, for the
runtime (:meth:`tactile_torch.robot.runtime.OnnxPipeline.read_npz`), training and the trade-off.

Examples
--------
>>> import numpy as np
>>> window_recordings([np.zeros((900, 3)), np.zeros((500, 3))], 400, 200).windows.shape
(4, 3, 400)
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from ...validation import check_count

MIN_WINDOW = 16
"""Fewest samples in a window that features are computed on (``train``, ``cluster``, model files): the
21 features of fewer samples are degenerate (20 crossing thresholds between a handful of values, the
upper half of a spectrum of a few bins)."""
MAX_WINDOW = 1 << 20
"""Most samples in a feature window (1,048,576: 22 minutes at 800 Hz, 10 s at 100 kHz). A model file
declaring more is refused before anything is allocated for it."""


def check_window(value: object, name: str = "window") -> int:
    """Return ``value`` as an int if it is a feature window of :data:`MIN_WINDOW` .. :data:`MAX_WINDOW` samples.

    >>> check_window(800)
    800
    >>> check_window(5)
    Traceback (most recent call last):
    ...
    ValueError: window must be a number of samples in 16 .. 1,048,576, got 5
    """
    if (
        isinstance(value, bool)
        or not isinstance(value, int | np.integer)
        or not MIN_WINDOW <= value <= MAX_WINDOW
    ):
        raise ValueError(
            f"{name} must be a number of samples in {MIN_WINDOW} .. {MAX_WINDOW:,}, got {value!r}"
        )
    return int(value)


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


def window_recordings(
    signals: Sequence[np.ndarray],
    size: int,
    step: int | None = None,
    *,
    max_per_recording: int | None = None,
    gaps: Sequence[np.ndarray] | None = None,
) -> Windows:
    """Cut every recording ``(n_i, 3)`` into windows of ``size`` samples every ``step``.

    Window ``j`` of a recording holds its samples ``j * step ... j * step + size - 1``, transposed to
    ``(3, size)``; trailing samples that do not fill a window are dropped and recordings shorter
    than ``size`` give none. The same windows as :func:`tactile_torch.signal.sliding_windows`, as
    NumPy. ``gaps`` (per recording, the samples that follow a gap in its time stamps,
    :attr:`tactile_torch.robot.files.formats.RecordingArrays.gaps`): no window spans a gap; each stretch
    between gaps is cut on its own, from its first sample, and ``position`` counts the windows of a
    recording in time order across its stretches.

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
    size, step = check_count(size, "size", 1), check_count(step, "step", 1)
    if size < 2:
        raise ValueError(f"size must be >= 2 samples, got {size}")
    parts, recording, position = [], [], []
    for i, rec in enumerate(signals):
        rec = np.asarray(rec)
        if rec.ndim != 2 or rec.shape[1] != 3:
            raise ValueError(f"signals[{i}] must have shape (n, 3), got {rec.shape}")
        bounds = [0, *(() if gaps is None else (int(g) for g in gaps[i])), len(rec)]
        stretches = [rec[a:b] for a, b in pairwise(bounds) if b - a >= size]
        if not stretches:
            continue
        views = [
            np.lib.stride_tricks.sliding_window_view(p, int(size), axis=0)[:: int(step)] for p in stretches
        ]
        view = views[0] if len(views) == 1 else np.concatenate(views)  # (n_w, 3, W)
        if max_per_recording is not None:
            view = view[:max_per_recording]
        parts.append(view.astype(np.float32, copy=False))
        recording.append(np.full(len(view), i, dtype=np.int64))
        position.append(np.arange(len(view), dtype=np.int64))
    if not parts:
        longest = max((len(s) for s in signals), default=0)
        if gaps is not None and longest >= size:
            raise ValueError(
                f"no stretch between gaps in the time stamps holds a window of {size} samples (the longest "
                f"recording has {longest} samples)"
            )
        raise ValueError(f"no recording holds a window of {size} samples (longest: {longest} samples)")
    return Windows(
        np.ascontiguousarray(np.concatenate(parts)), np.concatenate(recording), np.concatenate(position)
    )


__all__ = ["MAX_WINDOW", "MIN_WINDOW", "Windows", "check_window", "window_recordings"]
