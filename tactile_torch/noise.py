"""Random noise of the robustness experiments: on features at a given SNR, on raw frames, on raw signals.

Method 1: white noise on features at a given SNR (:func:`awgn`) and Gaussian noise on the raw frames
(:func:`gaussian_image_noise`); method 2: a sensor's additive Gaussian noise on raw signal windows
(:func:`gaussian_noise`). Each takes an explicit ``generator`` (int seed, numpy or torch generator) so
that trials are reproducible. The deterministic limits of a sensor (resolution, range, rate, grid,
length) are in :mod:`tactile_torch.robustness.sensor_limits`; :mod:`tactile_torch.robustness` sweeps both.
"""

from __future__ import annotations

import math

import torch

from .validation import RandomState, check_finite, check_floating, check_tensor, torch_generator


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
    check_tensor(x, "x")
    check_floating(x, "x")
    check_finite(x, "x")
    std = float(std)
    if not (math.isfinite(std) and std >= 0.0):
        raise ValueError(f"std must be a finite standard deviation >= 0, got {std}")
    noise = torch.randn(x.shape, generator=torch_generator(generator), dtype=x.dtype)
    return x + std * noise


__all__ = ["awgn", "gaussian_image_noise", "gaussian_noise"]
