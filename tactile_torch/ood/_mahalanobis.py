"""An out-of-distribution score for exported classifiers: how far a sample's features are from training.

A classifier always answers with one of its classes; fed zeros, a constant, white noise or a pure
tone it still names a surface, and its scores need not say anything is wrong. Every classifier model
file therefore carries, beside its head, the statistics of a **class-conditional Mahalanobis
distance** of its standardised features to the training data (Lee et al. 2018, with a tied
covariance), and every exported graph computes it as a third output, ``ood_distance``:

1. ``u = sign(z) * log(1 + |z|)`` of the standardised features ``z = x / scale`` (the features the
   head takes). Variance, total variation and spectral energy span orders of magnitude between
   surfaces; the signed log makes their spread comparable before a Gaussian model is fitted.
2. ``d(u) = min_c sqrt((u - mu_c)^T S^-1 (u - mu_c))``: ``mu_c`` the training mean of class ``c``,
   ``S`` the pooled within-class covariance plus a ridge of ``1e-3`` times its mean variance (so a
   feature that never varied in training cannot make ``S`` singular).
3. A second view (model files of this version; older ones have only the first) measures the same distance in
   ``u' = sign(z) * log(1 + |z| / f)``, ``f`` the 5th training percentile of a feature that is never
   negative in training (1 for the others, :func:`log_floor`): in the first view every value far
   below a feature's scale is about 0, so a sensor at rest (a tenth of the smoothest surface's
   variance) sits next to the smoothest surface; in the second it lies far from every one. The
   distance is the larger of the two, each divided by its 99.5 % training quantile (``norm``).
4. The threshold is the :data:`DEFAULT_QUANTILE` (99.5 %) quantile of ``d`` over the training
   windows, each measured against statistics fitted without it (5 folds: in-sample distances are
   too short when the training set is small). :class:`tactile_torch.robot.runtime.OnnxPipeline` labels a sample beyond it ``-1``
   ("unknown"), with the reason.

**One rule for every deployable graph.** :func:`fit_rule` fits it (on the features of every training
sample, standardised as the graph standardises them) for every path that writes a deployable file:
``tactile-torch train --out`` (:func:`tactile_torch.training.save_model`, then ``export``) and
``tactile-torch tradeoff``'s deployed models (:mod:`tactile_torch.tradeoff.deploy`): classical, neural,
int8, and re-exported from ``recommended.npz``. Which features: a classical model's own (its features,
selected columns and standardisation: the features its head takes); a learned model (a network, a
learned front end) on its embedding, the input of its last linear layer, as Lee et al. measure it on a
network's penultimate layer, standardised on the training data. A model file carries the rule as its
``ood`` part (the graph built from it computes the distance inside the head, :class:`WithDistance`);
the trade-off's bundles get it as a float part reading the tensor it is measured on
(:func:`tactile_torch.export.ood_branch.attach_distance`): it costs a few small matrix products, not a
second pass over the raw input, and stays in float in an int8 file.

Measured (``tests/export/test_model_graph.py``, ``docs/export.md``) on the windows of
:func:`tactile_torch.data.out_of_distribution.out_of_distribution_signals`, the one generator of signals no surface gives: at most 1 % of held-in windows unknown;
zeros, constants, white noise, pure tones, square waves and a still sensor unknown in at least 99 % of
windows on the synthetic surfaces; on real IMU recordings quiet input (a still sensor, low-amplitude
noise) and some tones are data-dependent (terrain vibration looks like noise, robots stand still).

References
----------
K. Lee, K. Lee, H. Lee and J. Shin, "A simple unified framework for detecting out-of-distribution
samples and adversarial attacks," NeurIPS 2018.
"""

from __future__ import annotations

from numbers import Real
from typing import ClassVar

import numpy as np
import torch
from sklearn.base import BaseEstimator, OutlierMixin, _fit_context
from sklearn.utils._param_validation import Interval
from sklearn.utils.validation import check_is_fitted, validate_data
from torch import nn

from ..robot.contract import LABELS_OUTPUT, OOD_OUTPUT, SCORES_OUTPUT

DEFAULT_QUANTILE = 0.995
"""Share of the training windows whose distance lies within the threshold."""
RIDGE = 1e-3
"""Ridge added to the pooled covariance, relative to its mean variance."""
FOLDS = 5
"""The threshold is calibrated on out-of-fold distances of this many folds."""


def signed_log(z: np.ndarray, floor: np.ndarray | float = 1.0) -> np.ndarray:
    """Return ``sign(z) * log1p(|z| / floor)`` elementwise (same shape), the space the distance is measured in.

    ``floor`` (per feature, broadcast along the last axis): below it the map is about linear, above it
    logarithmic (the second view's, :func:`log_floor`)."""
    return np.sign(z) * np.log1p(np.abs(z) / floor)


LOG_FLOOR_QUANTILE = 0.05
"""The second view compares a never-negative feature on a log scale down to this training quantile of it
(:func:`log_floor`)."""


def log_floor(features: np.ndarray) -> np.ndarray:
    """Return the per-feature ``floor`` of :func:`signed_log`'s second view for training ``features`` ``(N, F)``.

    A feature that is never negative in training (a variance, total variation, crossing count, spectral
    energy, gradient magnitude) gets its :data:`LOG_FLOOR_QUANTILE` training quantile (or its smallest
    positive value when that is 0): below it ``log(1 + z / floor)`` keeps falling on a log scale, so a
    sensor at rest, whose variance is a tenth of the smoothest surface's, lies far from every surface. A
    feature of both signs (a skewness) keeps 1 (one training standard deviation): a log of values near 0
    of either sign would split one cluster in two.
    """
    features = np.asarray(features, dtype=np.float64)
    floor = np.ones(features.shape[1])
    for j in np.flatnonzero((features >= 0).all(axis=0)):
        column = features[:, j]
        low = np.quantile(column, LOG_FLOOR_QUANTILE)
        low = low if low > 0 else column[column > 0].min(initial=0.0)
        if low > 0:
            floor[j] = low
    return floor


def _out_of_fold(u: np.ndarray, labels: np.ndarray, n_classes: int) -> np.ndarray:
    """Distances of rows measured against statistics fitted without them (5 folds, deterministic)."""
    fold = np.empty(len(labels), dtype=np.int64)
    for c in range(n_classes):
        rows = np.flatnonzero(labels == c)
        fold[rows] = np.arange(len(rows)) % FOLDS
    distance = np.empty(len(labels))
    for k in range(FOLDS):
        held = fold == k
        if not held.any():
            continue
        fit = ~held
        if len(np.unique(labels[fit])) < n_classes:  # a class too small to leave out: in-sample for it
            fit = np.ones_like(held)
        m, chol = _gaussian(u[fit], labels[fit], n_classes)
        distance[held] = _distance(u[held], m, chol)
    return distance


def fit_ood(
    features: np.ndarray,
    labels: np.ndarray,
    *,
    quantile: float = DEFAULT_QUANTILE,
    floor: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """Return the distance's statistics fitted on standardised training features.

    Parameters
    ----------
    features : ndarray of shape (N, F)
        Training features divided by the model's ``scale`` (what the head takes).
    labels : ndarray of shape (N,)
        Class index of each row, ``0 .. C - 1`` (every class present).
    quantile : float, default 0.995
        The threshold is this quantile of the training rows' distances.
    floor : ndarray of shape (F,), optional
        A second view (:func:`log_floor`): then the distance is the larger of the two views' distances,
        each divided by its own ``quantile`` of the training rows' distances (``norm``).

    Returns
    -------
    dict
        ``means`` ``(C, F)``, ``precision_cholesky`` ``(F, F)`` (``L`` with ``L L^T = S^-1``) and
        ``threshold`` (a 0-d array), float64; with ``floor`` also ``floor``, ``log_means``,
        ``log_precision_cholesky`` and ``norm`` ``(2,)``.
    """
    features = np.asarray(features, dtype=np.float64)
    labels = np.asarray(labels)
    if features.ndim != 2 or labels.shape != (len(features),):
        raise ValueError(f"features must be (N, F) with labels (N,), got {features.shape} and {labels.shape}")
    if not 0.5 <= quantile <= 1.0:
        raise ValueError(f"quantile must be in [0.5, 1], got {quantile!r}")
    classes = np.unique(labels)
    if len(classes) == 0 or classes[0] != 0 or classes[-1] != len(classes) - 1:
        raise ValueError(f"labels must hold every class 0..C-1, got {classes.tolist()}")
    # Calibrate on distances of rows the statistics were not fitted on: in-sample distances are
    # too short when the training set is small next to the F^2 covariance entries.
    u = signed_log(features)
    means, precision_cholesky = _gaussian(u, labels, len(classes))
    distance = _out_of_fold(u, labels, len(classes))
    state = {"means": means, "precision_cholesky": precision_cholesky}
    if floor is not None:
        floor = np.asarray(floor, dtype=np.float64)
        low = signed_log(features, floor)
        state["log_means"], state["log_precision_cholesky"] = _gaussian(low, labels, len(classes))
        views = np.stack([distance, _out_of_fold(low, labels, len(classes))])
        norm = np.quantile(views, quantile, axis=1)
        norm = np.where(norm > 0, norm, 1.0)
        distance = (views / norm[:, None]).max(axis=0)
        state.update(floor=floor, norm=norm)
    threshold = float(np.quantile(distance, quantile))
    if not threshold > 0:  # every training row at one point (features that never varied): a degenerate rule
        import warnings

        threshold = float(np.finfo(np.float32).tiny)
        warnings.warn(
            "the training features lie at one point (they do not vary between the training samples), so the "
            "'unknown' rule answers unknown to any other input; train on features that vary (per-taxel features "
            "on a small array)",
            stacklevel=3,
        )
    state["threshold"] = np.asarray(np.float64(threshold))
    return state


def fit_rule(
    features: np.ndarray,
    labels: np.ndarray,
    *,
    scale: np.ndarray,
    center: np.ndarray | None = None,
    quantile: float = DEFAULT_QUANTILE,
) -> dict[str, np.ndarray | float]:
    """Return the "unknown" rule fitted on a model's training features, as every deployed graph carries it.

    The distance is measured on ``z = features / scale`` in two views (:func:`signed_log` with floor 1,
    and with the floors of :func:`log_floor`); a graph that feeds it centred features
    ``(features - center) / scale`` adds ``offset = center / scale`` back first.

    Parameters
    ----------
    features : ndarray of shape (N, F)
        The training features the model's head takes, before its standardisation (after any column
        selection): every training sample.
    labels : array of shape (N,)
        Each row's class, any labels (encoded here in sorted order, as ``classes_`` are).
    scale, center : ndarray of shape (F,)
        The standardisation the graph applies, ``(features - center) / scale`` (``center`` 0 if ``None``).
    quantile : float

    Returns
    -------
    dict
        :func:`fit_ood`'s arrays and ``threshold``, the ``offset`` ``(F,)`` and the ``quantile``: what a
        model file's ``ood`` part holds and :class:`DistanceHead` takes.
    """
    features = np.asarray(features, dtype=np.float64)
    scale = np.asarray(scale, dtype=np.float64)
    state = MahalanobisNovelty(quantile=quantile).fit(features / scale, labels).state()
    offset = np.zeros(len(scale)) if center is None else np.asarray(center, dtype=np.float64) / scale
    return {**state, "offset": offset, "quantile": float(quantile)}


_STATE_KEYS = ("means", "precision_cholesky", "log_means", "log_precision_cholesky", "floor", "norm")


class MahalanobisNovelty(OutlierMixin, BaseEstimator):
    """The "unknown" rule as a scikit-learn novelty detector: class-conditional Mahalanobis distance.

    Shaped as scikit-learn's :class:`~sklearn.covariance.EllipticEnvelope`: ``fit`` learns the class
    means and the tied covariance of the signed-log features (:func:`signed_log`; two views with
    ``two_views``, the second's floors from :func:`log_floor` of the training features) and the
    ``quantile`` of the training rows' out-of-fold distances (:func:`fit_ood`, the module notes);
    :meth:`mahalanobis` is the distance, :meth:`score_samples` its negative, :meth:`decision_function`
    ``score_samples - offset_`` (``offset_ = -threshold_``: >= 0 within the threshold) and
    :meth:`predict` ``1`` for a known sample, ``-1`` for an unknown one.

    Parameters
    ----------
    quantile : float in [0.5, 1], default 0.995
        Share of the training rows (out of fold) within the threshold.
    two_views : bool, default True
        Also measure the distance on the floored log scale (what every deployed graph does).

    Attributes
    ----------
    classes_ : ndarray of shape (C,)
        The labels ``fit`` saw (one class, 0, when fitted without ``y``).
    means_ : ndarray of shape (C, F)
    precision_cholesky_ : ndarray of shape (F, F)
        ``L`` with ``L L^T = S^-1``, ``S`` the pooled within-class covariance plus the ridge.
    floor_, log_means_, log_precision_cholesky_, norm_ : ndarray
        The second view's (``two_views``); else ``None``.
    threshold_ : float
        The distance beyond which a sample is unknown.
    offset_ : float
        ``-threshold_`` (scikit-learn's convention: ``decision_function = score_samples - offset_``).
    n_features_in_ : int

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> X, y = rng.normal(size=(200, 4)), np.repeat([0, 1], 100)
    >>> rule = MahalanobisNovelty().fit(X, y)
    >>> rule.predict(np.vstack([X[:3], [[50.0, 50.0, 50.0, 50.0]]])).tolist()
    [1, 1, 1, -1]

    References
    ----------
    K. Lee, K. Lee, H. Lee and J. Shin, "A simple unified framework for detecting out-of-distribution
    samples and adversarial attacks," NeurIPS 2018.
    """

    _parameter_constraints: ClassVar[dict] = {
        "quantile": [Interval(Real, 0.5, 1.0, closed="both")],
        "two_views": ["boolean"],
    }

    def __init__(self, quantile: float = DEFAULT_QUANTILE, *, two_views: bool = True) -> None:
        self.quantile = quantile
        self.two_views = two_views

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X: object, y: object = None) -> MahalanobisNovelty:
        """Fit on features ``X`` ``(N, F)`` (standardised as the classifier takes them) of classes ``y``
        (any labels; none: one class); return ``self``."""
        if y is None:
            X = validate_data(self, X, dtype=np.float64, ensure_min_samples=2)
            y = np.zeros(len(X), dtype=np.int64)
        else:
            X, y = validate_data(self, X, y, dtype=np.float64, ensure_min_samples=2)
        self.classes_, codes = np.unique(y, return_inverse=True)
        state = fit_ood(X, codes, quantile=self.quantile, floor=log_floor(X) if self.two_views else None)
        self.threshold_ = float(state.pop("threshold"))
        self.offset_ = -self.threshold_
        for key in _STATE_KEYS:
            setattr(self, f"{key}_", state.get(key))
        return self

    def state(self) -> dict[str, np.ndarray]:
        """Return the fitted arrays as :func:`fit_ood` returns them (a model file's ``ood`` part holds them)."""
        check_is_fitted(self)
        keys = _STATE_KEYS if self.floor_ is not None else _STATE_KEYS[:2]
        return {
            **{k: getattr(self, f"{k}_") for k in keys},
            "threshold": np.asarray(np.float64(self.threshold_)),
        }

    def mahalanobis(self, X: object) -> np.ndarray:
        """Return the distance of each row of ``X`` ``(B, F)`` to the training classes, ``(B,)``."""
        state = self.state()
        del state["threshold"]
        return ood_distance(validate_data(self, X, dtype=np.float64, reset=False), **state)

    def score_samples(self, X: object) -> np.ndarray:
        """Return minus the distance (higher: more like the training data), ``(B,)``."""
        return -self.mahalanobis(X)

    def decision_function(self, X: object) -> np.ndarray:
        """Return ``threshold_ - distance``: >= 0 for a known sample, ``(B,)``."""
        return self.score_samples(X) - self.offset_

    def predict(self, X: object) -> np.ndarray:
        """Return ``1`` (known) or ``-1`` (unknown) per row of ``X``, ``(B,)`` int64."""
        return np.where(self.decision_function(X) >= 0, 1, -1).astype(np.int64)


def _gaussian(u: np.ndarray, labels: np.ndarray, n_classes: int) -> tuple[np.ndarray, np.ndarray]:
    """Class means ``(C, F)`` and a factor ``L`` ``(F, F)`` of the tied precision (``L L^T = S^-1``) of
    signed-log features ``u``: ``L = C^-T`` for the covariance's Cholesky factor ``C`` (one factorisation
    and one triangular inverse, where inverting ``S`` first cost twice as much on 2400 features)."""
    from scipy.linalg import solve_triangular

    means = np.stack([u[labels == c].mean(axis=0) for c in range(n_classes)])
    residual = u - means[labels]
    cov = residual.T @ residual / max(len(u) - n_classes, 1)
    cov += RIDGE * max(float(np.trace(cov)) / len(cov), 1e-12) * np.eye(len(cov))
    factor = np.linalg.cholesky(cov)
    return means, solve_triangular(factor, np.eye(len(cov)), lower=True).T


def _distance(u: np.ndarray, means: np.ndarray, precision_cholesky: np.ndarray) -> np.ndarray:
    # (u - m_c) L = u L - m_c L: one (F, F) product per sample, not one per class
    diff = (u @ precision_cholesky)[:, None, :] - (means @ precision_cholesky)[None]  # (B, C, F)
    return np.sqrt((diff**2).sum(axis=-1).min(axis=1))


def ood_distance(
    features: np.ndarray,
    means: np.ndarray,
    precision_cholesky: np.ndarray,
    *,
    offset: np.ndarray | None = None,
    floor: np.ndarray | None = None,
    log_means: np.ndarray | None = None,
    log_precision_cholesky: np.ndarray | None = None,
    norm: np.ndarray | None = None,
) -> np.ndarray:
    """Return the distance of each row of standardised ``features`` ``(B, F)`` to the training classes, ``(B,)``.

    ``offset`` is added first (centred features back to ``x / scale``); with the second view's
    ``floor``, ``log_means``, ``log_precision_cholesky`` and ``norm`` (:func:`fit_ood`), the larger of
    the two views' normalised distances. Without them (model files written before the second view
    existed): the first view's distance."""
    z = np.asarray(features, dtype=np.float64) + (0.0 if offset is None else np.asarray(offset))
    distance = _distance(signed_log(z), means, precision_cholesky)
    if floor is None:
        return distance
    low = _distance(signed_log(z, np.asarray(floor)), log_means, log_precision_cholesky)
    return np.maximum(distance / norm[0], low / norm[1])


class MahalanobisDistance(nn.Module):
    """Standardised features ``(B, F)`` → the distance ``(B,)`` of :func:`ood_distance`, as a graph.

    Parameters
    ----------
    means : array (C, F)
    precision_cholesky : array (F, F)
    offset : array (F,), optional
    floor, log_means, log_precision_cholesky, norm : arrays, optional
        The second view (all or none), as in :func:`ood_distance`.
    """

    def __init__(
        self,
        means: object,
        precision_cholesky: object,
        *,
        offset: object = None,
        floor: object = None,
        log_means: object = None,
        log_precision_cholesky: object = None,
        norm: object = None,
    ) -> None:
        super().__init__()

        def buffer(name: str, value: object) -> None:
            self.register_buffer(name, torch.as_tensor(np.asarray(value), dtype=torch.float32).clone())

        n = np.asarray(means).shape[1]
        chol = np.asarray(precision_cholesky, dtype=np.float64)
        # (u - m_c) L = u L - m_c L: the class means are whitened once here, so that a sample costs one
        # (F, F) product instead of one per class (C times fewer operations in the graph).
        buffer("whitened_means", np.asarray(means, dtype=np.float64) @ chol)
        buffer("precision_cholesky", chol)
        buffer("offset", np.zeros(n) if offset is None else offset)
        self.views = 1 if floor is None else 2
        if self.views == 2:
            log_chol = np.asarray(log_precision_cholesky, dtype=np.float64)
            buffer("floor", floor)
            buffer("whitened_log_means", np.asarray(log_means, dtype=np.float64) @ log_chol)
            buffer("log_precision_cholesky", log_chol)
            buffer("norm", norm)

    @staticmethod
    def _distance(u: torch.Tensor, whitened_means: torch.Tensor, chol: torch.Tensor) -> torch.Tensor:
        diff = torch.matmul(u, chol).unsqueeze(1) - whitened_means.unsqueeze(0)  # (B, C, F)
        return torch.sqrt(torch.amin((diff * diff).sum(dim=-1), dim=1))

    def forward(self, features: torch.Tensor) -> torch.Tensor:
        z = features.to(torch.float32) + self.offset
        size = torch.abs(z)
        u = torch.sign(z) * torch.log1p(size)
        distance = self._distance(u, self.whitened_means, self.precision_cholesky)
        if self.views == 1:
            return distance
        low = torch.sign(z) * torch.log1p(size / self.floor)
        low = self._distance(low, self.whitened_log_means, self.log_precision_cholesky)
        return torch.maximum(distance / self.norm[0], low / self.norm[1])


class WithDistance(nn.Module):
    """A head ``features → (labels, scores)`` that also returns the features' :class:`MahalanobisDistance`.

    ``forward(features) → (labels, scores, ood_distance)``.
    """

    output_names = (LABELS_OUTPUT, SCORES_OUTPUT, OOD_OUTPUT)

    def __init__(self, head: nn.Module, distance: MahalanobisDistance) -> None:
        super().__init__()
        self.head = head
        self.distance = distance

    def forward(self, features: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        labels, scores = self.head(features)[:2]
        return labels, scores, self.distance(features)


OOD_ARRAYS = ("means", "precision_cholesky", "offset", "floor", "log_means", "log_precision_cholesky", "norm")
"""The arrays of a fitted rule (:func:`fit_rule`), as a model file's ``ood.<name>`` holds them."""


def distance_module(rule: dict) -> MahalanobisDistance:
    """Return the :class:`MahalanobisDistance` of a fitted rule (or a model file's ``ood`` part)."""
    return MahalanobisDistance(
        rule["means"], rule["precision_cholesky"], **{k: rule.get(k) for k in OOD_ARRAYS[2:]}
    )


class DistanceHead(nn.Module):
    """Features ``(B, F)`` → ``ood_distance`` ``(B,)``: column selection, standardisation and
    :class:`MahalanobisDistance`; the part :func:`tactile_torch.export.ood_branch.attach_distance` adds to a
    bundle, reading the tensor the distance is measured on (its features, or a network's embedding).

    Parameters
    ----------
    rule : dict
        :func:`fit_rule`'s result.
    scale, center : array (k,)
        The standardisation the rule was fitted under.
    select : array of int, optional
        Columns of the features kept (before standardisation); default: all ``k``. The selection is
        always in the graph (a buffer), so that heads with and without one share an exported structure.
    """

    def __init__(self, rule: dict, *, scale: object, center: object = None, select: object = None) -> None:
        super().__init__()
        from ..signal import ScaleFeatures

        scale = torch.as_tensor(np.asarray(scale, dtype=np.float32))
        center = (
            torch.zeros_like(scale)
            if center is None
            else torch.as_tensor(np.asarray(center, dtype=np.float32))
        )
        columns = np.arange(len(scale)) if select is None else np.asarray(select)
        self.register_buffer("select", torch.as_tensor(columns, dtype=torch.int64).clone())
        self.standardise = ScaleFeatures(center, scale)
        self.distance = distance_module(rule)

    def forward(self, features: torch.Tensor) -> torch.Tensor:
        return self.distance(self.standardise(features.index_select(1, self.select).to(torch.float32)))
