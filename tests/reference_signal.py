"""NumPy/SciPy reference of the vibration features, used by the tests and by ``bench/bench_signal.py``.

Two references of the same definitions (``tactile_torch.signal``'s module docstring):

- :func:`window_features_loop` is what a researcher writes: a loop over windows and axes calling
  ``scipy.stats`` for the moments, ``numpy.fft.rfft`` for the spectrum and a loop over the 20
  thresholds for the crossings. It is the baseline of the benchmark's speed-up target.
- :func:`window_features_vectorized` is the same computation with ``axis=`` arguments over the whole
  batch (still a loop over the 20 thresholds), the fastest plain NumPy/SciPy version we could write.

Moments, total variation and spectrum are computed in float64 whatever the input dtype (the "true"
values the float32 op is compared with); the crossing thresholds are computed in the input dtype with
the formula of the definition (``mn + k * (mx - mn) / 21``), as a NumPy user would, so that the counts
can be compared exactly. Constant windows follow the library's convention (standardised moments 0),
which scipy does not (it returns NaN).
"""

from __future__ import annotations

import numpy as np
import scipy.stats

N_THRESHOLDS = 20


def crossings_loop(a: np.ndarray) -> int:
    """Crossings of the 20 thresholds by one axis of one window, by an explicit loop."""
    mn, mx = a.min(), a.max()
    count = 0
    for k in range(1, N_THRESHOLDS + 1):
        th = mn + k * (mx - mn) / (N_THRESHOLDS + 1)
        above = a > th
        count += int(np.count_nonzero(above[1:] != above[:-1]))
    return count


def axis_features(a: np.ndarray) -> list[float]:
    """The 7 features of one axis ``(W,)`` of one window."""
    w = len(a)
    crossings = crossings_loop(a)
    a = a.astype(np.float64)
    var = np.var(a, ddof=1)
    if np.ptp(a) == 0:
        skew = kurt = fifth = 0.0
    else:
        skew = scipy.stats.skew(a)
        kurt = scipy.stats.kurtosis(a, fisher=False)
        fifth = scipy.stats.moment(a, 5) / np.var(a) ** 2.5
    tv = np.abs(np.diff(a)).sum()
    hf = np.abs(np.fft.rfft(a))[w // 4 + 1 :].sum()
    return [var, skew, kurt, fifth, tv, crossings, hf]


def window_features_loop(windows: np.ndarray) -> np.ndarray:
    """``(B, 3, W)`` → ``(B, 21)`` float64, one window and one axis at a time."""
    return np.array([[f for axis in window for f in axis_features(axis)] for window in windows])


def window_features_vectorized(windows: np.ndarray) -> np.ndarray:
    """``(B, 3, W)`` → ``(B, 21)`` float64 with ``axis=`` arguments over the batch."""
    b, _, w = windows.shape
    mn = windows.min(-1, keepdims=True)
    mx = windows.max(-1, keepdims=True)
    crossings = np.zeros(windows.shape[:2], dtype=np.int64)
    for k in range(1, N_THRESHOLDS + 1):
        above = windows > mn + k * (mx - mn) / (N_THRESHOLDS + 1)
        crossings += np.count_nonzero(above[..., 1:] != above[..., :-1], axis=-1)
    a = windows.astype(np.float64)
    flat = (mx == mn)[..., 0]
    var = np.var(a, axis=-1, ddof=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        skew = np.where(flat, 0.0, scipy.stats.skew(a, axis=-1))
        kurt = np.where(flat, 0.0, scipy.stats.kurtosis(a, axis=-1, fisher=False))
        fifth = np.where(flat, 0.0, scipy.stats.moment(a, 5, axis=-1) / np.var(a, axis=-1) ** 2.5)
    tv = np.abs(np.diff(a, axis=-1)).sum(-1)
    hf = np.abs(np.fft.rfft(a, axis=-1))[..., w // 4 + 1 :].sum(-1)
    out = np.stack([var, skew, kurt, fifth, tv, crossings, hf], axis=-1)
    return out.reshape(b, 21)


def clustering_features(features: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    """``(B, 21)`` → ``(B, 12)``: per axis sqrt(var), log(tv + eps), log1p(cross), log(hf + eps)."""
    f = features.reshape(-1, 3, 7).astype(np.float64)
    out = np.stack(
        [np.sqrt(f[..., 0]), np.log(f[..., 4] + eps), np.log1p(f[..., 5]), np.log(f[..., 6] + eps)], -1
    )
    return out.reshape(-1, 12)


def clustering_pca(
    train: np.ndarray, test: np.ndarray, n_components: int = 3, eps: float = 1e-6
) -> np.ndarray:
    """Standardise (ddof=1) and project ``test`` on the leading principal axes of ``train`` (21 features each).

    Axes are signed so that the largest-magnitude loading is positive, as scikit-learn's PCA does.
    """
    x = clustering_features(train, eps)
    mean, std = x.mean(0), x.std(0, ddof=1)
    std = np.where(std > 0, std, 1.0)
    _, _, vh = np.linalg.svd((x - mean) / std, full_matrices=False)
    vh = vh[:n_components]
    vh *= np.sign(vh[np.arange(n_components), np.abs(vh).argmax(1)])[:, None]
    return ((clustering_features(test, eps) - mean) / std) @ vh.T
