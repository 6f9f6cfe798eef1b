"""Folds of :mod:`tactile_torch.engine.folds`: grouped when every class has two groups, never a group on both sides."""

import numpy as np
import pytest

from tactile_torch.engine.folds import sample_folds


def test_grouped_folds_keep_every_group_on_one_side():
    y = np.repeat([0, 1], 12)
    groups = np.array([f"s{i % 4}" for i in range(24)])
    folds, split = sample_folds(y, groups, n_folds=5, names=("a", "b"), what="rows", random_state=0)
    assert len(folds) == 4 and "grouped" in split  # 4 groups per class: at most 4 folds
    for train, test in folds:
        assert not set(groups[train]) & set(groups[test])
    assert sorted(np.concatenate([t for _, t in folds]).tolist()) == list(range(24))
    again, _ = sample_folds(y, groups, n_folds=5, names=("a", "b"), what="rows", random_state=0)
    assert all((a[1] == b[1]).all() for a, b in zip(folds, again, strict=True))


def test_a_class_with_one_group_falls_back_to_stratified_folds_and_says_so():
    y = np.repeat([0, 1], 6)
    groups = np.array(["only"] * 6 + ["p", "q"] * 3)
    folds, split = sample_folds(y, groups, n_folds=3, names=("a", "b"), what="rows", random_state=1)
    assert len(folds) == 3 and "not grouped: class 'a' has a single group" in split


def test_too_few_samples_or_one_class_are_one_line_errors():
    with pytest.raises(ValueError, match="at least 2 classes"):
        sample_folds(np.zeros(6, int), None, n_folds=3, names=("a",), what="rows")
    with pytest.raises(ValueError, match="class 'b' has too few rows"):
        sample_folds(np.array([0, 0, 0, 1]), None, n_folds=3, names=("a", "b"), what="rows")
