"""Train a classifier on a data file and save it: what ``tactile-torch train`` runs.

:func:`load_features` reads one ``.npz`` of DESIGN.md's formats (image explorations: ``frames``;
vibration recordings: ``signals``) and computes its features (:func:`tactile_torch.image.exploration_features`,
or windows and :func:`tactile_torch.signal.window_features`); a ``.npz`` with a ready ``features``
matrix (``(N, F)``, ``labels``, optional ``class_names``) is accepted too. :func:`train_classifier`
holds out a stratified test part, scales every feature to unit standard deviation on the training
part (DESIGN.md; the scale is kept with the model), fits the HM-SVM, a one-vs-one SVM, LDA or kNN
(k = 3, city-block, inverse-distance weights) and reports on the test part. :func:`save_model` writes
everything needed to classify new data with ``torch.save``: the fitted estimator, the scale, the
class names, how the features were made, and the state of the SVM's inference module
(:class:`tactile_torch.svm.SVMInference`) for export.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ._checks import RandomState, check_positive, numpy_rng

METHODS = ("hmsvm", "svm", "lda", "knn")
MODEL_FORMAT = "tactile-torch/classifier"


@dataclass
class FeatureSet:
    """Features of one data file.

    Attributes
    ----------
    X : ndarray of shape (N, F), float64
    y : ndarray of shape (N,), int64
        Class index of each row.
    class_names : tuple of str
    source : dict
        How the features were made (``kind`` = ``"image"``, ``"vibration"`` or ``"features"``, plus
        the window size, step and sample rate, or the fusion flag and the frame shape ``(T, 3, H, W)``,
        or the number of features).
    """

    X: np.ndarray
    y: np.ndarray
    class_names: tuple[str, ...]
    source: dict = field(default_factory=dict)


def load_features(
    path: str | Path,
    *,
    window: int = 800,
    step: int | None = None,
    fuse: bool = True,
    allow_pickle: bool = False,
) -> FeatureSet:
    """Read a ``.npz`` data file and return its features.

    Parameters
    ----------
    path : str or Path
        Image explorations (``frames``), vibration recordings (``signals``) or a feature matrix
        (``features``), each with ``labels`` (and ``class_names``).
    window, step : int
        Vibration windows: length and hop in samples (default hop: ``window``, no overlap).
    fuse : bool
        Image explorations: fused (12) or per-frame (T x 12) features.
    allow_pickle : bool
        Vibration files whose recordings differ in length store them as an object array, which
        needs unpickling: allow it only for files you trust.

    Returns
    -------
    FeatureSet
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"data must name an existing .npz file, got {str(path)!r}")
    with np.load(path, allow_pickle=False) as npz:
        keys = set(npz.files)
        if "features" in keys:
            X = np.asarray(npz["features"], dtype=np.float64)
            if "labels" not in keys:
                raise ValueError(f"{path}: a feature .npz needs 'labels' next to 'features'")
            labels = np.asarray(npz["labels"])
            names = tuple(str(c) for c in npz["class_names"]) if "class_names" in keys else None
    if "features" in keys:
        if X.ndim != 2 or labels.shape != (X.shape[0],):
            raise ValueError(
                f"{path}: features must have shape (N, F) and labels (N,), got {X.shape} and {labels.shape}"
            )
        if names is None:
            uniq, labels = np.unique(labels, return_inverse=True)
            names = tuple(str(c) for c in uniq)
        return FeatureSet(X, labels.astype(np.int64), names, {"kind": "features", "n_features": X.shape[1]})
    if "frames" in keys:
        from .data.images import load_explorations
        from .image import exploration_features

        data = load_explorations(path)
        X = exploration_features(data.frames, fuse=fuse).double().numpy()
        source = {"kind": "image", "fuse": fuse, "frame_shape": list(data.frames.shape[1:])}
        return FeatureSet(X, data.labels.numpy(), tuple(data.class_names), source)
    if "signals" in keys:
        from .data.vibration import load_vibration_npz
        from .signal import window_features

        rec = load_vibration_npz(path, allow_pickle=allow_pickle)
        ds = rec.windows(window, step)
        X = window_features(ds.windows).double().numpy()
        source = {"kind": "vibration", "window": window, "step": step or window, "rate_hz": rec.rate_hz}
        return FeatureSet(X, ds.labels.numpy(), tuple(ds.class_names), source)
    raise ValueError(
        f"{path}: expected an image (.npz with 'frames'), vibration ('signals') or feature ('features') "
        f"file, got keys {sorted(keys)}"
    )


def make_classifier(
    method: str,
    *,
    C: float = 16.0,
    gamma: str | float = "scale",
    kernel: str = "rbf",
    random_state: RandomState = None,
):
    """Return an unfitted classifier: ``hmsvm``, ``svm`` (one-vs-one), ``lda`` or ``knn``."""
    if method == "hmsvm":
        from .svm import HierarchicalSVC

        return HierarchicalSVC(C=C, gamma=gamma, kernel=kernel, random_state=random_state)
    if method == "svm":
        from .svm import SVC

        return SVC(C=C, gamma=gamma, kernel=kernel, random_state=random_state)
    if method == "lda":
        from sklearn.discriminant_analysis import LinearDiscriminantAnalysis

        return LinearDiscriminantAnalysis()
    if method == "knn":
        from sklearn.neighbors import KNeighborsClassifier

        return KNeighborsClassifier(n_neighbors=3, metric="cityblock", weights="distance")
    raise ValueError(f"method must be one of {METHODS}, got {method!r}")


@dataclass
class TrainedModel:
    """A classifier fitted by :func:`train_classifier`, with its feature scale and test report."""

    method: str
    estimator: object
    scale: np.ndarray
    report: object
    train_index: np.ndarray
    test_index: np.ndarray

    def predict(self, X: np.ndarray) -> np.ndarray:
        """Return the class index of each row of unscaled features ``X`` (N, F)."""
        return self.estimator.predict(np.asarray(X, dtype=np.float64) / self.scale)


def train_classifier(
    features: FeatureSet,
    method: str = "hmsvm",
    *,
    C: float = 16.0,
    gamma: str | float = "scale",
    kernel: str = "rbf",
    test_size: float = 0.25,
    random_state: RandomState = None,
) -> TrainedModel:
    """Fit ``method`` on a stratified ``1 - test_size`` of the features; report on the rest.

    Each feature is divided by its standard deviation (``ddof=1``) on the training part (1 for a
    constant feature); the same scale applies to any data the model classifies.
    """
    from sklearn.model_selection import train_test_split

    from .metrics import class_report

    if not 0.0 < test_size < 1.0:
        raise ValueError(f"test_size must be in (0, 1), got {test_size!r}")
    check_positive(C, "C")
    seed = int(numpy_rng(random_state).integers(2**31))
    index = np.arange(features.X.shape[0])
    train, test = train_test_split(index, test_size=test_size, stratify=features.y, random_state=seed)
    std = features.X[train].std(axis=0, ddof=1)
    scale = np.where(std > 0, std, 1.0)
    estimator = make_classifier(method, C=C, gamma=gamma, kernel=kernel, random_state=seed)
    estimator.fit(features.X[train] / scale, features.y[train])
    pred = estimator.predict(features.X[test] / scale)
    names = features.class_names
    report = class_report(features.y[test], pred, labels=np.arange(len(names)), names=names)
    return TrainedModel(method, estimator, scale, report, np.sort(train), np.sort(test))


def save_model(path: str | Path, model: TrainedModel, features: FeatureSet) -> Path:
    """Write the model with ``torch.save``; return ``path``.

    The file holds a dict: ``format``, ``method``, ``estimator`` (the fitted scikit-learn-style object),
    ``scale`` (F,), ``class_names``, ``source`` (how features are made) and, for the SVMs,
    ``inference`` (``mode``, ``kernel``, ``gamma``, ``depth`` and the ``state_dict`` of
    :class:`tactile_torch.svm.SVMInference`, which gives labels and scores from scaled features).
    """
    import torch

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = {
        "format": MODEL_FORMAT,
        "version": 1,
        "method": model.method,
        "estimator": model.estimator,
        "scale": model.scale,
        "class_names": list(features.class_names),
        "source": dict(features.source),
        "test_accuracy": model.report.overall_accuracy,
    }
    if hasattr(model.estimator, "to_module"):
        module = model.estimator.to_module()
        payload["inference"] = {
            "mode": module.mode,
            "kernel": module.kernel,
            "gamma": module.gamma,
            "depth": module.depth,
            "state_dict": module.state_dict(),
        }
    torch.save(payload, path)
    return path


def load_model(path: str | Path) -> dict:
    """Read a model written by :func:`save_model` (a trusted file: it is unpickled)."""
    import torch

    payload = torch.load(Path(path), weights_only=False)
    if not isinstance(payload, dict) or payload.get("format") != MODEL_FORMAT:
        raise ValueError(f"{path} is not a tactile-torch classifier written by save_model")
    return payload


__all__ = [
    "METHODS",
    "FeatureSet",
    "TrainedModel",
    "load_features",
    "load_model",
    "make_classifier",
    "save_model",
    "train_classifier",
]
