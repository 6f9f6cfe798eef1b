"""The sensor limits of tactile_torch.robustness.sensor_limits (breaking points), against NumPy/SciPy references.

(The random noise of ``tactile_torch.noise`` is tested in ``tests/test_noise.py``.)
"""

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.signal import resample_poly

from tactile_torch.robustness.sensor_limits import (
    coarsen_grid,
    crop_windows,
    downsample,
    keep_frames,
    quantize,
    saturate,
)


def _block_mean(x: np.ndarray, k: int) -> np.ndarray:
    """Reference: the mean of every k x k block of the last two axes, partial border blocks included."""
    h, w = x.shape[-2:]
    rows = [x[..., i : i + k, :].mean(axis=-2) for i in range(0, h, k)]
    out = np.stack(rows, axis=-2)
    cols = [out[..., j : j + k].mean(axis=-1) for j in range(0, w, k)]
    return np.stack(cols, axis=-1)


def _linear_resize(x: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Reference: separable linear interpolation at half-pixel centres, clamped at the borders."""

    def along(a: np.ndarray, n_out: int, axis: int) -> np.ndarray:
        n_in = a.shape[axis]
        src = np.clip((np.arange(n_out) + 0.5) * n_in / n_out - 0.5, 0, n_in - 1)
        return np.apply_along_axis(lambda v: np.interp(src, np.arange(n_in), v), axis, a)

    return along(along(x, size[0], -2), size[1], -1)


def test_quantize_and_saturate_match_numpy():
    x = np.random.default_rng(0).normal(scale=3.0, size=(4, 3, 257))
    t = torch.from_numpy(x)
    for step in (0.0039, 0.1, 1.0):
        np.testing.assert_array_equal(quantize(t, step).numpy(), np.round(x / step) * step)
    for limit in (0.05, 1.0, 5.0):
        np.testing.assert_array_equal(saturate(t, limit).numpy(), np.clip(x, -limit, limit))
    t32 = t.float()
    np.testing.assert_allclose(quantize(t32, 0.1).numpy(), np.round(x / 0.1) * 0.1, rtol=1e-5, atol=1e-6)
    assert quantize(t32, 0.1).dtype == torch.float32


@pytest.mark.parametrize(
    ("call", "err", "match"),
    [
        (lambda: quantize(torch.zeros(3), 0.0), ValueError, "step must be a finite quantisation step > 0"),
        (lambda: quantize(torch.zeros(3, dtype=torch.int64), 1.0), TypeError, "floating dtype"),
        (lambda: saturate(torch.zeros(3), float("inf")), ValueError, "limit must be a finite range > 0"),
        (lambda: keep_frames(torch.zeros(2, 3, 4, 4), 0), ValueError, "n must be > 0"),
        (
            lambda: coarsen_grid(torch.zeros(2, 4, 4), 2),
            ValueError,
            r"frames must have shape \(N, T, 3, H, W\)",
        ),
        (lambda: coarsen_grid(torch.zeros(1, 1, 4, 4), 1.5), TypeError, "factor must be an integer"),
        (lambda: crop_windows(torch.zeros(2, 3, 8), 0), ValueError, "size must be > 0"),
        (lambda: downsample(torch.zeros(2, 3, 8), 0), ValueError, "factor must be > 0"),
    ],
)
def test_documented_errors(call, err, match):
    with pytest.raises(err, match=match):
        call()


def test_keep_frames_and_crop_windows_are_slices():
    frames = torch.arange(2 * 5 * 3 * 2 * 2).reshape(2, 5, 3, 2, 2)
    assert torch.equal(keep_frames(frames, 3), frames[:, :3])
    assert torch.equal(keep_frames(frames, 9), frames)
    windows = torch.randn(4, 3, 100)
    assert torch.equal(crop_windows(windows, 40), windows[..., :40])


@pytest.mark.parametrize(("height", "width", "factor"), [(12, 12, 3), (10, 7, 4), (9, 16, 2)])
def test_coarsen_grid_matches_block_means_and_linear_display(height, width, factor):
    x = np.random.default_rng(1).random((2, 3, 3, height, width))
    coarse = coarsen_grid(torch.from_numpy(x), factor, keep_size=False).numpy()
    reference = _block_mean(x, factor)
    np.testing.assert_allclose(coarse, reference, rtol=1e-10, atol=1e-12)
    shown = coarsen_grid(torch.from_numpy(x), factor).numpy()
    np.testing.assert_allclose(shown, _linear_resize(reference, (height, width)), rtol=1e-10, atol=1e-12)
    maps = torch.from_numpy(x[:, :, 0])  # pressure maps (N, T, H, W)
    assert coarsen_grid(maps, factor).shape == maps.shape


def test_coarsen_grid_uint8_rounds_and_keeps_constant_images():
    frames = torch.full((1, 2, 3, 8, 8), 200, dtype=torch.uint8)
    out = coarsen_grid(frames, 4)
    assert out.dtype == torch.uint8 and torch.equal(out, frames)
    ramp = torch.arange(64, dtype=torch.uint8).reshape(1, 1, 1, 8, 8).expand(1, 1, 3, 8, 8)
    ref = np.clip(np.round(_linear_resize(_block_mean(ramp.numpy().astype(float), 2), (8, 8))), 0, 255)
    np.testing.assert_array_equal(coarsen_grid(ramp, 2).numpy(), ref)
    assert torch.equal(coarsen_grid(ramp, 1), ramp)


@pytest.mark.parametrize(("width", "factor"), [(800, 2), (801, 4), (200, 8), (97, 3)])
def test_downsample_matches_scipy_resample_poly(width, factor):
    x = np.random.default_rng(2).normal(size=(3, 3, width))
    out = downsample(torch.from_numpy(x), factor).numpy()
    np.testing.assert_allclose(out, resample_poly(x, 1, factor, axis=-1), rtol=1e-10, atol=1e-12)
    out32 = downsample(torch.from_numpy(x).float(), factor).numpy()
    np.testing.assert_allclose(out32, resample_poly(x, 1, factor, axis=-1), rtol=1e-5, atol=1e-5)


@settings(max_examples=20, deadline=None)
@given(st.integers(1, 4), st.integers(1, 5), st.integers(8, 60))
def test_downsample_batched_equals_per_window(batch, factor, width):
    x = torch.from_numpy(np.random.default_rng(width).normal(size=(batch, 3, width)))
    whole = downsample(x, factor)
    assert whole.shape == (batch, 3, -(-width // factor))
    for b in range(batch):
        assert torch.allclose(whole[b], downsample(x[b : b + 1], factor)[0], rtol=0, atol=1e-12)
