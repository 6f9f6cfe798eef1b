"""Raw input → features as scikit-learn transformers, each with the torch module that exports it.

Every candidate of the trade-off study is a scikit-learn ``Pipeline`` whose first step, named
``"features"``, takes the data file's raw input: RGB frames ``(N, T, 3, H, W)``, raw pressure maps
``(N, T, H, W)``, vibration windows ``(N, 3, W)`` or a feature matrix ``(N, F)``. The transformers
here are that step (clone-able, hyper-parameters stored unchanged, fitted values in trailing-underscore
attributes); :meth:`to_module` returns the fitted step as a :class:`torch.nn.Module` for ONNX export.

==================================  ==========================================  =====================
transformer                         raw input → features                        fitted on data
==================================  ==========================================  =====================
:class:`ImageFeatureTransformer`    RGB frames → 12 fused or T x 12 per-frame   threshold if
                                    (:func:`~tactile_torch.image.               ``"otsu"``
                                    exploration_features`)
:class:`PressureImageFeatures`      raw pressure maps (any counts) → pressed    resting level, contact
                                    region → the same image pipeline            sign, pressed level
:class:`TaxelFeatureTransformer`    each taxel's time series → its 7 vibration  no
                                    features (:func:`~tactile_torch.signal.
                                    window_features`)
:class:`WindowFeatureTransformer`   windows ``(N, 3, W)`` → 21 features         no
:class:`FeaturePassthrough`         a feature matrix, unchanged                 no
:class:`RankedFeatureSelector`      features → the ``k`` best-ranked columns    the ranking
==================================  ==========================================  =====================

Small taxel arrays: the study's constants are for 96-pixel display frames (a 10-pixel erosion, a
threshold of 240 on the 0-255 display scale). Here the erosion is relative to the frame
(:data:`EROSION_FRACTION` of its shorter side, at least 1: 10 pixels on 96-pixel frames) unless given
in pixels, and raw pressure maps (any counts, any resting level) are upsampled like a display and get
their pressed level from the data's own distribution (:class:`PressureImageFeatures`).
"""

from __future__ import annotations

from numbers import Integral, Real
from typing import ClassVar

import numpy as np
import torch
from sklearn.base import BaseEstimator, TransformerMixin, _fit_context
from sklearn.utils._param_validation import Interval, StrOptions
from sklearn.utils.validation import check_is_fitted, validate_data
from torch import nn

from ..image import (
    DEFAULT_THRESHOLD,
    GRAY_WEIGHTS,
    ExplorationFeatures,
    exploration_features,
    otsu_threshold,
    relative_erosion,
)
from ..robot.stream.touches import CONTACT, contact_sign, reading_noise, resting_level
from ..signal import AXIS_FEATURES, WindowFeatures, window_features

MAX_TAXELS = 256
"""Largest frame (taxels or pixels) for which per-taxel time-series features are offered (7 per taxel)."""


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
        X = _as_array(X)
        _check_ndim(X, 5, "(N, T, 3, H, W)")
        if X.shape[2] != 3:
            raise ValueError(f"X must have shape (N, T, 3, H, W) (RGB frames), got {X.shape}")
        self.frame_shape_ = tuple(int(s) for s in X.shape[1:])
        self.erosion_ = _resolve_erosion(self.erosion, *X.shape[-2:])
        if self.threshold == "otsu":
            from ..image import to_grayscale

            gray = to_grayscale(torch.from_numpy(np.ascontiguousarray(X)))
            self.threshold_ = float(otsu_threshold(gray.reshape(1, -1))[0])
        else:
            self.threshold_ = float(self.threshold)
        return self

    def transform(self, X: object) -> np.ndarray:
        check_is_fitted(self, "erosion_")
        frames = torch.from_numpy(np.ascontiguousarray(_as_array(X)))
        return (
            exploration_features(frames, fuse=self.fuse, threshold=self.threshold_, erosion=self.erosion_)
            .double()
            .numpy()
        )

    def to_module(self) -> nn.Module:
        """Return the fitted step as :class:`~tactile_torch.image.ExplorationFeatures`."""
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
        check_is_fitted(self, "level_")
        X = _as_array(X)
        _check_ndim(X, 4, "(N, T, H, W)")
        with torch.no_grad():
            frames = self._pressed()(torch.from_numpy(np.ascontiguousarray(X, dtype=np.float32)))
        return (
            exploration_features(frames, fuse=self.fuse, threshold=0.5, erosion=self.erosion_)
            .double()
            .numpy()
        )

    def to_module(self) -> nn.Module:
        """Return :class:`PressedFrames` followed by :class:`~tactile_torch.image.ExplorationFeatures`."""
        check_is_fitted(self, "level_")
        return nn.Sequential(
            self._pressed(), ExplorationFeatures(fuse=self.fuse, threshold=0.5, erosion=self.erosion_)
        )


def taxel_features(signals: torch.Tensor) -> torch.Tensor:
    """Return the 7 vibration features of each taxel's time series: ``(B, T, H, W)`` → ``(B, H * W * 7)``.

    Taxels in row-major order, features in the order of :data:`~tactile_torch.signal.AXIS_FEATURES`;
    each taxel's series is one "axis" of :func:`~tactile_torch.signal.window_features` (taxels are
    grouped three at a time, padded with constant series whose features are dropped).
    """
    batch, length = signals.shape[0], signals.shape[1]
    series = signals.reshape(batch, length, -1).transpose(1, 2)  # (B, n, T)
    n = series.shape[1]
    pad = (-n) % 3
    if pad:
        series = torch.cat([series, series.new_zeros(batch, pad, length)], dim=1)
    feats = window_features(series.reshape(batch, -1, 3, length).contiguous())  # (B, n3, 21)
    per_taxel = feats.reshape(batch, -1, len(AXIS_FEATURES))[:, :n]
    return per_taxel.reshape(batch, n * len(AXIS_FEATURES))


class _ShapeOnly(TransformerMixin, BaseEstimator):
    """A ``features`` step with no parameter whose ``fit`` learns the input's shape only: scikit-learn's
    ``requires_fit`` is off, so the evaluation computes its features once for all folds."""

    _parameter_constraints: ClassVar[dict] = {}

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.requires_fit = False
        return tags


class TaxelFeatures(nn.Module):
    """Module form of :func:`taxel_features`; RGB frames ``(B, T, 3, H, W)`` are first turned into
    ``1 - gray`` (pressure-like: 0 on the white background)."""

    def __init__(self, rgb: bool = False) -> None:
        super().__init__()
        self.rgb = rgb

    def forward(self, raw: torch.Tensor) -> torch.Tensor:
        if self.rgb:
            x = raw.to(torch.float32) / 255.0 if raw.dtype == torch.uint8 else raw.to(torch.float32)
            weights = torch.tensor(GRAY_WEIGHTS, dtype=torch.float32).reshape(1, 1, 3, 1, 1)
            raw = 1.0 - (x * weights).sum(2)
        return taxel_features(raw.to(torch.float32))


class TaxelFeatureTransformer(_ShapeOnly):
    """Per-taxel time-series features: the 7 vibration features of every taxel's signal over the exploration.

    Takes raw pressure maps ``(N, T, H, W)`` or RGB frames ``(N, T, 3, H, W)`` (then ``1 - gray``).
    Gives ``(N, H * W * 7)`` features; meant for small arrays (at most :data:`MAX_TAXELS` taxels).
    Nothing is learnt.
    """

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X: object, y: object = None) -> TaxelFeatureTransformer:
        X = _as_array(X)
        if X.ndim not in (4, 5) or X.shape[0] == 0 or X.shape[1] < 2:
            raise ValueError(
                f"X must have shape (N, T, H, W) or (N, T, 3, H, W) with T >= 2 frames, got {X.shape}"
            )
        self.rgb_ = X.ndim == 5
        self.frame_shape_ = tuple(int(s) for s in X.shape[1:])
        return self

    def transform(self, X: object) -> np.ndarray:
        check_is_fitted(self, "rgb_")
        X = np.ascontiguousarray(_as_array(X))
        raw = torch.from_numpy(X if X.dtype == np.uint8 else X.astype(np.float32))
        with torch.no_grad():
            return TaxelFeatures(self.rgb_)(raw).double().numpy()

    def to_module(self) -> nn.Module:
        check_is_fitted(self, "rgb_")
        return TaxelFeatures(self.rgb_)


class WindowFeatureTransformer(_ShapeOnly):
    """The 21 vibration features of windows ``(N, 3, W)`` (:func:`~tactile_torch.signal.window_features`)."""

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X: object, y: object = None) -> WindowFeatureTransformer:
        X = _as_array(X)
        _check_ndim(X, 3, "(N, 3, W)")
        self.window_size_ = int(X.shape[-1])
        return self

    def transform(self, X: object) -> np.ndarray:
        check_is_fitted(self, "window_size_")
        X = np.ascontiguousarray(_as_array(X))
        return window_features(torch.from_numpy(X.astype(np.float32, copy=False))).double().numpy()

    def to_module(self) -> nn.Module:
        check_is_fitted(self, "window_size_")
        return WindowFeatures(self.window_size_)


class FeaturePassthrough(_ShapeOnly):
    """A feature matrix ``(N, F)`` passed through unchanged (the ``features`` step of a feature file)."""

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X: object, y: object = None) -> FeaturePassthrough:
        validate_data(self, _from_torch(X), dtype=np.float64)  # 2-D, finite, real: sets n_features_in_
        return self

    def transform(self, X: object) -> np.ndarray:
        """Return ``X`` as float64 ``(N, F)``; once fitted, ``F`` must be the width seen by ``fit``."""
        return validate_data(self, _from_torch(X), dtype=np.float64, reset=False)

    def to_module(self) -> nn.Module:
        """Return the graph's front end: the features cast to float32, the dtype every head is exported for
        (the other fronts compute float32 features; a float64 file fed to a float32 head fails to load)."""
        return ToFloat32()


# RawInput and FeaturePassthrough are both an identity `features` step, but two jobs, kept as two classes
# (issue 40 looked at merging them): FeaturePassthrough is a feature matrix, validated as one (2-D, finite,
# float64) and exported as the float32 cast every classical head is exported for; RawInput is a network's
# raw input (windows, frames, pressure maps of any shape), passed as it is to a network that owns its
# dtype, and its class is what marks a candidate as learned (tradeoff.learned.is_learned). One class with a
# mode would branch on the mode in all three methods and in is_learned.
class RawInput(_ShapeOnly):
    """The raw input unchanged (the ``features`` step of a learned candidate); nothing is learnt."""

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X: object, y: object = None) -> RawInput:
        self.input_shape_ = tuple(np.shape(X)[1:])
        return self

    def transform(self, X: object) -> np.ndarray:
        return np.asarray(X)

    def to_module(self) -> object:
        from torch import nn

        return nn.Identity()


class ToFloat32(nn.Module):
    """Features ``(B, F)`` of any float dtype → float32."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x.to(torch.float32)


class ColumnSelect(nn.Module):
    """Features ``(B, F)`` → the chosen columns ``(B, k)``."""

    def __init__(self, columns: object) -> None:
        super().__init__()
        self.register_buffer("columns", torch.as_tensor(np.asarray(columns), dtype=torch.int64).clone())

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x.index_select(1, self.columns)


def single_feature_accuracy(X: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Return, per column of ``X``, the training accuracy of a nearest-class-mean rule on that column alone."""
    classes, index = np.unique(y, return_inverse=True)
    counts = np.bincount(index, minlength=len(classes)).astype(np.float64)
    means = np.stack([np.bincount(index, weights=col, minlength=len(classes)) for col in X.T], axis=1)
    means /= counts[:, None]  # (C, F)
    scores = np.empty(X.shape[1])
    step = max(1, (1 << 22) // max(1, X.shape[0] * len(classes)))  # columns per block: bounded memory
    for start in range(0, X.shape[1], step):
        block = slice(start, start + step)
        nearest = np.abs(X[:, None, block] - means[None, :, block]).argmin(axis=1)  # (N, columns)
        scores[block] = (nearest == index[:, None]).mean(axis=0)
    return scores


class RankedFeatureSelector(TransformerMixin, BaseEstimator):
    """Keep the ``k`` features that rank best by the accuracy each reaches alone, ranked on the training data.

    The study ranked features by the accuracy an SVM reaches on each alone; here, inside every
    training fold, each column is scored by a nearest-class-mean rule on that column alone (one
    mean per class: its training accuracy is close to a held-out one, and it costs one pass). Ties go
    to the earlier column.

    Parameters
    ----------
    k : int >= 1

    Attributes
    ----------
    scores_ : ndarray of shape (F,)
    columns_ : ndarray of shape (k,)
        The kept columns, best first.
    """

    _parameter_constraints: ClassVar[dict] = {"k": [Interval(Integral, 1, None, closed="left")]}

    def __init__(self, k: int = 7):
        self.k = k

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X: object, y: object) -> RankedFeatureSelector:
        X, y = validate_data(self, _from_torch(X), y, dtype=np.float64)  # sets n_features_in_
        if self.k > X.shape[1]:  # the table checked that k is an integer >= 1
            raise ValueError(
                f"k must be an integer in [1, {X.shape[1]}] (the number of features), got {self.k!r}"
            )
        self.scores_ = single_feature_accuracy(X, np.asarray(y))
        self.columns_ = np.argsort(-self.scores_, kind="stable")[: self.k]
        return self

    def transform(self, X: object) -> np.ndarray:
        check_is_fitted(self, "columns_")
        return validate_data(self, _from_torch(X), dtype=np.float64, reset=False)[:, self.columns_]

    def to_module(self) -> nn.Module:
        check_is_fitted(self, "columns_")
        return ColumnSelect(self.columns_)


__all__ = [
    "CONTACT",
    "DISPLAY_FLOOR_SHARE",
    "DISPLAY_SIDE",
    "MAX_TAXELS",
    "NOISE_MULTIPLE",
    "THRESHOLDS",
    "ColumnSelect",
    "FeaturePassthrough",
    "ImageFeatureTransformer",
    "PressedFrames",
    "PressureImageFeatures",
    "RankedFeatureSelector",
    "RawInput",
    "TaxelFeatureTransformer",
    "TaxelFeatures",
    "ToFloat32",
    "WindowFeatureTransformer",
    "display_factor",
    "single_feature_accuracy",
    "taxel_features",
]
