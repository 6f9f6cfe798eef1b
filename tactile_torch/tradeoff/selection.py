"""Accuracy intervals over folds, the Pareto front, and the one-standard-error parsimony rule.

The **cost** of a candidate is its time to a decision: the seconds of sensor data it needs (the
window ``W / rate`` for vibration, the exploration's length for images; 0 for a feature file) plus
the median latency of its exported ONNX pipeline on one sample. It is what a robot waits for before
it can act on a label, it includes the compute, and for explorations (whose length every candidate
shares) it orders candidates by latency alone. Model size breaks ties.

The **Pareto front** holds the candidates that no other candidate beats on both accuracy and cost
(at least as accurate and at most as costly, and strictly better in one).

The **one-standard-error rule** (Breiman et al. 1984; Hastie, Tibshirani & Friedman, *The Elements
of Statistical Learning*, 2nd ed., section 7.10): the recommended candidate is the cheapest one on
the front whose mean accuracy is within one standard error (over folds) of the best mean accuracy.
Differences smaller than the fold-to-fold noise are not evidence that the costlier model is better,
so the cheaper one is preferred. Costs within :data:`COST_TOLERANCE` (10 %) of the cheapest eligible
one count as equal, since repeated timings differ by that much; among those, the smallest file wins
(then the most accurate). The **runner-up** is the candidate the rule picks once the recommended one
is removed.

Examples
--------
>>> acc, cost = np.array([0.90, 0.89, 0.70]), np.array([5.0, 1.0, 0.5])
>>> pareto_front(acc, cost).tolist()
[True, True, True]
>>> one_standard_error_choice(acc, np.array([0.02, 0.02, 0.05]), cost)
1
"""

from __future__ import annotations

import math

import numpy as np

COST_TOLERANCE = 0.10
"""Costs within this fraction of the cheapest eligible one count as equal (timings of one machine vary
by that much between runs); among them the smaller model wins, then the more accurate."""


def fold_interval(fold_accuracy: object, confidence: float = 0.95) -> tuple[float, float, float, float]:
    """Return ``(mean, standard error, low, high)`` of the accuracy over folds.

    The standard error is ``std(ddof=1) / sqrt(k)`` over the ``k`` fold accuracies and the interval
    Student's ``t`` with ``k - 1`` degrees of freedom, clipped to [0, 1]. Folds share training data,
    so the fold accuracies are not independent and the interval is optimistic (Nadeau & Bengio 2003);
    it is the usual cross-validation interval and the one the one-standard-error rule uses.

    Examples
    --------
    >>> [round(v, 4) for v in fold_interval([0.8, 0.9, 1.0])]
    [0.9, 0.0577, 0.6516, 1.0]
    """
    from scipy.stats import t

    values = np.asarray(fold_accuracy, dtype=np.float64)
    if values.ndim != 1 or len(values) < 2:
        raise ValueError(f"fold_accuracy must hold at least 2 folds, got shape {values.shape}")
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must be in (0, 1), got {confidence!r}")
    mean = float(values.mean())
    se = float(values.std(ddof=1) / math.sqrt(len(values)))
    half = float(t.ppf(0.5 + confidence / 2, len(values) - 1)) * se
    return mean, se, max(0.0, mean - half), min(1.0, mean + half)


def pareto_front(accuracy: object, cost: object) -> np.ndarray:
    """Return a boolean mask of the candidates that no other dominates (higher accuracy, lower cost).

    ``j`` dominates ``i`` when ``accuracy[j] >= accuracy[i]`` and ``cost[j] <= cost[i]`` with at
    least one strict. Equal candidates (same accuracy and cost) are all on the front.
    """
    acc = np.asarray(accuracy, dtype=np.float64)
    cost = np.asarray(cost, dtype=np.float64)
    if acc.shape != cost.shape or acc.ndim != 1:
        raise ValueError(f"accuracy and cost must be 1-D of one length, got {acc.shape} and {cost.shape}")
    if not (np.isfinite(acc).all() and np.isfinite(cost).all()):
        raise ValueError("accuracy and cost must be finite")
    better_or_equal = (acc[None, :] >= acc[:, None]) & (cost[None, :] <= cost[:, None])
    strictly = (acc[None, :] > acc[:, None]) | (cost[None, :] < cost[:, None])
    return ~(better_or_equal & strictly).any(axis=1)


def one_standard_error_choice(
    accuracy: object,
    standard_error: object,
    cost: object,
    tie_break: object | None = None,
    *,
    exclude: object | None = None,
) -> int:
    """Return the index the one-standard-error rule recommends (see the module notes).

    Parameters
    ----------
    accuracy, standard_error, cost : array of shape (n,)
    tie_break : array of shape (n,), optional
        Second cost (model size): among candidates within :data:`COST_TOLERANCE` of the cheapest
        eligible cost, the smallest wins.
    exclude : array of bool of shape (n,), optional
        Candidates left out (e.g. the recommended one, to find the runner-up).

    Raises
    ------
    ValueError
        If no candidate is left.
    """
    acc = np.asarray(accuracy, dtype=np.float64)
    se = np.asarray(standard_error, dtype=np.float64)
    cost = np.asarray(cost, dtype=np.float64)
    second = np.zeros_like(cost) if tie_break is None else np.asarray(tie_break, dtype=np.float64)
    keep = np.ones(len(acc), dtype=bool) if exclude is None else ~np.asarray(exclude, dtype=bool)
    if not keep.any():
        raise ValueError("at least one candidate must be left to choose from")
    index = np.flatnonzero(keep)
    front = index[pareto_front(acc[index], cost[index])]
    # The best: highest accuracy, then cheapest (it is on the front).
    best = min(front, key=lambda i: (-acc[i], cost[i], second[i]))
    eligible = [i for i in front if acc[i] >= acc[best] - se[best] - 1e-12]
    cheapest = min(cost[i] for i in eligible)
    alike = [i for i in eligible if cost[i] <= cheapest * (1.0 + COST_TOLERANCE)]
    return int(min(alike, key=lambda i: (second[i], -acc[i], cost[i], i)))


__all__ = ["COST_TOLERANCE", "fold_interval", "one_standard_error_choice", "pareto_front"]
