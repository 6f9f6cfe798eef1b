"""Method 1: features of tactile-image explorations (grayscale, pressure mask, erosion, Sobel edges, fusion).

Every step is a plain function on batched CPU tensors with a thin :class:`torch.nn.Module` wrapper;
:func:`exploration_features` chains them: ``(B, T, 3, H, W)`` RGB frames → ``(B, 12)`` features (or
``(B, T*12)`` without fusion, the study's ablation).

The package's private modules, one concern each: ``_validation`` (argument checks), ``_kernels`` (the
tensor kernels), ``_integer_cut`` (the exact integer form of the uint8 pressed region),
``_scheduler`` (blocks, threads), ``_export`` (graph forms used while exporting to ONNX),
``_functional`` (the public functions), ``_modules`` (their module forms).

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
>>> import torch
>>> from tactile_torch.image import exploration_features
>>> frames = torch.full((2, 5, 3, 32, 32), 255, dtype=torch.uint8)
>>> frames[:, :, :, 8:24, 8:24] = 0                      # a pressed square in every frame
>>> exploration_features(frames, erosion=3).shape
torch.Size([2, 12])
"""

from .._exports import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {
        "_constants": (
            "CHUNK_PIXELS",
            "DEFAULT_EDGE_THRESHOLD",
            "DEFAULT_EROSION",
            "DEFAULT_FRAME_RATE_HZ",
            "DEFAULT_THRESHOLD",
            "EROSION_FRACTION",
            "FEATURE_NAMES",
            "GRAY_WEIGHTS",
            "HISTOGRAM_LEVELS",
            "STATISTICS",
            "relative_erosion",
        ),
        "_functional": (
            "erode",
            "exploration_features",
            "fuse_edges",
            "gradient",
            "gradient_statistics",
            "learnable_exploration_features",
            "otsu_threshold",
            "pressure_mask",
            "sobel_edges",
            "to_grayscale",
        ),
        "_modules": (
            "Erode",
            "ExplorationFeatures",
            "FuseEdges",
            "Gradient",
            "GradientStatistics",
            "PressureMask",
            "SobelEdges",
            "ToGrayscale",
        ),
        "_validation": ("Threshold",),
    },
)
