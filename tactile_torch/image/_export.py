"""Graph forms of two hard-mode steps, used while tracing for ONNX export instead of the eager kernels.

Both give the eager result exactly; they exist because onnxruntime runs them several times faster
than the direct translation of the eager code.
"""

from __future__ import annotations

import torch


def pressed_below_cut(frames: torch.Tensor, cut: int, gray_integer: tuple[int, int, int]) -> torch.Tensor:
    """Pressed region of uint8 frames ``(..., 3, H, W)`` as int8 ``S < cut`` → ``(..., H, W)``.

    ``S = w_R R + w_G G + w_B B`` is the integer gray (:mod:`._integer_cut`) formed as one MatMul over
    the colour axis: integers below 2^24, so exact in float32 in any order. Replaces a division and
    five elementwise passes of the float grayscale.
    """
    weights = torch.tensor([gray_integer], dtype=torch.float32)  # (1, 3)
    total = torch.matmul(weights, frames.flatten(-2).to(torch.float32))  # (..., 1, H * W)
    return (total < cut).to(torch.int8).reshape(*frames.shape[:-3], *frames.shape[-2:])


def or_over_frames(edges: torch.Tensor) -> torch.Tensor:
    """OR over the frames of {0, 1} edges ``(B, T, H, W)`` → ``(B, H, W)``, as a count by one MatMul.

    onnxruntime reduces int8 over a middle axis slowly; the count is exact (at most T ones per
    pixel): OR = count > 0.
    """
    ones = torch.ones(1, edges.shape[1], dtype=torch.float32)
    count = torch.matmul(ones, edges.flatten(2).to(torch.float32))  # (B, 1, H * W)
    return (count > 0).to(edges.dtype).reshape(edges.shape[0], *edges.shape[2:])
