"""The tensor kernels of method 1; inputs are validated by the callers (:mod:`._functional`).

Hard mode works on int8 {0, 1} masks where it can (a quarter of float32's memory traffic, exact); soft
mode (``temperature=t``) on floats, differentiably. The spatial kernels work on the flattened, padded
stack of images (see :func:`_window_min`).
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F

from ..validation import values_unavailable
from . import _export
from ._constants import GRAY_WEIGHTS, HISTOGRAM_LEVELS


def _gray(frames: torch.Tensor, dtype: torch.dtype) -> torch.Tensor:
    """(..., 3, H, W) → (..., H, W) gray in ``dtype``: the reference's elementwise operations, in order."""
    x = frames.to(dtype).div_(255.0) if frames.dtype == torch.uint8 else frames.to(dtype)
    r, g, b = x.unbind(-3)
    gray = r * GRAY_WEIGHTS[0]
    gray += g * GRAY_WEIGHTS[1]
    gray += b * GRAY_WEIGHTS[2]
    return gray


def _window_pads(k: int) -> tuple[int, int]:
    """(before, after) padding of a size-k window starting at ``i - k//2`` (scipy's origin)."""
    return k // 2, k - 1 - k // 2


# The spatial kernels work on the flattened, padded stack of images: a neighbour is a fixed offset in
# the 1-D buffer (1 along a row, the padded width along a column), so every step is one long contiguous
# elementwise operation instead of many short rows. Positions that mix rows or images land only in the
# padding, which is cut off afterwards.
def _window_min(
    x: torch.Tensor, k: int, stride: int, temperature: float | torch.Tensor | None
) -> torch.Tensor:
    """Minimum of ``x[q], x[q + stride], ..., x[q + (k-1) stride]`` for every ``q`` (1-D, shorter output).

    Hard: by doubling, windows of 1, 2, 4, ... from two shifted copies each and a last overlapping step,
    about ``2 log2(k)`` elementwise minima, exact. Soft: ``-t * logsumexp(-x / t)`` over the window
    (see :func:`_soft_window_min`).
    """
    n_out = x.shape[0] - (k - 1) * stride
    if temperature is not None:
        return _soft_window_min(x, k, stride, temperature)
    width = 1
    while 2 * width <= k:
        n = x.shape[0] - width * stride
        x = torch.minimum(x[:n], x[width * stride : width * stride + n])
        width *= 2
    if width < k:
        offset = (k - width) * stride
        return torch.minimum(x[:n_out], x[offset : offset + n_out])
    return x[:n_out]


def _soft_window_min(x: torch.Tensor, k: int, stride: int, temperature: float | torch.Tensor) -> torch.Tensor:
    """``-t * logsumexp(-x / t)`` over the windows of :func:`_window_min`, from ``k`` shifted slices.

    Shifted by the exact minimum ``m`` (a constant for autograd: the expression does not depend on
    it), ``m - t * log(sum_j exp((m - x_j) / t))`` has terms in (0, 1], one of them 1. Memory: ``k``
    output-sized terms kept for the backward pass (none without autograd); an unfolded view would
    make its backward materialise a ``(k - 1) * stride + 1``-wide gradient, which for the column pass
    of 100 frames of 96 x 96 was 4 GiB. The infinite padding contributes exactly 0 (its term is
    masked, so that the derivative in ``t``, ``0 * inf`` otherwise, is defined); windows lying wholly
    in the padding give ``inf`` with a zero gradient.
    """
    n_out = x.shape[0] - (k - 1) * stride
    with torch.no_grad():
        low = _window_min(x.detach(), k, stride, None)
        inside = torch.isfinite(x)
    finite = torch.isfinite(low)
    low = torch.where(finite, low, 0.0)
    total = 0.0
    for j in range(k):
        part, real = x[j * stride : j * stride + n_out], inside[j * stride : j * stride + n_out]
        total = total + torch.where(real, torch.exp((low - torch.where(real, part, low)) / temperature), 0.0)
    soft = low - temperature * torch.log(torch.where(finite, total, 1.0))
    return torch.where(finite, soft, math.inf)


def _erode(mask: torch.Tensor, k: int, temperature: float | torch.Tensor | None) -> torch.Tensor:
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
    mask: torch.Tensor,
    edge_threshold: float | torch.Tensor,
    temperature: float | torch.Tensor | None,
    *,
    ring: bool = False,
) -> torch.Tensor:
    """Edges of (..., H, W): {0, 1} in mask's dtype (hard) or float in (0, 1) (soft); ``ring``: see
    :func:`_unflat`."""
    gx, gy = _sobel_flat(mask.reshape(-1, *mask.shape[-2:]))
    # The squared magnitude keeps the soft edge differentiable where the gradient vanishes.
    squared = torch.addcmul(gx * gx, gy, gy)
    if temperature is not None:
        edges = torch.sigmoid((squared - edge_threshold * edge_threshold) / temperature)
    elif mask.is_floating_point() or isinstance(edge_threshold, torch.Tensor) or values_unavailable():
        edges = (squared > edge_threshold * edge_threshold).to(mask.dtype)
    else:
        # A binary int8 mask has integer squared magnitudes of at most 32 (|gx|, |gy| <= 4), so
        # ``squared > c`` is ``clamp(squared - c, 0, 1)``: int8 in place, no bool round trip.
        cut = min(math.floor(edge_threshold * edge_threshold), 32)
        edges = (squared.sub_(cut) if cut else squared).clamp_(0, 1)
    return _unflat(edges, mask.shape, ring=ring)


def _pressure(
    gray: torch.Tensor, threshold: torch.Tensor, temperature: float | torch.Tensor | None
) -> torch.Tensor:
    """Pressed region: int8 {0, 1} (hard) or float (soft)."""
    if temperature is None and values_unavailable():  # no out= under vmap or compile
        return (gray < threshold).to(torch.int8)
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


FLAT_MAGNITUDE = 0.5
"""Sobel magnitude below which the soft direction is faded out (see :func:`_gradient`)."""
CUT_WIDTH = 0.2
"""Width in radians of the arc below the ``atan2`` cut (just above ``-pi``) on which the soft direction
turns smoothly back to ``pi`` (see :func:`_gradient`)."""


def _gradient(image: torch.Tensor, soft: bool = False) -> tuple[torch.Tensor, torch.Tensor]:
    """Sobel magnitude and direction of (..., H, W).

    ``soft``: a direction that is a smooth function of the image, equal to ``atan2`` on binary images.
    ``atan2`` jumps by ``2 pi`` where ``gy`` changes sign with ``gx < 0`` (its cut, on which vertical
    edges of a binary image lie: ``A = pi``) and turns by up to ``2 pi`` under a tiny change of a
    nearly vanishing gradient; a soft image puts pixels at both, where the derivative means nothing.
    So (1) on the arc ``-pi < A < -pi + CUT_WIDTH`` the direction is replaced by the cubic that joins
    ``pi`` (slope 1) to ``-pi + CUT_WIDTH`` (slope 1), continuous across the cut; a binary image's
    gradient has integer components of at most 4, so no angle of it lies on that arc (the nearest,
    ``atan(1/4)`` = 0.245 rad from the cut, is outside); (2) the result is multiplied by
    ``w = s(min(M^2 / FLAT_MAGNITUDE^2, 1))``, ``s(u) = 3u^2 - 2u^3`` (continuously differentiable),
    which fades it out where the image is flat and is 1 wherever ``M >= 0.5``, hence at every
    non-flat pixel of a binary image (``M >= 1``). The hard limit is exact.
    """
    gx, gy = _sobel(image)
    squared = gx * gx + gy * gy
    flat = squared == 0
    # atan2(0, 0) = 0 by convention; the double where keeps its gradient finite there.
    direction = torch.where(flat, 0.0, torch.atan2(torch.where(flat, 1.0, gy), torch.where(flat, 1.0, gx)))
    # atan2(-0.0, x < 0) = -pi: fold it onto pi so that the range is (-pi, pi].
    direction = torch.where(direction <= -math.pi, -direction, direction)
    if soft:
        v = (direction + math.pi) / CUT_WIDTH  # in (0, 1) on the arc below the cut
        v2 = v * v
        # cubic Hermite: pi at v = 0, -pi + CUT_WIDTH at v = 1, slope 1 in the angle at both ends
        joined = (
            (2 * v2 * v - 3 * v2 + 1) * math.pi
            + (v2 * v - 2 * v2 + v) * CUT_WIDTH
            + (3 * v2 - 2 * v2 * v) * (CUT_WIDTH - math.pi)
            + (v2 * v - v2) * CUT_WIDTH
        )
        direction = torch.where(v < 1, joined, direction)
        u = torch.clamp(squared / (FLAT_MAGNITUDE * FLAT_MAGNITUDE), max=1.0)
        direction = direction * (u * u * (3.0 - 2.0 * u))
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


def _image_features(image: torch.Tensor, soft: bool = False) -> torch.Tensor:
    """(..., H, W) → (..., 12): statistics of the magnitude, then of the direction (``soft``: see
    :func:`_gradient`)."""
    magnitude, direction = _gradient(image, soft)
    return torch.cat([_statistics(magnitude), _statistics(direction)], dim=-1)


def _or_accumulate(acc: torch.Tensor | None, edges: torch.Tensor, soft: bool) -> torch.Tensor:
    """Fold (B, t, H, W) edges into the running OR: hard max, or the sum of ``log(1 - e)`` if soft."""
    if soft:
        # log(1 - e), -inf where e = 1 (so that the OR is exactly 1 there); the double where keeps the
        # gradient finite (e = 1 only where a sigmoid saturated, whose own gradient is 0).
        below = edges < 1.0
        part = torch.where(below, torch.log1p(-torch.where(below, edges, 0.0)), -math.inf).sum(1)
    elif torch.compiler.is_exporting():
        part = _export.or_over_frames(edges)
    else:
        part = edges.amax(1)
    return part if acc is None else _or_merge(acc, part, soft)


def _or_merge(acc: torch.Tensor, part: torch.Tensor, soft: bool) -> torch.Tensor:
    """Combine two results of :func:`_or_accumulate`."""
    return acc + part if soft else torch.maximum(acc, part)


def _or_finish(acc: torch.Tensor, soft: bool) -> torch.Tensor:
    return -torch.expm1(acc) if soft else acc
