"""Folds of :mod:`tactile_torch.model_selection`: grouped when every class has two groups, never a group on both sides."""

import numpy as np
import pytest

from tactile_torch.model_selection import sample_folds


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


def test_time_holdout_cuts_every_recording_in_time_order():
    from fractions import Fraction

    from tactile_torch.model_selection import time_holdout

    recording = np.array([0] * 5 + [1] * 4)
    position = np.array([4, 3, 2, 1, 0, 0, 1, 2, 3])  # recording 0 listed backwards in time
    # nearest: round(0.4 * 5) = 2 train, round(0.6 * 5) = 3 (1 calibration); round(0.4 * 4) = 2, round(2.4) = 2
    assert time_holdout(recording, position, (0.4, 0.2)).tolist() == [2, 2, 1, 0, 0, 0, 0, 2, 2]
    # floor of 2 m / 3: 3 of 5, 2 of 4 (nearest would give 3 of 4)
    part = time_holdout(recording, position, (Fraction(2, 3),), rounding="floor")
    assert part.tolist() == [1, 1, 0, 0, 0, 0, 0, 1, 1]
    assert time_holdout(recording, position, (Fraction(2, 3),)).tolist() == [1, 1, 0, 0, 0, 0, 0, 0, 1]
    with pytest.raises(ValueError, match="rounding must be"):
        time_holdout(recording, position, (0.5,), rounding="up")


def test_window_folds_fall_back_to_time_blocks_with_a_guard_window():
    from tactile_torch.model_selection import window_folds

    recording = np.repeat([0, 1], 12)
    position = np.tile(np.arange(12), 2)
    y = recording.copy()  # one recording per class: time blocks
    group, keep, folds, split = window_folds(
        recording, position, y, np.arange(2), n_folds=3, names=("a", "b"), window=100
    )
    assert len(folds) == 3 and "time blocks" in split and "class" in split
    assert not np.isin([4, 8, 16, 20], keep).any()  # the first window of every later block is dropped
    for train, test in folds:  # no training window next to a test window of its recording
        near = {(recording[keep][i], position[keep][i] + d) for i in test for d in (-1, 1)}
        assert not near & {(recording[keep][i], position[keep][i]) for i in train}
    assert len(np.unique(group[keep])) == 6  # 3 blocks of 2 recordings


def test_studies_folds_and_scores_are_scikit_learns():
    from sklearn.model_selection import GroupKFold, StratifiedKFold, cross_val_predict, cross_val_score
    from sklearn.neighbors import KNeighborsClassifier

    from tactile_torch.model_selection import fold_predictions, fold_scores, group_folds, stratified_folds

    rng = np.random.default_rng(0)
    y = np.repeat([0, 1, 2], 8)
    groups = np.tile(np.arange(4), 6)
    X = rng.normal(size=(24, 3)) + y[:, None]
    folds = stratified_folds(y, 4, seed=5)
    expected = StratifiedKFold(4, shuffle=True, random_state=5).split(y, y)
    assert all((a[1] == b[1]).all() for a, b in zip(folds, expected, strict=True))
    grouped = group_folds(y, groups, 4)
    assert all(not set(groups[tr]) & set(groups[te]) for tr, te in grouped)
    model = KNeighborsClassifier(3)
    np.testing.assert_array_equal(
        fold_predictions(model, X, y, grouped),
        cross_val_predict(model, X, y, cv=GroupKFold(4), groups=groups),
    )
    np.testing.assert_array_equal(
        fold_scores(model, X, y, folds),
        cross_val_score(model, X, y, cv=StratifiedKFold(4, shuffle=True, random_state=5)),
    )
