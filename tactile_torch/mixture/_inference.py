"""Torch inference of a fitted Gaussian mixture (exportable to ONNX): component scores and novelty."""

from __future__ import annotations

import math

import numpy as np
import torch

from ..robot.contract import LABELS_OUTPUT, NOVEL_OUTPUT, NOVELTY_SCORE_OUTPUT, SCORES_OUTPUT


def gaussian_mixture_scores(
    x: torch.Tensor, means: torch.Tensor, precisions_cholesky: torch.Tensor, log_weights: torch.Tensor
) -> torch.Tensor:
    """Return ``log w_k + log N(x | mean_k, (U_k U_k^T)^{-1})`` for every row and component: (B, K).

    Parameters
    ----------
    x : tensor (B, D)
    means : tensor (K, D)
    precisions_cholesky : tensor (K, D, D)
        ``U_k`` with precision ``U_k U_k^T`` (scikit-learn's ``precisions_cholesky_`` convention; any
        such factor works, triangular or not).
    log_weights : tensor (K,)

    Examples
    --------
    >>> s = gaussian_mixture_scores(torch.zeros(1, 2), torch.zeros(1, 2), torch.eye(2)[None], torch.zeros(1))
    >>> round(float(s), 4)  # log N(0 | 0, I) in 2-D = -log(2 pi)
    -1.8379
    """
    D = x.shape[-1]
    y = torch.einsum("bd,kde->bke", x, precisions_cholesky) - torch.einsum(
        "kd,kde->ke", means, precisions_cholesky
    )
    log_det = torch.log(torch.diagonal(precisions_cholesky, dim1=-2, dim2=-1).abs()).sum(-1)
    return log_weights + log_det - 0.5 * D * math.log(2 * math.pi) - 0.5 * (y * y).sum(-1)


class GaussianMixtureClassifier(torch.nn.Module):
    """Most likely component, and novelty: ``x (B, D) -> (labels (B,), log_resp (B, K), novel (B,), novelty (B,))``.

    Holds ``means`` (K, D), ``precisions_cholesky`` (K, D, D) and ``log_weights`` (K,) as buffers
    (float32 by default) and calls :func:`gaussian_mixture_scores`; exports to ONNX with a dynamic
    batch. ``log_resp`` are the log responsibilities over the K components (rows log-sum-exp to 0).

    ``novelty`` is minus the row's log density under the mixture (``-logsumexp`` of the scores), or,
    with ``density_means`` (M, F), ``density_precisions_cholesky`` (M, F, F) and
    ``density_log_weights`` (M,), under that mixture of every input column, while the components
    see the first ``cluster_features`` columns only (``x (B, F)``: e.g. 5 principal components, of
    which the first 3 are counted and clustered).
    ``novel``: with calibrated thresholds (``novelty_thresholds`` (N,), the thresholds of the mean
    ``novelty`` over N = 1, 2, ... windows; see
    :meth:`~tactile_torch.mixture.PitmanYorGMM.calibrate_novelty`), ``novelty >
    novelty_thresholds[0]``; without (shape (0,)), the model's own rule: True where a *new*
    component explains the row better than every existing one, the score of the new component
    being ``novelty_log_weight + log mean_m N(x | novelty_means[m], (U_m U_m^T)^{-1})``, a Monte
    Carlo form of the prior predictive density of a new component (see
    :meth:`tactile_torch.mixture.PitmanYorGMM.to_module`). Without novelty buffers (``M = 0``)
    and thresholds, ``novel`` is all False.
    """

    output_names = (LABELS_OUTPUT, SCORES_OUTPUT, NOVEL_OUTPUT, NOVELTY_SCORE_OUTPUT)
    """Names of the four outputs in an exported graph."""

    def __init__(
        self,
        means: object,
        precisions_cholesky: object,
        log_weights: object,
        novelty_means: object | None = None,
        novelty_precisions_cholesky: object | None = None,
        novelty_log_weight: float = 0.0,
        novelty_thresholds: object | None = None,
        density_means: object | None = None,
        density_precisions_cholesky: object | None = None,
        density_log_weights: object | None = None,
        cluster_features: int | None = None,
        dtype: torch.dtype = torch.float32,
    ) -> None:
        super().__init__()
        D = np.asarray(means).shape[-1]
        F = D if density_means is None else np.asarray(density_means).shape[-1]
        self.cluster_features = (
            None if cluster_features is None or cluster_features == F else int(cluster_features)
        )

        def buffer(name: str, value: object, shape: tuple[int, ...]) -> None:
            arr = np.zeros(shape) if value is None else np.asarray(value)
            self.register_buffer(name, torch.as_tensor(arr, dtype=dtype))

        buffer("means", means, ())
        buffer("precisions_cholesky", precisions_cholesky, ())
        buffer("log_weights", log_weights, ())
        buffer("novelty_means", novelty_means, (0, D))
        buffer("novelty_precisions_cholesky", novelty_precisions_cholesky, (0, D, D))
        self.register_buffer("novelty_log_weight", torch.tensor(float(novelty_log_weight), dtype=dtype))
        thresholds = np.zeros(0) if novelty_thresholds is None else np.asarray(novelty_thresholds).ravel()
        self.register_buffer("novelty_thresholds", torch.as_tensor(thresholds, dtype=dtype))
        buffer("density_means", density_means, (0, F))
        buffer("density_precisions_cholesky", density_precisions_cholesky, (0, F, F))
        buffer("density_log_weights", density_log_weights, (0,))

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        features = x
        if self.cluster_features is not None:  # components on the leading columns, novelty on all
            x = x[:, : self.cluster_features]
        scores = gaussian_mixture_scores(x, self.means, self.precisions_cholesky, self.log_weights)
        best = scores.max(dim=-1).values
        log_resp = scores - torch.logsumexp(scores, dim=-1, keepdim=True)
        if self.density_means.shape[0]:
            density = gaussian_mixture_scores(
                features, self.density_means, self.density_precisions_cholesky, self.density_log_weights
            )
            novelty = -torch.logsumexp(density, dim=-1)
        else:
            novelty = -torch.logsumexp(scores, dim=-1)
        m = self.novelty_means.shape[0]
        if self.novelty_thresholds.shape[0]:  # calibrated: the threshold of one window
            novel = novelty > self.novelty_thresholds[0]
        elif m:  # the model's own rule: a new component more probable than every known one
            new = gaussian_mixture_scores(
                x,
                self.novelty_means,
                self.novelty_precisions_cholesky,
                torch.full((m,), -math.log(m), dtype=x.dtype),
            )
            novel = torch.logsumexp(new, dim=-1) + self.novelty_log_weight > best
        else:
            novel = torch.zeros_like(best, dtype=torch.bool)
        return torch.argmax(scores, dim=-1), log_resp, novel, novelty
