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

import numpy as np

from .checks import check_count


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
    size, step = check_count(size, "size", 1), check_count(step, "step", 1)
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


__all__ = ["Windows", "window_recordings"]
