"""How long a study has left: an estimate from the tasks done so far, weighted by what each task is.

A study's tasks differ by orders of magnitude (a fold of LDA on 21 features takes milliseconds, a fold
of a network seconds to minutes), so a bar that counts tasks (what a progress bar over a stage shows)
swings between minutes and an hour as it passes from one kind to the next. :class:`RemainingTime`
estimates each task still to run from the tasks like it that have run:

1. every task belongs to a **group** (a candidate: its folds cost about the same) and a **family**
   (tasks alike in kind: the networks, the tuned SVMs, the exports ...) and has a **weight**, its
   expected cost relative to the other tasks of its family (the training samples of its fold);
2. a task still to run is estimated at the seconds per weight of its group when one of the group's
   tasks has run, else of its family, else the mean over every finished task times the family's prior
   :data:`PRIORS` (what a task of that family costs against the average one, measured on the bench's
   studies), or the seconds the caller expects of it (a stage after the cross-validation: the breaking
   points refit the recommended model about as many times as :func:`~.breaking.refits` says);
3. the study runs the first fold of every candidate before any second fold, and of each family one
   task first (:func:`probe_first`), so that every group's estimate comes from its own measurement after
   the first fold, about a fifth of the cross-validation with 5 folds.

The estimate is of the seconds left at the rate of the tasks done so far: a machine whose load doubles
half-way makes it low by up to 2x until the rate is seen again. ``tests/tradeoff/test_progress.py``
checks, on scripted schedules (no timing), that after the first tenth of the work the estimated total
stays within a factor of 2 of the real one.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

PRIORS = {
    "neural": 20.0,
    "learned front end": 20.0,
    "svm": 2.0,
    "classical": 1.0,
    "export": 1.0,
    "deploy": 5.0,
    "breaking": 10.0,
}
"""Cost of one task of a family against the mean task done so far, before any of the family has run."""


@dataclass(frozen=True)
class Task:
    """One unit of a study's work.

    Attributes
    ----------
    key : hashable
        Unique in the study (``(candidate, fold)``, ``("export", candidate)`` ...).
    group : str
        Tasks that cost about the same per weight (one candidate's folds).
    family : str
        A key of :data:`PRIORS` (or any other name: prior 1).
    weight : float
        Expected cost relative to the family's other tasks (> 0).
    expected : float or None
        Seconds expected before any task of its group or family has run (a stage after the
        cross-validation, estimated from the folds' times: the deployment, the breaking points); ``None``:
        the prior.
    """

    key: object
    group: str
    family: str
    weight: float = 1.0
    expected: float | None = None


@dataclass
class RemainingTime:
    """The tasks of a study, those done with their seconds, and the estimate of the seconds left."""

    tasks: dict = field(default_factory=dict)
    seconds: dict = field(default_factory=dict)

    def plan(self, tasks: Iterable[Task]) -> None:
        """Add tasks to run (a key already planned is replaced)."""
        for task in tasks:
            self.tasks[task.key] = task

    def drop(self, keys: Iterable[object]) -> None:
        """Remove planned tasks that will not run (a candidate stopped early); done ones stay."""
        for key in keys:
            if key not in self.seconds:
                self.tasks.pop(key, None)

    def finish(self, key: object, seconds: float) -> None:
        """Record that task ``key`` took ``seconds``."""
        self.seconds[key] = max(float(seconds), 0.0)

    @property
    def elapsed(self) -> float:
        """Seconds of the tasks done."""
        return float(sum(self.seconds.values()))

    def _rates(self) -> tuple[dict, dict, float]:
        groups: dict[str, list[float]] = {}
        families: dict[str, list[float]] = {}
        done = [(self.tasks[k], s) for k, s in self.seconds.items() if k in self.tasks]
        for task, s in done:
            groups.setdefault(task.group, [0.0, 0.0])
            families.setdefault(task.family, [0.0, 0.0])
            for acc in (groups[task.group], families[task.family]):
                acc[0] += s
                acc[1] += task.weight
        mean = sum(s for _, s in done) / len(done) if done else 0.0
        return (
            {g: s / w for g, (s, w) in groups.items() if w > 0},
            {f: s / w for f, (s, w) in families.items() if w > 0},
            mean,
        )

    def estimate(self, task: Task, rates: tuple[dict, dict, float] | None = None) -> float:
        """Return the seconds task ``task`` is expected to take (module notes)."""
        groups, families, mean = rates or self._rates()
        if task.group in groups:
            return groups[task.group] * task.weight
        if task.family in families:
            return families[task.family] * task.weight
        if task.expected is not None:
            return task.expected
        return mean * PRIORS.get(task.family, 1.0)

    def remaining(self) -> float:
        """Return the estimated seconds of the tasks still to run (0 before any task has finished)."""
        rates = self._rates()
        return float(sum(self.estimate(t, rates) for k, t in self.tasks.items() if k not in self.seconds))

    def fraction_done(self) -> float:
        """Return the share of the estimated work done, in [0, 1]."""
        left = self.remaining()
        total = self.elapsed + left
        return self.elapsed / total if total > 0 else 0.0


def probe_first(tasks: Sequence[Task]) -> list[Task]:
    """Return ``tasks`` with the first task of every family first (in their order), then the rest in order."""
    seen, first, rest = set(), [], []
    for task in tasks:
        (rest if task.family in seen else first).append(task)
        seen.add(task.family)
    return first + rest


def minutes(seconds: float) -> str:
    """``"about 3 min"``, ``"about 40 s"``: an estimate in words, rounded as it deserves."""
    if seconds < 90:
        return f"about {max(5, round(seconds / 5) * 5):.0f} s"
    return f"about {seconds / 60:.0f} min"


__all__ = ["PRIORS", "RemainingTime", "Task", "minutes", "probe_first"]
