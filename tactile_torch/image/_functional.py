"""The public functions of method 1 (re-exported by :mod:`tactile_torch.image`); each validates its
arguments once and calls the kernels."""

from __future__ import annotations

import math

import torch

from ..validation import check_floating, check_positive, check_tensor
from ._constants import DEFAULT_EDGE_THRESHOLD, DEFAULT_EROSION, DEFAULT_THRESHOLD
from ._kernels import (
    _edges,
    _erode,
    _gradient,
    _gray,
    _image_features,
    _level_histogram,
    _or_accumulate,
    _or_finish,
    _otsu_from_histogram,
    _pressure,
    _statistics,
    _threshold_tensor,
)
from ._scheduler import run_exploration_features
from ._validation import (
    Threshold,
    check_frames,
    check_image,
    check_temperature,
    check_threshold,
    check_unit_range,
)


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
    check_frames(frames, batched=False)
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
    check_unit_range(gray, "gray")
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
    check_image(gray, "gray", ["B", "T", "H", "W"])
    check_threshold(threshold, gray.shape[0])
    check_temperature(temperature)
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
        (below the minimum by at most ``t * log(size**2)``); under autograd it keeps ``2 * size``
        input-sized terms for the backward pass, as suits the small inputs of training, not bulk
        feature extraction.

    Returns
    -------
    tensor of shape (..., H, W), mask's dtype.

    Examples
    --------
    >>> m = torch.zeros(1, 7, 7); m[0, 1:6, 1:6] = 1
    >>> erode(m, 3)[0].sum().item()
    9.0
    """
    check_image(mask, "mask", ["*", "H", "W"])
    check_positive(size, "size", integer=True)
    check_temperature(temperature)
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
    check_image(mask, "mask", ["*", "H", "W"])
    check_positive(edge_threshold, "edge_threshold", strict=False)
    check_temperature(temperature)
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
    check_image(edges, "edges", ["B", "T", "H", "W"])
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
    check_image(image, "image", ["*", "H", "W"])
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
    check_image(image, "image", ["*", "H", "W"])
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
    ``torch.get_num_threads()`` worker threads, each running its torch ops on one thread (a setting
    of the worker thread only: nothing process-wide changes); results do not depend on the thread
    count. Hard mode on uint8 frames decides the pressed region on integers (bit-identical to the
    float32 grayscale, see ``tactile_torch.image._integer_cut``). The soft mode and
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
    check_frames(frames)
    check_threshold(threshold, frames.shape[0])
    check_positive(erosion, "erosion", integer=True)
    check_positive(edge_threshold, "edge_threshold", strict=False)
    check_temperature(temperature)
    if frames_per_chunk is not None:
        check_positive(frames_per_chunk, "frames_per_chunk", integer=True)
    return run_exploration_features(
        frames,
        fuse=fuse,
        threshold=threshold,
        erosion=erosion,
        edge_threshold=edge_threshold,
        temperature=temperature,
        frames_per_chunk=frames_per_chunk,
    )


def learnable_exploration_features(
    frames: torch.Tensor,
    threshold: torch.Tensor,
    edge_threshold: torch.Tensor,
    temperatures: tuple[torch.Tensor, float, torch.Tensor],
    erosion: int,
) -> torch.Tensor:
    """Return the 12 fused method-1 features of explorations with every setting a tensor (the soft ops).

    The graph of :class:`tactile_torch.neural.LearnedFrontEndClassifier`: grayscale (float32), soft
    pressed region, soft erosion, soft edges and noisy-OR fusion over the frames, then the gradient
    statistics, with ``threshold``, ``edge_threshold`` and the mask and edge temperatures as tensors,
    so that gradients reach them. No check and no blocks: a training step's batch is small, and the
    caller (a module's ``forward``) owns its arguments.

    Parameters
    ----------
    frames : tensor of shape (B, T, 3, H, W)
    threshold, edge_threshold : tensors of shape ()
    temperatures : (mask temperature, erosion temperature, edge temperature)
        Tensors of shape () but the erosion's, a float.
    erosion : int >= 1

    Returns
    -------
    tensor of shape (B, 12), float32.

    Examples
    --------
    >>> t = torch.tensor(0.05)
    >>> frames = torch.randint(0, 256, (2, 3, 3, 16, 16), dtype=torch.uint8)
    >>> learnable_exploration_features(frames, torch.tensor(0.9), torch.tensor(0.5), (t, 0.05, t), 3).shape
    torch.Size([2, 12])
    """
    t_mask, t_erosion, t_edge = temperatures
    gray = _gray(frames, torch.float32)
    mask = _pressure(gray, threshold, t_mask)
    eroded = _erode(mask, erosion, t_erosion)
    edges = _edges(eroded, edge_threshold, t_edge)
    below = edges < 1.0  # noisy-OR over the frames, as fuse_edges(soft=True), an edge of 1 kept exact
    log_not = torch.where(below, torch.log1p(-torch.where(below, edges, 0.0)), -math.inf).sum(1)
    return _image_features(-torch.expm1(log_not))
