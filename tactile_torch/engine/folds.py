"""Folds that never put related samples on both sides: stratified, grouped when every class has two groups.

The trade-off's inputs (:mod:`tactile_torch.tradeoff.inputs`) and ``train`` make their explorations'
and feature rows' folds here; :func:`sample_folds` is also importable from ``tactile_torch.tradeoff.inputs``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .._checks import RandomState, numpy_rng

Fold = tuple[np.ndarray, np.ndarray]


def _group_ids(values: np.ndarray) -> np.ndarray:
    return np.unique(np.asarray(values).astype(str), return_inverse=True)[1]


def _class_name(names: Sequence[str], c: int) -> str:
    return names[c] if 0 <= c < len(names) else str(c)


def _check_folds(folds: list[Fold], y: np.ndarray, names: Sequence[str], what: str) -> None:
    """Every class needs 2 training samples in every fold (the SVMs learn from at least 2 per class)."""
    classes = np.unique(y)
    for train, _ in folds:
        counts = np.bincount(y[train], minlength=classes.max() + 1)[classes]
        if counts.min() < 2:
            c = classes[counts.argmin()]
            raise ValueError(
                f"data: too few {what} of class {_class_name(names, c)!r} for the folds (a training fold "
                f"holds {counts.min()}, at least 2 are needed); use fewer folds (n_folds=) or more data"
            )


def sample_folds(
    y: np.ndarray,
    groups: np.ndarray | None,
    *,
    n_folds: int,
    names: Sequence[str],
    what: str,
    group_label: str = "the file's groups",
    random_state: RandomState = None,
) -> tuple[list[Fold], str]:
    """Return stratified folds of ``y`` (grouped by ``groups`` when every class has two groups) and their description."""
    from sklearn.model_selection import StratifiedGroupKFold, StratifiedKFold

    seed = int(numpy_rng(random_state).integers(2**31))
    classes, counts = np.unique(y, return_counts=True)
    if len(classes) < 2:
        raise ValueError(f"data: at least 2 classes are needed, got only {_class_name(names, classes[0])!r}")
    note = ""
    if groups is not None:
        gid = _group_ids(groups)
        per_class = np.array([len(np.unique(gid[y == c])) for c in classes])
        k = min(n_folds, int(per_class.min()))
        if k >= 2:
            folds = list(StratifiedGroupKFold(k, shuffle=True, random_state=seed).split(y, y, gid))
            _check_folds(folds, y, names, f"groups of {what}")
            return folds, f"{k} folds grouped by {group_label} (none on both sides), stratified"
        lonely = _class_name(names, classes[per_class.argmin()])
        note = (
            f"; not grouped: class {lonely!r} has a single group, so its samples share a group across folds"
        )
    k = min(n_folds, int(counts.min()))
    if k < 2:
        raise ValueError(
            f"data: class {_class_name(names, classes[counts.argmin()])!r} has too few {what} ({counts.min()}); "
            "cross-validation needs at least 2 per class"
        )
    folds = list(StratifiedKFold(k, shuffle=True, random_state=seed).split(y, y))
    _check_folds(folds, y, names, what)
    return folds, f"{k} stratified folds{note}"


__all__ = ["Fold", "sample_folds"]
