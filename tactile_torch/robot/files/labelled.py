"""Raw input read from a data file for a bundle, with its labels (:class:`LabelledInput`; numpy only)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class LabelledInput:
    """Raw input read from a data file by :meth:`tactile_torch.robot.runtime.OnnxPipeline.read_npz`.

    Attributes
    ----------
    raw : ndarray
        In the bundle's input layout (uint8 frames are kept uint8: :meth:`~tactile_torch.robot.runtime.OnnxPipeline.validate`
        scales them).
    labels : ndarray of shape (N,) int64, or None
        Class index into the bundle's ``class_names`` (-1: a class the bundle does not know); ``None``
        when the file has no labels.
    file_class_names : list of str or None
        The file's own class names.
    rate_hz : float or None
        Sample rate of vibration recordings (``None`` for other data).
    file_labels : ndarray of shape (N,) int64, or None
        The file's own labels (indices into ``file_class_names``), e.g. to score a clustering.
    note : str or None
        What was done to fit the data to the bundle (explorations of another length brought to its
        frames), one line.
    """

    raw: np.ndarray
    labels: np.ndarray | None
    file_class_names: list[str] | None
    rate_hz: float | None = None
    file_labels: np.ndarray | None = None
    note: str | None = None


__all__ = ["LabelledInput"]
