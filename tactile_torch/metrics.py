"""Evaluation metrics of the two studies.

``class_report`` (per-class accuracy, Type-I and Type-II errors, confusion matrix) and ``mcnemar``
(paired comparison of two classifiers) score the supervised experiments (method 1), with
``time_per_sample`` for the cost of classifying one sample; ``pairwise_accuracy`` scores a
clustering against true labels (method 2, unsupervised).
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


def _as_label_array(labels: object, name: str) -> np.ndarray:
    # torch is not imported here (the metrics serve the torch-free `predict` too): a tensor can only
    # exist if its module is loaded.
    torch = sys.modules.get("torch")
    if torch is not None and isinstance(labels, torch.Tensor):
        labels = labels.detach().cpu().numpy()
    if hasattr(labels, "columns") and len(labels.columns) == 1:  # a one-column pandas DataFrame
        labels = labels.iloc[:, 0]
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


@dataclass(frozen=True)
class ClassReport:
    """Per-class accuracy and error rates of one classification, as :func:`class_report` returns.

    Attributes
    ----------
    labels : ndarray of shape (C,)
        The classes, in the order of every per-class array and of the confusion matrix.
    confusion : ndarray of shape (C, C), int64
        ``confusion[i, j]``: samples of class ``labels[i]`` predicted as ``labels[j]``.
    accuracy : ndarray of shape (C,)
        Per-class accuracy (recall): share of the class's samples labelled correctly.
    type1 : ndarray of shape (C,)
        Type-I error (false alarm) of each class: share of the *other* classes' samples labelled as
        this class.
    type2 : ndarray of shape (C,)
        Type-II error (miss) of each class: ``1 - accuracy``.
    overall_accuracy : float
        Share of all samples labelled correctly.
    names : tuple of str
        Display names of the classes.
    """

    labels: np.ndarray
    confusion: np.ndarray
    accuracy: np.ndarray
    type1: np.ndarray
    type2: np.ndarray
    overall_accuracy: float
    names: tuple[str, ...]

    @property
    def mean_accuracy(self) -> float:
        """Mean of the per-class accuracies (balanced accuracy)."""
        return float(np.nanmean(self.accuracy))

    @property
    def mean_type1(self) -> float:
        """Mean Type-I error over the classes."""
        return float(np.nanmean(self.type1))

    @property
    def mean_type2(self) -> float:
        """Mean Type-II error over the classes."""
        return float(np.nanmean(self.type2))

    def rows(self) -> list[dict]:
        """Return one table row per class plus a ``mean`` row (for :meth:`Section.table`)."""
        rows = [
            {
                "class": name,
                "samples": int(self.confusion[i].sum()),
                "accuracy": float(self.accuracy[i]),
                "type I error": float(self.type1[i]),
                "type II error": float(self.type2[i]),
            }
            for i, name in enumerate(self.names)
        ]
        rows.append(
            {
                "class": "mean",
                "samples": int(self.confusion.sum()),
                "accuracy": self.mean_accuracy,
                "type I error": self.mean_type1,
                "type II error": self.mean_type2,
            }
        )
        return rows

    def to_dict(self, *, mean_row: bool = False) -> dict[str, list]:
        """Return the table as a dict of columns, one entry per class (and the ``mean`` row last if
        ``mean_row``): ``class``, ``samples``, ``accuracy``, ``type I error``, ``type II error``.

        ``pandas.DataFrame(report.to_dict())`` makes a data frame of it. A class absent from
        ``y_true`` has NaN accuracy and Type-II error.
        """
        rows = self.rows() if mean_row else self.rows()[:-1]
        return {column: [row[column] for row in rows] for column in rows[0]}

    def __str__(self) -> str:
        """The table as text: one line per class, the mean row, then the overall accuracy ("n/a" where
        a rate is undefined: a class absent from ``y_true``, or one class only)."""
        rows = self.rows()
        width = max(5, *(len(row["class"]) for row in rows))

        def rate(value: float) -> str:
            return f"{value:.4f}" if np.isfinite(value) else "n/a"

        lines = [f"{'class':<{width}} {'samples':>7} {'accuracy':>9} {'type I':>8} {'type II':>8}"]
        for row in rows:
            lines.append(
                f"{row['class']:<{width}} {row['samples']:>7} {rate(row['accuracy']):>9} "
                f"{rate(row['type I error']):>8} {rate(row['type II error']):>8}"
            )
        lines.append(f"overall accuracy {self.overall_accuracy:.4f}")
        return "\n".join(lines)


def class_report(
    y_true: object, y_pred: object, *, labels: object = None, names: object = None
) -> ClassReport:
    """Return per-class accuracy, Type-I and Type-II errors and the confusion matrix.

    For class ``c``: accuracy = share of its samples labelled ``c`` (recall); Type-II error =
    ``1 - accuracy``; Type-I error = share of the samples of the *other* classes labelled ``c``
    (method 1's definitions). A class absent from ``y_true`` has NaN accuracy and Type-II error
    (left out of the means); with a single class there are no other samples and its Type-I error is
    NaN too.

    Parameters
    ----------
    y_true, y_pred : array-like, pandas Series or tensor of shape (n,)
    labels : array-like of shape (C,), optional
        The classes and their order (default: the sorted union of both label arrays).
    names : sequence of str of length C, optional
        Display names (default: ``str`` of each label).

    Returns
    -------
    ClassReport
        ``print(report)`` shows it as a table; ``report.to_dict()`` gives its columns.

    Examples
    --------
    >>> rep = class_report([0, 0, 1, 1, 2, 2], [0, 1, 1, 1, 2, 0], names=["cork", "felt", "foam"])
    >>> rep.accuracy.tolist(), rep.type1.tolist()
    ([0.5, 1.0, 0.5], [0.25, 0.25, 0.0])
    >>> print(rep)
    class samples  accuracy   type I  type II
    cork        2    0.5000   0.2500   0.5000
    felt        2    1.0000   0.2500   0.0000
    foam        2    0.5000   0.0000   0.5000
    mean        6    0.6667   0.1667   0.3333
    overall accuracy 0.6667
    >>> rep.to_dict()["accuracy"]
    [0.5, 1.0, 0.5]
    """
    a = _as_label_array(y_true, "y_true")
    b = _as_label_array(y_pred, "y_pred")
    if a.shape != b.shape:
        raise ValueError(f"y_true and y_pred must have the same length, got {a.shape[0]} and {b.shape[0]}")
    if a.shape[0] == 0:
        raise ValueError("y_true must hold at least one sample, got an empty array")
    if labels is None:
        labels = np.union1d(a, b)
    else:
        labels = _as_label_array(labels, "labels")
        if np.unique(labels).shape[0] != labels.shape[0]:
            raise ValueError(f"labels must not repeat a class, got {labels.tolist()}")
        unknown = np.setdiff1d(np.union1d(a, b), labels)
        if unknown.shape[0]:
            raise ValueError(f"labels must list every class in y_true and y_pred; missing {unknown.tolist()}")
    k = labels.shape[0]
    if names is None:
        names = tuple(str(v) for v in labels.tolist())
    else:
        names = tuple(str(v) for v in names)
        if len(names) != k:
            raise ValueError(f"names must have one entry per class ({k}), got {len(names)}")
    index = {v: i for i, v in enumerate(labels.tolist())}
    ia = np.array([index[v] for v in a.tolist()], dtype=np.int64)
    ib = np.array([index[v] for v in b.tolist()], dtype=np.int64)
    confusion = np.bincount(ia * k + ib, minlength=k * k).reshape(k, k)
    support = confusion.sum(1)
    correct = np.diag(confusion)
    with np.errstate(invalid="ignore", divide="ignore"):
        accuracy = np.where(support > 0, correct / np.maximum(support, 1), np.nan)
        others = support.sum() - support
        false_alarms = confusion.sum(0) - correct
        type1 = np.where(others > 0, false_alarms / np.maximum(others, 1), np.nan)
    return ClassReport(
        labels=labels,
        confusion=confusion,
        accuracy=accuracy,
        type1=type1,
        type2=1.0 - accuracy,
        overall_accuracy=float(correct.sum() / support.sum()),
        names=names,
    )


@dataclass(frozen=True)
class McNemarResult:
    """McNemar's test of two classifiers on the same samples, as :func:`mcnemar` returns.

    Attributes
    ----------
    n01 : int
        Samples classifier A got wrong and B right.
    n10 : int
        Samples A got right and B wrong.
    chi2 : float
        ``(|n01 - n10| - 1)^2 / (n01 + n10)`` (continuity-corrected); 0 when ``n01 + n10 = 0``.
    p_value : float
        ``P(chi2_1 >= chi2)`` under the null hypothesis that both err equally often; 1 when
        ``n01 + n10 = 0``.
    reject : bool
        ``chi2 > 3.841`` (the 0.05 quantile of chi-square with 1 degree of freedom), i.e.
        ``p_value < 0.05``: the classifiers differ.
    """

    n01: int
    n10: int
    chi2: float
    p_value: float
    reject: bool


CHI2_1DOF_95 = 3.841458820694124  # scipy.stats.chi2.ppf(0.95, 1)


def mcnemar(y_true: object, pred_a: object, pred_b: object) -> McNemarResult:
    """Return McNemar's test (continuity-corrected) of classifiers A and B on the same samples.

    Only the discordant samples count: ``n01`` (A wrong, B right) and ``n10`` (A right, B wrong).
    ``chi2 = (|n01 - n10| - 1)^2 / (n01 + n10)``, compared with chi-square with 1 degree of freedom
    (``p = erfc(sqrt(chi2 / 2))``); the difference is significant at 0.05 when ``chi2 > 3.841``.
    Without discordant samples the classifiers are indistinguishable: ``chi2 = 0``, ``p = 1``.

    Parameters
    ----------
    y_true, pred_a, pred_b : array-like or tensor of shape (n,)

    Returns
    -------
    McNemarResult

    Examples
    --------
    >>> r = mcnemar([0] * 30, [0] * 20 + [1] * 10, [0] * 28 + [1] * 2)
    >>> r.n01, r.n10, round(r.chi2, 4), r.reject
    (8, 0, 6.125, True)
    """
    t = _as_label_array(y_true, "y_true")
    a = _as_label_array(pred_a, "pred_a")
    b = _as_label_array(pred_b, "pred_b")
    if not (t.shape == a.shape == b.shape):
        raise ValueError(
            f"y_true, pred_a and pred_b must have the same length, got {t.shape[0]}, {a.shape[0]} and {b.shape[0]}"
        )
    right_a, right_b = a == t, b == t
    n01 = int((~right_a & right_b).sum())
    n10 = int((right_a & ~right_b).sum())
    if n01 + n10 == 0:
        return McNemarResult(n01, n10, 0.0, 1.0, False)
    chi2 = (abs(n01 - n10) - 1.0) ** 2 / (n01 + n10)
    # Survival function of chi-square with 1 degree of freedom: P(Z^2 >= x) = erfc(sqrt(x / 2)).
    p_value = math.erfc(math.sqrt(chi2 / 2.0))
    return McNemarResult(n01, n10, chi2, p_value, chi2 > CHI2_1DOF_95)


def time_per_sample(
    predict: Callable[[object], object], X: object, *, repeat: int = 5, min_time: float = 0.05
) -> float:
    """Return the median wall-clock seconds ``predict`` takes per sample of ``X``.

    ``predict(X)`` runs once untimed (warm-up), then at least ``repeat`` times and at least
    ``min_time`` seconds; the median of the timed calls is divided by ``len(X)``. Pass one sample
    (``X[:1]``) for the latency of classifying one sample alone, a batch for the throughput.

    Examples
    --------
    >>> time_per_sample(lambda x: [v > 0 for v in x], [1.0, -1.0]) < 1e-3
    True
    """
    n = len(X)  # type: ignore[arg-type]
    if n == 0:
        raise ValueError("X must hold at least one sample, got 0")
    predict(X)
    times: list[float] = []
    start = time.perf_counter()
    while len(times) < repeat or time.perf_counter() - start < min_time:
        t0 = time.perf_counter()
        predict(X)
        times.append(time.perf_counter() - t0)
    return float(np.median(times)) / n


__all__ = [
    "CHI2_1DOF_95",
    "ClassReport",
    "McNemarResult",
    "class_report",
    "mcnemar",
    "pairwise_accuracy",
    "time_per_sample",
]
