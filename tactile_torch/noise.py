"""Noise and sensor models of the robustness experiments.

Method 1: white noise on features at a given SNR (:func:`awgn`), Gaussian noise on the raw frames
(:func:`gaussian_image_noise`), a shorter exploration (:func:`keep_frames`) and a coarser sensel grid
(:func:`coarsen_grid`). Method 2, a sensor's imperfections on raw signal windows: additive Gaussian
noise (:func:`gaussian_noise`), quantisation to a step (:func:`quantize`), saturation at a range
(:func:`saturate`), a shorter window (:func:`crop_windows`) and a lower sample rate
(:func:`downsample`). The random ones take an explicit ``generator`` (int seed, numpy or torch
generator) so that trials are reproducible. :mod:`tactile_torch.robustness` sweeps them.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F

from ._checks import RandomState, check_finite, check_floating, check_positive, check_tensor, torch_generator


def awgn(x: torch.Tensor, snr_db: float, *, generator: RandomState = None) -> torch.Tensor:
    """Return ``x`` plus white Gaussian noise at a signal-to-noise ratio of ``snr_db`` decibels.

    The signal power is measured per sample: for ``x`` of shape ``(B, F)`` each row gets noise of
    variance ``mean(x[b]**2) / 10**(snr_db / 10)`` (MATLAB's ``awgn(x, snr, 'measured')`` applied row by
    row). A row of zeros has zero power and is returned unchanged.

    Parameters
    ----------
    x : tensor of shape (B, F), floating
        Feature matrix (one sample per row).
    snr_db : float
        Signal-to-noise ratio in dB (the study uses 30 down to 1).
    generator : int, numpy.random.Generator, torch.Generator or None
        Source of randomness.

    Examples
    --------
    >>> noisy = awgn(torch.ones(4, 12), snr_db=10.0, generator=0)
    """
    check_tensor(x, "x")
    check_floating(x, "x")
    if x.ndim != 2:
        raise ValueError(f"x must have shape (B, F), got {tuple(x.shape)}")
    check_finite(x, "x")
    snr_db = float(snr_db)
    if not torch.isfinite(torch.tensor(snr_db)):
        raise ValueError(f"snr_db must be a finite number of decibels, got {snr_db}")
    power = x.pow(2).mean(dim=1, keepdim=True)
    sigma = torch.sqrt(power / 10.0 ** (snr_db / 10.0))
    noise = torch.randn(x.shape, generator=torch_generator(generator), dtype=x.dtype)
    return x + sigma * noise


def gaussian_image_noise(
    frames: torch.Tensor, mean: float, var: float, *, generator: RandomState = None
) -> torch.Tensor:
    """Return frames with added Gaussian noise of the given mean and variance, clipped to [0, 1].

    Like MATLAB's ``imnoise(I, 'gaussian', mean, var)`` on the 0-1 intensity scale; the study uses
    mean 0.1 ... 0.5 and variance 0.01 ... 0.09. uint8 frames are converted to float in [0, 1] first.

    Parameters
    ----------
    frames : tensor of shape (B, T, 3, H, W), float in [0, 1] or uint8
    mean, var : float
        Mean and variance (>= 0) of the added noise.
    generator : int, numpy.random.Generator, torch.Generator or None

    Returns
    -------
    tensor of shape (B, T, 3, H, W), float (float32 for uint8 input), in [0, 1].
    """
    check_tensor(frames, "frames")
    if frames.ndim != 5 or frames.shape[2] != 3:
        raise ValueError(f"frames must have shape (B, T, 3, H, W), got {tuple(frames.shape)}")
    if frames.dtype == torch.uint8:
        frames = frames.float() / 255.0
    check_floating(frames, "frames")
    check_finite(frames, "frames")
    if not (var >= 0.0) or not torch.isfinite(torch.tensor(float(var))):
        raise ValueError(f"var must be a finite variance >= 0, got {var}")
    if not torch.isfinite(torch.tensor(float(mean))):
        raise ValueError(f"mean must be finite, got {mean}")
    noise = torch.randn(frames.shape, generator=torch_generator(generator), dtype=frames.dtype)
    # in place on the fresh noise tensor: one allocation (these tensors are a whole exploration set)
    return noise.mul_(float(var) ** 0.5).add_(float(mean)).add_(frames).clamp_(0.0, 1.0)


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


def gaussian_noise(x: torch.Tensor, std: float, *, generator: RandomState = None) -> torch.Tensor:
    """Return ``x`` plus white Gaussian noise of standard deviation ``std`` (in the units of ``x``).

    A sensor's own noise, e.g. on accelerometer windows in g (the ADXL345 of the study: about 1.2 LSB
    of 3.9 mg). Unlike :func:`awgn` the level is absolute, not relative to the signal's power.

    Parameters
    ----------
    x : tensor of any shape, floating
    std : float >= 0
    generator : int, numpy.random.Generator, torch.Generator or None

    Returns
    -------
    tensor like ``x`` (same shape and dtype); ``std = 0`` returns a copy of ``x``.

    Examples
    --------
    >>> gaussian_noise(torch.zeros(2, 3, 800), 0.01, generator=0).shape
    torch.Size([2, 3, 800])
    """
    _check_signal(x, "x")
    std = _check_level(std, "std", "standard deviation", strict=False)
    noise = torch.randn(x.shape, generator=torch_generator(generator), dtype=x.dtype)
    return x + std * noise


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
    "awgn",
    "coarsen_grid",
    "crop_windows",
    "downsample",
    "gaussian_image_noise",
    "gaussian_noise",
    "keep_frames",
    "quantize",
    "saturate",
]
