"""The hard pressed region of uint8 frames decided on integers, bit for bit as the float32 grayscale.

The exact gray of a uint8 colour times :data:`GRAY_SCALE` is the integer
``S = 2989 R + 5870 G + 1140 B``; the float32 gray that :func:`._kernels._gray` (and the NumPy
reference) computes is within 2.6 units of it (six roundings of relative 2^-24 on a value <= 1), so
``S`` decides every pixel but those within :data:`GRAY_BAND` units of the threshold.
:func:`integer_cut` finds, for one threshold, the integer cut that is exact for every colour, when
one exists; :func:`pressed_uint8` uses it (or decides the few band pixels by the float formula).

:func:`integer_cut` is a pure function of the threshold computed with NumPy, never with torch: it
gives the same answer whether it runs eagerly or while a graph is traced for export (where torch ops
would be recorded into the graph), in a fresh process or not. It is memoised only because a search
costs a few milliseconds.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import torch

from ._constants import GRAY_WEIGHTS
from ._kernels import _gray

GRAY_INTEGER = tuple(round(w * 10_000) for w in GRAY_WEIGHTS)
"""Integer weights of R, G, B: ``(2989, 5870, 1140)``."""
GRAY_SCALE = 255 * 10_000
"""``S / GRAY_SCALE`` is the exact gray of uint8 RGB on the [0, 1] scale."""
GRAY_BAND = 4
"""Pixels farther than this from ``threshold * GRAY_SCALE`` are decided on ``S`` alone."""


def float32(value: float) -> float:
    """``value`` rounded to float32 (the threshold as the float32 comparisons see it)."""
    return float(np.float32(value))


def gray_float32(colours: np.ndarray) -> np.ndarray:
    """The float32 gray of uint8 colours ``(n, 3)``, with :func:`._kernels._gray`'s operations in its
    order (``tests/image/test_image.py`` checks that both agree on all 2^24 colours)."""
    x = colours.astype(np.float32) / np.float32(255.0)
    gray = x[:, 0] * np.float32(GRAY_WEIGHTS[0])
    gray += x[:, 1] * np.float32(GRAY_WEIGHTS[1])
    gray += x[:, 2] * np.float32(GRAY_WEIGHTS[2])
    return gray


@functools.lru_cache(maxsize=256)
def integer_cut(limit: float) -> int | None:
    """The integer ``c`` such that ``gray < limit`` iff ``S < c`` for every uint8 colour, if one exists.

    ``limit`` is a float32 value (:func:`float32`); ``gray`` the float32 grayscale, ``S`` the integer
    gray. Only colours with ``S`` within :data:`GRAY_BAND` of the threshold can disagree with the
    order of ``S``: they are enumerated (at most one blue level per red-green pair, the band being
    narrower than a blue step) and decided by the float32 formula itself. ``None`` if a value of
    ``S`` in the band holds colours on both sides (about 10 % of thresholds; then the pixels in the
    band are decided one by one).
    """
    cut = limit * GRAY_SCALE
    low, high = math.ceil(cut - GRAY_BAND), math.floor(cut + GRAY_BAND) + 1
    red, green = (c.ravel() for c in np.meshgrid(np.arange(256), np.arange(256), indexing="ij"))
    rest = GRAY_INTEGER[0] * red + GRAY_INTEGER[1] * green
    blue = -((rest - low) // GRAY_INTEGER[2])  # the least blue with S >= low
    total = rest + GRAY_INTEGER[2] * blue
    keep = (blue >= 0) & (blue <= 255) & (total < high)
    colours = np.stack([red[keep], green[keep], blue[keep]], axis=1).astype(np.uint8)
    pressed = gray_float32(colours) < np.float32(limit)
    total = total[keep]
    exact = int(total[pressed].max()) + 1 if pressed.any() else low
    return exact if bool((total[~pressed] >= exact).all()) else None


def pressed_uint8(frames: torch.Tensor, threshold: torch.Tensor) -> torch.Tensor:
    """``_pressure(_gray(frames, float32), threshold)`` for uint8 frames, bit for bit, in integers.

    ``frames`` ``(B, t, 3, H, W)``; ``threshold`` of shape () or (B,). For a single threshold with an
    :func:`integer_cut` the mask is one comparison; otherwise (per-exploration thresholds, or no exact
    cut) ``S`` decides every pixel outside the band and the float formula the pixels inside it.
    About a third of the float path's memory traffic.
    """
    limit = threshold.to(torch.float32)
    if limit.ndim:  # per exploration
        limit = limit.view(-1, 1, 1, 1)
        cut = limit.double() * GRAY_SCALE
        low = torch.ceil(cut - GRAY_BAND).to(torch.int32)
        high = torch.floor(cut + GRAY_BAND).to(torch.int32) + 1
    else:  # Python numbers: cheaper than a few tiny tensor ops per block
        cut = float(limit) * GRAY_SCALE  # exact: a float32 times a 22-bit integer
        low, high = math.ceil(cut - GRAY_BAND), math.floor(cut + GRAY_BAND) + 1
    # S < low: pressed whatever the rounding; S >= high: not pressed
    r, g, b = (channel.to(torch.int32) for channel in frames.unbind(-3))
    total = r.mul_(GRAY_INTEGER[0]).add_(g, alpha=GRAY_INTEGER[1]).add_(b, alpha=GRAY_INTEGER[2])
    exact = None if limit.ndim else integer_cut(float(limit))
    if exact is not None:  # one comparison decides every colour
        return torch.lt(total, exact, out=torch.empty(total.shape, dtype=torch.int8))
    mask = torch.lt(total, low, out=torch.empty(total.shape, dtype=torch.int8))
    near = torch.lt(total, high, out=torch.empty(total.shape, dtype=torch.int8)).sub_(mask)  # 1 in the band
    if int(near.amax()) > 0:  # (an int8 max is several times cheaper than torch.equal or any)
        near = near.nonzero(as_tuple=True)
        gray = _gray(frames.movedim(-3, -1)[near].view(-1, 3, 1, 1), torch.float32).view(-1)
        mask[near] = torch.lt(gray, limit.expand(total.shape)[near]).to(torch.int8)
    return mask
