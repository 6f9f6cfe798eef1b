"""Nested tuning: choose a model's hyper-parameters on inner folds of one outer training part."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from sklearn.base import clone

from ._models import inner_splits

PROTOCOLS = ("kfold", "validation")


@dataclass(frozen=True)
class Tuning:
    """How a model's hyper-parameters are chosen inside every outer training fold.

    Attributes
    ----------
    grid : dict or list of dict
        Parameter grid in the model's parameter names (``"classifier__C"`` for a pipeline's step), as
        scikit-learn's ``GridSearchCV`` takes it.
    n_splits : int
        Inner folds (grouped and stratified where the training part's groups allow, see
        :func:`~tactile_torch.model_selection.inner_splits`).
    protocol : {"kfold", "validation"}
        ``"kfold"``: the mean accuracy over the inner folds chooses (method 2's stratified k-fold grid
        search). ``"validation"``: the first inner fold alone is the validation part (method 1's
        60/20/20 protocol with ``n_splits=4`` on an 80 % outer training part).
    """

    grid: dict | list
    n_splits: int = 3
    protocol: str = "kfold"

    def __post_init__(self) -> None:
        if self.protocol not in PROTOCOLS:
            raise ValueError(f"protocol must be one of {PROTOCOLS}, got {self.protocol!r}")
        if isinstance(self.n_splits, bool) or not isinstance(self.n_splits, int) or self.n_splits < 2:
            raise ValueError(f"n_splits must be an integer >= 2, got {self.n_splits!r}")

    @property
    def size(self) -> int:
        """Number of parameter combinations of the grid."""
        from sklearn.model_selection import ParameterGrid

        return len(ParameterGrid(self.grid))


def tune(
    model: Any,
    Z: Any,
    y: np.ndarray,
    groups: np.ndarray | None,
    tuning: Tuning,
    seed: int,
    *,
    threads: int | None = None,
) -> tuple[dict, str]:
    """Return the parameters of ``tuning.grid`` with the best inner-fold accuracy, and a note.

    Our SVMs (alone or last in a ``Pipeline``) go through the batched
    :class:`~tactile_torch.model_selection.SVMGridSearchCV` (one kernel per gamma and inner fold, warm
    starts along C); any other model through scikit-learn's ``GridSearchCV`` on the same inner folds.
    Ties go to the first combination in grid order. With a grid of one combination, or no inner fold
    possible (a class with a single training sample), the grid's first combination is returned untried;
    when every combination fails on the inner folds (too few samples of a class), ``{}`` (the model's
    own parameters); the note says which.
    """
    from sklearn.model_selection import GridSearchCV, ParameterGrid

    from ._search import SVMGridSearchCV, supports_batched_search

    combinations = list(ParameterGrid(tuning.grid))
    if len(combinations) == 1:
        return dict(combinations[0]), "one combination: nothing to tune"
    splits, how = inner_splits(y, groups, tuning.n_splits, seed)
    if not splits:
        return dict(combinations[0]), f"not tuned: {how}"
    if tuning.protocol == "validation":
        splits, how = splits[:1], f"one validation part of {how}"
    if supports_batched_search(model):
        search = SVMGridSearchCV(clone(model), tuning.grid, cv=splits, refit=False, n_jobs=threads)
    else:
        search = GridSearchCV(clone(model), tuning.grid, cv=splits, scoring="accuracy", refit=False)
    try:
        search.fit(Z, y)
    except Exception as err:  # too few samples in an inner fold for every combination: the defaults
        return {}, f"not tuned: every combination failed on {how} ({_first_line(err)})"
    return dict(search.best_params_), how


def _first_line(err: Exception) -> str:
    lines = [line.strip() for line in str(err).splitlines() if line.strip()]
    return f"{type(err).__name__}: {(lines or [''])[0][:160]}"
