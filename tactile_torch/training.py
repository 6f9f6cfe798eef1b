"""Train a classifier on a data file and save it: what ``tactile-torch train`` runs.

:func:`load_features` reads a data file of ``docs/formats.md`` through :mod:`tactile_torch.formats`
(image explorations: ``frames``; vibration recordings: ``signals`` or CSV logs; a ready ``features``
matrix) and computes its features (:func:`tactile_torch.image.exploration_features`, or windows and
:func:`tactile_torch.signal.window_features`). :func:`train_classifier` reports the accuracy of a
classifier of the catalogue (:mod:`tactile_torch.catalogue`: the HM-SVM, a one-vs-one SVM, LDA, kNN
with k = 3, city-block distance and inverse-distance weights, or nearest class mean) held out by
recording, session or time block (the trade-off's folds, :func:`held_out_folds`), then fits it on
every sample, each feature scaled to unit standard deviation (as in the study; the scale is kept
with the model). :func:`save_model` writes an SVM's model
file (:mod:`tactile_torch.model_file`: plain arrays and a JSON header, no pickle) with everything the
export needs: the scale, the class names, how the features were made and the arrays of the SVM's
inference module (:class:`tactile_torch.svm.SVMInference`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import catalogue
from ._checks import RandomState, check_positive, numpy_rng

METHODS = tuple(catalogue.choices())
"""Accepted ``method`` names: the catalogue's keys (:data:`tactile_torch.catalogue.CLASSIFIERS`) and
``"svm"``, an alias of ``"svc"`` (the one-vs-one SVM)."""
MODEL_FORMAT = "tactile-torch/model"
"""``format`` of model files (:data:`tactile_torch.model_file.FORMAT`; kept for old imports)."""


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
    groups : ndarray of shape (N,), optional
        What must stay on one side of a held-out split: each window's recording session (the file's
        ``session``, else its recording), or an exploration's ``groups``; ``None``: independent rows.
    recording, position : ndarray of shape (N,), optional
        Vibration windows: the recording each comes from and its index in it (time order).
    """

    X: np.ndarray
    y: np.ndarray
    class_names: tuple[str, ...]
    source: dict = field(default_factory=dict)
    groups: np.ndarray | None = None
    recording: np.ndarray | None = None
    position: np.ndarray | None = None


def load_features(
    path,
    *,
    window: int = 800,
    step: int | None = None,
    fuse: bool = True,
    allow_pickle: bool = False,
    options=None,
    name: str | None = None,
) -> FeatureSet:
    """Read a data file (:func:`tactile_torch.data.sources.read_source`) and return its features.

    Parameters
    ----------
    path : path, sequence of paths, or arrays already read
        Image explorations (``frames``), vibration recordings (``signals``) or a feature matrix
        (``features``) in one ``.npz``, each with ``labels`` (and ``class_names``); CSV logs
        (one recording each); ROS 2 bags. Class and session of logs and bags come from the naming
        rule (``felt_3.csv``: class ``felt``, session ``3``) or an index. See ``docs/formats.md``.
        Or what :func:`~tactile_torch.data.sources.read_source` returned.
    window, step : int
        Vibration windows: length and hop in samples (default hop: ``window``, no overlap).
    fuse : bool
        Image explorations: fused (12) or per-frame (T x 12) features.
    allow_pickle : bool
        Only for vibration files written by tactile-torch 0.1 with recordings of different lengths
        (a pickled object array): allow it only for files you trust.
    options : DataOptions, optional
        Columns, units, time unit, topic ... (:class:`tactile_torch.data.sources.DataOptions`).
    name : str, optional
        How messages name the data (default: the file, or ``"data"`` for arrays already read).

    Returns
    -------
    FeatureSet
        With ``groups`` (and, for windows, ``recording`` and ``position``) for held-out splits.

    Raises
    ------
    FileNotFoundError, ValueError
        One line naming the file and the field (see :mod:`tactile_torch.formats`), or the
        recording and sample that the declared units make implausible; labels are required here.
    """
    from .formats import data_name

    if hasattr(path, "kind"):
        data, where = path, name or "data"
    else:
        from .data.sources import DataOptions, read_source

        data = read_source(path, options or DataOptions(allow_pickle=allow_pickle))
        where = name or data_name(path)
    if data.kind == "features":
        if data.labels is None:
            raise ValueError(f"{where}: missing 'labels'; training needs labels (N,) next to 'features'")
        source = {"kind": "features", "n_features": data.features.shape[1]}
        return FeatureSet(data.features, data.labels, data.class_names, source)
    if data.kind == "image":
        from .data.images import explorations_from_arrays
        from .image import exploration_features

        images = explorations_from_arrays(data)
        X = exploration_features(images.frames, fuse=fuse).double().numpy()
        source = {"kind": "image", "fuse": fuse, "frame_shape": list(images.frames.shape[1:])}
        return FeatureSet(X, data.labels, data.class_names, source, groups=data.groups)
    import torch

    from .formats import window_recordings
    from .signal import window_features

    try:
        cut = window_recordings(data.signals, window, step)
    except ValueError as err:
        raise ValueError(f"{where}: {err}; pass a smaller window (--window)") from None
    X = window_features(torch.from_numpy(cut.windows)).double().numpy()
    overflow = ~np.isfinite(X).all(axis=1)
    if overflow.any():  # e.g. a corrupted 1e30 sample: say so, rather than "X must be finite" later
        first = int(np.argmax(overflow))
        peak = float(np.abs(cut.windows[first]).max())
        raise ValueError(
            f"{where}: {int(overflow.sum())} window(s) hold samples out of range (window {first} of recording "
            f"{int(cut.recording[first])} reaches {peak:.3g} g), whose features overflow; remove or clip them"
        )
    source = {"kind": "vibration", "window": window, "step": step or window, "rate_hz": data.rate_hz}
    return FeatureSet(
        X,
        data.labels[cut.recording],
        data.class_names,
        source,
        groups=None if data.session is None else np.asarray(data.session)[cut.recording],
        recording=cut.recording,
        position=cut.position,
    )


def make_classifier(
    method: str,
    *,
    C: float = 16.0,
    gamma: str | float = "scale",
    kernel: str = "rbf",
    random_state: RandomState = None,
):
    """Return an unfitted classifier of the catalogue (:mod:`tactile_torch.catalogue`): ``hmsvm``,
    ``svc`` (or ``svm``, one-vs-one), ``lda``, ``knn`` or ``ncm``, at its defaults; ``C``, ``gamma`` and
    ``kernel`` apply to the SVMs only."""
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    key = catalogue.resolve(method)
    params = {"C": C, "gamma": gamma, "kernel": kernel} if key in ("hmsvm", "svc") else {}
    return catalogue.make_classifier(key, random_state=random_state, **params)


@dataclass
class TrainedModel:
    """A classifier fitted by :func:`train_classifier`, with its feature scale and held-out report.

    Attributes
    ----------
    method : str
    estimator : fitted classifier (on every sample)
    scale : ndarray (F,)
    report : ClassReport
        Of the held-out predictions: every sample of ``test_index`` predicted by the fold's model
        that did not see its group.
    train_index : ndarray
        The samples the final ``estimator`` was fitted on (all of them).
    test_index : ndarray
        The samples with a held-out prediction (all but the guard windows of time-block folds).
    split : str
        How the held-out folds were made, in words.
    fold_accuracy : list of float
        Accuracy on each fold's test part.
    """

    method: str
    estimator: object
    scale: np.ndarray
    report: object
    train_index: np.ndarray
    test_index: np.ndarray
    split: str = ""
    fold_accuracy: list = field(default_factory=list)

    def predict(self, X: np.ndarray) -> np.ndarray:
        """Return the class index of each row of unscaled features ``X`` (N, F)."""
        return self.estimator.predict(np.asarray(X, dtype=np.float64) / self.scale)


def held_out_folds(features: FeatureSet, n_folds: int = 5, *, random_state: RandomState = None):
    """Return ``(keep, folds, split)``: the folds ``train`` reports on, those of the trade-off.

    Windows are grouped by session (or recording) when every class has two, else cut into
    consecutive time blocks of every recording with guard windows between blocks
    (:func:`tactile_torch.tradeoff.inputs.window_folds`); explorations and feature rows are grouped
    by ``groups`` when given, else stratified (:func:`~tactile_torch.tradeoff.inputs.sample_folds`).
    ``folds`` index ``keep``, the samples used; ``split`` names the split in words.
    """
    from .tradeoff.inputs import sample_folds, window_folds

    names = features.class_names
    if features.recording is not None:
        window = int(features.source.get("window", 1))
        step = int(features.source.get("step", window))
        n_rec = int(features.recording.max()) + 1
        given = features.groups is not None
        session = np.arange(n_rec).astype(object)
        if given:
            session[features.recording] = np.asarray(features.groups).astype(str)
        _, keep, folds, split = window_folds(
            features.recording,
            features.position,
            features.y,
            session.astype(str) if given else np.arange(n_rec),
            group_label="session" if given else "recording",
            n_folds=n_folds,
            names=names,
            window=window,
            guard=-(-window // step),
            random_state=random_state,
        )
        return keep, folds, f"{len(keep)} windows; {split}"
    what = "samples" if features.source.get("kind") == "features" else "explorations"
    folds, split = sample_folds(
        features.y, features.groups, n_folds=n_folds, names=names, what=what, random_state=random_state
    )
    return np.arange(len(features.y)), folds, f"{len(features.y)} {what}; {split}"


def _fit_scaled(method: str, X: np.ndarray, y: np.ndarray, seed: int, **params):
    std = X.std(axis=0, ddof=1)
    scale = np.where(std > 0, std, 1.0)
    return make_classifier(method, random_state=seed, **params).fit(X / scale, y), scale


def train_classifier(
    features: FeatureSet,
    method: str = "hmsvm",
    *,
    C: float = 16.0,
    gamma: str | float = "scale",
    kernel: str = "rbf",
    n_folds: int = 5,
    test_size: float | None = None,
    random_state: RandomState = None,
) -> TrainedModel:
    """Fit ``method`` on every sample; report its accuracy held out by recording, session or time block.

    The held-out report pools the test parts of :func:`held_out_folds` (the trade-off's folds): each
    sample is predicted by a model fitted on the other folds, which never saw its recording or
    session (or, with one recording per class, its time block). No random split of windows: the
    neighbouring windows of one recording are alike, and a random split scores memory, not
    recognition. The returned model is then fitted on every sample. Each feature is divided by its
    standard deviation (``ddof=1``) on the data a model is fitted on (1 for a constant feature);
    the final scale applies to any data the model classifies.

    Parameters
    ----------
    n_folds : int
        Folds (at most; fewer when a class has fewer groups or time blocks), at least 2.
    test_size : float, optional
        Kept for old callers: ``n_folds = round(1 / test_size)`` (0.25 → 4 folds).
    """
    from .metrics import class_report

    if test_size is not None:
        if not 0.0 < test_size < 1.0:
            raise ValueError(f"test_size must be in (0, 1), got {test_size!r}")
        n_folds = max(2, round(1.0 / test_size))
    if isinstance(n_folds, bool) or not isinstance(n_folds, int | np.integer) or n_folds < 2:
        raise ValueError(f"n_folds must be an int >= 2, got {n_folds!r}")
    check_positive(C, "C")
    counts = np.bincount(features.y, minlength=len(features.class_names))
    if (counts == 1).any():
        lonely = [features.class_names[i] for i in np.flatnonzero(counts == 1)]
        raise ValueError(
            f"labels: every class needs at least 2 samples (one to train on, one to test), "
            f"class(es) {lonely} have 1"
        )
    if (counts > 0).sum() < 2:
        raise ValueError(
            f"labels: training needs at least 2 classes with samples, got {int((counts > 0).sum())}"
        )
    seed = int(numpy_rng(random_state).integers(2**31))
    keep, folds, split = held_out_folds(features, n_folds, random_state=seed)
    X, y = features.X[keep], features.y[keep]
    params = {"C": C, "gamma": gamma, "kernel": kernel}
    pred = np.empty(len(keep), dtype=np.int64)
    fold_accuracy = []
    for train, test in folds:
        fitted, scale = _fit_scaled(method, X[train], y[train], seed, **params)
        pred[test] = fitted.predict(X[test] / scale)
        fold_accuracy.append(float(np.mean(pred[test] == y[test])))
    tested = np.unique(np.concatenate([test for _, test in folds]))
    estimator, scale = _fit_scaled(method, features.X, features.y, seed, **params)
    names = features.class_names
    report = class_report(y[tested], pred[tested], labels=np.arange(len(names)), names=names)
    return TrainedModel(
        method,
        estimator,
        scale,
        report,
        np.arange(len(features.y)),
        np.sort(keep[tested]),
        split=split,
        fold_accuracy=fold_accuracy,
    )


def save_model(path: str | Path, model: TrainedModel, features: FeatureSet) -> Path:
    """Write a trained SVM (``hmsvm`` or ``svm``) to a model file; return ``path``.

    The file (:mod:`tactile_torch.model_file`, no pickle) holds the feature ``scale``, the class
    names in the order of the SVM's labels, how features are made (``source``), the
    hyper-parameters, the held-out accuracy and the arrays of the SVM's inference path
    (:class:`tactile_torch.svm.SVMInference`: support vectors, dual coefficients, intercepts and,
    for the HM-SVM, the tree tables), which is what ``tactile-torch export`` turns into ONNX.

    Raises
    ------
    ValueError
        For LDA and kNN, which have no exportable inference path (they serve as the study's
        baselines; persist them with scikit-learn's own tools if needed).
    """
    if not hasattr(model.estimator, "to_module"):
        raise ValueError(
            f"method {model.method!r} has no exportable inference path, so it has no model file: "
            "save an SVM (--method hmsvm or --method svm)"
        )
    from .model_file import save_model_file

    module = model.estimator.to_module()
    params = {
        k: v
        for k, v in model.estimator.get_params().items()
        if isinstance(v, str | int | float | bool) and k != "random_state"
    }
    header = {
        "kind": "classifier",
        "method": model.method,
        "class_names": [str(features.class_names[int(c)]) for c in model.estimator.classes_],
        "source": dict(features.source),
        "params": params,
        "test_accuracy": float(model.report.overall_accuracy),
        "head": {
            "type": "svm",
            "mode": module.mode,
            "kernel": module.kernel,
            "gamma": float(module.gamma),
            "depth": int(module.depth),
        },
    }
    arrays = {"scale": np.asarray(model.scale, dtype=np.float64)}
    arrays.update({f"head.{name}": buf.numpy() for name, buf in module.named_buffers()})
    # "unknown" as an answer: the distance of a sample's features to the training classes
    # (tactile_torch.ood), fitted on the training rows, classes in the order of the head's labels
    from .ood import DEFAULT_QUANTILE, fit_ood

    classes = np.asarray(model.estimator.classes_)
    known = np.isin(features.y, classes)  # every row of the data: train and test part alike
    head_labels = np.searchsorted(classes, features.y[known])
    ood = fit_ood(features.X[known] / model.scale, head_labels, quantile=DEFAULT_QUANTILE)
    header["ood"] = {
        "type": "mahalanobis",
        "quantile": DEFAULT_QUANTILE,
        "threshold": float(ood["threshold"]),
    }
    arrays.update({"ood.means": ood["means"], "ood.precision_cholesky": ood["precision_cholesky"]})
    return save_model_file(path, header, arrays)


def load_model(path: str | Path):
    """Read and validate a classifier's model file (see :func:`tactile_torch.model_file.load_model_file`).

    Returns a :class:`tactile_torch.model_file.ModelFile`; nothing in it is unpickled.
    """
    from .model_file import load_model_file

    return load_model_file(path, kind="classifier")


__all__ = [
    "METHODS",
    "FeatureSet",
    "TrainedModel",
    "held_out_folds",
    "load_features",
    "load_model",
    "make_classifier",
    "save_model",
    "train_classifier",
]
