"""Torch inference graphs of fitted classifiers (LDA, kNN, nearest class mean, the SVMs), for ONNX export.

The SVMs of :mod:`tactile_torch.svm` carry their own torch inference path (``to_module()``); the
baselines the studies compare them with are scikit-learn's estimators, which have none. This module
gives each fitted baseline the same form, a :class:`torch.nn.Module` whose ``forward(x)`` maps
features ``(B, F)`` to ``(labels (B,) int64, scores (B, C))`` with labels indexing the estimator's
``classes_``, so that a whole pipeline (raw input → features → scale → classifier) exports to one
ONNX file (:mod:`tactile_torch.export.model_graph`). :func:`inference_module` picks the module of any fitted
classifier of the package.

Each family's knowledge is one :class:`ClassifierCodec` of the registry :data:`CODECS` (skl2onnx's one
converter per operator family is the model): fitted estimator → torch module → the arrays of a model
file (:func:`encode_classifier`, what ``train`` writes) → the module again (:func:`decode_classifier`,
what ``export`` builds from a model file). A new family of classifier is one codec here.

==============================================  ============================================================
estimator                                       module
==============================================  ============================================================
``LinearDiscriminantAnalysis``                  :class:`LinearInference`: ``x @ coef_.T + intercept_`` (the
                                                estimator's ``decision_function``); two classes ``[-f, f]``
``KNeighborsClassifier`` (uniform or distance   :class:`NeighboursInference`: the ``k`` nearest training
weights; ``minkowski``/``euclidean``/           samples, votes weighted as scikit-learn does; scores are its
``manhattan``/``cityblock`` metric)             ``predict_proba``; of samples at equal distance the earlier
                                                is nearer (:class:`~tactile_torch.neighbors.StableKNeighborsClassifier`'s
                                                rule, which scikit-learn's own leaves to its search tree)
``NearestCentroid`` (euclidean)                 :class:`LinearInference` of the equivalent linear rule:
                                                scores ``2 x . mean_c - ||mean_c||^2`` (``||x||^2 -
                                                ||x - mean_c||^2``: ranked as minus the distance)
:class:`~tactile_torch.svm.SVC`,                their ``to_module()``
:class:`~tactile_torch.svm.HierarchicalSVC`
==============================================  ============================================================

Every module computes in float64 by default (the input is cast), so that its labels equal the
estimator's ``predict``: ties of scores go to the lowest class index (``argmax``), as the estimators' own.

Examples
--------
>>> from sklearn.discriminant_analysis import LinearDiscriminantAnalysis
>>> X = torch.randn(40, 3, dtype=torch.float64); y = (X[:, 0] > 0).long()
>>> lda = LinearDiscriminantAnalysis().fit(X.numpy(), y.numpy())
>>> labels, scores = inference_module(lda)(X)
>>> bool((labels.numpy() == lda.predict(X.numpy())).all()), tuple(scores.shape)
(True, (40, 2))
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from ..exceptions import InputTypeError

_CITY_BLOCK = ("manhattan", "cityblock", "l1")
_EUCLIDEAN = ("euclidean", "l2")


def _buffer(value: object, dtype: torch.dtype) -> torch.Tensor:
    return torch.as_tensor(np.asarray(value), dtype=dtype).clone()


class LinearInference(nn.Module):
    """A linear classifier: scores ``x @ coef.T + intercept``, label the largest.

    Parameters
    ----------
    coef : array of shape (K, F)
        One row per class, or one row for two classes (scores then ``[-f, f]``, label ``f > 0``).
    intercept : array of shape (K,)
    dtype : torch.dtype, default float64
    """

    def __init__(self, coef: object, intercept: object, *, dtype: torch.dtype = torch.float64) -> None:
        super().__init__()
        self.register_buffer("coef", _buffer(coef, dtype))
        self.register_buffer("intercept", _buffer(intercept, dtype))
        if self.coef.ndim != 2 or self.intercept.shape != (self.coef.shape[0],):
            raise ValueError(
                f"coef must have shape (K, F) and intercept (K,), got {tuple(self.coef.shape)} and "
                f"{tuple(self.intercept.shape)}"
            )

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        scores = x.to(self.coef.dtype) @ self.coef.T + self.intercept
        if self.coef.shape[0] == 1:
            scores = torch.cat([-scores, scores], dim=1)
        return scores.argmax(dim=1), scores


class NeighboursInference(nn.Module):
    """k-nearest-neighbour vote: the ``k`` closest training samples, weighted like scikit-learn.

    ``weights="distance"`` weighs each neighbour by ``1 / d``; a query at distance 0 from some
    training samples takes the vote of those alone (scikit-learn's rule). ``"uniform"`` counts them.
    Scores are the votes normalised to sum to 1 (``predict_proba``).

    Parameters
    ----------
    samples : array of shape (N, F)
        The training samples.
    labels : array of shape (N,)
        Their class index (into ``classes_``), ``0 .. n_classes - 1``.
    n_classes : int
    n_neighbors : int
    weights : {"uniform", "distance"}
    p : {1, 2}
        City-block (1) or Euclidean (2) distance.
    dtype : torch.dtype, default float64
    """

    def __init__(
        self,
        samples: object,
        labels: object,
        n_classes: int,
        *,
        n_neighbors: int,
        weights: str,
        p: int,
        dtype: torch.dtype = torch.float64,
    ) -> None:
        super().__init__()
        if weights not in ("uniform", "distance"):
            raise ValueError(f"weights must be 'uniform' or 'distance', got {weights!r}")
        if p not in (1, 2):
            raise ValueError(f"p must be 1 (city-block) or 2 (Euclidean), got {p!r}")
        self.register_buffer("samples", _buffer(samples, dtype))
        labels = np.asarray(labels, dtype=np.int64)
        self.register_buffer("votes", torch.from_numpy(np.eye(n_classes)[labels]).to(dtype))
        self.n_neighbors = min(int(n_neighbors), self.samples.shape[0])
        self.weights, self.p = weights, int(p)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        diff = x.to(self.samples.dtype)[:, None, :] - self.samples[None, :, :]  # (B, N, F)
        dist = diff.abs().sum(-1) if self.p == 1 else (diff * diff).sum(-1).sqrt()
        # Ties in training order (tactile_torch.neighbors.StableKNeighborsClassifier): ONNX's TopK keeps
        # the lower index first, torch's topk leaves the order of equal values open, so torch sorts stably
        # (a stable sort has no ONNX export).
        if torch.compiler.is_exporting():
            near, index = torch.topk(dist, self.n_neighbors, dim=1, largest=False)  # (B, k)
        else:
            near, index = torch.sort(dist, dim=1, stable=True)
            near, index = near[:, : self.n_neighbors], index[:, : self.n_neighbors]
        if self.weights == "distance":
            exact = near == 0
            any_exact = exact.any(dim=1, keepdim=True)
            weight = torch.where(any_exact, exact.to(near.dtype), 1.0 / torch.where(exact, 1.0, near))
        else:
            weight = torch.ones_like(near)
        votes = (self.votes[index] * weight[..., None]).sum(1)  # (B, C)
        scores = votes / votes.sum(1, keepdim=True)
        return scores.argmax(dim=1), scores


def _neighbours_module(est: object, dtype: torch.dtype) -> NeighboursInference:
    metric, p = est.effective_metric_, est.effective_metric_params_.get("p", getattr(est, "p", 2))
    if metric in _CITY_BLOCK or (metric == "minkowski" and p == 1):
        p = 1
    elif metric in _EUCLIDEAN or (metric == "minkowski" and p == 2):
        p = 2
    else:
        raise ValueError(
            f"a KNeighborsClassifier exports with the city-block or Euclidean metric only, got {metric!r} (p={p})"
        )
    if callable(est.weights) or est.weights not in ("uniform", "distance"):
        raise ValueError(
            f"a KNeighborsClassifier exports with weights 'uniform' or 'distance', got {est.weights!r}"
        )
    return NeighboursInference(
        est._fit_X,
        est._y,
        len(est.classes_),
        n_neighbors=est.n_neighbors,
        weights=est.weights,
        p=p,
        dtype=dtype,
    )


def _svm_classes() -> tuple[type, ...]:
    from ..svm import SVC, HierarchicalSVC

    return (HierarchicalSVC, SVC)


def _linear_classes() -> tuple[type, ...]:
    from sklearn.discriminant_analysis import LinearDiscriminantAnalysis
    from sklearn.neighbors import NearestCentroid

    return (LinearDiscriminantAnalysis, NearestCentroid)


def _neighbours_classes() -> tuple[type, ...]:
    from sklearn.neighbors import KNeighborsClassifier

    return (KNeighborsClassifier,)


def _svm_module(est: object, dtype: torch.dtype) -> nn.Module:
    return est.to_module(dtype)


def _svm_head(est: object, module: nn.Module) -> tuple[str, dict, dict[str, np.ndarray]]:
    from ..svm import HierarchicalSVC

    head = {
        "type": "svm",
        "mode": module.mode,
        "kernel": module.kernel,
        "gamma": float(module.gamma),
        "depth": int(module.depth),
    }
    buffers = {name: buf.numpy() for name, buf in module.named_buffers()}
    return ("hmsvm" if isinstance(est, HierarchicalSVC) else "svm"), head, buffers


def _svm_from_head(settings: dict, arrays: dict[str, np.ndarray], n_classes: int) -> nn.Module:
    from ..svm import SVMInference

    tensors = {name: torch.from_numpy(np.array(value)) for name, value in arrays.items()}
    core = ("support_vectors", "dual_coef", "intercept")
    return SVMInference(
        *(tensors.pop(name) for name in core),
        kernel=settings["kernel"],
        gamma=settings["gamma"],
        mode=settings["mode"],
        tree=tensors or None,
        depth=settings["depth"],
    )


def _linear_module(est: object, dtype: torch.dtype) -> nn.Module:
    from sklearn.discriminant_analysis import LinearDiscriminantAnalysis

    if isinstance(est, LinearDiscriminantAnalysis):
        return LinearInference(est.coef_, est.intercept_, dtype=dtype)
    if est.metric != "euclidean":
        raise ValueError(f"a NearestCentroid exports with metric='euclidean' only, got {est.metric!r}")
    means = np.asarray(est.centroids_, dtype=np.float64)
    # argmin ||x - m_c|| = argmax (2 x . m_c - ||m_c||^2): the nearest-mean rule is linear.
    return LinearInference(2.0 * means, -(means * means).sum(1), dtype=dtype)


def _linear_head(est: object, module: nn.Module) -> tuple[str, dict, dict[str, np.ndarray]]:
    from sklearn.discriminant_analysis import LinearDiscriminantAnalysis

    coef, intercept = module.coef.numpy(), module.intercept.numpy()
    mode = "binary" if coef.shape[0] == 1 else "multiclass"
    method = "lda" if isinstance(est, LinearDiscriminantAnalysis) else "ncm"
    return method, {"type": "linear", "mode": mode}, {"coef": coef, "intercept": intercept}


def _linear_from_head(settings: dict, arrays: dict[str, np.ndarray], n_classes: int) -> nn.Module:
    return LinearInference(arrays["coef"], arrays["intercept"])


def _neighbours_head(est: object, module: nn.Module) -> tuple[str, dict, dict[str, np.ndarray]]:
    head = {"type": "neighbours", "n_neighbors": module.n_neighbors, "weights": module.weights, "p": module.p}
    labels = module.votes.numpy().argmax(1).astype(np.int64)
    return "knn", head, {"samples": module.samples.numpy(), "labels": labels}


def _neighbours_from_head(settings: dict, arrays: dict[str, np.ndarray], n_classes: int) -> nn.Module:
    return NeighboursInference(
        arrays["samples"],
        arrays["labels"],
        n_classes,
        n_neighbors=settings["n_neighbors"],
        weights=settings["weights"],
        p=settings["p"],
    )


@dataclass(frozen=True)
class ClassifierCodec:
    """One family of fitted classifiers: estimator -> torch module -> a model file's arrays -> module.

    Attributes
    ----------
    head_type : str
        The model file's ``head["type"]`` (``"svm"``, ``"linear"``, ``"neighbours"``).
    classes : callable
        ``classes()`` returns the estimator classes of the family (imported on first use).
    module : callable
        ``module(estimator, dtype)``: the fitted estimator's inference module.
    head : callable
        ``head(estimator, module)``: ``(method, head settings, head arrays)`` of its model file.
    from_head : callable
        ``from_head(settings, arrays, n_classes)``: the inference module again, from a model file.
    """

    head_type: str
    classes: Callable[[], tuple[type, ...]]
    module: Callable[[object, torch.dtype], nn.Module]
    head: Callable[[object, nn.Module], tuple[str, dict, dict[str, np.ndarray]]]
    from_head: Callable[[dict, dict[str, np.ndarray], int], nn.Module]


CODECS: dict[str, ClassifierCodec] = {
    c.head_type: c
    for c in (
        ClassifierCodec("svm", _svm_classes, _svm_module, _svm_head, _svm_from_head),
        ClassifierCodec("linear", _linear_classes, _linear_module, _linear_head, _linear_from_head),
        ClassifierCodec(
            "neighbours", _neighbours_classes, _neighbours_module, _neighbours_head, _neighbours_from_head
        ),
    )
}
"""The registry: one codec per family (skl2onnx's one converter per operator family), by head type."""


def codec_of(estimator: object) -> ClassifierCodec:
    """Return the :class:`ClassifierCodec` of a classifier's family.

    Raises
    ------
    TypeError
        (:class:`~tactile_torch.exceptions.InputTypeError`) For a classifier of no registered family.
    """
    for codec in CODECS.values():
        if isinstance(estimator, codec.classes()):
            return codec
    raise InputTypeError(
        "estimator must be a fitted tactile_torch SVM, LinearDiscriminantAnalysis, KNeighborsClassifier or "
        f"NearestCentroid, got {type(estimator).__name__}"
    )


def inference_module(estimator: object, *, dtype: torch.dtype = torch.float64) -> nn.Module:
    """Return the torch inference module of a fitted classifier: features ``(B, F)`` → ``(labels, scores)``.

    Labels index ``estimator.classes_``. Supported: the package's SVMs (``to_module()``),
    scikit-learn's ``LinearDiscriminantAnalysis``, ``KNeighborsClassifier`` (city-block or Euclidean,
    uniform or distance weights) and ``NearestCentroid`` (Euclidean): :data:`CODECS`.

    Raises
    ------
    TypeError
        For another kind of estimator.
    ValueError
        For an unsupported setting (another metric, callable weights).
    sklearn.exceptions.NotFittedError
        If the estimator is not fitted.
    """
    from sklearn.utils.validation import check_is_fitted

    if hasattr(estimator, "to_module"):
        return estimator.to_module(dtype)
    codec = codec_of(estimator)
    check_is_fitted(estimator)
    return codec.module(estimator, dtype)


def encode_classifier(estimator: object) -> tuple[str, dict, dict[str, np.ndarray]]:
    """Return ``(method, head settings, head arrays)`` of a fitted classifier for its model file.

    The arrays are those of its inference module (:func:`inference_module`): an SVM's support vectors,
    dual coefficients, intercepts (and tree tables); LDA's and the nearest class mean's linear scores
    ``coef`` ``(M, F)``, ``intercept`` ``(M,)``; kNN's training ``samples`` and ``labels``.
    :func:`decode_classifier` makes the module again.

    Raises
    ------
    TypeError
        For a classifier without an inference module.
    """
    codec = codec_of(estimator)
    return codec.head(estimator, inference_module(estimator))


def decode_classifier(settings: dict, arrays: dict[str, np.ndarray], n_classes: int) -> nn.Module:
    """Return the inference module of a model file's classifier ``head`` settings and arrays."""
    return CODECS[settings["type"]].from_head(settings, arrays, n_classes)


__all__ = [
    "CODECS",
    "ClassifierCodec",
    "LinearInference",
    "NeighboursInference",
    "codec_of",
    "decode_classifier",
    "encode_classifier",
    "inference_module",
]
