"""Method 1: features of tactile-image explorations (grayscale, pressure mask, erosion, Sobel edges, fusion).

Every step is a plain function on batched CPU tensors with a thin :class:`torch.nn.Module` wrapper;
:func:`exploration_features` chains them: ``(B, T, 3, H, W)`` RGB frames → ``(B, 12)`` features (or
``(B, T*12)`` without fusion, the study's ablation).

Conventions (each matches the SciPy call named in ``tests/reference_image.py``):

* **Grayscale** ``I = 0.2989 R + 0.5870 G + 0.1140 B`` on the [0, 1] scale (uint8 is divided by 255
  first), MATLAB's ``rgb2gray`` weights.
* **Pressed region** ``I < threshold`` (strict). The automatic threshold is Otsu's method on a
  256-level histogram of one exploration's pixels (all its frames pooled), MATLAB ``graythresh``
  style (a plateau of the between-class variance gives its middle).
* **Erosion** is a minimum filter over a ``k x k`` square whose window at pixel ``i`` covers
  ``i - k//2 ... i - k//2 + k - 1`` (scipy's origin for even ``k``; MATLAB's ``strel('square', k)``
  centres even squares one pixel earlier, a one-pixel shift of the mask). Outside the image counts as
  pressed (MATLAB ``imerode`` pads with the maximum), so a region touching the border is not eroded
  from the border: ``scipy.ndimage.binary_erosion(mask, np.ones((k, k)), border_value=1)``.
* **Sobel** gradients are unnormalised (``scipy.ndimage.sobel``: ``gx[i, j] = `` smoothed
  ``x[., j+1] - x[., j-1]``), border mode ``'reflect'`` (the edge pixel repeated); ``gx`` along
  columns (x to the right), ``gy`` along rows (y downwards). kornia's ``sobel`` divides by 8.
* **Edges** are the pixels where the Sobel magnitude of the eroded mask exceeds ``edge_threshold``
  (default 0.5). On a binary mask the magnitude is 0 or at least 1, so the default marks exactly the
  pixels next to a boundary of the pressed region, on both sides (a 2-pixel band): parameter-free on
  binary input and exactly reproducible, unlike MATLAB ``edge(..., 'sobel')``'s automatic threshold
  and thinning (which keeps a 1-pixel line).
* **Fusion** is the logical OR over the frames.
* **Gradient** of the fused image: magnitude ``M = sqrt(gx^2 + gy^2)``, direction
  ``A = atan2(gy, gx)`` in radians in ``(-pi, pi]`` (``A = 0`` where ``gx = gy = 0``). MATLAB's
  ``imgradient`` reports ``atan2(-gy, gx)`` in degrees instead.
* **Statistics** over the row-major flattened image: mean, standard deviation (``ddof=1``), biased
  skewness, Pearson kurtosis (3 for a normal), 95th percentile (linear interpolation, numpy's
  default), mean absolute deviation about the mean. A constant image (zero variance, e.g. the fused
  image of a blank exploration) has skewness 0 and kurtosis 0 (scipy returns NaN); a 1-pixel image has
  standard deviation 0.

Differentiable mode (``temperature=t``): the threshold becomes ``sigmoid((threshold - I) / t)``, the
erosion a soft minimum ``-t * logsumexp(-x / t)`` over the window, the edges
``sigmoid((gx^2 + gy^2 - edge_threshold^2) / t)`` and the OR a noisy-OR ``1 - prod(1 - e)``; as
``t → 0`` the features converge to the hard ones. Gradients reach the frames and a tensor threshold.

Examples
--------
>>> frames = torch.full((2, 5, 3, 32, 32), 255, dtype=torch.uint8)
>>> frames[:, :, :, 8:24, 8:24] = 0                      # a pressed square in every frame
>>> exploration_features(frames, erosion=3).shape
torch.Size([2, 12])
"""

from __future__ import annotations

import contextlib
import functools
import math

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from ._checks import check_finite, check_floating, check_positive, check_shape, check_tensor
from ._parallel import map_blocks, serial_torch_ops

DEFAULT_THRESHOLD = 240.0 / 255.0
"""Pressed-region threshold of the study (240 on the 0-255 scale)."""
DEFAULT_EROSION = 10
"""Side of the square structuring element of the study, in pixels."""
DEFAULT_EDGE_THRESHOLD = 0.5
"""Sobel magnitude above which a pixel is an edge (any non-zero magnitude on a binary mask)."""
GRAY_WEIGHTS = (0.2989, 0.5870, 0.1140)
"""Weights of R, G, B in the grayscale conversion (MATLAB ``rgb2gray``)."""
STATISTICS = ("mean", "std", "skew", "kurt", "p95", "mad")
"""The six statistics of :func:`gradient_statistics`, in order."""
FEATURE_NAMES = tuple(f"{image}_{stat}" for image in ("M", "A") for stat in STATISTICS)
"""Names of the 12 features of :func:`exploration_features` (magnitude first, then direction)."""
HISTOGRAM_LEVELS = 256
"""Gray levels of the histogram behind :func:`otsu_threshold`."""
CHUNK_PIXELS = 1 << 19
"""Pixels (explorations x frames x height x width) of one block of :func:`exploration_features`."""
_GRAY_INTEGER = tuple(round(w * 10_000) for w in GRAY_WEIGHTS)
# 255 * 10_000 times the exact gray of uint8 RGB is the integer 2989 R + 5870 G + 1140 B.
_GRAY_SCALE = 255 * 10_000
# The float32 gray of uint8 RGB (six roundings of relative 2**-24 on a value <= 1) is within 1e-6 of
# the exact one, i.e. within 2.6 units of the integer sum; pixels farther than this from the threshold
# are decided on the integer alone.
_GRAY_BAND = 4

Threshold = float | torch.Tensor | str


# ----------------------------------------------------------------------------------------- validation
def _check_frames(frames: object, name: str = "frames", *, batched: bool = True) -> torch.Tensor:
    """Validate RGB frames (uint8, or float in [0, 1]); data-dependent checks are skipped while exporting."""
    check_tensor(frames, name)
    check_shape(frames, name, ["B", "T", 3, "H", "W"] if batched else ["*", 3, "H", "W"])
    if frames.dtype != torch.uint8 and not frames.is_floating_point():
        raise TypeError(f"{name} must be uint8 (0-255) or float in [0, 1], got {frames.dtype}")
    if any(s == 0 for s in frames.shape):
        what = (
            "frame per exploration (T >= 1)" if batched and frames.shape[1] == 0 else "non-empty dimensions"
        )
        raise ValueError(f"{name} must have at least one {what}, got shape {tuple(frames.shape)}")
    if frames.is_floating_point() and not torch.compiler.is_exporting():
        _check_unit_range(frames, name)
    return frames


def _check_unit_range(x: torch.Tensor, name: str) -> None:
    lo, hi = torch.aminmax(x.detach())
    if not (bool(torch.isfinite(lo)) and bool(torch.isfinite(hi))):
        check_finite(x, name)
    if float(lo) < 0.0 or float(hi) > 1.0:
        raise ValueError(
            f"{name} must be float in [0, 1] (or uint8 0-255), got values in [{float(lo):g}, {float(hi):g}]"
        )


def _check_image(x: object, name: str, spec: list) -> torch.Tensor:
    check_tensor(x, name)
    check_shape(x, name, spec)
    check_floating(x, name)
    if any(s == 0 for s in x.shape):
        raise ValueError(f"{name} must have non-empty dimensions, got shape {tuple(x.shape)}")
    if not torch.compiler.is_exporting():
        check_finite(x, name)
    return x


def _check_temperature(temperature: float | None) -> None:
    if temperature is not None:
        check_positive(temperature, "temperature")


def _check_threshold(threshold: Threshold, batch: int, name: str = "threshold") -> None:
    if isinstance(threshold, str):
        if threshold != "otsu":
            raise ValueError(f"{name} must be a number in (0, 1], a tensor or 'otsu', got {threshold!r}")
        return
    if isinstance(threshold, torch.Tensor):
        if threshold.ndim > 1 or (threshold.ndim == 1 and threshold.shape[0] not in (1, batch)):
            raise ValueError(
                f"{name} must be a scalar tensor or have shape ({batch},), got {tuple(threshold.shape)}"
            )
        check_floating(threshold, name)
        if not torch.compiler.is_exporting():
            check_finite(threshold, name)
        return
    check_positive(threshold, name)
    if threshold > 1.0:
        raise ValueError(f"{name} must be in (0, 1] (the 0-255 scale divided by 255), got {threshold!r}")


# ------------------------------------------------------------------------------------------ kernels
def _gray(frames: torch.Tensor, dtype: torch.dtype) -> torch.Tensor:
    """(..., 3, H, W) → (..., H, W) in ``dtype``, with the reference's elementwise operations in its order."""
    x = frames.to(dtype).div_(255.0) if frames.dtype == torch.uint8 else frames.to(dtype)
    r, g, b = x.unbind(-3)
    gray = r * GRAY_WEIGHTS[0]
    gray += g * GRAY_WEIGHTS[1]
    gray += b * GRAY_WEIGHTS[2]
    return gray


def _pressed(
    frames: torch.Tensor,
    threshold: torch.Tensor,
    dtype: torch.dtype,
    temperature: float | None,
    integer_cut: int | None = None,
) -> torch.Tensor:
    """Pressed region of (B, t, 3, H, W) frames: int8 {0, 1} (hard) or ``dtype`` (soft).

    ``threshold``: shape () or (B,), ``dtype``. Hard on uint8 frames (not while exporting) the gray level
    is never formed: :func:`_pressed_uint8` gives the same mask from integers. While exporting, an
    ``integer_cut`` (:func:`_integer_cut` of the threshold) does the same in the graph: the integer
    gray ``S`` as one MatMul over the colour axis (integers below 2^24: exact in float32 in any
    order), then ``S < integer_cut``, instead of a division and five elementwise passes.
    """
    if temperature is None and frames.dtype == torch.uint8:
        if not torch.compiler.is_exporting():
            return _pressed_uint8(frames, threshold)
        if integer_cut is not None:
            weights = torch.tensor([_GRAY_INTEGER], dtype=torch.float32)  # (1, 3)
            total = torch.matmul(weights, frames.flatten(-2).to(torch.float32))  # (..., 1, H * W)
            return (total < integer_cut).to(torch.int8).reshape(*frames.shape[:-3], *frames.shape[-2:])
    gray = _gray(frames, dtype)
    return _pressure(gray, _threshold_tensor(threshold, gray), temperature)


def _pressed_uint8(frames: torch.Tensor, threshold: torch.Tensor) -> torch.Tensor:
    """``_pressure(_gray(frames, float32), threshold)`` for uint8 frames, bit for bit, in integers.

    The exact gray times :data:`_GRAY_SCALE` is the integer ``S = 2989 R + 5870 G + 1140 B``; the
    float32 gray is within :data:`_GRAY_BAND` units of it, so ``S`` decides every pixel but those
    within the band around the threshold (a few integers out of 2.55 million). For a single
    threshold :func:`_integer_cut` usually finds one integer cut that is exact for every colour (one
    comparison); otherwise (per-exploration thresholds, or a band value shared by colours on both
    sides) the pixels in the band get the float formula itself. About a third of the float path's
    memory traffic.
    """
    limit = threshold.to(torch.float32)
    if limit.ndim:  # per exploration
        limit = limit.view(-1, 1, 1, 1)
        cut = limit.double() * _GRAY_SCALE
        low = torch.ceil(cut - _GRAY_BAND).to(torch.int32)
        high = torch.floor(cut + _GRAY_BAND).to(torch.int32) + 1
    else:  # Python numbers: cheaper than a few tiny tensor ops per block
        cut = float(limit) * _GRAY_SCALE  # exact: a float32 times a 22-bit integer
        low, high = math.ceil(cut - _GRAY_BAND), math.floor(cut + _GRAY_BAND) + 1
    # S < low: pressed whatever the rounding; S >= high: not pressed
    r, g, b = (channel.to(torch.int32) for channel in frames.unbind(-3))
    total = r.mul_(_GRAY_INTEGER[0]).add_(g, alpha=_GRAY_INTEGER[1]).add_(b, alpha=_GRAY_INTEGER[2])
    exact = None if limit.ndim else _integer_cut(float(limit))
    if exact is not None:  # one comparison decides every colour
        return torch.lt(total, exact, out=torch.empty(total.shape, dtype=torch.int8))
    mask = torch.lt(total, low, out=torch.empty(total.shape, dtype=torch.int8))
    near = torch.lt(total, high, out=torch.empty(total.shape, dtype=torch.int8)).sub_(mask)  # 1 in the band
    if int(near.amax()) > 0:  # (an int8 max is several times cheaper than torch.equal or any)
        near = near.nonzero(as_tuple=True)
        gray = _gray(frames.movedim(-3, -1)[near].view(-1, 3, 1, 1), torch.float32).view(-1)
        mask[near] = torch.lt(gray, limit.expand(total.shape)[near]).to(torch.int8)
    return mask


def _float32(value: float) -> float:
    """``value`` rounded to float32 (the threshold as the float32 comparisons see it)."""
    return float(np.float32(value))  # NumPy, not a tensor: also called while tracing for export


class _CutCache:
    """Memo of :func:`_find_integer_cut` per float32 threshold; ``known`` looks up without computing."""

    def __init__(self, size: int = 512) -> None:
        self._cuts: dict[float, int | None] = {}
        self._size = size

    def __call__(self, limit: float) -> int | None:
        if limit not in self._cuts:
            if len(self._cuts) >= self._size:
                self._cuts.clear()
            self._cuts[limit] = _find_integer_cut(limit)
        return self._cuts[limit]

    def known(self, limit: float) -> int | None:
        return self._cuts.get(limit)


def _find_integer_cut(limit: float) -> int | None:
    """The integer ``c`` such that ``gray < limit`` iff ``S < c`` for every uint8 colour, if one exists.

    ``limit`` is a float32 value; ``gray`` is the float32 grayscale of :func:`_gray` and ``S`` the
    integer of :func:`_pressed_uint8`. Only colours with ``S`` within :data:`_GRAY_BAND` of the
    threshold can disagree with the order of ``S``: they are enumerated (at most one blue level per
    red-green pair, the band being narrower than a blue step) and decided by :func:`_gray` itself.
    ``None`` if a value of ``S`` in the band holds colours on both sides (then the caller decides
    pixel by pixel). Cached: a few milliseconds per new threshold.
    """
    cut = limit * _GRAY_SCALE
    low, high = math.ceil(cut - _GRAY_BAND), math.floor(cut + _GRAY_BAND) + 1
    red, green = (c.reshape(-1) for c in torch.meshgrid(torch.arange(256), torch.arange(256), indexing="ij"))
    rest = _GRAY_INTEGER[0] * red + _GRAY_INTEGER[1] * green
    blue = -torch.div(rest - low, _GRAY_INTEGER[2], rounding_mode="floor")  # the least with S >= low
    total = rest + _GRAY_INTEGER[2] * blue
    keep = (blue >= 0) & (blue <= 255) & (total < high)
    colours = torch.stack([red[keep], green[keep], blue[keep]], dim=1).to(torch.uint8)
    pressed = _gray(colours.view(-1, 3, 1, 1), torch.float32).view(-1) < limit
    total = total[keep]
    exact = int(total[pressed].max()) + 1 if bool(pressed.any()) else low
    return exact if bool((total[~pressed] >= exact).all()) else None


_integer_cut = _CutCache()


def _window_pads(k: int) -> tuple[int, int]:
    """(before, after) padding of a size-k window starting at ``i - k//2`` (scipy's origin)."""
    return k // 2, k - 1 - k // 2


# The spatial kernels work on the flattened, padded stack of images: a neighbour is a fixed offset in
# the 1-D buffer (1 along a row, the padded width along a column), so every step is one long contiguous
# elementwise operation instead of many short rows. Positions that mix rows or images land only in the
# padding, which is cut off afterwards.
def _window_min(x: torch.Tensor, k: int, stride: int, temperature: float | None) -> torch.Tensor:
    """Minimum of ``x[q], x[q + stride], ..., x[q + (k-1) stride]`` for every ``q`` (1-D, shorter output).

    Hard: by doubling, windows of 1, 2, 4, ... from two shifted copies each and a last overlapping step,
    about ``2 log2(k)`` elementwise minima, exact. Soft: ``-t * logsumexp(-x / t)`` over the window.
    """
    n_out = x.shape[0] - (k - 1) * stride
    if temperature is not None:
        windows = x.unfold(0, (k - 1) * stride + 1, 1)[:, ::stride]
        return -temperature * torch.logsumexp(-windows / temperature, dim=-1)
    width = 1
    while 2 * width <= k:
        n = x.shape[0] - width * stride
        x = torch.minimum(x[:n], x[width * stride : width * stride + n])
        width *= 2
    if width < k:
        offset = (k - width) * stride
        return torch.minimum(x[:n_out], x[offset : offset + n_out])
    return x[:n_out]


def _erode(mask: torch.Tensor, k: int, temperature: float | None) -> torch.Tensor:
    """Minimum filter of (..., H, W) by a k x k square, outside ignored (any dtype; soft: float)."""
    if k == 1:
        return mask
    *lead, height, width = mask.shape
    before, after = _window_pads(k)
    # The maximum outside: the border never lowers the minimum (MATLAB imerode's padding).
    fill = math.inf if mask.is_floating_point() else 1
    padded = F.pad(mask.reshape(-1, height, width), (before, after, before, after), value=fill)
    padded_width = width + k - 1
    # The soft minimum over a square is separable exactly: logsumexp over a 2-D window is the logsumexp
    # over rows of the per-row logsumexps.
    flat = _window_min(padded.reshape(-1), k, 1, temperature)
    flat = _window_min(flat, k, padded_width, temperature)
    flat = F.pad(flat, (0, padded.numel() - flat.numel()))
    return flat.reshape(padded.shape)[:, :height, :width].reshape(*lead, height, width)


def _sobel_flat(image: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Unnormalised Sobel (gx, gy) of (N, H, W), 'reflect' border, as 1-D buffers for :func:`_unflat`."""
    # One repeated pixel on each side: scipy's 'reflect' (d c b a | a b c d) for a 3 x 3 kernel.
    p = F.pad(image, (1, 1, 1, 1), mode="replicate").reshape(-1)
    s, n = image.shape[-1] + 2, p.shape[0]
    # a + 2 b as one op (2 b is exact, so the sum rounds once either way), then + c: the reference's order
    smooth_y = torch.add(p[: n - 2 * s], p[s : n - s], alpha=2).add_(p[2 * s :])
    diff_y = p[2 * s :] - p[: n - 2 * s]
    gx = smooth_y[2:] - smooth_y[:-2]
    gy = torch.add(diff_y[:-2], diff_y[1:-1], alpha=2).add_(diff_y[2:])
    return gx, gy


def _unflat(values: torch.Tensor, shape: torch.Size, *, ring: bool = False) -> torch.Tensor:
    """Map a 1-D result of :func:`_sobel_flat` back to (..., H, W).

    ``ring=True``: return the contiguous (..., H + 2, W + 2) buffer instead, the result inside a
    one-pixel ring of junk (values that mix rows), for reductions over frames that slice afterwards.
    """
    height, width = shape[-2:]
    s = width + 2
    full = F.pad(values, (s + 1, s + 1)).reshape(*shape[:-2], height + 2, width + 2)
    return full if ring else full[..., 1:-1, 1:-1]


def _sobel(image: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Unnormalised Sobel ``(gx, gy)`` of (..., H, W) with scipy's 'reflect' border (edge repeated)."""
    gx, gy = _sobel_flat(image.reshape(-1, *image.shape[-2:]))
    return _unflat(gx, image.shape), _unflat(gy, image.shape)


def _edges(
    mask: torch.Tensor, edge_threshold: float, temperature: float | None, *, ring: bool = False
) -> torch.Tensor:
    """Edges of (..., H, W): {0, 1} in mask's dtype (hard) or float in (0, 1) (soft); ``ring``: see
    :func:`_unflat`."""
    gx, gy = _sobel_flat(mask.reshape(-1, *mask.shape[-2:]))
    # The squared magnitude keeps the soft edge differentiable where the gradient vanishes.
    squared = torch.addcmul(gx * gx, gy, gy)
    if temperature is not None:
        edges = torch.sigmoid((squared - edge_threshold * edge_threshold) / temperature)
    elif mask.is_floating_point():
        edges = (squared > edge_threshold * edge_threshold).to(mask.dtype)
    else:
        # A binary int8 mask has integer squared magnitudes of at most 32 (|gx|, |gy| <= 4), so
        # ``squared > c`` is ``clamp(squared - c, 0, 1)``: int8 in place, no bool round trip.
        cut = min(math.floor(edge_threshold * edge_threshold), 32)
        edges = (squared.sub_(cut) if cut else squared).clamp_(0, 1)
    return _unflat(edges, mask.shape, ring=ring)


def _pressure(gray: torch.Tensor, threshold: torch.Tensor, temperature: float | None) -> torch.Tensor:
    """Pressed region: int8 {0, 1} (hard) or float (soft)."""
    if temperature is None:
        # written straight to int8: several times faster than a bool result converted afterwards
        return torch.lt(gray, threshold, out=torch.empty(gray.shape, dtype=torch.int8))
    return torch.sigmoid((threshold - gray) / temperature)


def _level_histogram(gray: torch.Tensor) -> torch.Tensor:
    """(B, ...) → (B, 256) float64 counts of the gray levels ``round(255 I)``."""
    levels = torch.round(gray.reshape(gray.shape[0], -1) * (HISTOGRAM_LEVELS - 1))
    levels = levels.clamp(0, HISTOGRAM_LEVELS - 1).long()
    hist = torch.zeros(gray.shape[0], HISTOGRAM_LEVELS, dtype=torch.float64)
    return hist.scatter_add_(1, levels, torch.ones(levels.shape, dtype=torch.float64))


def _otsu_from_histogram(hist: torch.Tensor) -> torch.Tensor:
    """(B, L) counts → (B,) thresholds on the [0, 1] scale, ``I < t`` selecting the darker class."""
    p = hist / hist.sum(-1, keepdim=True)
    levels = torch.arange(hist.shape[-1], dtype=hist.dtype)
    omega = p.cumsum(-1)
    mu = (p * levels).cumsum(-1)
    mu_total = mu[..., -1:]
    denom = omega * (1.0 - omega)
    valid = denom > 0
    between = torch.where(valid, (mu_total * omega - mu) ** 2 / torch.where(valid, denom, 1.0), 0.0)
    top = between.amax(-1, keepdim=True)
    best = between == top
    # MATLAB graythresh: the middle of a plateau of maxima (e.g. across empty bins between two modes);
    # level 0 when no split separates anything (a constant sample).
    level = torch.where(top.squeeze(-1) > 0, (best * levels).sum(-1) / best.sum(-1), 0.0)
    return (level + 0.5) / (hist.shape[-1] - 1)


def _threshold_tensor(threshold: float | torch.Tensor, like: torch.Tensor) -> torch.Tensor:
    """A threshold broadcastable against (B, T, H, W), in ``like``'s dtype."""
    t = torch.as_tensor(threshold, dtype=like.dtype)
    return t.reshape(-1, *([1] * (like.ndim - 1))) if t.ndim == 1 else t


def _safe_sqrt(x: torch.Tensor) -> torch.Tensor:
    """sqrt with a zero (not NaN) gradient at 0."""
    positive = x > 0
    return torch.where(positive, torch.sqrt(torch.where(positive, x, 1.0)), 0.0)


def _gradient(image: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    gx, gy = _sobel(image)
    squared = gx * gx + gy * gy
    flat = squared == 0
    # atan2(0, 0) = 0 by convention; the double where keeps its gradient finite there.
    direction = torch.where(flat, 0.0, torch.atan2(torch.where(flat, 1.0, gy), torch.where(flat, 1.0, gx)))
    # atan2(-0.0, x < 0) = -pi: fold it onto pi so that the range is (-pi, pi].
    direction = torch.where(direction <= -math.pi, -direction, direction)
    return _safe_sqrt(squared), direction


def _statistics(image: torch.Tensor) -> torch.Tensor:
    # Accumulated in float64: the third and fourth moments of thousands of float32 values would
    # otherwise lose about five digits.
    values = image.flatten(-2).to(torch.float64)
    n = values.shape[-1]
    mean = values.mean(-1, keepdim=True)
    dev = values - mean
    sq = dev * dev
    m2 = sq.mean(-1)
    m3 = (sq * dev).mean(-1)
    m4 = (sq * sq).mean(-1)
    std = _safe_sqrt(sq.sum(-1) / max(n - 1, 1))
    # Zero variance up to rounding (scipy.stats' criterion): skewness and kurtosis are defined as 0.
    resolution = torch.finfo(values.dtype).resolution
    constant = m2 <= (resolution * mean.squeeze(-1)) ** 2
    safe_m2 = torch.where(constant, 1.0, m2)
    skew = torch.where(constant, 0.0, m3 / (safe_m2 * _safe_sqrt(safe_m2)))
    kurt = torch.where(constant, 0.0, m4 / (safe_m2 * safe_m2))
    # Linear-interpolation percentile from the top 5 % only (cheaper than a sort; exports as TopK).
    position = 0.95 * (n - 1)
    lower = math.floor(position)
    fraction = position - lower
    top = torch.topk(values, n - lower, dim=-1, largest=True, sorted=False).values
    pair = torch.topk(top, min(2, n - lower), dim=-1, largest=False, sorted=True).values
    below, above = pair[..., 0], pair[..., -1]
    p95 = below + (above - below) * fraction
    mad = dev.abs().mean(-1)
    return torch.stack([mean.squeeze(-1), std, skew, kurt, p95, mad], dim=-1).to(image.dtype)


def _image_features(image: torch.Tensor) -> torch.Tensor:
    magnitude, direction = _gradient(image)
    return torch.cat([_statistics(magnitude), _statistics(direction)], dim=-1)


def _or_accumulate(acc: torch.Tensor | None, edges: torch.Tensor, soft: bool) -> torch.Tensor:
    """Fold (B, t, H, W) edges into the running OR: hard max, or the sum of ``log(1 - e)`` if soft."""
    if soft:
        # log(1 - e), -inf where e = 1 (so that the OR is exactly 1 there); the double where keeps the
        # gradient finite (e = 1 only where a sigmoid saturated, whose own gradient is 0).
        below = edges < 1.0
        part = torch.where(below, torch.log1p(-torch.where(below, edges, 0.0)), -math.inf).sum(1)
    elif torch.compiler.is_exporting():
        # onnxruntime reduces int8 over a middle axis slowly; a count by one MatMul is several times
        # faster and exact (at most T ones per pixel): OR = count > 0.
        ones = torch.ones(1, edges.shape[1], dtype=torch.float32)
        count = torch.matmul(ones, edges.flatten(2).to(torch.float32))  # (B, 1, H * W)
        part = (count > 0).to(edges.dtype).reshape(edges.shape[0], *edges.shape[2:])
    else:
        part = edges.amax(1)
    return part if acc is None else _or_merge(acc, part, soft)


def _or_merge(acc: torch.Tensor, part: torch.Tensor, soft: bool) -> torch.Tensor:
    """Combine two results of :func:`_or_accumulate`."""
    return acc + part if soft else torch.maximum(acc, part)


def _or_finish(acc: torch.Tensor, soft: bool) -> torch.Tensor:
    return -torch.expm1(acc) if soft else acc


# ---------------------------------------------------------------------------------- public functions
def to_grayscale(frames: torch.Tensor) -> torch.Tensor:
    """Return the grayscale image ``0.2989 R + 0.5870 G + 0.1140 B`` of RGB frames, on the [0, 1] scale.

    Parameters
    ----------
    frames : tensor of shape (..., 3, H, W)
        uint8 (0-255, converted to float32 / 255) or float in [0, 1].

    Returns
    -------
    tensor of shape (..., H, W), float (the input's float dtype, float32 for uint8).

    Examples
    --------
    >>> to_grayscale(torch.full((1, 2, 3, 4, 4), 255, dtype=torch.uint8))[0, 0, 0, 0]
    tensor(0.9999)
    """
    _check_frames(frames, batched=False)
    return _gray(frames, frames.dtype if frames.is_floating_point() else torch.float32)


def otsu_threshold(gray: torch.Tensor) -> torch.Tensor:
    """Return Otsu's threshold of each sample, pooled over all its pixels (e.g. all frames of an exploration).

    The gray levels are quantised to ``round(255 I)`` (MATLAB ``im2uint8``); the level ``k`` maximising
    the between-class variance of ``{<= k}`` and ``{> k}`` is chosen (the middle of a plateau of
    maxima, as MATLAB ``graythresh``), and ``(k + 0.5) / 255`` is returned so that
    ``I < threshold`` selects the darker class. A constant sample gives ``0.5 / 255`` (nothing pressed
    unless it is black).

    Parameters
    ----------
    gray : tensor of shape (B, ...), float in [0, 1]

    Returns
    -------
    tensor of shape (B,), float64.

    Examples
    --------
    >>> gray = torch.tensor([[0.1, 0.12, 0.9, 0.95]])
    >>> bool(0.12 < otsu_threshold(gray)[0] < 0.9)
    True
    """
    check_tensor(gray, "gray")
    if gray.ndim < 1 or gray.numel() == 0:
        raise ValueError(f"gray must have shape (B, ...) with at least one pixel, got {tuple(gray.shape)}")
    check_floating(gray, "gray")
    _check_unit_range(gray, "gray")
    return _otsu_from_histogram(_level_histogram(gray))


def pressure_mask(
    gray: torch.Tensor, threshold: Threshold = DEFAULT_THRESHOLD, *, temperature: float | None = None
) -> torch.Tensor:
    """Return the pressed region ``gray < threshold`` (1 pressed, 0 not) of every frame.

    Parameters
    ----------
    gray : tensor of shape (B, T, H, W), float in [0, 1]
    threshold : float in (0, 1], tensor of shape () or (B,), or ``"otsu"``
        Pressed below this intensity (the study: 240/255, white being no pressure); ``"otsu"`` picks one
        per exploration with :func:`otsu_threshold`. A tensor threshold may require gradients.
    temperature : float, optional
        ``None``: hard mask. Otherwise ``sigmoid((threshold - gray) / temperature)``.

    Returns
    -------
    tensor of shape (B, T, H, W), gray's dtype, values in {0, 1} (hard) or (0, 1) (soft).

    Examples
    --------
    >>> pressure_mask(torch.tensor([[[[0.2, 0.99]]]])).tolist()
    [[[[1.0, 0.0]]]]
    """
    _check_image(gray, "gray", ["B", "T", "H", "W"])
    _check_threshold(threshold, gray.shape[0])
    _check_temperature(temperature)
    if isinstance(threshold, str):
        threshold = otsu_threshold(gray)
    return _pressure(gray, _threshold_tensor(threshold, gray), temperature).to(gray.dtype)


def erode(
    mask: torch.Tensor, size: int = DEFAULT_EROSION, *, temperature: float | None = None
) -> torch.Tensor:
    """Return the erosion (minimum filter) of ``mask`` by a ``size x size`` square.

    The window of pixel ``(i, j)`` covers rows ``i - size//2 ... i - size//2 + size - 1`` (and the same
    for columns): scipy's origin, which matters for even sizes. Pixels outside the image are ignored
    (as if pressed: MATLAB ``imerode``), so for a binary mask this equals
    ``scipy.ndimage.binary_erosion(mask, np.ones((size, size)), border_value=1)`` and for any image
    ``scipy.ndimage.grey_erosion(x, size=(size, size), mode='constant', cval=inf)``. Computed as two
    1-D running minima (separable square), each by doubling.

    Parameters
    ----------
    mask : tensor of shape (..., H, W), floating
    size : int >= 1
        Side of the square (1: no erosion).
    temperature : float, optional
        ``None``: exact minimum. Otherwise the soft minimum ``-t * logsumexp(-x / t)`` over the window
        (below the minimum by at most ``t * log(size**2)``); it materialises the windows (``size``
        times the input's memory), as suits the small inputs of training, not bulk feature extraction.

    Returns
    -------
    tensor of shape (..., H, W), mask's dtype.

    Examples
    --------
    >>> m = torch.zeros(1, 7, 7); m[0, 1:6, 1:6] = 1
    >>> erode(m, 3)[0].sum().item()
    9.0
    """
    _check_image(mask, "mask", ["*", "H", "W"])
    check_positive(size, "size", integer=True)
    _check_temperature(temperature)
    return _erode(mask, int(size), temperature)


def sobel_edges(
    mask: torch.Tensor, edge_threshold: float = DEFAULT_EDGE_THRESHOLD, *, temperature: float | None = None
) -> torch.Tensor:
    """Return the binary edge map: pixels whose Sobel gradient magnitude exceeds ``edge_threshold``.

    The Sobel gradients are unnormalised with scipy's 'reflect' border (see the module notes). On a
    binary mask the magnitude is 0 or at least 1, so the default 0.5 marks the pixels on both sides of
    every boundary; ``scipy.ndimage.sobel`` on the mask followed by ``hypot(gx, gy) > 0.5`` is the
    reference.

    Parameters
    ----------
    mask : tensor of shape (..., H, W), floating
    edge_threshold : float >= 0
    temperature : float, optional
        ``None``: {0, 1} edges. Otherwise ``sigmoid((gx^2 + gy^2 - edge_threshold^2) / temperature)``.

    Returns
    -------
    tensor of shape (..., H, W), mask's dtype.

    Examples
    --------
    >>> m = torch.zeros(1, 6, 6); m[0, :, 3:] = 1
    >>> sobel_edges(m)[0, 0].tolist()
    [0.0, 0.0, 1.0, 1.0, 0.0, 0.0]
    """
    _check_image(mask, "mask", ["*", "H", "W"])
    check_positive(edge_threshold, "edge_threshold", strict=False)
    _check_temperature(temperature)
    return _edges(mask, float(edge_threshold), temperature).to(mask.dtype)


def fuse_edges(edges: torch.Tensor, *, soft: bool = False) -> torch.Tensor:
    """Return the logical OR of the edge maps over the frame axis.

    Parameters
    ----------
    edges : tensor of shape (B, T, H, W), floating, values in [0, 1]
    soft : bool
        ``False``: maximum over frames (the OR of {0, 1} maps). ``True``: noisy-OR ``1 - prod(1 - e)``,
        computed as ``-expm1(sum(log1p(-e)))`` (exactly 1 where some ``e`` is 1).

    Returns
    -------
    tensor of shape (B, H, W), edges' dtype.

    Examples
    --------
    >>> fuse_edges(torch.tensor([[[[0.0, 1.0]], [[1.0, 0.0]]]])).tolist()
    [[[1.0, 1.0]]]
    """
    _check_image(edges, "edges", ["B", "T", "H", "W"])
    return _or_finish(_or_accumulate(None, edges, soft), soft)


def gradient(image: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Return the Sobel gradient magnitude ``M`` and direction ``A = atan2(gy, gx)`` of an image.

    Unnormalised Sobel with scipy's 'reflect' border; ``gx`` along columns, ``gy`` along rows
    (downwards); ``A`` in radians in ``(-pi, pi]``, 0 where both gradients vanish.

    Parameters
    ----------
    image : tensor of shape (..., H, W), floating

    Returns
    -------
    (magnitude, direction) : two tensors of shape (..., H, W)

    Examples
    --------
    >>> m, a = gradient(torch.arange(16.0, dtype=torch.float64).reshape(1, 4, 4))
    >>> round(m[0, 1, 1].item(), 4), round(a[0, 1, 1].item(), 4)   # gx = 8, gy = 32
    (32.9848, 1.3258)
    """
    _check_image(image, "image", ["*", "H", "W"])
    return _gradient(image)


def gradient_statistics(image: torch.Tensor) -> torch.Tensor:
    """Return the six statistics ``[mean, std, skew, kurt, p95, mad]`` of each image's pixels.

    Over the row-major flattened image: mean; standard deviation with ``ddof=1``; biased skewness and
    Pearson kurtosis (``scipy.stats.skew``, ``kurtosis(fisher=False)``); 95th percentile with linear
    interpolation (``numpy.percentile``); mean absolute deviation about the mean. A constant image has
    skewness 0 and kurtosis 0 (scipy: NaN); a one-pixel image has standard deviation 0. The moments are
    accumulated in float64 and returned in the image's dtype.

    Parameters
    ----------
    image : tensor of shape (..., H, W), floating

    Returns
    -------
    tensor of shape (..., 6)

    Examples
    --------
    >>> gradient_statistics(torch.zeros(2, 4, 4))[0].tolist()
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    """
    _check_image(image, "image", ["*", "H", "W"])
    return _statistics(image)


def exploration_features(
    frames: torch.Tensor,
    *,
    fuse: bool = True,
    threshold: Threshold = DEFAULT_THRESHOLD,
    erosion: int = DEFAULT_EROSION,
    edge_threshold: float = DEFAULT_EDGE_THRESHOLD,
    temperature: float | None = None,
    frames_per_chunk: int | None = None,
) -> torch.Tensor:
    """Return the method-1 features of explorations: 12 per exploration, or 12 per frame without fusion.

    Per frame: grayscale, pressed region ``I < threshold``, erosion by a ``erosion x erosion`` square,
    Sobel edges; then the OR of all frames' edges (``fuse=True``), its Sobel magnitude and direction and
    their six statistics each (order :data:`FEATURE_NAMES`). With ``fuse=False`` the same 12 statistics
    are taken of every frame's edge image and concatenated frame by frame (the study's ablation).

    The work is cut into blocks of explorations x frames of about :data:`CHUNK_PIXELS` pixels (whole
    explorations share a block when they fit; the OR is accumulated across a long exploration's
    blocks), so the memory stays bounded whatever ``B`` and ``T``. In the hard mode the blocks run on
    ``torch.get_num_threads()`` Python threads while torch's intra-op pool is held at one thread for
    the duration of the call (a process-wide setting, restored on return, also on error); results do
    not depend on the thread count. Hard mode on uint8 frames decides the pressed region on integers
    (bit-identical to the float32 grayscale, see the notes of ``_pressed_uint8``). The soft mode and
    the ONNX export trace run in the caller's thread, on one block. A blank exploration (no pressure
    anywhere) has an all-zero fused image and all-zero features.

    Parameters
    ----------
    frames : tensor of shape (B, T, 3, H, W)
        RGB, uint8 (0-255) or float in [0, 1]; white means no pressure.
    fuse : bool
        Fuse the frames (``(B, 12)``) or not (``(B, T * 12)``).
    threshold : float in (0, 1], tensor of shape () or (B,), or ``"otsu"``
        See :func:`pressure_mask`; ``"otsu"`` takes one threshold per exploration over all its frames.
    erosion : int >= 1
        Side of the square structuring element (see :func:`erode`).
    edge_threshold : float >= 0
        See :func:`sobel_edges`.
    temperature : float, optional
        ``None``: the hard pipeline. Otherwise every step is smooth (soft threshold, soft erosion, soft
        edges, noisy-OR fusion), so gradients reach ``frames`` (float) and a tensor ``threshold``.
    frames_per_chunk : int, optional
        Frames per block; default: as many as fit :data:`CHUNK_PIXELS` pixels (at least 1). While
        exporting to ONNX all frames and explorations form one block.

    Returns
    -------
    tensor of shape (B, 12) or (B, T * 12), float (float32 for uint8 frames).

    Examples
    --------
    >>> frames = torch.randint(0, 256, (2, 4, 3, 24, 24), dtype=torch.uint8)
    >>> exploration_features(frames, fuse=False, erosion=2).shape
    torch.Size([2, 48])
    """
    _check_frames(frames)
    batch, n_frames, _, height, width = frames.shape
    _check_threshold(threshold, batch)
    check_positive(erosion, "erosion", integer=True)
    check_positive(edge_threshold, "edge_threshold", strict=False)
    _check_temperature(temperature)
    if frames_per_chunk is not None:
        check_positive(frames_per_chunk, "frames_per_chunk", integer=True)
    dtype = frames.dtype if frames.is_floating_point() else torch.float32
    exporting = torch.compiler.is_exporting()
    soft = temperature is not None
    # The hard eager path runs blocks on Python threads with single-threaded torch ops (see
    # tactile_torch._parallel); the soft path (autograd) and the export trace run in the caller's thread.
    with serial_torch_ops() if not (soft or exporting) else contextlib.nullcontext(1) as threads:
        if exporting:  # one block: no Python arithmetic on the symbolic batch size
            blocks, per_row = [(slice(None), slice(None))], 1
        else:
            blocks, per_row = _blocks(batch, n_frames, height * width, frames_per_chunk)
        if isinstance(threshold, str):
            hists = map_blocks(lambda b: _level_histogram(_gray(frames[b], dtype)), blocks, threads)
            threshold = _otsu_from_histogram(torch.cat([sum(row) for row in _rows(hists, per_row)]))
        exact_cut = None
        if exporting and not soft and frames.dtype == torch.uint8 and isinstance(threshold, float | int):
            # Only a cut found eagerly before (ExplorationFeatures does it on construction): searching
            # for it here would be traced into the graph. Without one, the float grayscale is exported.
            exact_cut = _integer_cut.known(_float32(threshold))
        threshold = torch.as_tensor(threshold, dtype=dtype)
        if threshold.ndim == 1:
            threshold = threshold.expand(batch)
        step = functools.partial(
            _block_step,
            frames=frames,
            threshold=threshold,
            erosion=int(erosion),
            edge_threshold=float(edge_threshold),
            temperature=temperature,
            dtype=dtype,
            fuse=fuse,
            integer_cut=exact_cut,
        )
        rows = _rows(map_blocks(step, blocks, threads), per_row)
        if not fuse:
            return torch.cat([torch.cat(row, dim=1) for row in rows]).reshape(batch, -1)
        fused = torch.cat([functools.reduce(functools.partial(_or_merge, soft=soft), row) for row in rows])
        fused = _or_finish(fused[:, 1:-1, 1:-1], soft).to(dtype)
        if threads == 1:
            return _image_features(fused)
        return torch.cat(map_blocks(_image_features, fused.split(-(-batch // threads)), threads))


def _blocks(
    batch: int, n_frames: int, frame_pixels: int, frames_per_chunk: int | None
) -> tuple[list[tuple[slice, slice]], int]:
    """Blocks ``(explorations, frames)`` of about :data:`CHUNK_PIXELS` pixels, exploration-major, and
    the number of blocks per row of explorations (whole explorations share a block when they fit)."""
    n_t = min(n_frames, frames_per_chunk or max(1, CHUNK_PIXELS // frame_pixels))
    n_b = max(1, CHUNK_PIXELS // (n_frames * frame_pixels)) if n_t == n_frames else 1
    times = [slice(s, s + n_t) for s in range(0, n_frames, n_t)]
    return [(slice(b, b + n_b), t) for b in range(0, batch, n_b) for t in times], len(times)


def _rows(results: list, per_row: int) -> list[list]:
    return [results[i : i + per_row] for i in range(0, len(results), per_row)]


def _block_step(
    block: tuple[slice, slice],
    *,
    frames: torch.Tensor,
    threshold: torch.Tensor,
    erosion: int,
    edge_threshold: float,
    temperature: float | None,
    dtype: torch.dtype,
    fuse: bool,
    integer_cut: int | None = None,
) -> torch.Tensor:
    """One block of :func:`exploration_features`: the partial OR (b, H + 2, W + 2) of its frames (the
    image inside a junk ring, see :func:`_unflat`) if ``fuse``, else the features (b, t, 12) of each."""
    explorations, _ = block
    mask = _pressed(
        frames[block],
        threshold[explorations] if threshold.ndim else threshold,
        dtype,
        temperature,
        integer_cut,
    )
    edges = _edges(_erode(mask, erosion, temperature), edge_threshold, temperature, ring=fuse)
    if fuse:
        return _or_accumulate(None, edges, temperature is not None)
    return _image_features(edges.to(dtype))


# ---------------------------------------------------------------------------------- module wrappers
class ToGrayscale(nn.Module):
    """Module form of :func:`to_grayscale`: (..., 3, H, W) → (..., H, W)."""

    def forward(self, frames: torch.Tensor) -> torch.Tensor:
        return to_grayscale(frames)


class PressureMask(nn.Module):
    """Module form of :func:`pressure_mask`: (B, T, H, W) → (B, T, H, W)."""

    def __init__(self, threshold: Threshold = DEFAULT_THRESHOLD, *, temperature: float | None = None):
        super().__init__()
        self.threshold = threshold
        self.temperature = temperature

    def forward(self, gray: torch.Tensor) -> torch.Tensor:
        return pressure_mask(gray, self.threshold, temperature=self.temperature)


class Erode(nn.Module):
    """Module form of :func:`erode`: (..., H, W) → (..., H, W)."""

    def __init__(self, size: int = DEFAULT_EROSION, *, temperature: float | None = None):
        super().__init__()
        self.size = size
        self.temperature = temperature

    def forward(self, mask: torch.Tensor) -> torch.Tensor:
        return erode(mask, self.size, temperature=self.temperature)


class SobelEdges(nn.Module):
    """Module form of :func:`sobel_edges`: (..., H, W) → (..., H, W)."""

    def __init__(self, edge_threshold: float = DEFAULT_EDGE_THRESHOLD, *, temperature: float | None = None):
        super().__init__()
        self.edge_threshold = edge_threshold
        self.temperature = temperature

    def forward(self, mask: torch.Tensor) -> torch.Tensor:
        return sobel_edges(mask, self.edge_threshold, temperature=self.temperature)


class FuseEdges(nn.Module):
    """Module form of :func:`fuse_edges`: (B, T, H, W) → (B, H, W)."""

    def __init__(self, *, soft: bool = False):
        super().__init__()
        self.soft = soft

    def forward(self, edges: torch.Tensor) -> torch.Tensor:
        return fuse_edges(edges, soft=self.soft)


class Gradient(nn.Module):
    """Module form of :func:`gradient`: (..., H, W) → ((..., H, W), (..., H, W))."""

    def forward(self, image: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return gradient(image)


class GradientStatistics(nn.Module):
    """Module form of :func:`gradient_statistics`: (..., H, W) → (..., 6)."""

    def forward(self, image: torch.Tensor) -> torch.Tensor:
        return gradient_statistics(image)


class ExplorationFeatures(nn.Module):
    """Module form of :func:`exploration_features`: (B, T, 3, H, W) → (B, 12) or (B, T * 12).

    The keyword arguments are stored unchanged and passed on; this is the module to export to ONNX.

    Examples
    --------
    >>> ExplorationFeatures(erosion=3)(torch.zeros(1, 2, 3, 16, 16)).shape
    torch.Size([1, 12])
    """

    def __init__(
        self,
        *,
        fuse: bool = True,
        threshold: Threshold = DEFAULT_THRESHOLD,
        erosion: int = DEFAULT_EROSION,
        edge_threshold: float = DEFAULT_EDGE_THRESHOLD,
        temperature: float | None = None,
        frames_per_chunk: int | None = None,
    ):
        super().__init__()
        self.fuse = fuse
        self.threshold = threshold
        if temperature is None and isinstance(threshold, float | int) and 0 < threshold <= 1:
            _integer_cut(_float32(threshold))  # found eagerly now, so that an export can use it
        self.erosion = erosion
        self.edge_threshold = edge_threshold
        self.temperature = temperature
        self.frames_per_chunk = frames_per_chunk

    def forward(self, frames: torch.Tensor) -> torch.Tensor:
        return exploration_features(
            frames,
            fuse=self.fuse,
            threshold=self.threshold,
            erosion=self.erosion,
            edge_threshold=self.edge_threshold,
            temperature=self.temperature,
            frames_per_chunk=self.frames_per_chunk,
        )


__all__ = [
    "CHUNK_PIXELS",
    "DEFAULT_EDGE_THRESHOLD",
    "DEFAULT_EROSION",
    "DEFAULT_THRESHOLD",
    "FEATURE_NAMES",
    "GRAY_WEIGHTS",
    "STATISTICS",
    "Erode",
    "ExplorationFeatures",
    "FuseEdges",
    "Gradient",
    "GradientStatistics",
    "PressureMask",
    "SobelEdges",
    "ToGrayscale",
    "erode",
    "exploration_features",
    "fuse_edges",
    "gradient",
    "gradient_statistics",
    "otsu_threshold",
    "pressure_mask",
    "sobel_edges",
    "to_grayscale",
]
