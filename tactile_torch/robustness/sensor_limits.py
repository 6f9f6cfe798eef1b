"""A sensor's limits applied to its data: coarser resolution, smaller range, lower rate, shorter recordings.

Method 1, the tactile images: a shorter exploration (:func:`keep_frames`) and a coarser sensel grid
(:func:`coarsen_grid`). Method 2, raw signal windows: quantisation to a step (:func:`quantize`),
saturation at a range (:func:`saturate`), a shorter window (:func:`crop_windows`) and a lower sample
rate (:func:`downsample`). None of them draws random numbers; the random perturbations (additive
noise) are in :mod:`tactile_torch.noise`. :mod:`tactile_torch.robustness` sweeps both.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F

from ..validation import check_finite, check_floating, check_positive, check_tensor


def _check_signal(x: torch.Tensor, name: str) -> None:
    check_tensor(x, name)
    check_floating(x, name)
    check_finite(x, name)


def _check_level(value: float, name: str, what: str, *, strict: bool) -> float:
    value = float(value)
    ok = math.isfinite(value) and (value > 0.0 if strict else value >= 0.0)
    if not ok:
        raise ValueError(f"{name} must be a finite {what} {'> 0' if strict else '>= 0'}, got {value}")
    return value


def quantize(x: torch.Tensor, step: float) -> torch.Tensor:
    """Return ``x`` rounded to the nearest multiple of ``step`` (ties to even, like ``numpy.round``).

    An analogue-to-digital converter of resolution ``step`` (the study's ADXL345: 3.9 mg per LSB).

    Parameters
    ----------
    x : tensor of any shape, floating
    step : float > 0

    Returns
    -------
    tensor like ``x``: ``step * round(x / step)``.

    Examples
    --------
    >>> quantize(torch.tensor([0.004, 0.006, -0.013]), 0.01)
    tensor([ 0.0000,  0.0100, -0.0100])
    """
    _check_signal(x, "x")
    step = _check_level(step, "step", "quantisation step", strict=True)
    return torch.round(x / step) * step


def saturate(x: torch.Tensor, limit: float) -> torch.Tensor:
    """Return ``x`` clipped to ``[-limit, limit]``: a sensor whose range is ``±limit``.

    Parameters
    ----------
    x : tensor of any shape, floating
    limit : float > 0

    Returns
    -------
    tensor like ``x``.

    Examples
    --------
    >>> saturate(torch.tensor([-3.0, 0.5, 2.5]), 2.0)
    tensor([-2.0000,  0.5000,  2.0000])
    """
    _check_signal(x, "x")
    limit = _check_level(limit, "limit", "range", strict=True)
    return x.clamp(-limit, limit)


def keep_frames(frames: torch.Tensor, n: int) -> torch.Tensor:
    """Return the first ``n`` frames of every exploration: ``(N, T, ...)`` → ``(N, min(n, T), ...)``.

    An exploration cut short (a robot that decides after ``n`` frames).
    """
    check_positive(n, "n", integer=True)
    return frames[:, : int(n)]


def coarsen_grid(frames: torch.Tensor, factor: int, *, keep_size: bool = True) -> torch.Tensor:
    """Return frames as a sensor with ``factor`` times fewer sensels per side would show them.

    Each ``factor x factor`` block of pixels is averaged (blocks at the right and bottom borders that
    the image does not fill are averaged over the pixels they hold: ``ceil(H / factor)`` cells per
    column); with ``keep_size`` the coarse map is shown again at the original size by bilinear
    interpolation (``align_corners=False``, the display of a pressure-mapping array), so that pixel
    sizes (such as the erosion element) keep their meaning.

    Parameters
    ----------
    frames : tensor of shape (N, T, 3, H, W) or (N, T, H, W)
        uint8 (rounded back to uint8) or float.
    factor : int >= 1
    keep_size : bool

    Returns
    -------
    tensor of shape like ``frames`` (``keep_size``) or with ``ceil(H / factor) x ceil(W / factor)``
    pixels; same dtype.
    """
    check_positive(factor, "factor", integer=True)
    if frames.ndim not in (4, 5):
        raise ValueError(f"frames must have shape (N, T, 3, H, W) or (N, T, H, W), got {tuple(frames.shape)}")
    factor = int(factor)
    if factor == 1:
        return frames.clone()
    height, width = frames.shape[-2:]
    x = frames.reshape(-1, 1, height, width)
    x = x.float() if not x.is_floating_point() else x
    coarse = F.avg_pool2d(x, factor, ceil_mode=True)
    if keep_size:
        coarse = F.interpolate(coarse, size=(height, width), mode="bilinear", align_corners=False)
    out = coarse.reshape(*frames.shape[:-2], *coarse.shape[-2:])
    if not frames.is_floating_point():
        out = out.round().clamp(0, 255).to(frames.dtype)
    return out


def crop_windows(windows: torch.Tensor, size: int) -> torch.Tensor:
    """Return the first ``size`` samples of every window: ``(..., W)`` → ``(..., min(size, W))``."""
    check_positive(size, "size", integer=True)
    return windows[..., : int(size)]


def downsample(windows: torch.Tensor, factor: int) -> torch.Tensor:
    """Return windows resampled to ``1 / factor`` of their rate, with an anti-aliasing filter.

    Equal to ``scipy.signal.resample_poly(windows, 1, factor, axis=-1)`` (its default Kaiser-window
    FIR of ``20 factor + 1`` taps, zero padding at both ends): ``ceil(W / factor)`` samples.

    Parameters
    ----------
    windows : tensor of shape (..., W), floating
    factor : int >= 1
    """
    from scipy.signal import firwin

    check_positive(factor, "factor", integer=True)
    factor = int(factor)
    if factor == 1:
        return windows.clone()
    half = 10 * factor
    taps = torch.as_tensor(firwin(2 * half + 1, 1.0 / factor, window=("kaiser", 5.0)), dtype=windows.dtype)
    lead, width = windows.shape[:-1], windows.shape[-1]
    flat = F.pad(windows.reshape(-1, 1, width), (half, half))
    out = F.conv1d(flat, taps.view(1, 1, -1), stride=factor)
    return out.reshape(*lead, out.shape[-1])


__all__ = [
    "coarsen_grid",
    "crop_windows",
    "downsample",
    "keep_frames",
    "quantize",
    "saturate",
]
