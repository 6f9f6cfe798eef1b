"""Early stopping of the candidates that cannot be recommended: the rule, and the bookkeeping of a study.

The study evaluates its candidates fold by fold, every running candidate on fold ``r`` before any on
fold ``r + 1`` (:mod:`.evaluation`), and after each fold but the last it stops the candidates that the
evidence says cannot end up recommended. ``exhaustive=True`` (``tradeoff --exhaustive``) stops none.

**What can be recommended** (:func:`~.selection.choose`). Without a target the choice is the cheapest
candidate on the Pareto front within one standard error of the best, among those above the trivial
baseline. Take a candidate ``c`` and another ``L`` that is cheaper beyond the cost tolerance
(``cost(c) > (1 + COST_TOLERANCE) cost(L)``) and ends above the baseline. If ``c`` is recommended then
``L`` is not eligible: it is off the front (dominated by an adequate ``D``, itself not eligible) or more
than one standard error below the best; either way ``c``, which is eligible, ends strictly more accurate
than ``L`` (the standard error is never 0). So **a candidate that ends no more accurate than a cheaper
adequate one is never recommended**, and removing it changes nothing: it is dominated, and a dominated
candidate is neither on the front nor the best. With a target, the choice needs the interval's lower
end at the target, hence the mean at the target: **a candidate whose mean ends below the target is
never recommended**, and its removal changes nothing either.

**The test** (after ``k`` of the ``g`` units of the data have been tested, ``m = g - k`` to come). The
study's intervals already treat the units' accuracies as exchangeable draws (the prediction interval
for a new unit); under the same model the mean of the ``m`` units to come is predicted from the ``k``
seen with Student's ``t`` on ``k - 1`` degrees of freedom, ``x̄_m - x̄_k ~ s sqrt(1/k + 1/m) t``.

* Against a cheaper candidate ``L`` (no target): with the paired differences ``d_u = acc_L(u) -
  acc_c(u)`` on the units both have been tested on, ``c`` ends more accurate than ``L`` only if the
  differences to come average below ``-k d̄ / m``; its probability is
  ``P = F_t(-d̄ (g / m) / (s sqrt(1/k + 1/m)); k - 1)`` (:func:`chance_to_beat`).
* Against the target: ``c``'s mean ends at the target only if its units to come average at least
  ``(g target - k ā) / m`` (:func:`chance_to_reach`).

``s`` is at least the binomial noise of one unit's accuracy, ``sqrt(p (1 - p) / n)`` with ``p`` the
Agresti-Coull estimate and ``n`` the mean samples per unit, as in the study's intervals (so that units
that agree exactly do not make ``s`` zero). A candidate is stopped when ``P < level`` (below), and never before
:data:`MIN_UNITS` units are seen.

**The guarantee.** Removing a candidate changes the recommendation only if it is the one the
exhaustive study recommends, or (without a target) the most accurate one, whose accuracy sets the
one-standard-error bar: any other is dominated, or on the front but neither the best nor cheaper than
the choice. Each of those two meets at most one check per fold but the last, and each check stops it
with probability below ``level`` under the model above, so **the stopped study recommends what the
exhaustive one would, except with probability at most** ``2 (folds - 1) level`` = :data:`STOP_RISK`
(1 %): ``level`` is set from the number of folds (``0.01 / 8`` with 5 folds). The premise "``L`` ends
above the baseline" is verified at the end (:meth:`EarlyStopping.to_resume`): a candidate stopped by
one that did not end adequate (directly or through the candidate that stopped its stopper) is
evaluated on its remaining folds after all. A candidate with no exported file (its export failed) can
never be chosen and stops at once.

This is Optuna's ``WilcoxonPruner`` idea (stop a trial whose paired per-instance results are worse than
the best's beyond a p-value) with the study's own model of units in place of a rank test: with one
session per fold a rank test cannot reach a small p-value on 2-4 pairs. Unlike scikit-learn's
``HalvingGridSearchCV`` (keep the best ``1 / factor`` at each rung, whatever their margin) it never
stops a candidate for being merely behind.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .selection import COST_TOLERANCE

STOP_RISK = 0.01
"""The probability, at most, that early stopping changes the recommendation (the guarantee above)."""
MIN_UNITS = 2
"""Units seen before any check (Student's ``t`` needs one degree of freedom)."""


def stop_level(folds: int) -> float:
    """Return the level of one check in a study of ``folds`` folds: ``STOP_RISK / (2 (folds - 1))``.

    >>> stop_level(5)
    0.00125
    """
    return STOP_RISK / (2 * max(int(folds) - 1, 1))


def _floor(correct: float, count: float, per_unit: float) -> float:
    p = (correct + 2.0) / (count + 4.0)
    return math.sqrt(p * (1.0 - p) / max(per_unit, 1.0))


def chance_to_beat(difference: np.ndarray, remaining: int, *, floor: float = 0.0) -> float:
    """Return the probability that a candidate ends more accurate than a leader (module notes).

    Parameters
    ----------
    difference : array of shape (k,)
        Per unit seen, the leader's accuracy minus the candidate's.
    remaining : int
        Units still to be tested (``m``).
    floor : float
        Lower bound of the differences' standard deviation.

    Examples
    --------
    >>> round(chance_to_beat([0.30, 0.25, 0.35, 0.28], 1, floor=0.02), 6) < 0.001
    True
    >>> chance_to_beat([0.30, -0.25], 3) > 0.1
    True
    """
    from scipy.stats import t

    d = np.asarray(difference, dtype=np.float64)
    k, m = len(d), int(remaining)
    if m <= 0:
        return float(d.mean() < 0)
    if k < MIN_UNITS:
        return 1.0
    s = max(float(d.std(ddof=1)), floor, 1e-12)
    g = k + m
    return float(t.cdf(-d.mean() * (g / m) / (s * math.sqrt(1 / k + 1 / m)), k - 1))


def chance_to_reach(accuracy: np.ndarray, remaining: int, target: float, *, floor: float = 0.0) -> float:
    """Return the probability that a candidate's mean accuracy over all units ends at ``target`` or above.

    >>> chance_to_reach([0.5, 0.55, 0.45], 2, 0.95, floor=0.05) < 0.01
    True
    """
    from scipy.stats import t

    a = np.asarray(accuracy, dtype=np.float64)
    k, m = len(a), int(remaining)
    if m <= 0:
        return float(a.mean() >= target - 1e-12)
    if k < MIN_UNITS:
        return 1.0
    s = max(float(a.std(ddof=1)), floor, 1e-12)
    g = k + m
    need = (g * target - k * a.mean()) / m
    return float(t.sf((need - a.mean()) / (s * math.sqrt(1 / k + 1 / m)), k - 1))


@dataclass
class Stop:
    """Why a candidate was stopped: after ``folds`` folds, by ``by`` (a cheaper candidate, ``"target"`` or
    ``"no exported file"``), with ``chance`` the probability the test gave it."""

    folds: int
    by: str
    chance: float
    reason: str


@dataclass
class Progress:
    """A candidate's per-unit results so far (correct and tested samples by unit name)."""

    correct: dict[str, float] = field(default_factory=dict)
    count: dict[str, float] = field(default_factory=dict)

    def add(self, names: list[str], correct: np.ndarray, count: np.ndarray) -> None:
        for name, c, n in zip(names, correct, count, strict=True):
            self.correct[name] = self.correct.get(name, 0.0) + float(c)
            self.count[name] = self.count.get(name, 0.0) + float(n)

    def accuracy(self, names: list[str]) -> np.ndarray:
        return np.array([self.correct[u] / self.count[u] for u in names])


@dataclass
class EarlyStopping:
    """The early stops of one study (module notes): feed each fold's results, ask which to stop.

    Parameters
    ----------
    units : dict of str to int
        Per raw input, the number of units of its data (``g``).
    folds : int
        The study's number of folds (the checks come after each but the last).
    target : float or None
    enabled : bool
        ``False`` (``exhaustive``): :meth:`check` stops nothing.
    """

    units: dict[str, int]
    folds: int
    target: float | None = None
    enabled: bool = True
    progress: dict[str, Progress] = field(default_factory=dict)
    inputs: dict[str, str] = field(default_factory=dict)
    cost: dict[str, float] = field(default_factory=dict)
    stopped: dict[str, Stop] = field(default_factory=dict)

    @property
    def level(self) -> float:
        """The level of each check: :data:`STOP_RISK` shared by the two candidates' checks (module notes)."""
        return stop_level(self.folds)

    def record(self, name: str, input_key: str, names: list[str], correct: object, count: object) -> None:
        """Add one fold's per-unit results (``correct``, ``count`` by unit ``names``) of candidate ``name``."""
        self.inputs[name] = input_key
        self.progress.setdefault(name, Progress()).add(
            list(names), np.asarray(correct, dtype=np.float64), np.asarray(count, dtype=np.float64)
        )

    def set_cost(self, name: str, cost: float | None) -> None:
        """The candidate's time to a decision (``None``: no exported file, so it can never be chosen)."""
        if cost is None:
            self.cost.pop(name, None)
            if self.enabled and name not in self.stopped:
                self.stopped[name] = Stop(0, "no exported file", 0.0, "no ONNX file could be exported")
        else:
            self.cost[name] = float(cost)

    def running(self, names: list[str]) -> list[str]:
        """Those of ``names`` not stopped."""
        return [n for n in names if n not in self.stopped]

    def _floor(self, name: str) -> float:
        p = self.progress[name]
        correct, count = sum(p.correct.values()), sum(p.count.values())
        return _floor(correct, count, count / max(len(p.count), 1))

    def check(self, folds_done: int) -> dict[str, Stop]:
        """Stop the running candidates the tests of the module notes rule out; return the new stops."""
        if not self.enabled:
            return {}
        new: dict[str, Stop] = {}
        running = [n for n in self.progress if n not in self.stopped]
        for name in running:
            p = self.progress[name]
            g = self.units[self.inputs[name]]
            seen = sorted(p.count)
            if len(seen) < MIN_UNITS or len(seen) >= g:
                continue
            if self.target is not None:
                chance = chance_to_reach(
                    p.accuracy(seen), g - len(seen), self.target, floor=self._floor(name)
                )
                if chance < self.level:
                    new[name] = Stop(
                        folds_done,
                        "target",
                        chance,
                        f"stopped after {folds_done} folds: its mean accuracy reaches the target "
                        f"{self.target:.3f} with probability {chance:.2g}",
                    )
                continue
            if name not in self.cost:
                continue
            best = None
            for other in running:
                if other == name or other not in self.cost or other in new:
                    continue
                if not self.cost[name] > (1.0 + COST_TOLERANCE) * self.cost[other]:
                    continue
                q = self.progress[other]
                shared = sorted(set(seen) & set(q.count))
                if len(shared) < MIN_UNITS or self.units[self.inputs[other]] != g:
                    continue
                diff = q.accuracy(shared) - p.accuracy(shared)
                chance = chance_to_beat(
                    diff, g - len(shared), floor=max(self._floor(name), self._floor(other))
                )
                if best is None or chance < best[1]:
                    best = (other, chance)
            if best is not None and best[1] < self.level:
                other, chance = best
                new[name] = Stop(
                    folds_done,
                    other,
                    chance,
                    f"stopped after {folds_done} folds: it ends more accurate than {other}, which is cheaper, "
                    f"with probability {chance:.2g}",
                )
        self.stopped.update(new)
        return new

    def to_resume(self, adequate: dict[str, bool]) -> list[str]:
        """Return the stopped candidates whose premise failed (module notes), and forget their stops.

        ``adequate``: per finished candidate, whether it ended above the trivial baseline. A candidate
        stopped by another is resumed unless the chain of stoppers ends in a finished adequate one.
        """
        resume = []
        for name, stop in list(self.stopped.items()):
            if stop.by in ("target", "no exported file"):
                continue
            by, seen = stop.by, {name}
            while by in self.stopped and self.stopped[by].by not in ("target", "no exported file"):
                if by in seen:
                    break
                seen.add(by)
                by = self.stopped[by].by
            if by in self.stopped or not adequate.get(by, False):
                resume.append(name)
        for name in resume:
            del self.stopped[name]
        return resume


__all__ = [
    "MIN_UNITS",
    "STOP_RISK",
    "EarlyStopping",
    "Stop",
    "chance_to_beat",
    "chance_to_reach",
    "stop_level",
]
