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
3. The threshold is the :data:`DEFAULT_QUANTILE` (99.5 %) quantile of ``d`` over the training
   windows, each measured against statistics fitted without it (5 folds: in-sample distances are
   too short when the training set is small). :class:`tactile_torch.robot.runtime.OnnxPipeline` labels a sample beyond it ``-1``
   ("unknown"), with the reason.

Measured (``tests/test_pipeline.py``, ``docs/export.md``) on the windows of
:func:`out_of_distribution_signals`, the one generator of signals no surface gives: at most 1 % of held-in windows unknown;
zeros, constants, white noise, pure tones and square waves unknown in at least 99 % of windows on
the synthetic surfaces; on real IMU recordings the square waves and low-amplitude noise are
data-dependent (terrain vibration looks like noise).

References
----------
K. Lee, K. Lee, H. Lee and J. Shin, "A simple unified framework for detecting out-of-distribution
samples and adversarial attacks," NeurIPS 2018.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torch import nn

from .robot.checks import check_count, check_positive, numpy_rng
from .robot.contract import LABELS_OUTPUT, OOD_OUTPUT, SCORES_OUTPUT

DEFAULT_QUANTILE = 0.995
"""Share of the training windows whose distance lies within the threshold."""
RIDGE = 1e-3
"""Ridge added to the pooled covariance, relative to its mean variance."""
FOLDS = 5
"""The threshold is calibrated on out-of-fold distances of this many folds."""
OUT_OF_DISTRIBUTION_KINDS = (
    "zeros",
    "constant",
    "constant 1 g",
    "white noise 4.9 g",
    "white noise sd 0.01 g",
    "white noise sd 0.1 g",
    "white noise sd 1 g",
    "pure tone",
    "square wave",
)
"""Signals of :func:`out_of_distribution_signals`, in the order they are drawn."""


def out_of_distribution_signals(
    n: int,
    window: int,
    rate_hz: float,
    random_state: object = None,
    *,
    kinds: Sequence[str] | None = None,
) -> dict[str, np.ndarray]:
    """Return ``n`` vibration windows ``(n, 3, window)`` float32 of each signal no surface gives, by kind.

    The kinds (:data:`OUT_OF_DISTRIBUTION_KINDS`): ``"zeros"``; ``"constant"`` (each axis constant,
    uniform in [-4, 4] g) and ``"constant 1 g"`` (0, 0, 1 g: a sensor at rest), as a stuck sensor
    gives; white noise uniform in ±4.9 g, and Gaussian of sd 0.01, 0.1 and 1 g (the last clipped to
    ±5 g); a ``"pure tone"`` and a ``"square wave"`` of one frequency per window, uniform in
    [5, rate_hz / 2.2] Hz, an amplitude uniform in [0.05, 4] g and a phase per axis. The tones'
    frequencies, phases and amplitudes are drawn first, then each selected kind in the order above;
    a kind left out draws nothing, so a kind's windows depend only on the seed and the kinds before it.

    Parameters
    ----------
    n : int
        Windows of each kind (>= 1).
    window : int
        Samples per window (>= 1).
    rate_hz : float
        Sample rate in Hz (> 0): sets the tones' time axis and top frequency.
    random_state : int, numpy or torch generator, or None
        Source of randomness; a ``numpy.random.Generator`` is drawn from as is.
    kinds : sequence of str, optional
        The kinds to return, in the order given (default: all of :data:`OUT_OF_DISTRIBUTION_KINDS`).

    Examples
    --------
    >>> signals = out_of_distribution_signals(2, 8, 100.0, random_state=0, kinds=["zeros", "pure tone"])
    >>> {kind: x.shape for kind, x in signals.items()}
    {'zeros': (2, 3, 8), 'pure tone': (2, 3, 8)}
    """
    n = check_count(n, "n", 1)
    window = check_count(window, "window", 1)
    check_positive(rate_hz, "rate_hz")
    selected = OUT_OF_DISTRIBUTION_KINDS if kinds is None else tuple(kinds)
    unknown = [kind for kind in selected if kind not in OUT_OF_DISTRIBUTION_KINDS]
    if unknown or not selected:
        raise ValueError(
            f"kinds must be a non-empty list of {list(OUT_OF_DISTRIBUTION_KINDS)}, got {kinds!r}"
        )
    rng = numpy_rng(random_state)
    t = np.arange(window) / rate_hz
    freq = rng.uniform(5, rate_hz / 2.2, (n, 1, 1))
    phase = rng.uniform(0, 2 * np.pi, (n, 3, 1))
    amp = rng.uniform(0.05, 4, (n, 1, 1))
    shape = (n, 3, window)
    draw = {
        "zeros": lambda: np.zeros(shape),
        "constant": lambda: np.zeros(shape) + rng.uniform(-4, 4, (n, 3, 1)),
        "constant 1 g": lambda: np.zeros(shape) + np.array([0.0, 0.0, 1.0])[:, None],
        "white noise 4.9 g": lambda: rng.uniform(-4.9, 4.9, shape),
        "white noise sd 0.01 g": lambda: rng.normal(0, 0.01, shape),
        "white noise sd 0.1 g": lambda: rng.normal(0, 0.1, shape),
        "white noise sd 1 g": lambda: rng.normal(0, 1.0, shape).clip(-5, 5),
        "pure tone": lambda: amp * np.sin(2 * np.pi * freq * t + phase),
        "square wave": lambda: amp * np.sign(np.sin(2 * np.pi * freq * t + phase)),
    }
    wanted = set(selected)
    signals = {kind: draw[kind]().astype(np.float32) for kind in OUT_OF_DISTRIBUTION_KINDS if kind in wanted}
    return {kind: signals[kind] for kind in selected}


def signed_log(z: np.ndarray) -> np.ndarray:
    """Return ``sign(z) * log1p(|z|)`` elementwise (same shape), the space the distance is measured in."""
    return np.sign(z) * np.log1p(np.abs(z))


def fit_ood(
    features: np.ndarray, labels: np.ndarray, *, quantile: float = DEFAULT_QUANTILE
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

    Returns
    -------
    dict
        ``means`` ``(C, F)``, ``precision_cholesky`` ``(F, F)`` (``L`` with ``L L^T = S^-1``) and
        ``threshold`` (a 0-d array), float64.
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
    means, precision_cholesky = _gaussian(features, labels, len(classes))
    # Calibrate on distances of rows the statistics were not fitted on: in-sample distances are
    # too short when the training set is small next to the F^2 covariance entries (5 folds, the
    # rows of each class dealt to the folds in turn: deterministic).
    fold = np.empty(len(labels), dtype=np.int64)
    for c in classes:
        rows = np.flatnonzero(labels == c)
        fold[rows] = np.arange(len(rows)) % FOLDS
    distance = np.empty(len(labels))
    for k in range(FOLDS):
        held = fold == k
        if not held.any():
            continue
        fit = ~held
        present = np.unique(labels[fit])
        if len(present) < len(classes):  # a class too small to leave out: in-sample for it
            fit = np.ones_like(held)
        m, chol = _gaussian(features[fit], labels[fit], len(classes))
        distance[held] = ood_distance(features[held], m, chol)
    threshold = np.float64(np.quantile(distance, quantile))
    return {"means": means, "precision_cholesky": precision_cholesky, "threshold": np.asarray(threshold)}


def _gaussian(features: np.ndarray, labels: np.ndarray, n_classes: int) -> tuple[np.ndarray, np.ndarray]:
    """Class means ``(C, F)`` and the tied precision's Cholesky factor ``(F, F)`` in the signed-log space."""
    u = signed_log(features)
    means = np.stack([u[labels == c].mean(axis=0) for c in range(n_classes)])
    residual = u - means[labels]
    cov = residual.T @ residual / max(len(u) - n_classes, 1)
    cov += RIDGE * max(float(np.trace(cov)) / len(cov), 1e-12) * np.eye(len(cov))
    return means, np.linalg.cholesky(np.linalg.inv(cov))


def ood_distance(features: np.ndarray, means: np.ndarray, precision_cholesky: np.ndarray) -> np.ndarray:
    """Return the distance of each row of standardised ``features`` ``(B, F)`` to the training classes, ``(B,)``."""
    u = signed_log(np.asarray(features, dtype=np.float64))
    diff = (u[:, None, :] - means[None]) @ precision_cholesky  # (B, C, F)
    return np.sqrt((diff**2).sum(axis=-1).min(axis=1))


class MahalanobisDistance(nn.Module):
    """Standardised features ``(B, F)`` → the distance ``(B,)`` of :func:`ood_distance`, as a graph.

    Parameters
    ----------
    means : array (C, F)
    precision_cholesky : array (F, F)
    """

    def __init__(self, means: object, precision_cholesky: object) -> None:
        super().__init__()
        self.register_buffer("means", torch.as_tensor(np.asarray(means), dtype=torch.float32).clone())
        self.register_buffer(
            "precision_cholesky", torch.as_tensor(np.asarray(precision_cholesky), dtype=torch.float32).clone()
        )

    def forward(self, features: torch.Tensor) -> torch.Tensor:
        z = features.to(torch.float32)
        u = torch.sign(z) * torch.log1p(torch.abs(z))
        diff = torch.matmul(u.unsqueeze(1) - self.means.unsqueeze(0), self.precision_cholesky)
        return torch.sqrt(torch.amin((diff * diff).sum(dim=-1), dim=1))


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


__all__ = [
    "DEFAULT_QUANTILE",
    "OUT_OF_DISTRIBUTION_KINDS",
    "MahalanobisDistance",
    "WithDistance",
    "fit_ood",
    "ood_distance",
    "out_of_distribution_signals",
    "signed_log",
]
