"""Accuracy intervals over the data's units, the trivial baseline, the Pareto front and the choice.

**Unit.** What a deployment meets is a new session, recording or object, not a new fold: the
accuracy a user sees there differs from the pooled cross-validation accuracy by the session-to-session
spread. Each sample belongs to one *unit* (:attr:`~.inputs.Samples.units`: the session, recording,
group, time block, or, when the data name none, the test fold); every candidate's out-of-fold
predictions give one accuracy per unit.

**Interval** (:func:`unit_interval`): a 95 % *prediction* interval for the accuracy on one new unit,
``mean ± t(0.975, g - 1) · s · sqrt(1 + 1/g)`` over the ``g`` per-unit accuracies (unweighted: each
unit counts once, as the next session will), clipped to [0, 1]. A confidence interval of the mean
(``± t s / sqrt(g)``) would describe the average over many new sessions and is ``sqrt(g + 1)`` times
narrower than the spread one new session shows. ``s`` is at least the binomial noise of one unit of
the average size, ``sqrt(p (1 - p) / n)`` with ``p = (correct + 2) / (n + 4)`` (Agresti & Coull
1998): units that all happen to score 1.0 do not make an interval of zero width. With fewer than
:data:`MIN_UNITS` units there is no interval: the *range* over the units (lowest, highest) is given
instead, with one warning line.

**Trivial baseline** (:func:`majority_predictions`): per fold, the training fold's most frequent class
for every test sample; it is the best of the trivial rules (a stratified random guess scores
``sum p_c^2 <= max p_c`` in expectation). **Chance** is ``1 / n_classes``. A candidate is *above the
baseline* when a one-sided paired t-test over the units of (candidate − baseline) accuracy rejects at
5 % (:func:`above_baseline`; with fewer than 3 units, a one-sided binomial test of the pooled correct
count against the baseline's pooled accuracy, which ignores the grouping).

The **cost** of a candidate is its time to a decision: the seconds of sensor data it needs (the
window ``W / rate`` for vibration, the exploration's length for images; 0 for a feature file) plus
the median latency of its exported ONNX pipeline on one sample. It is what a robot waits for before
it can act on a label, it includes the compute, and for explorations (whose length every candidate
shares) it orders candidates by latency alone. Model size breaks ties.

The **Pareto front** holds the candidates that no other candidate beats on both accuracy and cost
(at least as accurate and at most as costly, and strictly better in one).

**The choice** (:func:`choose`). With a target accuracy: the cheapest candidate whose interval's
lower end (the range's lowest unit with few units) reaches the target. Without one, the
**one-standard-error rule** (Breiman et al. 1984; Hastie, Tibshirani & Friedman, *The Elements of
Statistical Learning*, 2nd ed., section 7.10): the cheapest candidate on the front whose mean
accuracy is within one standard error (``s / sqrt(g)`` over units) of the best mean accuracy, among
the candidates significantly above the trivial baseline. Costs within :data:`COST_TOLERANCE` (10 %) of
the cheapest eligible one count as equal, since repeated timings differ by that much; among those,
the smallest file wins (then the most accurate). No eligible candidate: no recommendation. The
**runner-up** is the candidate the rule picks once the recommended one is removed.

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
from dataclasses import dataclass

import numpy as np

COST_TOLERANCE = 0.10
"""Costs within this fraction of the cheapest eligible one count as equal (timings of one machine vary
by that much between runs); among them the smaller model wins, then the more accurate."""
MIN_UNITS = 5
"""Fewer units than this give the range over the units instead of an interval (and a warning)."""
CONFIDENCE = 0.95
"""Coverage of the prediction interval."""
ALPHA = 0.05
"""Level of the one-sided test against the trivial baseline."""


@dataclass(frozen=True)
class UnitAccuracy:
    """Per-unit accuracies of one candidate and the interval they give (module notes).

    Attributes
    ----------
    units : ndarray of shape (g,)
        The unit ids, sorted.
    accuracy : ndarray of shape (g,)
        Accuracy on each unit's samples.
    correct, count : ndarray of shape (g,)
        Correct and tested samples of each unit.
    mean, se, low, high : float
        Mean over units, standard error ``s / sqrt(g)``, interval (``kind == "prediction"``) or range
        (``kind == "range"``).
    kind : {"prediction", "range"}
    """

    units: np.ndarray
    accuracy: np.ndarray
    correct: np.ndarray
    count: np.ndarray
    mean: float
    se: float
    low: float
    high: float
    kind: str

    @property
    def n(self) -> int:
        """Number of units."""
        return len(self.units)


def unit_accuracy(y: object, predicted: object, units: object) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return ``(unit ids, correct, tested)`` per unit; samples predicted ``-1`` (never tested) are left out."""
    y, predicted, units = (np.asarray(a) for a in (y, predicted, units))
    if not (y.shape == predicted.shape == units.shape and y.ndim == 1):
        raise ValueError(
            f"y, predicted and units must be 1-D of one length, got {y.shape}, {predicted.shape}, {units.shape}"
        )
    tested = predicted >= 0
    ids, inverse = np.unique(units[tested], return_inverse=True)
    correct = np.bincount(
        inverse, weights=(predicted[tested] == y[tested]).astype(np.float64), minlength=len(ids)
    )
    count = np.bincount(inverse, minlength=len(ids)).astype(np.float64)
    return ids, correct, count


def unit_interval(
    correct: object, count: object, *, units: object | None = None, confidence: float = CONFIDENCE
) -> UnitAccuracy:
    """Return the per-unit accuracies and the prediction interval (or range) for one new unit.

    Parameters
    ----------
    correct, count : array of shape (g,)
        Correct and tested samples of each unit (``count > 0``).
    units : array of shape (g,), optional
        The unit ids (default ``0 .. g - 1``).
    confidence : float in (0, 1)

    Examples
    --------
    >>> u = unit_interval([9, 8, 10, 7, 9], [10, 10, 10, 10, 10])
    >>> round(u.mean, 2), u.kind, round(u.low, 3), round(u.high, 3)
    (0.86, 'prediction', 0.502, 1.0)
    >>> unit_interval([10, 10, 10], [10, 10, 10]).kind   # three units: the range, never [1, 1] as an interval
    'range'
    """
    from scipy.stats import t

    correct = np.asarray(correct, dtype=np.float64)
    count = np.asarray(count, dtype=np.float64)
    if correct.ndim != 1 or correct.shape != count.shape or len(count) == 0:
        raise ValueError(
            f"correct and count must be 1-D of one length >= 1, got {correct.shape} and {count.shape}"
        )
    if (count <= 0).any() or (correct < 0).any() or (correct > count).any():
        raise ValueError("count must be > 0 and 0 <= correct <= count for every unit")
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must be in (0, 1), got {confidence!r}")
    ids = np.arange(len(count)) if units is None else np.asarray(units)
    acc = correct / count
    g = len(acc)
    mean = float(acc.mean())
    p = (correct.sum() + 2.0) / (count.sum() + 4.0)
    floor = math.sqrt(p * (1 - p) / count.mean())
    s = max(float(acc.std(ddof=1)) if g > 1 else 0.0, floor)
    se = s / math.sqrt(g)
    if g < MIN_UNITS:
        return UnitAccuracy(ids, acc, correct, count, mean, se, float(acc.min()), float(acc.max()), "range")
    half = float(t.ppf(0.5 + confidence / 2, g - 1)) * s * math.sqrt(1 + 1 / g)
    return UnitAccuracy(
        ids, acc, correct, count, mean, se, max(0.0, mean - half), min(1.0, mean + half), "prediction"
    )


def majority_predictions(y: object, folds: object) -> np.ndarray:
    """Return the trivial baseline's out-of-fold predictions: each fold's training majority class (ties: lowest)."""
    y = np.asarray(y)
    out = np.full(len(y), -1, dtype=np.int64)
    for train, test in folds:
        out[test] = int(np.bincount(y[train]).argmax())
    return out


def above_baseline(
    candidate: UnitAccuracy, baseline: UnitAccuracy, *, alpha: float = ALPHA
) -> tuple[bool, float]:
    """Return ``(significant, p-value)`` of the one-sided test *candidate better than baseline* (module notes).

    Both must be measured on the same units, in the same order.
    """
    from scipy.stats import binomtest, ttest_1samp

    if not np.array_equal(candidate.units, baseline.units):
        raise ValueError("candidate and baseline must be measured on the same units")
    diff = candidate.accuracy - baseline.accuracy
    if len(diff) >= 3:
        if np.ptp(diff) == 0:  # no spread: the sign decides
            p = 0.0 if diff[0] > 0 else 1.0
        else:
            p = float(ttest_1samp(diff, 0.0, alternative="greater").pvalue)
    else:
        k, n = int(candidate.correct.sum()), int(candidate.count.sum())
        base = float(min(max(baseline.correct.sum() / baseline.count.sum(), 1e-12), 1 - 1e-12))
        p = float(binomtest(k, n, base, alternative="greater").pvalue)
    return p < alpha, p


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


def _cheapest(index: list[int], acc: np.ndarray, cost: np.ndarray, second: np.ndarray) -> int:
    cheapest = min(cost[i] for i in index)
    alike = [i for i in index if cost[i] <= cheapest * (1.0 + COST_TOLERANCE)]
    return int(min(alike, key=lambda i: (second[i], -acc[i], cost[i], i)))


def choose(
    accuracy: object,
    standard_error: object,
    low: object,
    cost: object,
    tie_break: object | None = None,
    *,
    adequate: object | None = None,
    target: float | None = None,
    exclude: object | None = None,
) -> int | None:
    """Return the index the rule of the module notes recommends, or ``None`` when no candidate is adequate.

    Parameters
    ----------
    accuracy, standard_error, low, cost : array of shape (n,)
        Mean accuracy over units, its standard error, the interval's (or range's) lower end, the cost.
    tie_break : array of shape (n,), optional
        Model size.
    adequate : array of bool of shape (n,), optional
        Without a target: the candidates significantly above the trivial baseline (default: all).
    target : float in (0, 1], optional
        The accuracy a deployment needs: the cheapest candidate whose ``low`` reaches it.
    exclude : array of bool of shape (n,), optional
        Candidates left out (the recommended one, to find the runner-up).
    """
    acc = np.asarray(accuracy, dtype=np.float64)
    cost = np.asarray(cost, dtype=np.float64)
    second = np.zeros_like(cost) if tie_break is None else np.asarray(tie_break, dtype=np.float64)
    keep = np.ones(len(acc), dtype=bool) if exclude is None else ~np.asarray(exclude, dtype=bool)
    if target is not None:
        if not 0 < target <= 1:
            raise ValueError(f"target must be an accuracy in (0, 1], got {target!r}")
        index = [int(i) for i in np.flatnonzero(keep & (np.asarray(low, dtype=np.float64) >= target - 1e-12))]
        return _cheapest(index, acc, cost, second) if index else None
    if adequate is not None:
        keep &= np.asarray(adequate, dtype=bool)
    if not keep.any():
        return None
    se = np.asarray(standard_error, dtype=np.float64)
    index = np.flatnonzero(keep)
    return int(index[one_standard_error_choice(acc[index], se[index], cost[index], second[index])])


__all__ = [
    "ALPHA",
    "CONFIDENCE",
    "COST_TOLERANCE",
    "MIN_UNITS",
    "UnitAccuracy",
    "above_baseline",
    "choose",
    "fold_interval",
    "majority_predictions",
    "one_standard_error_choice",
    "pareto_front",
    "unit_accuracy",
    "unit_interval",
]
