"""Thin :class:`torch.nn.Module` forms of the public functions (re-exported by :mod:`tactile_torch.image`).

Each stores its arguments unchanged and calls its function; none holds logic of its own.
"""

from __future__ import annotations

import torch
from torch import nn

from ._constants import DEFAULT_EDGE_THRESHOLD, DEFAULT_EROSION, DEFAULT_THRESHOLD
from ._functional import (
    erode,
    exploration_features,
    fuse_edges,
    gradient,
    gradient_statistics,
    pressure_mask,
    sobel_edges,
    to_grayscale,
)
from ._validation import Threshold


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
