"""NumPy/SciPy reference of method 1 (tactile-image features), written the way a researcher would.

One exploration at a time, one frame at a time, with ``scipy.ndimage`` (erosion, Sobel),
``scipy.stats`` (moments) and ``numpy.percentile``. Used by ``tests/image/test_image.py`` for equivalence
and by ``bench/bench_image.py`` as the baseline. Conventions (see ``tactile_torch.image``): erosion with
``border_value=1`` (MATLAB ``imerode``), scipy's origin for even squares; Sobel in scipy's default
'reflect' mode, unnormalised; edges where the Sobel magnitude exceeds 0.5; ``A = atan2(gy, gx)`` with
-pi folded onto pi; skewness and kurtosis of a constant image reported as 0 (scipy gives NaN).
"""

from __future__ import annotations

import numpy as np
import scipy.ndimage as ndi
import scipy.stats

WEIGHTS = (0.2989, 0.5870, 0.1140)


def grayscale(frame: np.ndarray, dtype=np.float64) -> np.ndarray:
    """(3, H, W) uint8 or float → (H, W) float gray on [0, 1]."""
    x = frame.astype(dtype)
    if frame.dtype == np.uint8:
        x = x / dtype(255.0)
    return WEIGHTS[0] * x[0] + WEIGHTS[1] * x[1] + WEIGHTS[2] * x[2]


def otsu(gray: np.ndarray) -> float:
    """MATLAB ``graythresh`` on ``round(255 I)``, returned as ``(k + 0.5) / 255`` (``I < t`` is dark)."""
    levels = np.clip(np.rint(gray.astype(np.float64).ravel() * 255), 0, 255).astype(int)
    p = np.bincount(levels, minlength=256) / levels.size
    omega = np.cumsum(p)
    mu = np.cumsum(p * np.arange(256))
    with np.errstate(divide="ignore", invalid="ignore"):
        sigma_b = (mu[-1] * omega - mu) ** 2 / (omega * (1 - omega))
    sigma_b[~np.isfinite(sigma_b)] = 0.0
    k = np.mean(np.flatnonzero(sigma_b == sigma_b.max())) if sigma_b.max() > 0 else 0.0
    return (k + 0.5) / 255


def erode(mask: np.ndarray, size: int) -> np.ndarray:
    """Binary erosion by a size x size square, pixels outside counted as set."""
    return ndi.binary_erosion(mask.astype(bool), structure=np.ones((size, size), bool), border_value=1)


def sobel(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(gx, gy): scipy.ndimage.sobel along columns (axis 1) and rows (axis 0)."""
    return ndi.sobel(image, axis=1), ndi.sobel(image, axis=0)


def edges(eroded: np.ndarray, edge_threshold: float = 0.5) -> np.ndarray:
    gx, gy = sobel(eroded.astype(np.float64))
    return np.hypot(gx, gy) > edge_threshold


def gradient(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    gx, gy = sobel(image)
    direction = np.arctan2(gy, gx)
    direction[direction == -np.pi] = np.pi
    return np.hypot(gx, gy), direction


def statistics(image: np.ndarray) -> np.ndarray:
    """[mean, std (ddof=1), skew (biased), kurtosis (Pearson), p95 (linear), mad about the mean]."""
    v = image.ravel()
    with np.errstate(all="ignore"):
        skew = scipy.stats.skew(v)
        kurt = scipy.stats.kurtosis(v, fisher=False)
    return np.array(
        [
            v.mean(),
            v.std(ddof=1) if v.size > 1 else 0.0,
            0.0 if np.isnan(skew) else skew,
            0.0 if np.isnan(kurt) else kurt,
            np.percentile(v, 95),
            np.mean(np.abs(v - v.mean())),
        ]
    )


def image_features(edge_image: np.ndarray) -> np.ndarray:
    magnitude, direction = gradient(edge_image.astype(np.float64))
    return np.concatenate([statistics(magnitude), statistics(direction)])


def frame_edges(
    frame: np.ndarray, threshold: float, erosion: int, dtype=np.float64, edge_threshold: float = 0.5
) -> np.ndarray:
    gray = grayscale(frame, dtype)
    return edges(erode(gray < dtype(threshold), erosion), edge_threshold)


def exploration_features(
    frames: np.ndarray,
    *,
    fuse: bool = True,
    threshold: float | str = 240 / 255,
    erosion: int = 10,
    edge_threshold: float = 0.5,
    dtype=np.float64,
) -> np.ndarray:
    """(B, T, 3, H, W) → (B, 12) or (B, T * 12), looping over explorations and frames."""
    out = []
    for exploration in frames:
        thr = threshold
        if threshold == "otsu":
            thr = otsu(np.stack([grayscale(f, dtype) for f in exploration]))
        per_frame = [frame_edges(f, thr, erosion, dtype, edge_threshold) for f in exploration]
        if fuse:
            fused = np.zeros(per_frame[0].shape, bool)
            for e in per_frame:
                fused |= e
            out.append(image_features(fused))
        else:
            out.append(np.concatenate([image_features(e) for e in per_frame]))
    return np.stack(out)
