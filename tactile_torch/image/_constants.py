"""The study's parameters and the fixed names of method 1 (re-exported by :mod:`tactile_torch.image`)."""

from __future__ import annotations

import math

DEFAULT_THRESHOLD = 240.0 / 255.0
"""Pressed-region threshold of the study (240 on the 0-255 scale)."""
DEFAULT_EROSION = 10
"""Side of the square structuring element of the study, in pixels."""
EROSION_FRACTION = DEFAULT_EROSION / 96
"""Side of the erosion element relative to the frame's shorter side: the study's 10 pixels on the
bundled 96-pixel frames."""
DEFAULT_FRAME_RATE_HZ = 10.0
"""Frames per second of an exploration file that does not say (the study's 10)."""
DEFAULT_EDGE_THRESHOLD = 0.5
"""Sobel magnitude above which a pixel is an edge (any non-zero magnitude on a binary mask)."""
GRAY_WEIGHTS = (0.2989, 0.5870, 0.1140)
"""Weights of R, G, B in the grayscale conversion (MATLAB ``rgb2gray``)."""
STATISTICS = ("mean", "std", "skew", "kurt", "p95", "mad")
"""The six statistics of :func:`~tactile_torch.image.gradient_statistics`, in order."""
FEATURE_NAMES = tuple(f"{image}_{stat}" for image in ("M", "A") for stat in STATISTICS)
"""Names of the 12 features of :func:`~tactile_torch.image.exploration_features` (magnitude first)."""
HISTOGRAM_LEVELS = 256
"""Gray levels of the histogram behind :func:`~tactile_torch.image.otsu_threshold`."""
CHUNK_PIXELS = 1 << 19
"""Pixels (explorations x frames x height x width) of one block of
:func:`~tactile_torch.image.exploration_features`."""


def relative_erosion(height: int, width: int) -> int:
    """Return the erosion side for a ``height x width`` frame: :data:`EROSION_FRACTION` of the shorter side.

    Rounded half up, at least 1 (no erosion).

    Examples
    --------
    >>> relative_erosion(96, 96), relative_erosion(4, 4), relative_erosion(14, 6)
    (10, 1, 1)
    """
    return max(1, math.floor(EROSION_FRACTION * min(height, width) + 0.5))
