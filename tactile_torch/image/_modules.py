"""Thin :class:`torch.nn.Module` forms of the public functions (re-exported by :mod:`tactile_torch.image`).

Each stores its arguments unchanged and calls its function; none holds logic of its own. A soft
parameter given as a :class:`torch.nn.Parameter` (threshold, edge threshold, temperature) is
registered as the module's parameter by that assignment, so an optimiser over ``module.parameters()``
trains it.
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
from ._validation import Scalar, Threshold


class ToGrayscale(nn.Module):
    """Module form of :func:`to_grayscale`: (..., 3, H, W) → (..., H, W).

    Examples
    --------
    >>> ToGrayscale()(torch.ones(1, 3, 2, 2)).shape
    torch.Size([1, 2, 2])
    """

    def forward(self, frames: torch.Tensor) -> torch.Tensor:
        """Return :func:`to_grayscale` of ``frames``.

        Parameters
        ----------
        frames : tensor of shape (..., 3, H, W), uint8 or floating

        Returns
        -------
        tensor of shape (..., H, W)
            The dtype of float ``frames``, float32 for uint8. Errors as :func:`to_grayscale`.
        """
        return to_grayscale(frames)


class PressureMask(nn.Module):
    """Module form of :func:`pressure_mask`: (B, T, H, W) → (B, T, H, W).

    Parameters
    ----------
    threshold : float in (0, 1], tensor of shape () or (B,), or ``"otsu"``
        As in :func:`pressure_mask`; an ``nn.Parameter`` is registered (trainable).
    temperature : float or 0-d tensor, optional
        As in :func:`pressure_mask`; an ``nn.Parameter`` is registered (trainable).

    Examples
    --------
    >>> PressureMask(0.5)(torch.tensor([[[[0.2, 0.9]]]])).tolist()
    [[[[1.0, 0.0]]]]
    """

    def __init__(self, threshold: Threshold = DEFAULT_THRESHOLD, *, temperature: Scalar | None = None):
        super().__init__()
        self.threshold = threshold
        self.temperature = temperature

    def forward(self, gray: torch.Tensor) -> torch.Tensor:
        """Return :func:`pressure_mask` of ``gray`` with the stored arguments.

        Parameters
        ----------
        gray : tensor of shape (B, T, H, W), floating in [0, 1]

        Returns
        -------
        tensor of shape (B, T, H, W)
            The dtype of ``gray``. Errors as :func:`pressure_mask`.
        """
        return pressure_mask(gray, self.threshold, temperature=self.temperature)


class Erode(nn.Module):
    """Module form of :func:`erode`: (..., H, W) → (..., H, W).

    Parameters
    ----------
    size : int >= 1
        Side of the square in pixels.
    temperature : float or 0-d tensor, optional
        As in :func:`erode`; an ``nn.Parameter`` is registered (trainable).

    Examples
    --------
    >>> m = torch.zeros(1, 7, 7); m[0, 1:6, 1:6] = 1
    >>> Erode(3)(m).sum().item()
    9.0
    """

    def __init__(self, size: int = DEFAULT_EROSION, *, temperature: Scalar | None = None):
        super().__init__()
        self.size = size
        self.temperature = temperature

    def forward(self, mask: torch.Tensor) -> torch.Tensor:
        """Return :func:`erode` of ``mask`` with the stored arguments.

        Parameters
        ----------
        mask : tensor of shape (..., H, W), floating

        Returns
        -------
        tensor of shape (..., H, W)
            The dtype of ``mask``. Errors as :func:`erode`.
        """
        return erode(mask, self.size, temperature=self.temperature)


class SobelEdges(nn.Module):
    """Module form of :func:`sobel_edges`: (..., H, W) → (..., H, W).

    Parameters
    ----------
    edge_threshold : float >= 0 or 0-d tensor
        As in :func:`sobel_edges`; an ``nn.Parameter`` is registered (trainable).
    temperature : float or 0-d tensor, optional
        As in :func:`sobel_edges`; an ``nn.Parameter`` is registered (trainable).

    Examples
    --------
    >>> m = torch.zeros(1, 6, 6); m[0, :, 3:] = 1
    >>> SobelEdges()(m)[0, 0].tolist()
    [0.0, 0.0, 1.0, 1.0, 0.0, 0.0]
    """

    def __init__(self, edge_threshold: Scalar = DEFAULT_EDGE_THRESHOLD, *, temperature: Scalar | None = None):
        super().__init__()
        self.edge_threshold = edge_threshold
        self.temperature = temperature

    def forward(self, mask: torch.Tensor) -> torch.Tensor:
        """Return :func:`sobel_edges` of ``mask`` with the stored arguments.

        Parameters
        ----------
        mask : tensor of shape (..., H, W), floating

        Returns
        -------
        tensor of shape (..., H, W)
            The dtype of ``mask``. Errors as :func:`sobel_edges`.
        """
        return sobel_edges(mask, self.edge_threshold, temperature=self.temperature)


class FuseEdges(nn.Module):
    """Module form of :func:`fuse_edges`: (B, T, H, W) → (B, H, W).

    Parameters
    ----------
    soft : bool
        Noisy-OR instead of the maximum (see :func:`fuse_edges`).

    Examples
    --------
    >>> FuseEdges()(torch.tensor([[[[0.0, 1.0]], [[1.0, 0.0]]]])).tolist()
    [[[1.0, 1.0]]]
    """

    def __init__(self, *, soft: bool = False):
        super().__init__()
        self.soft = soft

    def forward(self, edges: torch.Tensor) -> torch.Tensor:
        """Return :func:`fuse_edges` of ``edges`` with the stored arguments.

        Parameters
        ----------
        edges : tensor of shape (B, T, H, W), floating

        Returns
        -------
        tensor of shape (B, H, W)
            The dtype of ``edges``. Errors as :func:`fuse_edges`.
        """
        return fuse_edges(edges, soft=self.soft)


class Gradient(nn.Module):
    """Module form of :func:`gradient`: (..., H, W) → ((..., H, W), (..., H, W)).

    Parameters
    ----------
    soft : bool
        Fade the direction out where the image is flat (see :func:`gradient`).

    Examples
    --------
    >>> magnitude, direction = Gradient()(torch.zeros(1, 4, 4))
    >>> magnitude.shape, float(direction.abs().max())
    (torch.Size([1, 4, 4]), 0.0)
    """

    def __init__(self, *, soft: bool = False):
        super().__init__()
        self.soft = soft

    def forward(self, image: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Return :func:`gradient` of ``image``: ``(magnitude, direction)``.

        Parameters
        ----------
        image : tensor of shape (..., H, W), floating

        Returns
        -------
        magnitude, direction : tensors of shape (..., H, W)
            The dtype of ``image``. Errors as :func:`gradient`.
        """
        return gradient(image, soft=self.soft)


class GradientStatistics(nn.Module):
    """Module form of :func:`gradient_statistics`: (..., H, W) → (..., 6).

    Examples
    --------
    >>> GradientStatistics()(torch.zeros(2, 4, 4)).shape
    torch.Size([2, 6])
    """

    def forward(self, image: torch.Tensor) -> torch.Tensor:
        """Return :func:`gradient_statistics` of ``image``.

        Parameters
        ----------
        image : tensor of shape (..., H, W), floating

        Returns
        -------
        tensor of shape (..., 6)
            The dtype of ``image``. Errors as :func:`gradient_statistics`.
        """
        return gradient_statistics(image)


class ExplorationFeatures(nn.Module):
    """Module form of :func:`exploration_features`: (B, T, 3, H, W) → (B, 12) or (B, T * 12).

    The keyword arguments are stored unchanged and passed on; this is the module to export to ONNX.
    A soft parameter given as an ``nn.Parameter`` is registered, so an optimiser over the module's
    parameters trains it (with ``temperature`` set).

    Parameters
    ----------
    fuse : bool
        Fuse the frames (``(B, 12)``) or not (``(B, T * 12)``).
    threshold : float in (0, 1], tensor of shape () or (B,), or ``"otsu"``
        Pressure threshold (see :func:`pressure_mask`).
    erosion : int >= 1
        Side of the erosion's square in pixels (see :func:`erode`).
    edge_threshold : float >= 0 or 0-d tensor
        See :func:`sobel_edges`.
    temperature : float or 0-d tensor, optional
        ``None``: the hard pipeline; otherwise the soft one (see :func:`exploration_features`).
    frames_per_chunk : int, optional
        Frames per block (memory bound; results do not depend on it).

    Examples
    --------
    >>> ExplorationFeatures(erosion=3)(torch.zeros(1, 2, 3, 16, 16)).shape
    torch.Size([1, 12])
    >>> soft = ExplorationFeatures(erosion=3, temperature=torch.nn.Parameter(torch.tensor(0.1)))
    >>> [name for name, _ in soft.named_parameters()]
    ['temperature']
    """

    def __init__(
        self,
        *,
        fuse: bool = True,
        threshold: Threshold = DEFAULT_THRESHOLD,
        erosion: int = DEFAULT_EROSION,
        edge_threshold: Scalar = DEFAULT_EDGE_THRESHOLD,
        temperature: Scalar | None = None,
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
        """Return :func:`exploration_features` of ``frames`` with the stored arguments.

        Parameters
        ----------
        frames : tensor of shape (B, T, 3, H, W), uint8 or floating

        Returns
        -------
        tensor of shape (B, 12), or (B, T * 12) with ``fuse=False``
            Float32 for uint8 frames, else their dtype. Errors as :func:`exploration_features`.
        """
        return exploration_features(
            frames,
            fuse=self.fuse,
            threshold=self.threshold,
            erosion=self.erosion,
            edge_threshold=self.edge_threshold,
            temperature=self.temperature,
            frames_per_chunk=self.frames_per_chunk,
        )
