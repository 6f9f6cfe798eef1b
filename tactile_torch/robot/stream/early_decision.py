"""Anytime decisions: give a touch's label before it ends, as soon as the model is sure enough.

A hand should not have to wait for the end of a grasp when its first frames already say what it
holds. During a touch the stream classifies its frames so far at a few **checkpoints** (frame counts
into the touch, :func:`checkpoints_for`), each brought to the bundle's ``T`` frames as at the end
(:func:`~tactile_torch.robot.stream.touches.fit_frames`), and decides early at the first checkpoint whose
**score margin** (the label's score minus the best other class's score, :func:`score_margins`, in the
bundle's own score units) reaches the rule's threshold.

The threshold is calibrated (:func:`calibrate_early_rule`) on held-out touches of the training data
(each classified at every checkpoint by a model that did not see it) to a stated error rate ``alpha``:
the smallest threshold whose early decisions on those touches satisfy ``(errors + 1) / (decided + 1)
<= alpha`` (the +1 keeps a handful of lucky touches from passing: at ``alpha = 0.05`` at least 19
touches must be decided early without an error). When no threshold satisfies it, the rule never
decides early (threshold ``inf``) and says so. The rule travels in the bundle's metadata
(:data:`~tactile_torch.robot.contract.EARLY_RULE_KEY`, :meth:`EarlyRule.to_metadata`). numpy only.

Examples
--------
>>> score_margins(np.array([[2.0, 0.5, 1.0]]), np.array([0]))
array([1.])
>>> checkpoints_for(8)
(1, 2, 3, 4, 5, 6, 7)
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

DEFAULT_ERROR = 0.05
"""Default error rate the early decisions are calibrated to."""
CHECKPOINT_SHARES = (0.125, 0.25, 0.375, 0.5, 0.625, 0.75, 0.875)
"""Checkpoints as shares of the bundle's ``T`` frames (rounded, at least 1 frame, below ``T``)."""
_MAX_CANDIDATES = 4096


def checkpoints_for(n_frames: int) -> tuple[int, ...]:
    """Return the checkpoints (frames into a touch) for a bundle that takes ``n_frames`` frames."""
    return tuple(sorted({max(1, round(s * n_frames)) for s in CHECKPOINT_SHARES} - {n_frames}))


def score_margins(scores: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """Return each row's margin: the score of its label minus the largest other score.

    ``scores`` ``(N, C)``, ``labels`` ``(N,)``; ``-inf`` for a label outside ``0 .. C-1`` (unknown) or
    non-finite scores; with one class the margin is ``inf``.
    """
    scores = np.asarray(scores, dtype=np.float64)
    labels = np.asarray(labels)
    n, c = scores.shape
    out = np.full(n, -np.inf)
    ok = (labels >= 0) & (labels < c) & np.isfinite(scores).all(axis=1)
    if not ok.any():
        return out
    rows = np.flatnonzero(ok)
    own = scores[rows, labels[rows]]
    others = scores[rows].copy()
    others[np.arange(len(rows)), labels[rows]] = -np.inf
    out[rows] = own - others.max(axis=1) if c > 1 else np.inf
    return out


@dataclass(frozen=True)
class EarlyRule:
    """Decide a touch early when the score margin at a checkpoint reaches ``threshold``.

    Attributes
    ----------
    threshold : float
        ``inf``: never early (the calibration found no threshold that meets ``target_error``).
    checkpoints : tuple of int
        Frames into a touch at which it is checked.
    target_error : float
        The error rate the threshold was calibrated to (``alpha``).
    error : float or None
        Share of wrong early decisions on the calibration touches.
    decided : int
        Calibration touches decided early.
    touches : int
        Calibration touches.
    median_frames : float or None
        Median checkpoint (frames into the touch) of the early decisions on the calibration touches.
    how : str
        What the calibration ran on, in words.
    """

    threshold: float
    checkpoints: tuple[int, ...]
    target_error: float = DEFAULT_ERROR
    error: float | None = None
    decided: int = 0
    touches: int = 0
    median_frames: float | None = None
    how: str = ""

    @property
    def active(self) -> bool:
        """Whether the rule can decide early at all."""
        return math.isfinite(self.threshold) and bool(self.checkpoints)

    def describe(self) -> str:
        """One line: the rule and what it achieved on its calibration touches."""
        if not self.active:
            return (
                f"no early decisions: no margin threshold kept the early errors at {self.target_error:.0%} on "
                f"{self.touches} held-out touches; decisions at the end of each touch"
            )
        error = "" if self.error is None else f", {self.error:.1%} wrong"
        frames = (
            "" if self.median_frames is None else f", median {self.median_frames:g} frames into the touch"
        )
        return (
            f"early when the score margin reaches {self.threshold:.4g} at {len(self.checkpoints)} checkpoints "
            f"(calibrated to {self.target_error:.0%} errors: {self.decided} of {self.touches} held-out touches "
            f"decided early{error}{frames})"
        )

    def to_metadata(self) -> dict:
        """Return the rule as a JSON-able dict (``threshold`` ``null`` for never)."""
        return {
            "rule": "score margin",
            "threshold": self.threshold if math.isfinite(self.threshold) else None,
            "checkpoints": [int(c) for c in self.checkpoints],
            "target_error": float(self.target_error),
            "error": None if self.error is None else float(self.error),
            "decided": int(self.decided),
            "touches": int(self.touches),
            "median_frames": None if self.median_frames is None else float(self.median_frames),
            "how": self.how,
        }

    @classmethod
    def from_metadata(cls, value: str | dict) -> EarlyRule:
        """Return the rule a bundle records (JSON text or dict); ``ValueError`` naming what is wrong."""
        try:
            d = json.loads(value) if isinstance(value, str) else dict(value)
            threshold = d.get("threshold")
            threshold = math.inf if threshold is None else float(threshold)
            checkpoints = tuple(int(c) for c in d.get("checkpoints", ()))
            if math.isnan(threshold) or any(c < 1 for c in checkpoints):
                raise ValueError("threshold must be a number, checkpoints >= 1")
            return cls(
                threshold=threshold,
                checkpoints=checkpoints,
                target_error=float(d.get("target_error", DEFAULT_ERROR)),
                error=None if d.get("error") is None else float(d["error"]),
                decided=int(d.get("decided", 0)),
                touches=int(d.get("touches", 0)),
                median_frames=None if d.get("median_frames") is None else float(d["median_frames"]),
                how=str(d.get("how", "")),
            )
        except (json.JSONDecodeError, TypeError, ValueError, AttributeError) as err:
            raise ValueError(
                f"early_decision metadata must be the JSON of an early-decision rule, got {str(value)[:80]!r}: {err}"
            ) from None


def first_decisions(margins: np.ndarray, threshold: float) -> np.ndarray:
    """Return, per touch, the index of the first checkpoint whose margin reaches ``threshold``, else -1."""
    reached = np.asarray(margins) >= threshold
    first = reached.argmax(axis=1)
    return np.where(reached.any(axis=1), first, -1)


def calibrate_early_rule(
    margins: np.ndarray,
    correct: np.ndarray,
    checkpoints: tuple[int, ...],
    *,
    target_error: float = DEFAULT_ERROR,
    how: str = "",
) -> EarlyRule:
    """Return the :class:`EarlyRule` whose threshold keeps early errors on held-out touches at ``target_error``.

    Parameters
    ----------
    margins : ndarray of shape (N, K)
        Score margin of each held-out touch at each checkpoint (:func:`score_margins`; ``-inf`` where
        the label was unknown).
    correct : ndarray of shape (N, K), bool
        Whether the label at that checkpoint was the touch's class.
    checkpoints : tuple of int
        The ``K`` checkpoints (frames into the touch).
    target_error : float in (0, 1)
    how : str
        What the touches are, in words (kept in the rule).

    The threshold is the smallest candidate (the held-out margins themselves) whose early decisions
    satisfy ``(errors + 1) / (decided + 1) <= target_error``; ``inf`` when none does.
    """
    margins = np.asarray(margins, dtype=np.float64)
    correct = np.asarray(correct, dtype=bool)
    if margins.ndim != 2 or margins.shape != correct.shape or margins.shape[1] != len(checkpoints):
        raise ValueError(
            f"margins and correct must have shape (N, {len(checkpoints)}) (touches, checkpoints), got "
            f"{margins.shape} and {correct.shape}"
        )
    if not 0.0 < target_error < 1.0:
        raise ValueError(f"target_error must be in (0, 1), got {target_error!r}")
    n = len(margins)
    candidates = np.unique(margins[np.isfinite(margins) & (margins > 0)])
    if len(candidates) > _MAX_CANDIDATES:
        candidates = np.unique(np.quantile(candidates, np.linspace(0, 1, _MAX_CANDIDATES)))
    best = None
    for threshold in candidates:  # ascending: the first that meets the bound decides the most touches
        first = first_decisions(margins, threshold)
        decided = first >= 0
        m = int(decided.sum())
        errors = int((~correct[np.flatnonzero(decided), first[decided]]).sum())
        if (errors + 1) / (m + 1) <= target_error:
            best = (float(threshold), m, errors, first[decided])
            break
    if best is None:
        return EarlyRule(math.inf, tuple(checkpoints), target_error, None, 0, n, None, how)
    threshold, m, errors, first = best
    median = float(np.median(np.asarray(checkpoints)[first]))
    return EarlyRule(threshold, tuple(checkpoints), target_error, errors / m, m, n, median, how)


def held_out_rule(
    y: np.ndarray,
    folds: Sequence[tuple[np.ndarray, np.ndarray]],
    checkpoints: tuple[int, ...],
    classify: Callable[[int, int, np.ndarray], tuple[np.ndarray, np.ndarray]],
    *,
    target_error: float = DEFAULT_ERROR,
    how: str = "",
) -> tuple[np.ndarray, np.ndarray, EarlyRule]:
    """Return the held-out decisions of touches at each checkpoint, their margins, and the rule they calibrate.

    The one calibration of the early rule, for ``tactile-torch tradeoff`` (its touch-time study) and
    ``train`` (its held-out folds): each touch ``i`` of a fold's test part is classified at every
    checkpoint by that fold's model, which did not see it, and :func:`calibrate_early_rule` sets the
    threshold on what those decisions were worth.

    Parameters
    ----------
    y : ndarray of shape (N,)
        Each touch's class.
    folds : sequence of (train rows, test rows)
    checkpoints : tuple of int
        Frames into the touch (:func:`checkpoints_for`).
    classify : callable
        ``classify(fold, j, test)`` -> ``(classes, margins)`` of the touches ``test`` at checkpoint ``j``:
        the predicted class of each, and its score margin (:func:`score_margins`, in the bundle's scores).
    target_error, how
        As :func:`calibrate_early_rule`.

    Returns
    -------
    predicted : ndarray of shape (N, K) int64
        The class each touch was given at each checkpoint (-1: not tested).
    margins : ndarray of shape (N, K)
    rule : EarlyRule
    """
    n, k = len(y), len(checkpoints)
    predicted = np.full((n, k), -1, dtype=np.int64)
    margins = np.full((n, k), -np.inf)
    for f, (_, test) in enumerate(folds):
        for j in range(k):
            predicted[test, j], margins[test, j] = classify(f, j, test)
    tested = predicted[:, 0] >= 0 if k else np.zeros(n, dtype=bool)
    correct = predicted == np.asarray(y)[:, None]
    rule = calibrate_early_rule(
        margins[tested], correct[tested], checkpoints, target_error=target_error, how=how
    )
    return predicted, margins, rule


__all__ = [
    "CHECKPOINT_SHARES",
    "DEFAULT_ERROR",
    "EarlyRule",
    "calibrate_early_rule",
    "checkpoints_for",
    "first_decisions",
    "held_out_rule",
    "score_margins",
]
