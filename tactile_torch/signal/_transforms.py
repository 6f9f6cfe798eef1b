"""The fitted transforms after the window features: scaling (supervised path) and the unsupervised
projection, as scikit-learn transformers whose ``to_module()`` gives the torch graph for export."""

from __future__ import annotations

from numbers import Integral, Real
from typing import ClassVar

import numpy as np
import torch
from sklearn.base import (
    BaseEstimator,
    ClassNamePrefixFeaturesOutMixin,
    OneToOneFeatureMixin,
    TransformerMixin,
    _fit_context,
)
from sklearn.utils._param_validation import Interval, StrOptions
from sklearn.utils.validation import check_is_fitted, validate_data
from torch import nn

from ..validation import check_finite, check_floating, check_positive, check_shape, check_tensor
from ._features import AXIS_FEATURES, CLUSTERING_FEATURE_NAMES, FEATURE_NAMES


def clustering_features(features: torch.Tensor, *, eps: float = 1e-6) -> torch.Tensor:
    """Return the 12 per-axis features of the unsupervised path from the 21 window features.

    Per axis: ``sqrt(var)``, ``log(tv + eps)``, ``log1p(cross)``, ``log(hf + eps)``
    (:data:`CLUSTERING_FEATURE_NAMES`); skewness, kurtosis and the fifth moment are dropped (the
    study's unsupervised path). The offsets keep a constant window (``var = tv = cross = hf = 0``)
    finite: ``log(0 + eps)`` for ``tv`` and ``hf`` (``eps`` in the signal's unit, default 1e-6 g, far below
    the 3.9 mg resolution of the sensor, so ``log(x + eps) = log(x)`` to within 3e-4 for every
    non-constant quantised window), and ``log1p`` for the integer crossing count (``log1p(0) = 0``;
    ``log1p(n) - log(n) < 1/n``, under 0.01 for the hundreds of crossings of real windows). All four
    maps are strictly increasing.

    Parameters
    ----------
    features : Tensor, shape ``(B, 21)``
        Output of :func:`window_features` (unscaled); the var, tv, cross and hf columns must be >= 0.
    eps : float
        Offset inside the logarithms of ``tv`` and ``hf``, > 0.

    Returns
    -------
    Tensor, shape ``(B, 12)``

    Examples
    --------
    >>> from tactile_torch.signal import window_features
    >>> clustering_features(window_features(torch.zeros(1, 3, 100)))[0, :4]
    tensor([  0.0000, -13.8155,   0.0000, -13.8155])
    """
    if not torch.compiler.is_exporting():
        check_tensor(features, "features")
        check_shape(features, "features", ["B", len(FEATURE_NAMES)])
        check_floating(features, "features")
        check_finite(features, "features")
        check_positive(eps, "eps")
        _check_window_features(features.detach(), "features")
    per_axis = features.reshape(-1, 3, len(AXIS_FEATURES))
    out = torch.stack(
        [
            per_axis[..., 0].sqrt(),
            torch.log(per_axis[..., 4] + eps),
            torch.log1p(per_axis[..., 5]),
            torch.log(per_axis[..., 6] + eps),
        ],
        dim=-1,
    )
    return out.reshape(-1, len(CLUSTERING_FEATURE_NAMES))


def _check_window_features(features: torch.Tensor | np.ndarray, name: str) -> None:
    kept = features.reshape(-1, 3, len(AXIS_FEATURES))[:, :, [0, 4, 5, 6]]
    if bool((kept < 0).any()):
        raise ValueError(f"{name} must have var, tv, cross and hf >= 0 (window_features output)")


def _validate_features(estimator: BaseEstimator, X: object, *, reset: bool) -> tuple[np.ndarray, bool]:
    """Check ``X`` with scikit-learn's ``validate_data`` (shape, finite, ``n_features_in_``).

    Returns ``X`` as a float array (float64 or float32, a view of a float tensor where possible) and
    whether it came as a tensor. A tensor must have a floating dtype (``TypeError`` otherwise, as
    everywhere in the torch API); other inputs follow scikit-learn (integers become float64).
    """
    if isinstance(X, torch.Tensor):
        check_floating(X, "X")
        X = X.detach().cpu().numpy()
        is_tensor = True
    else:
        is_tensor = False
    X = validate_data(
        estimator, X, reset=reset, dtype=[np.float64, np.float32], ensure_min_samples=2 if reset else 1
    )
    return X, is_tensor


def _as_tensor(X: object, validated: np.ndarray, is_tensor: bool) -> torch.Tensor:
    # the caller's tensor itself (its dtype and autograd graph), or the validated array as one
    return X if is_tensor else torch.from_numpy(validated)


def _returned(result: torch.Tensor, is_tensor: bool) -> torch.Tensor | np.ndarray:
    return result if is_tensor else result.numpy()


def _scale(features: torch.Tensor, mean: torch.Tensor, scale: torch.Tensor) -> torch.Tensor:
    """``(features - mean) / scale`` in the features' dtype."""
    return (features - mean.to(features.dtype)) / scale.to(features.dtype)


class ScaleFeatures(nn.Module):
    """The torch form of a fitted :class:`FeatureScaler`: ``(features - mean) / scale``, ``(B, F)``.

    Parameters
    ----------
    mean, scale : Tensor, shape ``(F,)``
        Stored as buffers (so they travel with ``state_dict`` and into an ONNX export); the input's
        dtype is kept.

    Examples
    --------
    >>> ScaleFeatures(torch.zeros(2), torch.tensor([2.0, 4.0]))(torch.ones(1, 2))
    tensor([[0.5000, 0.2500]])
    """

    def __init__(self, mean: torch.Tensor, scale: torch.Tensor) -> None:
        super().__init__()
        self.register_buffer("mean", torch.as_tensor(mean))
        self.register_buffer("scale", torch.as_tensor(scale))

    def forward(self, features: torch.Tensor) -> torch.Tensor:
        return _scale(features, self.mean, self.scale)


class FeatureScaler(OneToOneFeatureMixin, TransformerMixin, BaseEstimator):
    """Scales each feature to unit standard deviation, with the scale fitted on training features.

    ``transform(X) = (X - mean_) / scale_``; ``scale_`` is the per-feature standard deviation of the
    training features (``ddof=1``), ``mean_`` their mean if ``center=True`` else 0 (the study scales
    without centring; an RBF kernel does not care). A feature that is constant in the training data
    gets ``scale_ = 1`` (as scikit-learn's ``StandardScaler``), so nothing is divided by zero.

    A scikit-learn transformer (``clone``, pipelines, ``get_params``); ``transform`` takes a tensor
    (returned as a tensor of its dtype, differentiable) or an array (returned as an array).
    :meth:`to_module` gives the fitted scaling as a torch module for the exported inference graph.

    Parameters
    ----------
    center : bool, default False
        Also subtract the training mean.

    Attributes
    ----------
    scale_ : ndarray of shape (n_features_in_,)
        The fitted standard deviations (1 for constant features), float64.
    mean_ : ndarray of shape (n_features_in_,)
        The fitted means, or zeros, float64.
    n_features_in_ : int
        Number of features seen in ``fit``.

    Examples
    --------
    >>> scaler = FeatureScaler().fit(torch.randn(100, 21) * 5)
    >>> scaler.transform(torch.randn(4, 21)).shape
    torch.Size([4, 21])
    >>> scaler.to_module()(torch.randn(4, 21)).shape
    torch.Size([4, 21])
    """

    _parameter_constraints: ClassVar[dict] = {"center": ["boolean"]}

    def __init__(self, center: bool = False) -> None:
        self.center = center

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X, y=None) -> FeatureScaler:
        """Fit the scale on ``X`` ``(n, F)``, ``n >= 2`` finite rows (tensor or array); return ``self``."""
        X, _ = _validate_features(self, X, reset=True)
        X = X.astype(np.float64, copy=False)
        std = X.std(axis=0, ddof=1)
        self.scale_ = np.where(std > 0, std, 1.0)
        self.mean_ = X.mean(axis=0) if self.center else np.zeros_like(std)
        return self

    def transform(self, X):
        """Return ``(X - mean_) / scale_``, shape ``(B, F)``: a tensor for a tensor, else an array."""
        check_is_fitted(self)
        validated, is_tensor = _validate_features(self, X, reset=False)
        x = _as_tensor(X, validated, is_tensor)
        return _returned(_scale(x, torch.from_numpy(self.mean_), torch.from_numpy(self.scale_)), is_tensor)

    def to_module(self) -> ScaleFeatures:
        """Return the fitted scaling as a :class:`ScaleFeatures` module (float64 buffers)."""
        check_is_fitted(self)
        return ScaleFeatures(torch.tensor(self.mean_), torch.tensor(self.scale_))

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.transformer_tags.preserves_dtype = ["float64", "float32"]
        return tags


def _project(
    features: torch.Tensor,
    mean: torch.Tensor,
    scale: torch.Tensor,
    components: torch.Tensor,
    *,
    eps: float,
    window: bool,
) -> torch.Tensor:
    """``((map(features) - mean) / scale) @ components.T`` in the features' dtype; ``map`` is
    :func:`clustering_features` if ``window``, else the identity."""
    x = clustering_features(features, eps=eps) if window else features
    return _scale(x, mean, scale) @ components.to(x.dtype).T


class ClusteringProjection(nn.Module):
    """The torch form of a fitted :class:`ClusteringTransform`: ``(B, 21)`` → ``(B, n_components)``.

    Parameters
    ----------
    mean, scale : Tensor, shape ``(D,)``
        Standardisation of the mapped features (buffers).
    components : Tensor, shape ``(n_components, D)``
        Principal axes (buffer).
    eps : float, default 1e-6
        Offset of :func:`clustering_features`.
    features : {"window", "passthrough"}, default "window"
        As in :class:`ClusteringTransform`.
    """

    def __init__(
        self,
        mean: torch.Tensor,
        scale: torch.Tensor,
        components: torch.Tensor,
        *,
        eps: float = 1e-6,
        features: str = "window",
    ) -> None:
        super().__init__()
        self.register_buffer("mean", torch.as_tensor(mean))
        self.register_buffer("scale", torch.as_tensor(scale))
        self.register_buffer("components", torch.as_tensor(components))
        self.eps = eps
        self.features = features

    def forward(self, features: torch.Tensor) -> torch.Tensor:
        return _project(
            features, self.mean, self.scale, self.components, eps=self.eps, window=self.features == "window"
        )

    def extra_repr(self) -> str:
        return f"n_components={self.components.shape[0]}, eps={self.eps}, features={self.features!r}"


class ClusteringTransform(ClassNamePrefixFeaturesOutMixin, TransformerMixin, BaseEstimator):
    """The unsupervised transform: 21 window features → ``n_components`` principal components.

    ``transform(X) = ((clustering_features(X) - mean_) / scale_) @ components_.T``: the 12 features
    of :func:`clustering_features`, standardised (if ``standardize``; ``ddof=1``, constant columns
    scale 1) with training statistics, projected on the leading principal axes of the training data.
    Components are the right singular vectors of the centred (standardised) training matrix, signed
    so that the largest-magnitude loading of each is positive (scikit-learn's ``svd_flip``
    convention), so a fit is reproducible.

    A scikit-learn transformer; ``transform`` takes a tensor (returned as a tensor of its dtype,
    differentiable) or an array (returned as an array). :meth:`to_module` gives the fitted projection
    as a torch module for the exported inference graph.

    Parameters
    ----------
    n_components : int, default 3
        Number of principal components, at most the number of mapped features (12 for window
        features) and of training rows.
    standardize : bool, default True
        Scale the mapped features to unit variance before the PCA (they mix g, log g and log counts).
    eps : float, default 1e-6
        Offset in the logarithms (see :func:`clustering_features`), > 0.
    features : {"window", "passthrough"}, default "window"
        ``"window"``: ``X`` holds the 21 features of :func:`window_features` and is mapped by
        :func:`clustering_features` first (the study's unsupervised path). ``"passthrough"``: the
        columns of ``X`` are standardised and projected as they are (features of another kind).

    Attributes
    ----------
    mean_, scale_ : ndarray of shape (D,)
        Training mean and standard deviation of the mapped features (scale 1 if not
        ``standardize``), float64; ``D = 12`` for window features.
    components_ : ndarray of shape (n_components, D)
        Principal axes, float64.
    explained_variance_ : ndarray of shape (n_components,)
        Variance of the training data along each axis (``ddof=1``).
    explained_variance_ratio_ : ndarray of shape (n_components,)
        Its share of the total variance.
    n_features_in_ : int
        Number of features seen in ``fit`` (21 for window features).

    Examples
    --------
    >>> from tactile_torch.signal import window_features
    >>> feats = window_features(torch.randn(50, 3, 200))
    >>> ClusteringTransform(n_components=3).fit_transform(feats).shape
    torch.Size([50, 3])
    """

    _parameter_constraints: ClassVar[dict] = {
        "n_components": [Interval(Integral, 1, None, closed="left")],
        "standardize": ["boolean"],
        "eps": [Interval(Real, 0, None, closed="neither")],
        "features": [StrOptions({"window", "passthrough"})],
    }

    def __init__(
        self, n_components: int = 3, *, standardize: bool = True, eps: float = 1e-6, features: str = "window"
    ) -> None:
        self.n_components = n_components
        self.standardize = standardize
        self.eps = eps
        self.features = features

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X, y=None) -> ClusteringTransform:
        """Fit the standardisation and the PCA on ``X`` ``(n, 21)`` (or ``(n, D)``), ``n >= 2``; return
        ``self``."""
        X, _ = _validate_features(self, X, reset=True)
        x = torch.from_numpy(X.astype(np.float64, copy=False))
        if self.features == "window":
            if X.shape[1] != len(FEATURE_NAMES):
                raise ValueError(
                    f"X must hold the {len(FEATURE_NAMES)} window features (features='window'), got "
                    f"shape {X.shape}; use features='passthrough' for other features"
                )
            x = clustering_features(x, eps=self.eps)
        most = min(x.shape)
        if self.n_components > most:
            raise ValueError(
                f"n_components must be <= min(n_samples, n_features) = {most} (after the feature map), "
                f"got {self.n_components}"
            )
        mean = x.mean(0)
        std = x.std(0, correction=1)
        scale = torch.where(std > 0, std, torch.ones_like(std)) if self.standardize else torch.ones_like(std)
        _, sing, vh = torch.linalg.svd((x - mean) / scale, full_matrices=False)
        vh = vh[: self.n_components]
        sign = torch.sign(vh.gather(1, vh.abs().argmax(1, keepdim=True)))
        variance = sing**2 / (x.shape[0] - 1)
        total = variance.sum()
        self.mean_ = mean.numpy()
        self.scale_ = scale.numpy()
        self.components_ = (vh * sign).numpy()
        self.explained_variance_ = variance[: self.n_components].numpy()
        # all-constant training data: no variance to share
        ratio = variance[: self.n_components] / total if total > 0 else torch.zeros(self.n_components)
        self.explained_variance_ratio_ = ratio.numpy()
        self._n_features_out = self.n_components
        return self

    def transform(self, X):
        """Return the principal components of ``X`` ``(B, 21)`` → ``(B, n_components)``: a tensor for
        a tensor, else an array."""
        check_is_fitted(self)
        validated, is_tensor = _validate_features(self, X, reset=False)
        if self.features == "window":
            _check_window_features(validated, "X")
        x = _as_tensor(X, validated, is_tensor)
        mean, scale, components = (torch.from_numpy(a) for a in (self.mean_, self.scale_, self.components_))
        projected = _project(x, mean, scale, components, eps=self.eps, window=self.features == "window")
        return _returned(projected, is_tensor)

    def to_module(self) -> ClusteringProjection:
        """Return the fitted projection as a :class:`ClusteringProjection` module (float64 buffers)."""
        check_is_fitted(self)
        mean, scale, components = (torch.tensor(a) for a in (self.mean_, self.scale_, self.components_))
        return ClusteringProjection(mean, scale, components, eps=self.eps, features=self.features)

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.transformer_tags.preserves_dtype = ["float64", "float32"]
        return tags


def fit_clustering_transform(features, n_components: int = 3, *, fit_rows=None):
    """Return ``(transform, components)``: a :class:`ClusteringTransform` fitted on the rows ``fit_rows`` of
    window ``features`` (every row by default) and the components of every row, a float64 array.

    The one recipe "window features -> principal components" of the unsupervised path (``cluster``, the
    default bundles and the clustering, novelty and feature sections).

    Parameters
    ----------
    features : tensor or array of shape (n, 21)
        :func:`window_features` of the windows.
    n_components : int, default 3
    fit_rows : boolean mask or indices, optional
        The rows the transform is fitted on (the training part); all of them by default.

    Returns
    -------
    transform : ClusteringTransform
    components : ndarray of shape (n, n_components)

    Examples
    --------
    >>> from tactile_torch.signal import window_features
    >>> feats = window_features(torch.randn(40, 3, 200, dtype=torch.float64))
    >>> transform, X = fit_clustering_transform(feats, 3, fit_rows=np.arange(30))
    >>> X.shape, transform.n_features_in_
    ((40, 3), 21)
    """
    fitted_on = features if fit_rows is None else features[_row_index(features, fit_rows)]
    transform = ClusteringTransform(n_components=n_components).fit(fitted_on)
    return transform, np.asarray(transform.transform(features))


def _row_index(features, rows):
    return torch.as_tensor(rows) if isinstance(features, torch.Tensor) else np.asarray(rows)
