"""Frames and pressure maps → method-1 features: :class:`ImageFeatureTransformer`,
:class:`PressureImageFeatures` and their helpers (public from :mod:`tactile_torch.features.transformers`;
split from it to keep modules short), and the input checks every transformer shares."""

from __future__ import annotations

from numbers import Integral, Real
from typing import ClassVar

import numpy as np
import torch
from sklearn.base import BaseEstimator, TransformerMixin, _fit_context
from sklearn.utils._param_validation import Interval, StrOptions
from sklearn.utils.validation import check_is_fitted
from torch import nn

from ..image import (
    DEFAULT_THRESHOLD,
    ExplorationFeatures,
    exploration_features,
    otsu_threshold,
    relative_erosion,
)
from ..robot.stream.touches import CONTACT, contact_sign, reading_noise, resting_level
from ..validation import tensor_from_array


def _from_torch(X: object) -> object:
    """``X`` as a numpy array if it is a tensor, else unchanged (scikit-learn's validation reads the rest)."""
    return X.detach().cpu().numpy() if isinstance(X, torch.Tensor) else X


def _as_array(X: object, name: str = "X") -> np.ndarray:
    return np.asarray(_from_torch(X))


def _check_ndim(X: np.ndarray, ndim: int, layout: str, name: str = "X") -> None:
    if X.ndim != ndim or X.shape[0] == 0:
        raise ValueError(f"{name} must have shape {layout} with at least one sample, got {X.shape}")


_EROSION = [Interval(Integral, 1, None, closed="left"), StrOptions({"relative"})]
"""The ``erosion`` entry of the image transformers' constraint tables (pixels, or relative to the frame)."""


def _resolve_erosion(erosion: object, height: int, width: int) -> int:
    return relative_erosion(height, width) if erosion == "relative" else int(erosion)


class ImageFeatureTransformer(TransformerMixin, BaseEstimator):
    """Method-1 features of RGB explorations: 12 fused statistics, or 12 per frame.

    Parameters
    ----------
    fuse : bool, default True
        ``(N, 12)`` fused features or the ``(N, T * 12)`` per-frame ablation.
    threshold : float in (0, 1] or "otsu", default 240/255
        Pressed below this gray level (the study's 240 on the 0-255 scale); ``"otsu"`` fits
        Otsu's threshold to the pooled gray levels of the training frames.
    erosion : int >= 1 or "relative", default "relative"
        Side of the square structuring element in pixels, or :func:`relative_erosion` of the frame.

    Attributes
    ----------
    threshold_ : float
    erosion_ : int
    frame_shape_ : tuple (T, 3, H, W)

    Examples
    --------
    >>> frames = np.random.default_rng(0).integers(0, 256, (2, 3, 3, 16, 16), dtype=np.uint8)
    >>> ImageFeatureTransformer(erosion=3).fit(frames).transform(frames).shape
    (2, 12)
    """

    _parameter_constraints: ClassVar[dict] = {
        "fuse": ["boolean"],
        "threshold": [Interval(Real, 0, 1, closed="right"), StrOptions({"otsu"})],
        "erosion": _EROSION,
    }

    def __init__(
        self, fuse: bool = True, threshold: float | str = DEFAULT_THRESHOLD, erosion: int | str = "relative"
    ):
        self.fuse = fuse
        self.threshold = threshold
        self.erosion = erosion

    def __sklearn_tags__(self):
        # Only Otsu's threshold is learnt from the training frames; otherwise fit learns the shapes only,
        # so the features can be computed once for all folds (the engine's one "needs no fit" protocol).
        tags = super().__sklearn_tags__()
        tags.requires_fit = self.threshold == "otsu"
        return tags

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X: object, y: object = None) -> ImageFeatureTransformer:
        """Learn the frames' shape, the erosion and, with ``threshold="otsu"``, Otsu's threshold; return ``self``.

        Parameters
        ----------
        X : array or tensor of shape (N, T, 3, H, W)
            RGB frames, uint8 or floating in [0, 1].
        y : ignored

        Returns
        -------
        self : ImageFeatureTransformer

        Raises
        ------
        ValueError
            If ``X`` is not ``(N, T, 3, H, W)`` with ``N >= 1``, or a parameter is out of its range.
        """
        X = _as_array(X)
        _check_ndim(X, 5, "(N, T, 3, H, W)")
        if X.shape[2] != 3:
            raise ValueError(f"X must have shape (N, T, 3, H, W) (RGB frames), got {X.shape}")
        self.frame_shape_ = tuple(int(s) for s in X.shape[1:])
        self.erosion_ = _resolve_erosion(self.erosion, *X.shape[-2:])
        if self.threshold == "otsu":
            from ..image import to_grayscale

            gray = to_grayscale(tensor_from_array(np.ascontiguousarray(X)))
            self.threshold_ = float(otsu_threshold(gray.reshape(1, -1))[0])
        else:
            self.threshold_ = float(self.threshold)
        return self

    def transform(self, X: object) -> np.ndarray:
        """Return the method-1 features of ``X``.

        Parameters
        ----------
        X : array or tensor of shape (N, T, 3, H, W)

        Returns
        -------
        ndarray of shape (N, 12), or (N, T * 12) with ``fuse=False``, float64

        Raises
        ------
        sklearn.exceptions.NotFittedError
            Before :meth:`fit`.
        ValueError, TypeError
            As :func:`~tactile_torch.image.exploration_features` (shape, dtype, range), naming
            ``frames``.
        """
        check_is_fitted(self, "erosion_")
        frames = tensor_from_array(np.ascontiguousarray(_as_array(X)))
        return (
            exploration_features(frames, fuse=self.fuse, threshold=self.threshold_, erosion=self.erosion_)
            .double()
            .numpy()
        )

    def to_module(self) -> nn.Module:
        """Return the fitted step as :class:`~tactile_torch.image.ExplorationFeatures`.

        Returns
        -------
        ExplorationFeatures
            ``(B, T, 3, H, W)`` → ``(B, 12)`` (or ``(B, T * 12)``), float32.

        Raises
        ------
        sklearn.exceptions.NotFittedError
            Before :meth:`fit`.
        """
        check_is_fitted(self, "erosion_")
        return ExplorationFeatures(fuse=self.fuse, threshold=self.threshold_, erosion=self.erosion_)


DISPLAY_SIDE = 48
"""Raw pressure maps are upsampled (bilinear, as a pressure-mapping display does) by the smallest
integer factor that makes the shorter side at least this many pixels."""
DISPLAY_FLOOR_SHARE = 4.0 / 255.0
"""``threshold="display"``: pressed above this share of the pressure scale (the largest pressure above
rest in the training maps, which a display maps to the top of its colours): the share of the 8-bit
scale below which the bundled display shows white, so that the study's 240/255 on it marks no pressure."""
NOISE_MULTIPLE = 5.0
"""``threshold="display"``: the pressed level is also at least this many noise standard deviations above
rest (the resting level, a 5th percentile, lies about 1.6 of them below the mean resting reading)."""
THRESHOLDS = ("display", "otsu")


def display_factor(height: int, width: int) -> int:
    """Return the upsampling factor of a ``height x width`` pressure map (see :data:`DISPLAY_SIDE`).

    Examples
    --------
    >>> display_factor(4, 4), display_factor(14, 6), display_factor(96, 96)
    (12, 8, 1)
    """
    return max(1, -(-DISPLAY_SIDE // min(height, width)))


class PressedFrames(nn.Module):
    """Raw pressure maps ``(B, T, H, W)`` → black-on-white frames ``(B, T, 3, f H, f W)`` of the pressed region.

    The pressure above rest, ``sign * raw - resting`` (``resting`` per taxel), is upsampled ``factor``
    times (bilinear, ``align_corners=False``) and a pixel is pressed where it exceeds ``level``.
    Pressed pixels are black (0), the others white (1), so that the image pipeline's ``gray < 0.5``
    gives this mask.
    """

    def __init__(self, resting: torch.Tensor, sign: float, level: float, factor: int = 1) -> None:
        super().__init__()
        self.register_buffer("resting", torch.as_tensor(resting, dtype=torch.float32).clone())
        self.sign, self.level, self.factor = float(sign), float(level), int(factor)

    def forward(self, raw: torch.Tensor) -> torch.Tensor:
        above = raw.to(torch.float32) * self.sign - self.resting
        if self.factor > 1:
            b, t, h, w = above.shape
            above = torch.nn.functional.interpolate(
                above.reshape(b * t, 1, h, w), scale_factor=self.factor, mode="bilinear", align_corners=False
            ).reshape(b, t, h * self.factor, w * self.factor)
        white = (above <= self.level).to(torch.float32)
        return white.unsqueeze(2).expand(white.shape[0], white.shape[1], 3, white.shape[2], white.shape[3])


class PressureImageFeatures(TransformerMixin, BaseEstimator):
    """Method-1 features of raw pressure-map explorations ``(N, T, H, W)``, constants fitted to the data.

    A small taxel array's raw counts are not a display image, so the study's constants are replaced by
    ones that scale with the array and the data. Fitted on the training maps: each taxel's resting
    level (the 5th percentile of ``sign * reading``), the pressure scale (the largest pressure above
    rest) and the pressed level (``threshold``). The pressure above rest is upsampled
    like a pressure-mapping display (:func:`display_factor`), thresholded, and goes through the image
    pipeline (erosion relative to the upsampled frame, Sobel edges, OR-fusion, gradient statistics) of
    :func:`~tactile_torch.image.exploration_features`.

    Parameters
    ----------
    fuse : bool, default True
    threshold : "display", "otsu" or float in (0, 1), default "display"
        Pressed level: :data:`DISPLAY_FLOOR_SHARE` of the pressure scale (what a display colours, the
        study's choice of 240/255 on its display), but at least :data:`NOISE_MULTIPLE` times the
        sensor noise (estimated from frame-to-frame differences); Otsu's threshold on the histogram of
        the pressure above rest; or this fraction of the pressure scale.
    erosion : int >= 1 or "relative", default "relative"
        Pixels of the upsampled frame, or :func:`relative_erosion` of it.
    contact : {"raises", "lowers", "auto"}, default "raises"
        Whether contact raises the reading (force arrays such as Tekscan or the Schunk hand's) or lowers
        it (iCub's capacitive skin). ``"auto"`` decides from the skewness of the readings around each
        taxel's median, towards contact when contact is the rarer state; it fails when contact is the
        usual state of the recordings (a held grasp).
    upsample : int >= 1 or "auto", default "auto"
        Upsampling factor, or :func:`display_factor`.

    Attributes
    ----------
    sign_ : float
        +1 if contact raises the reading, -1 if it lowers it.
    resting_ : ndarray of shape (H, W)
        Resting level of each taxel, in ``sign * reading`` units.
    scale_ : float
    level_ : float
        Pressed above ``resting_ + level_`` (counts).
    factor_, erosion_ : int
    noise_ : float
        ``threshold="display"``: the estimated noise standard deviation of a reading (counts).
    skewness_ : float
        Skewness of the readings around each taxel's median (positive: a tail of high readings).
    frame_shape_ : tuple (T, H, W)

    Raises
    ------
    ValueError
        At ``fit``, naming the parameter to set, when the data cannot decide it: the readings never
        leave their resting level, or (``contact="auto"``) their skewness does not say which way
        contact moves them.

    Examples
    --------
    >>> maps = 500.0 + np.random.default_rng(0).normal(0, 1, size=(4, 5, 4, 4))  # raw counts, 4 x 4 taxels
    >>> maps[:, 3:, 1:3, 1:3] += 80.0  # a press in the middle, last two frames
    >>> features = PressureImageFeatures().fit(maps)
    >>> features.factor_, features.transform(maps).shape  # shown as 48 x 48 frames
    (12, (4, 12))
    """

    _parameter_constraints: ClassVar[dict] = {
        "fuse": ["boolean"],
        "threshold": [StrOptions(set(THRESHOLDS)), Interval(Real, 0, 1, closed="neither")],
        "erosion": _EROSION,
        "contact": [StrOptions(set(CONTACT))],
        "upsample": [Interval(Integral, 1, None, closed="left"), StrOptions({"auto"})],
    }

    def __init__(
        self,
        fuse: bool = True,
        threshold: float | str = "display",
        erosion: int | str = "relative",
        contact: str = "raises",
        upsample: int | str = "auto",
    ):
        self.fuse = fuse
        self.threshold = threshold
        self.erosion = erosion
        self.contact = contact
        self.upsample = upsample

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X: object, y: object = None) -> PressureImageFeatures:
        """Fit the contact direction, resting levels, pressure scale and pressed level; return ``self``.

        Parameters
        ----------
        X : array or tensor of shape (N, T, H, W)
            Raw pressure maps (any unit).
        y : ignored

        Returns
        -------
        self : PressureImageFeatures

        Raises
        ------
        ValueError
            If ``X`` is not ``(N, T, H, W)``, the maps never rise above their resting level with
            this ``contact``, ``threshold="otsu"`` finds no split, or a parameter is out of its range.
        """
        X = _as_array(X)
        _check_ndim(X, 4, "(N, T, H, W)")
        threshold = self.threshold
        self.factor_ = display_factor(*X.shape[-2:]) if self.upsample == "auto" else int(self.upsample)
        values = X.astype(np.float64).reshape(-1, *X.shape[2:])  # (N * T, H, W)
        # the contact direction and each taxel's resting level: the robot's touch levels use the same
        self.sign_, self.skewness_ = contact_sign(values, self.contact)
        signed = self.sign_ * values
        self.resting_ = resting_level(signed)
        above = np.maximum(signed - self.resting_, 0.0)
        self.scale_ = float(above.max())
        if self.scale_ <= 0:
            raise ValueError(
                "contact: the pressure maps never rise above their resting level with "
                f"contact={self.contact!r}; check contact="
            )
        if threshold == "otsu":
            unit = torch.from_numpy(above / self.scale_).reshape(1, -1)
            cut = float(otsu_threshold(1.0 - unit)[0])  # pressed where 1 - q < cut
            if not 0 < cut < 1:
                raise ValueError(
                    "threshold: the histogram of the pressure maps has no Otsu split; set threshold= "
                    "(a fraction of the pressure scale in (0, 1), or 'display')"
                )
            self.level_ = (1.0 - cut) * self.scale_
        elif threshold == "display":
            # Frame-to-frame differences cancel the slowly changing contact: their median absolute value
            # measures the sensor noise (Gaussian: sigma = 1.4826 * MAD / sqrt(2)).
            self.noise_ = reading_noise(X)
            self.level_ = max(DISPLAY_FLOOR_SHARE * self.scale_, NOISE_MULTIPLE * self.noise_)
        else:
            self.level_ = float(threshold) * self.scale_
        height, width = X.shape[-2] * self.factor_, X.shape[-1] * self.factor_
        self.erosion_ = _resolve_erosion(self.erosion, height, width)
        self.frame_shape_ = tuple(int(s) for s in X.shape[1:])
        return self

    def _pressed(self) -> PressedFrames:
        return PressedFrames(torch.from_numpy(self.resting_), self.sign_, self.level_, self.factor_)

    def transform(self, X: object) -> np.ndarray:
        """Return the method-1 features of the pressed regions of ``X``.

        Parameters
        ----------
        X : array or tensor of shape (N, T, H, W)

        Returns
        -------
        ndarray of shape (N, 12), or (N, T * 12) with ``fuse=False``, float64

        Raises
        ------
        sklearn.exceptions.NotFittedError
            Before :meth:`fit`.
        ValueError
            If ``X`` is not ``(N, T, H, W)`` or its maps are not the fitted size.
        """
        check_is_fitted(self, "level_")
        X = _as_array(X)
        _check_ndim(X, 4, "(N, T, H, W)")
        if X.shape[2:] != self.resting_.shape:
            raise ValueError(
                f"X must hold maps of the fitted size {self.resting_.shape}, got shape {X.shape}"
            )
        with torch.no_grad():
            frames = self._pressed()(tensor_from_array(np.ascontiguousarray(X, dtype=np.float32)))
        return (
            exploration_features(frames, fuse=self.fuse, threshold=0.5, erosion=self.erosion_)
            .double()
            .numpy()
        )

    def to_module(self) -> nn.Module:
        """Return :class:`PressedFrames` followed by :class:`~tactile_torch.image.ExplorationFeatures`.

        Returns
        -------
        nn.Sequential
            ``(B, T, H, W)`` → ``(B, 12)`` (or ``(B, T * 12)``), float32.

        Raises
        ------
        sklearn.exceptions.NotFittedError
            Before :meth:`fit`.
        """
        check_is_fitted(self, "level_")
        return nn.Sequential(
            self._pressed(), ExplorationFeatures(fuse=self.fuse, threshold=0.5, erosion=self.erosion_)
        )
