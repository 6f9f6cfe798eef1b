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

from numbers import Integral
from typing import ClassVar

import numpy as np
import torch
from sklearn.base import BaseEstimator, TransformerMixin, _fit_context
from sklearn.utils._param_validation import Interval
from sklearn.utils.validation import check_is_fitted, validate_data
from torch import nn

from ..image import GRAY_WEIGHTS
from ..robot.stream.touches import CONTACT
from ..signal import AXIS_FEATURES, WindowFeatures, window_features
from ..validation import tensor_from_array
from ._frames import (
    DISPLAY_FLOOR_SHARE,
    DISPLAY_SIDE,
    NOISE_MULTIPLE,
    THRESHOLDS,
    ImageFeatureTransformer,
    PressedFrames,
    PressureImageFeatures,
    _as_array,
    _check_ndim,
    _from_torch,
    display_factor,
)

MAX_TAXELS = 256
"""Largest frame (taxels or pixels) for which per-taxel time-series features are offered (7 per taxel)."""


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

    Examples
    --------
    >>> maps = np.random.default_rng(0).poisson(3.0, (2, 6, 4, 4)).astype(float)
    >>> TaxelFeatureTransformer().fit(maps).transform(maps).shape  # 16 taxels x 7
    (2, 112)
    """

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X: object, y: object = None) -> TaxelFeatureTransformer:
        """Learn whether ``X`` holds RGB frames and its shape; return ``self``.

        Parameters
        ----------
        X : array or tensor of shape (N, T, H, W) or (N, T, 3, H, W)
        y : ignored

        Returns
        -------
        self : TaxelFeatureTransformer

        Raises
        ------
        ValueError
            If ``X`` is neither shape, has no sample or fewer than 2 frames.
        """
        X = _as_array(X)
        if X.ndim not in (4, 5) or X.shape[0] == 0 or X.shape[1] < 2:
            raise ValueError(
                f"X must have shape (N, T, H, W) or (N, T, 3, H, W) with T >= 2 frames, got {X.shape}"
            )
        self.rgb_ = X.ndim == 5
        self.frame_shape_ = tuple(int(s) for s in X.shape[1:])
        return self

    def transform(self, X: object) -> np.ndarray:
        """Return the 7 features of every taxel's series.

        Parameters
        ----------
        X : array or tensor of shape (N, T, H, W) or (N, T, 3, H, W), as in ``fit``

        Returns
        -------
        ndarray of shape (N, H * W * 7), float64

        Raises
        ------
        sklearn.exceptions.NotFittedError
            Before :meth:`fit`.
        ValueError
            As :func:`~tactile_torch.signal.window_features`, on the taxels' series.
        """
        check_is_fitted(self, "rgb_")
        X = np.ascontiguousarray(_as_array(X))
        raw = tensor_from_array(X if X.dtype == np.uint8 else X.astype(np.float32))
        with torch.no_grad():
            return TaxelFeatures(self.rgb_)(raw).double().numpy()

    def to_module(self) -> nn.Module:
        """Return the fitted step as a :class:`TaxelFeatures` module.

        Returns
        -------
        TaxelFeatures
            ``(B, T, H, W)`` (or RGB ``(B, T, 3, H, W)``) → ``(B, H * W * 7)``, float32.

        Raises
        ------
        sklearn.exceptions.NotFittedError
            Before :meth:`fit`.
        """
        check_is_fitted(self, "rgb_")
        return TaxelFeatures(self.rgb_)


class WindowFeatureTransformer(_ShapeOnly):
    """The 21 vibration features of windows ``(N, 3, W)`` (:func:`~tactile_torch.signal.window_features`).

    Examples
    --------
    >>> windows = np.random.default_rng(0).normal(size=(2, 3, 64))
    >>> WindowFeatureTransformer().fit(windows).transform(windows).shape
    (2, 21)
    """

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X: object, y: object = None) -> WindowFeatureTransformer:
        """Learn the window length; return ``self``.

        Parameters
        ----------
        X : array or tensor of shape (N, 3, W)
        y : ignored

        Returns
        -------
        self : WindowFeatureTransformer

        Raises
        ------
        ValueError
            If ``X`` is not ``(N, 3, W)`` with ``N >= 1``.
        """
        X = _as_array(X)
        _check_ndim(X, 3, "(N, 3, W)")
        self.window_size_ = int(X.shape[-1])
        return self

    def transform(self, X: object) -> np.ndarray:
        """Return the 21 window features of ``X``.

        Parameters
        ----------
        X : array or tensor of shape (N, 3, W)

        Returns
        -------
        ndarray of shape (N, 21), float64

        Raises
        ------
        sklearn.exceptions.NotFittedError
            Before :meth:`fit`.
        ValueError, TypeError
            As :func:`~tactile_torch.signal.window_features` (shape, finite values).
        """
        check_is_fitted(self, "window_size_")
        X = np.ascontiguousarray(_as_array(X))
        return window_features(tensor_from_array(X.astype(np.float32, copy=False))).double().numpy()

    def to_module(self) -> nn.Module:
        """Return the fitted step as a :class:`~tactile_torch.signal.WindowFeatures` module.

        Returns
        -------
        WindowFeatures
            ``(B, 3, W)`` → ``(B, 21)``, ``W`` the fitted length.

        Raises
        ------
        sklearn.exceptions.NotFittedError
            Before :meth:`fit`.
        """
        check_is_fitted(self, "window_size_")
        return WindowFeatures(self.window_size_)


class FeaturePassthrough(_ShapeOnly):
    """A feature matrix ``(N, F)`` passed through unchanged (the ``features`` step of a feature file).

    Examples
    --------
    >>> X = np.ones((3, 2))
    >>> FeaturePassthrough().fit(X).transform(X).shape
    (3, 2)
    """

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X: object, y: object = None) -> FeaturePassthrough:
        """Learn the number of features; return ``self``.

        Parameters
        ----------
        X : array, tensor or DataFrame of shape (N, F)
        y : ignored

        Returns
        -------
        self : FeaturePassthrough

        Raises
        ------
        ValueError
            If ``X`` is not 2-D, empty or not finite (scikit-learn's messages).
        """
        validate_data(self, _from_torch(X), dtype=np.float64)  # 2-D, finite, real: sets n_features_in_
        return self

    def transform(self, X: object) -> np.ndarray:
        """Return ``X`` as float64 ``(N, F)``; once fitted, ``F`` must be the width seen by ``fit``.

        Parameters
        ----------
        X : array, tensor or DataFrame of shape (N, F)

        Returns
        -------
        ndarray of shape (N, F), float64

        Raises
        ------
        ValueError
            If ``X`` is not 2-D, not finite or (fitted) of another width.
        """
        return validate_data(self, _from_torch(X), dtype=np.float64, reset=False)

    def to_module(self) -> nn.Module:
        """Return the graph's front end: the features cast to float32, the dtype every head is exported for
        (the other fronts compute float32 features; a float64 file fed to a float32 head fails to load).

        Returns
        -------
        ToFloat32
            ``(B, F)`` → ``(B, F)``, float32.
        """
        return ToFloat32()


# RawInput and FeaturePassthrough are both an identity `features` step, but two jobs, kept as two classes
# (issue 40 looked at merging them): FeaturePassthrough is a feature matrix, validated as one (2-D, finite,
# float64) and exported as the float32 cast every classical head is exported for; RawInput is a network's
# raw input (windows, frames, pressure maps of any shape), passed as it is to a network that owns its
# dtype, and its class is what marks a candidate as learned (tradeoff.learned.is_learned). One class with a
# mode would branch on the mode in all three methods and in is_learned.
class RawInput(_ShapeOnly):
    """The raw input unchanged (the ``features`` step of a learned candidate); nothing is learnt.

    Examples
    --------
    >>> RawInput().fit(np.zeros((2, 3, 8))).transform(np.zeros((2, 3, 8))).shape
    (2, 3, 8)
    """

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X: object, y: object = None) -> RawInput:
        """Record the shape of one sample; return ``self``.

        Parameters
        ----------
        X : array-like of shape (N, ...)
            Windows, frames or pressure maps.
        y : ignored

        Returns
        -------
        self : RawInput
        """
        self.input_shape_ = tuple(np.shape(X)[1:])
        return self

    def transform(self, X: object) -> np.ndarray:
        """Return ``X`` as an array, unchanged.

        Parameters
        ----------
        X : array-like of shape (N, ...)

        Returns
        -------
        ndarray of shape (N, ...)
            ``np.asarray(X)``: the network that follows validates it.
        """
        return np.asarray(X)

    def to_module(self) -> object:
        """Return the identity module of the exported graph.

        Returns
        -------
        torch.nn.Identity
            ``(B, ...)`` → the same tensor.
        """
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

    Examples
    --------
    >>> X = np.array([[0, 5, 0], [1, 3, 0], [0, 4, 0], [1, 5, 1], [0, 3, 1], [1, 4, 1]], dtype=float)
    >>> y = np.array([0, 0, 0, 1, 1, 1])  # the third column separates the classes
    >>> RankedFeatureSelector(k=1).fit(X, y).columns_
    array([2])
    """

    _parameter_constraints: ClassVar[dict] = {"k": [Interval(Integral, 1, None, closed="left")]}

    def __init__(self, k: int = 7):
        self.k = k

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X: object, y: object) -> RankedFeatureSelector:
        """Score every column alone and keep the ``k`` best; return ``self``.

        Parameters
        ----------
        X : array, tensor or DataFrame of shape (N, F)
        y : array-like of shape (N,)
            Class labels.

        Returns
        -------
        self : RankedFeatureSelector

        Raises
        ------
        ValueError
            If ``X`` is not 2-D or not finite, ``y`` of another length (scikit-learn's messages),
            or ``k`` exceeds the number of features.
        """
        X, y = validate_data(self, _from_torch(X), y, dtype=np.float64)  # sets n_features_in_
        if self.k > X.shape[1]:  # the table checked that k is an integer >= 1
            raise ValueError(
                f"k must be an integer in [1, {X.shape[1]}] (the number of features), got {self.k!r}"
            )
        self.scores_ = single_feature_accuracy(X, np.asarray(y))
        self.columns_ = np.argsort(-self.scores_, kind="stable")[: self.k]
        return self

    def transform(self, X: object) -> np.ndarray:
        """Return the kept columns of ``X``, best first.

        Parameters
        ----------
        X : array, tensor or DataFrame of shape (N, F)

        Returns
        -------
        ndarray of shape (N, k), float64

        Raises
        ------
        sklearn.exceptions.NotFittedError
            Before :meth:`fit`.
        ValueError
            If ``X`` is not 2-D, not finite or of another width than in ``fit``.
        """
        check_is_fitted(self, "columns_")
        return validate_data(self, _from_torch(X), dtype=np.float64, reset=False)[:, self.columns_]

    def to_module(self) -> nn.Module:
        """Return the fitted selection as a :class:`ColumnSelect` module.

        Returns
        -------
        ColumnSelect
            ``(B, F)`` → ``(B, k)``.

        Raises
        ------
        sklearn.exceptions.NotFittedError
            Before :meth:`fit`.
        """
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
