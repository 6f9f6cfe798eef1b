"""Evaluation metrics of the two studies.

``pairwise_accuracy`` scores a clustering against true labels (method 2, unsupervised).
"""

from __future__ import annotations

import numpy as np
import torch


def _as_label_array(labels: object, name: str) -> np.ndarray:
    if isinstance(labels, torch.Tensor):
        labels = labels.detach().cpu().numpy()
    arr = np.asarray(labels)
    if arr.ndim != 1:
        raise ValueError(f"{name} must be a 1-D array of labels, got shape {arr.shape}")
    if arr.dtype.kind == "f" and not np.isfinite(arr).all():
        raise ValueError(f"{name} must not contain NaN or inf")
    return arr


def pairwise_accuracy(labels_true: object, labels_pred: object) -> float:
    """Return the share of point pairs whose same/different status agrees between two labellings.

    ``1 - (pairs together in one labelling and apart in the other) / (n choose 2)``: the clustering
    accuracy of the Pitman-Yor study (it equals the Rand index). Label values are arbitrary; only
    which points share a label matters. Computed from the contingency table in O(n + K1*K2).

    Parameters
    ----------
    labels_true, labels_pred : array-like or tensor of shape (n,)
        Two labellings of the same n points (ints, strings, ...).

    Returns
    -------
    float in [0, 1]. With fewer than two points there is no pair and the result is defined as 1.0.

    Examples
    --------
    >>> pairwise_accuracy([0, 0, 1, 1], [5, 5, 7, 7])
    1.0
    >>> round(pairwise_accuracy([0, 0, 1, 1], [0, 1, 0, 1]), 4)  # 2 of 6 pairs agree
    0.3333
    """
    a = _as_label_array(labels_true, "labels_true")
    b = _as_label_array(labels_pred, "labels_pred")
    if a.shape != b.shape:
        raise ValueError(
            f"labels_true and labels_pred must have the same length, got {a.shape[0]} and {b.shape[0]}"
        )
    n = a.shape[0]
    if n < 2:
        return 1.0
    _, ia = np.unique(a, return_inverse=True)
    _, ib = np.unique(b, return_inverse=True)
    table = np.zeros((ia.max() + 1, ib.max() + 1), dtype=np.int64)
    np.add.at(table, (ia, ib), 1)

    def pairs(counts: np.ndarray) -> int:
        return int((counts * (counts - 1) // 2).sum())

    together_both = pairs(table)
    disagree = pairs(table.sum(axis=1)) + pairs(table.sum(axis=0)) - 2 * together_both
    return 1.0 - disagree / (n * (n - 1) / 2)


__all__ = ["pairwise_accuracy"]
