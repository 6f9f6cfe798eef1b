"""What a sweep returns: the accuracy :class:`Curve` of each model under each factor, its
:class:`BreakingPoint`, and the :class:`SweepResult` that holds them."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .degradations import Degradation


@dataclass(frozen=True)
class BreakingPoint:
    """Where a curve falls halfway from its clean accuracy to chance.

    Positions count along the curve's path: 0 is the clean input, ``k`` its ``k``-th level (from 1),
    ``math.inf`` beyond the harshest level tested.

    Attributes
    ----------
    status : str
        ``"reached"``; ``"not reached"`` (never at or below the threshold); ``"fit failed"`` (never at
        or below the threshold while the model could be fitted, and not at the next level, which is
        then its breaking level); ``"at chance"`` (the clean accuracy is not above chance).
    position, low, high : float
        The breaking position and its 95 % bootstrap interval.
    threshold : float
        ``chance + (clean - chance) / 2``.
    text : str
        The breaking level and its interval in the factor's unit, e.g. ``"8.3 dB [5.1 dB, 11 dB]"``.
    level : float or None
        The breaking level as a number (when reached between two numeric levels).
    """

    status: str
    position: float
    low: float
    high: float
    threshold: float
    text: str
    level: float | None = None


@dataclass
class Curve:
    """Accuracy of one model under one factor, level by level, with its breaking point.

    Attributes
    ----------
    factor : Degradation
    model : str
    levels : tuple
        The levels evaluated (those the data allows; fewer when a fit failed), mildest first.
    accuracy, low, high : ndarray of shape (len(levels),)
        Accuracy of the pooled test predictions and its 95 % cluster-bootstrap interval.
    clean, clean_low, clean_high : float
        The same without degradation (drift: on the segment right after training).
    chance : float
        ``1 / n_classes``.
    breaking : BreakingPoint
    note : str
        Why the curve stops early (a level at which the model could not be fitted), or ``""``.
    """

    factor: Degradation
    model: str
    levels: tuple
    accuracy: np.ndarray
    low: np.ndarray
    high: np.ndarray
    clean: float
    clean_low: float
    clean_high: float
    chance: float
    breaking: BreakingPoint
    note: str = ""

    def path(self) -> tuple[list, np.ndarray, np.ndarray, np.ndarray]:
        """The levels, accuracies and bounds along the breaking path (Table 4: the grid's diagonal)."""
        idx = [i for i in (self.factor.path or range(len(self.levels))) if i < len(self.levels)]
        return [self.levels[i] for i in idx], self.accuracy[idx], self.low[idx], self.high[idx]


@dataclass
class SweepResult:
    """What :func:`~.sweeps.sweep` returns: the curves, the factors skipped and why, the factors that
    failed (an error: a bug; the other factors' curves are kept) and the folds used."""

    curves: list[Curve]
    skipped: list[tuple[str, str]] = field(default_factory=list)
    failed: list[tuple[str, str]] = field(default_factory=list)
    n_splits: int = 0
    kind: str = ""

    def by_factor(self) -> dict[str, list[Curve]]:
        """Curves grouped by factor name, in sweep order."""
        out: dict[str, list[Curve]] = {}
        for c in self.curves:
            out.setdefault(c.factor.name, []).append(c)
        return out
