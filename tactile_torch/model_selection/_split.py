"""Every fold of the library: cross-validation folds and time hold-outs that never put related samples on both sides.

The one home of fold making (``tests/project/test_evaluation_home.py`` fails when a module outside
:mod:`tactile_torch.model_selection` builds scikit-learn splitters):

* :func:`sample_folds`: stratified folds of explorations and feature rows, grouped (object, subject,
  session) when every class has two groups; the trade-off's inputs and ``train`` use them;
* :func:`window_folds`: folds of windows cut from recordings, grouped by session or recording when
  every class has two, else consecutive time blocks of every recording with guard windows between
  blocks (:func:`single_group` says why, in words); :func:`fold_units`, :func:`cap_per_class`;
* :func:`rotating_splits`: method 1's rounds (train, validation, test: 60 / 20 / 20 %);
  :func:`odd_even_split`: method 2's odd/even windows;
* :func:`stratified_splitter`, :func:`stratified_folds`, :func:`group_folds`: scikit-learn's
  ``StratifiedKFold`` (shuffled, seeded; the splitter, or its folds as a list) and ``GroupKFold`` folds,
  for the grid searches and the report's studies;
* :func:`time_holdout`: each recording cut in time order into consecutive parts (train, calibration,
  test), the hold-out of the studies that train on a recording's past and test on its future.

:func:`sample_folds`, :func:`window_folds`, :func:`fold_units` and :func:`cap_per_class` are also
importable from ``tactile_torch.tradeoff.inputs``, :class:`Split`, :func:`rotating_splits` and
:func:`odd_even_split` from ``tactile_torch.model_selection``, and :func:`time_holdout` serves ``studies.novelty.time_split``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import accumulate
from numbers import Integral, Real

import numpy as np

from ..validation import RandomState, numpy_rng

Fold = tuple[np.ndarray, np.ndarray]


def group_ids(values: np.ndarray) -> np.ndarray:
    """Return an integer id per value, ``0 .. n_groups - 1`` in the sorted order of the values as strings.

    >>> group_ids(np.array(["day2", "day1", "day2"])).tolist()
    [1, 0, 1]
    """
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
        gid = group_ids(groups)
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


def _evenly(index: np.ndarray, cap: int) -> np.ndarray:
    if len(index) <= cap:
        return index
    return index[np.unique(np.linspace(0, len(index) - 1, cap).round().astype(int))]


def cap_per_class(y: np.ndarray, cap: int | None) -> np.ndarray:
    """Indices keeping at most ``cap`` samples per class, evenly spaced in the given order (all if ``None``)."""
    if cap is None:
        return np.arange(len(y))
    return np.sort(np.concatenate([_evenly(np.flatnonzero(y == c), cap) for c in np.unique(y)]))


def fold_units(folds: list[Fold], n: int) -> np.ndarray:
    """Return the index of the fold that tests each of ``n`` samples."""
    units = np.full(n, -1, dtype=np.int64)
    for k, (_, test) in enumerate(folds):
        units[test] = k
    return units


def window_folds(
    recording: np.ndarray,
    position: np.ndarray,
    y: np.ndarray,
    session: np.ndarray,
    *,
    group_label: str = "session",
    n_folds: int,
    names: Sequence[str],
    window: int,
    guard: int = 1,
    max_per_class: int | None = None,
    random_state: RandomState = None,
) -> tuple[np.ndarray, np.ndarray, list[Fold], str]:
    """Folds of windows cut from recordings, every ``step`` samples, that never split neighbouring windows.

    The decision of :func:`tactile_torch.tradeoff.inputs.vibration_samples` (module notes) for windows that may overlap: grouped by
    session (or recording) when every class has two, else consecutive time blocks with ``guard``
    windows dropped between blocks. What ``tactile-torch train`` reports on
    (:func:`tactile_torch.training.held_out_folds`).

    Parameters
    ----------
    recording, position, y : ndarray (N,)
        Each window's recording, its index within the recording (time order), its class.
    session : ndarray (R,)
        Each recording's session (or its index); windows are grouped by it.
    group_label : str
        What ``session`` holds, in the description (``"session"``, ``"recording"``).
    guard : int
        Time blocks: windows dropped at the start of every later block (``ceil(W / step)`` for
        windows cut every ``step`` samples, so that no kept window overlaps another block's).

    Returns
    -------
    groups : ndarray (N,)
        What the folds keep on one side (session or recording, or a recording's time block).
    keep : ndarray
        The windows used (every window but the guards, at most ``max_per_class`` per class).
    folds : list of (train, test)
        Index arrays into ``keep``.
    split : str
        How the folds were made, in words.
    """
    group = group_ids(np.asarray(session))[recording]
    per_class = np.array([len(np.unique(group[y == c])) for c in np.unique(y)])
    if per_class.min() >= 2:
        keep = cap_per_class(y, max_per_class)
        folds, split = sample_folds(
            y[keep],
            group[keep],
            n_folds=n_folds,
            names=names,
            what="recordings",
            group_label=group_label,
            random_state=random_state,
        )
        return group, keep, folds, split
    # one recording (or session) for some class: consecutive time blocks of every recording
    why = single_group(group, recording, y, names, group_label)
    return _time_blocks(recording, position, y, window, n_folds, max_per_class, names, guard, why=why)


def single_group(
    group: np.ndarray, recording: np.ndarray, y: np.ndarray, names: Sequence[str], label: str
) -> str:
    """Why windows are not grouped, in words the data bear out: the classes with a single ``label``."""
    classes = np.unique(y)
    single = [c for c in classes if len(np.unique(group[y == c])) < 2]
    c = single[0]
    n_recordings = len(np.unique(recording[y == c]))
    which = (
        f"class {_class_name(names, c)!r} has"
        if len(single) == 1
        else f"{len(single)} of {len(classes)} classes have"
    )
    if label == "session" and n_recordings > 1:
        return f"{which} a single session (the {n_recordings} recordings of {_class_name(names, c)!r} are one session)"
    return f"{which} a single {label}"


def _time_blocks(
    recording: np.ndarray,
    position: np.ndarray,
    y: np.ndarray,
    window: int,
    n_folds: int,
    max_per_class: int | None,
    names: Sequence[str],
    guard: int = 1,
    *,
    why: str = "a class has a single recording",
) -> tuple[np.ndarray, np.ndarray, list[Fold], str]:
    """Time-block folds: ``(block of each window, windows kept, folds over the kept ones, description)``;
    ``why`` says why the windows are not grouped (:func:`single_group`)."""
    present = np.unique(recording)
    n_windows = np.bincount(recording)[present]
    blocks = min(
        n_folds, int(n_windows.min() // (guard + 1))
    )  # every later block keeps a window after its guard
    if blocks < 2:
        short = names[int(y[recording == present[n_windows.argmin()]][0])]
        need = 2 * (guard + 1)
        raise ValueError(
            f"window: {window} samples leaves a recording of class {short!r} only {n_windows.min()} window(s); "
            f"time-block folds need at least {need} (two blocks, each with {guard} guard window(s)): choose a "
            "shorter window (window=)"
        )
    count = np.bincount(recording)[recording]
    block = position * blocks // count
    guarded = (position > 0) & (block != np.maximum(position - guard, 0) * blocks // count)
    keep = np.flatnonzero(~guarded)
    keep = keep[cap_per_class(y[keep], max_per_class)]
    folds = [(np.flatnonzero(block[keep] != b), np.flatnonzero(block[keep] == b)) for b in range(blocks)]
    _check_folds(folds, y[keep], names, "windows")
    dropped = (
        "the first window of each later block is"
        if guard == 1
        else f"the first {guard} windows of each later block are"
    )
    split = (
        f"{blocks} folds of consecutive time blocks of every recording ({why}); "
        f"{dropped} dropped so that no neighbouring windows are split"
    )
    return recording * blocks + block, keep, folds, split


def labels_1d(y: object, name: str = "y") -> np.ndarray:
    """``y`` (array-like or torch tensor) as a 1-D NumPy array; ``ValueError`` naming ``name`` otherwise."""
    if hasattr(y, "detach"):
        y = y.detach().cpu().numpy()
    y = np.asarray(y)
    if y.ndim != 1:
        raise ValueError(f"{name} must be a 1-D array, got shape {y.shape}")
    return y


@dataclass(frozen=True)
class Split:
    """Indices of one round of the 60/20/20 protocol."""

    train: np.ndarray
    validation: np.ndarray
    test: np.ndarray


def rotating_splits(y: object, *, n_folds: int = 5, random_state: RandomState = None) -> list[Split]:
    """Return method 1's rounds: stratified folds; round ``k`` tests on fold ``k``, validates on fold
    ``k + 1`` and trains on the others (with 5 folds: 60 % / 20 % / 20 %).

    Every sample is in exactly one test fold. Folds are stratified (each class spread evenly),
    which needs at least ``n_folds`` samples of every class.

    Parameters
    ----------
    y : array-like of shape (n,)
    n_folds : int, default 5
    random_state : int, numpy or torch Generator, or None
        Shuffles the samples before folding.

    Returns
    -------
    list of ``n_folds`` :class:`Split`

    Examples
    --------
    >>> splits = rotating_splits(np.repeat([0, 1], 10), random_state=0)
    >>> [(len(s.train), len(s.validation), len(s.test)) for s in splits][:2]
    [(12, 4, 4), (12, 4, 4)]
    """
    y = labels_1d(y)
    if n_folds < 3:
        raise ValueError(f"n_folds must be >= 3 (train, validation and test folds), got {n_folds}")
    _, counts = np.unique(y, return_counts=True)
    if counts.min() < n_folds:
        raise ValueError(
            f"every class needs at least n_folds={n_folds} samples for stratified folds, "
            f"got a class with {counts.min()}"
        )
    seed = int(numpy_rng(random_state).integers(2**31))
    folds = [test for _, test in stratified_folds(y, n_folds, seed)]
    splits = []
    for k in range(n_folds):
        validation = folds[(k + 1) % n_folds]
        train = np.sort(np.concatenate([folds[j] for j in range(n_folds) if j not in (k, (k + 1) % n_folds)]))
        splits.append(Split(train=train, validation=np.sort(validation), test=np.sort(folds[k])))
    return splits


def odd_even_split(position: int | object) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(train, test)`` indices: odd-numbered windows train, even-numbered ones test.

    Windows are numbered from 1 in recording order, as in method 2's study (so the first window of a
    recording, numbered 1, is odd and trains).

    Parameters
    ----------
    position : int or array-like of shape (n,)
        The number of windows of one recording, or the index of every window inside its own
        recording (``VibrationWindows.position``), for windows of several recordings.

    Examples
    --------
    >>> odd_even_split(5)
    (array([0, 2, 4]), array([1, 3]))
    >>> odd_even_split([0, 1, 2, 0, 1])  # two recordings: windows 1, 2, 3 and 1, 2
    (array([0, 2, 3]), array([1, 4]))
    """
    if isinstance(position, Integral) and not isinstance(position, bool):
        if position < 0:
            raise ValueError(f"position must be a number of windows >= 0, got {position}")
        position = np.arange(position)
    else:
        position = labels_1d(position, "position")
        if not np.issubdtype(position.dtype, np.integer) or (position < 0).any():
            raise ValueError(
                "position must hold the windows' indices (integers >= 0) inside their recordings"
            )
    return np.flatnonzero(position % 2 == 0), np.flatnonzero(position % 2 == 1)


def stratified_splitter(n_folds: int, seed: int):
    """Return scikit-learn's ``StratifiedKFold(n_folds, shuffle=True, random_state=seed)``: the splitter to
    hand to a grid search's ``cv=`` (e.g. :func:`tactile_torch.model_selection.stratified_grid_search`)."""
    from sklearn.model_selection import StratifiedKFold

    return StratifiedKFold(n_folds, shuffle=True, random_state=seed)


def stratified_folds(y: np.ndarray, n_folds: int, seed: int) -> list[Fold]:
    """Return the folds of :func:`stratified_splitter` on ``y`` (shuffled, stratified, seeded), as a list.

    Examples
    --------
    >>> folds = stratified_folds(np.repeat([0, 1], 6), 3, seed=0)
    >>> len(folds), sorted(np.concatenate([test for _, test in folds]).tolist()) == list(range(12))
    (3, True)
    """
    y = np.asarray(y)
    return list(stratified_splitter(n_folds, seed).split(y, y))


def group_folds(y: np.ndarray, groups: np.ndarray, n_folds: int) -> list[Fold]:
    """Return scikit-learn's ``GroupKFold(n_folds)`` folds (every group on one side, unshuffled), as a list."""
    from sklearn.model_selection import GroupKFold

    y = np.asarray(y)
    return list(GroupKFold(n_folds).split(y, y, groups))


def time_holdout(
    recording: np.ndarray,
    position: np.ndarray,
    shares: Sequence[Real],
    *,
    rounding: str = "nearest",
) -> np.ndarray:
    """Return the part of every window when each recording is cut in time order, shape ``(n,)``.

    A recording of ``m`` windows (ordered by ``position``) gives its first ``c1`` windows part 0, the
    next up to ``c2`` part 1, ... and the rest part ``len(shares)``, where ``ck`` is ``m`` times the
    sum of the first ``k`` shares, rounded to the nearest integer (``rounding="nearest"``, Python's
    ``round``: halves to even) or down (``"floor"``; pass a :class:`fractions.Fraction` such as
    ``Fraction(2, 3)`` for an exact cut).

    Parameters
    ----------
    recording, position : ndarray (n,)
        Each window's recording and its place in time within the recording.
    shares : sequence of real
        The leading parts' shares of every recording (e.g. ``(0.4, 0.2)``: train, calibration; the
        rest is test).
    rounding : {"nearest", "floor"}

    Examples
    --------
    >>> recording, position = np.zeros(5, int), np.arange(5)
    >>> time_holdout(recording, position, (0.4, 0.2)).tolist()
    [0, 0, 1, 2, 2]
    >>> from fractions import Fraction
    >>> time_holdout(np.zeros(4, int), np.arange(4), (Fraction(2, 3),), rounding="floor").tolist()
    [0, 0, 1, 1]
    """
    if rounding not in ("nearest", "floor"):
        raise ValueError(f"rounding must be 'nearest' or 'floor', got {rounding!r}")
    cut = round if rounding == "nearest" else math.floor
    recording, position = np.asarray(recording), np.asarray(position)
    part = np.full(recording.shape, len(shares))
    bounds = list(accumulate(shares))
    for r in np.unique(recording):
        idx = np.flatnonzero(recording == r)
        idx = idx[np.argsort(position[idx], kind="stable")]
        start = 0
        for k, share in enumerate(bounds):
            end = int(cut(share * idx.size))
            part[idx[start:end]] = k
            start = max(start, end)
    return part
