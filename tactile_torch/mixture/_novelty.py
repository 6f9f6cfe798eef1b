"""Novelty of windows under a fitted mixture: a calibrated threshold on a score, over one or N windows.

The functions here take any per-window score (larger = more novel). The estimator's score
(:meth:`~tactile_torch.mixture.PitmanYorGMM.novelty_score`, the exported graph's ``novelty``) is
minus the window's log density under the point estimate's mixture: a window no known component
explains. A decision after ``N`` consecutive windows of one recording averages the N scores;
:func:`calibrate_thresholds` sets the threshold of each N as the ``1 - false_alarm`` quantile of
the N-window means of windows of known surfaces that the fit did not see, so that the false-alarm
rate is set on those windows rather than hoped for.
"""

from __future__ import annotations

import numpy as np


def _group_runs(groups: np.ndarray | None, n_rows: int) -> list[np.ndarray]:
    """Return the row indices of each group (rows in their given order); one group when ``groups`` is None."""
    if groups is None:
        return [np.arange(n_rows)]
    return [np.flatnonzero(groups == g) for g in np.unique(groups)]


def window_means(score: np.ndarray, n: int, groups: np.ndarray | None = None) -> np.ndarray:
    """Return, per row, the mean score of it and the ``n - 1`` rows before it in its group; NaN before the n-th row, shape (n_rows,).

    Parameters
    ----------
    score : ndarray (n_rows,)
        Per-window scores, rows in time order within each group.
    n : int
        Windows per decision (>= 1).
    groups : ndarray (n_rows,), optional
        Recording of each row: a run never spans two recordings.
    """
    out = np.full(score.shape, np.nan)
    for idx in _group_runs(groups, score.size):
        if idx.size >= n:
            out[idx[n - 1 :]] = np.lib.stride_tricks.sliding_window_view(score[idx], n).mean(axis=1)
    return out


def calibrate_thresholds(
    score: np.ndarray, false_alarm: float, max_windows: int, groups: np.ndarray | None = None
) -> np.ndarray:
    """Return the threshold of every N = 1 … ``max_windows``: the ``1 - false_alarm`` quantile of the N-window means, shape (max_windows,).

    The quantile is the sample value just above (``method="higher"``): at most ``false_alarm`` of
    the given N-window means exceed it.

    ``score``: the novelty scores of windows of known surfaces, in time order within each group. Where no
    group has N windows, the threshold of N is that of the largest N that has some.
    """
    out = np.zeros(max_windows)
    for n in range(1, max_windows + 1):
        means = window_means(score, n, groups)
        means = means[np.isfinite(means)]
        # "higher": at most a share false_alarm of these means lies above the threshold
        out[n - 1] = np.quantile(means, 1.0 - false_alarm, method="higher") if means.size else out[n - 2]
    return out


def novel_after(
    score: np.ndarray, thresholds: np.ndarray, n: int, groups: np.ndarray | None = None
) -> np.ndarray:
    """Return, per row, whether the mean score of the ``n`` windows ending there exceeds ``thresholds[n - 1]``, shape (n_rows,).

    False for the first ``n - 1`` rows of each group (no decision yet).
    """
    means = window_means(score, n, groups)
    return np.nan_to_num(means, nan=-np.inf) > thresholds[n - 1]
