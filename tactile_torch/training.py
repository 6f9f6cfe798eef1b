"""Train a classifier on a data file and save it: what ``tactile-torch train`` runs.

:func:`~tactile_torch.features.load_features` reads a data file of ``docs/formats.md`` through :mod:`tactile_torch.robot.files.formats`
(image explorations: ``frames``; vibration recordings: ``signals`` or CSV logs; a ready ``features``
matrix) and computes its features (:func:`tactile_torch.image.exploration_features`, or windows and
:func:`tactile_torch.signal.window_features`). :func:`train_classifier` reports the accuracy of a
classifier of the catalogue (:mod:`tactile_torch.catalogue`: the HM-SVM, a one-vs-one SVM, LDA, kNN
with k = 3, city-block distance and inverse-distance weights, or nearest class mean) held out by
recording, session or time block (the trade-off's folds, :func:`held_out_folds`), then fits it on
every sample, each feature scaled to unit standard deviation (as in the study; the scale is kept
with the model); ``select`` keeps the best-ranked features only. :func:`save_model` writes the model
file (:mod:`tactile_torch.robot.files.model_file`: plain arrays and a JSON header, no pickle) with everything the
export needs: the scale, the class names, how the features were made and the arrays of the SVM's
inference module (:func:`tactile_torch.export.classifier_inference.encode_classifier`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import catalogue
from .features.files import FeatureSet
from .validation import RandomState, check_positive, numpy_rng

METHODS = tuple(catalogue.choices())
"""Accepted ``method`` names: the catalogue's keys (:data:`tactile_torch.catalogue.CLASSIFIERS`) and
``"svm"``, an alias of ``"svc"`` (the one-vs-one SVM)."""


@dataclass
class TrainedModel:
    """A classifier fitted by :func:`train_classifier`, with its feature scale and held-out report.

    Attributes
    ----------
    method : str
    estimator : fitted classifier (on every sample)
    scale : ndarray (F,)
        Of the selected features when ``select`` is set.
    report : ClassReport
        Of the held-out predictions: every sample of ``test_index`` predicted by the fold's model
        that did not see its group.
    train_index : ndarray
        The samples the final ``estimator`` was fitted on (all of them).
    test_index : ndarray
        The samples with a held-out prediction (all but the guard windows of time-block folds).
    select : ndarray or None
        The columns kept by ``select`` (ranked on every sample), else ``None``.
    split : str
        How the held-out folds were made, in words.
    fold_accuracy : list of float
        Accuracy on each fold's test part.
    early_rule : EarlyRule or None
        Frames (explorations, touches): the early-decision rule calibrated on the held-out touches, each
        classified on its first frames by the fold's model that did not see it, in the exported graph's
        scores (:func:`tactile_torch.robot.stream.early_decision.held_out_rule`, the trade-off's calibration).
    """

    method: str
    estimator: object
    scale: np.ndarray
    report: object
    train_index: np.ndarray
    test_index: np.ndarray
    select: np.ndarray | None = None
    split: str = ""
    fold_accuracy: list = field(default_factory=list)
    early_rule: object | None = None

    def predict(self, X: np.ndarray) -> np.ndarray:
        """Return the class index of each row of unscaled features ``X`` (N, F)."""
        X = np.asarray(X, dtype=np.float64)
        if self.select is not None:
            X = X[:, self.select]
        return self.estimator.predict(X / self.scale)


def held_out_folds(features: FeatureSet, n_folds: int = 5, *, random_state: RandomState = None):
    """Return ``(keep, folds, split)``: the folds ``train`` reports on, those of the trade-off.

    Windows are grouped by session (or recording) when every class has two, else cut into
    consecutive time blocks of every recording with guard windows between blocks
    (:func:`tactile_torch.model_selection.window_folds`); explorations and feature rows are grouped
    by ``groups`` when given, else stratified (:func:`~tactile_torch.model_selection.sample_folds`).
    ``folds`` index ``keep``, the samples used; ``split`` names the split in words.
    """
    from .model_selection import sample_folds, window_folds

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
        if given and "grouped by" in split:  # say which sessions the folds keep apart
            split += f"; {_listing(np.unique(session.astype(str)), 'session')}"
        return keep, folds, f"{len(keep)} windows; {split}"
    what = "samples" if features.source.get("kind") == "features" else "explorations"
    what = "touches" if features.group_label == "session" else what
    folds, split = sample_folds(
        features.y,
        features.groups,
        n_folds=n_folds,
        names=names,
        what=what,
        group_label=features.group_label,
        random_state=random_state,
    )
    return np.arange(len(features.y)), folds, f"{len(features.y)} {what}; {split}"


def _listing(names: Sequence[str], what: str, limit: int = 8) -> str:
    """``"4 sessions: day1, day2, day3, day4"``, the first ``limit`` names and how many more.

    >>> _listing(["a", "b", "c"], "session", limit=2)
    '3 sessions: a, b and 1 more'
    """
    shown = ", ".join(str(n) for n in names[:limit])
    more = f" and {len(names) - limit} more" if len(names) > limit else ""
    return f"{len(names)} {what}{'s' if len(names) != 1 else ''}: {shown}{more}"


def _fit_scaled(method: str, X: np.ndarray, y: np.ndarray, seed: int, select: int | None, **params):
    """Return ``(fitted classifier, scale, selected columns or None)`` fitted on ``X``, ``y``: the catalogue's
    pipeline (:func:`tactile_torch.catalogue.classifier_pipeline`) with the study's unit-std scaling."""
    key = catalogue.resolve(method)
    params = params if key in catalogue.KERNEL_CLASSIFIERS else {}
    pipe = catalogue.classifier_pipeline(key, select=select, scaling="unit", random_state=seed, **params)
    pipe.fit(X, y)
    columns = pipe.named_steps["select"].columns_ if select is not None else None
    return pipe.named_steps["classifier"], pipe.named_steps["scale"].scale_, columns


def train_classifier(
    features: FeatureSet,
    method: str = "hmsvm",
    *,
    C: float = 16.0,
    gamma: str | float = "scale",
    kernel: str = "rbf",
    n_folds: int = 5,
    test_size: float | None = None,
    select: int | None = None,
    random_state: RandomState = None,
) -> TrainedModel:
    """Fit ``method`` on every sample; report its accuracy held out by recording, session or time block.

    The held-out report pools the test parts of :func:`held_out_folds` (the trade-off's folds): each
    sample is predicted by a model fitted on the other folds, which never saw its recording or
    session (or, with one recording per class, its time block). No random split of windows: the
    neighbouring windows of one recording are alike, and a random split scores memory, not
    recognition. The returned model is then fitted on every sample. Each feature is divided by its
    standard deviation (``ddof=1``) on the data a model is fitted on (1 for a constant feature);
    the final scale applies to any data the model classifies. ``select``: keep only the ``select``
    best-ranked features (the trade-off's "top k" feature sets,
    :class:`~tactile_torch.features.transformers.RankedFeatureSelector`), ranked on the data each model
    is fitted on.

    Parameters
    ----------
    n_folds : int
        Folds (at most; fewer when a class has fewer groups or time blocks), at least 2.
    test_size : float, optional
        Kept for old callers: ``n_folds = round(1 / test_size)`` (0.25 → 4 folds).
    """
    from .metrics import class_report

    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
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
    if len(features.X) and (np.ptp(features.X, axis=0) == 0).all():
        what = features.source.get("features") or features.source.get("kind", "")
        raise ValueError(
            f"features: all {features.X.shape[1]} {what} features are the same for every sample, so there is nothing "
            "to learn from (e.g. image features of frames too small for the image pipeline); choose other features "
            "(features='per-taxel' for a small taxel array)"
        )
    seed = int(numpy_rng(random_state).integers(2**31))
    if select is not None:
        check_positive(select, "select", integer=True)
        if select > features.X.shape[1]:
            raise ValueError(f"select must be at most the {features.X.shape[1]} features, got {select}")
    keep, folds, split = held_out_folds(features, n_folds, random_state=seed)
    X, y = features.X[keep], features.y[keep]
    params = {"C": C, "gamma": gamma, "kernel": kernel}
    pred = np.empty(len(keep), dtype=np.int64)
    fold_accuracy, fold_models = [], []
    for train, test in folds:
        fitted, scale, columns = _fit_scaled(method, X[train], y[train], seed, select, **params)
        X_test = X[test] if columns is None else X[test][:, columns]
        pred[test] = fitted.predict(X_test / scale)
        fold_accuracy.append(float(np.mean(pred[test] == y[test])))
        fold_models.append((fitted, scale, columns))
    rule = None if features.raw is None else _early_rule(features, keep, folds, fold_models)
    tested = np.unique(np.concatenate([test for _, test in folds]))
    estimator, scale, columns = _fit_scaled(method, features.X, features.y, seed, select, **params)
    names = features.class_names
    report = class_report(y[tested], pred[tested], labels=np.arange(len(names)), names=names)
    return TrainedModel(
        method,
        estimator,
        scale,
        report,
        np.arange(len(features.y)),
        np.sort(keep[tested]),
        columns,
        split=split,
        fold_accuracy=fold_accuracy,
        early_rule=rule,
    )


def _early_rule(features: FeatureSet, keep: np.ndarray, folds: list, fold_models: list):
    """The early rule of frame data, calibrated on the held-out touches as the trade-off calibrates it.

    Each held-out exploration is a touch: its first ``k`` frames, brought to ``T`` as the live stream brings
    them (:func:`~tactile_torch.robot.stream.touches.fit_frames`), are classified by the fold's model in the
    scores the exported graph computes (the classifier's inference module on the scaled features), at the
    checkpoints of :func:`~tactile_torch.robot.stream.early_decision.checkpoints_for`.
    """
    import torch

    from .export.classifier_inference import inference_module
    from .features.files import frame_features
    from .robot.stream.early_decision import checkpoints_for, held_out_rule, score_margins
    from .robot.stream.touches import fit_frames

    raw = features.raw[keep]
    t = raw.shape[1]
    checkpoints = checkpoints_for(t)
    kind = features.source.get("features") or ("fused" if features.source.get("fuse", True) else "per-frame")
    prefixes = [frame_features(np.stack([fit_frames(x[:c], t) for x in raw]), kind) for c in checkpoints]
    heads = [inference_module(fitted).eval() for fitted, _, _ in fold_models]

    def classify(fold: int, j: int, test: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        fitted, scale, columns = fold_models[fold]
        z = prefixes[j][test] if columns is None else prefixes[j][test][:, columns]
        with torch.no_grad():
            labels, scores = heads[fold](torch.from_numpy(z / scale))
        labels = labels.numpy().astype(np.int64)
        return np.asarray(fitted.classes_)[labels], score_margins(scores.numpy(), labels)

    return held_out_rule(
        features.y[keep],
        folds,
        checkpoints,
        classify,
        how=f"{len(keep)} held-out touches of {t} frames (train's fold models)",
    )[2]


def write_classifier_file(
    path: str | Path,
    estimator: object,
    *,
    class_names: Sequence[str],
    source: dict,
    scale: np.ndarray,
    center: np.ndarray | None = None,
    select: np.ndarray | None = None,
    test_accuracy: float | None = None,
    extra: dict | None = None,
    ood: dict | None = None,
) -> Path:
    """Write a fitted classifier and its feature preprocessing to a model file (no pickle); return ``path``.

    ``class_names`` name the estimator's ``classes_`` in order; ``source`` says how raw input becomes
    features (:mod:`tactile_torch.robot.files.model_file`); the head takes ``(features[:, select] - center) / scale``.
    ``ood``: the fitted "unknown" rule (:func:`tactile_torch.ood.fit_rule` on those features, classes in
    the head's order), written as the file's ``ood`` part.
    """
    from .export.classifier_inference import encode_classifier
    from .robot.files.model_file import save_model_file

    method, head, head_arrays = encode_classifier(estimator)
    params = {
        k: v
        for k, v in estimator.get_params().items()
        if isinstance(v, str | int | float | bool) and k != "random_state"
    }
    header = {
        "kind": "classifier",
        "method": method,
        "class_names": [str(c) for c in class_names],
        "source": dict(source),
        "params": params,
        "head": head,
        **({"test_accuracy": float(test_accuracy)} if test_accuracy is not None else {}),
        **(extra or {}),
    }
    arrays = {"scale": np.asarray(scale, dtype=np.float64)}
    if center is not None:
        arrays["center"] = np.asarray(center, dtype=np.float64)
    if select is not None:
        arrays["select"] = np.asarray(select, dtype=np.int64)
    arrays.update({f"head.{name}": value for name, value in head_arrays.items()})
    if ood is not None:  # "unknown" as an answer (tactile_torch.ood): distances to the training classes
        header["ood"] = {
            "type": "mahalanobis",
            "quantile": ood["quantile"],
            "threshold": float(ood["threshold"]),
        }
        from .ood import OOD_ARRAYS

        arrays.update({f"ood.{k}": np.asarray(ood[k], dtype=np.float64) for k in OOD_ARRAYS if k in ood})
    return save_model_file(path, header, arrays)


def save_model(path: str | Path, model: TrainedModel, features: FeatureSet) -> Path:
    """Write a trained classifier (any of :data:`METHODS`) to a model file; return ``path``.

    The file (:mod:`tactile_torch.robot.files.model_file`, no pickle) holds the feature ``scale`` (and ``select``,
    the kept columns), the class names in the order of the classifier's labels, how features are made
    (``source``), the hyper-parameters, the held-out accuracy and the arrays of the classifier's
    inference module (:func:`~tactile_torch.export.classifier_inference.encode_classifier`), which is what
    ``tactile-torch export`` turns into ONNX.
    """
    from .ood import fit_rule

    names = [str(features.class_names[int(c)]) for c in model.estimator.classes_]
    # "unknown" as an answer: the distance of a sample's features to the training classes
    # (tactile_torch.ood, the rule every deployed graph carries), fitted on every row of the data
    classes = np.asarray(model.estimator.classes_)
    known = np.isin(features.y, classes)
    X = features.X[known] if model.select is None else features.X[known][:, model.select]
    ood = fit_rule(X, features.y[known], scale=model.scale)
    return write_classifier_file(
        path,
        model.estimator,
        class_names=names,
        source=_with_rule(features.source, model.early_rule),
        scale=model.scale,
        select=model.select,
        test_accuracy=float(model.report.overall_accuracy),
        ood=ood,
    )


def _with_rule(source: dict, rule) -> dict:
    """``source`` with the early-decision rule a frame model records for the live stream (``early_decision``)."""
    from .robot.contract import EARLY_RULE_KEY

    return source if rule is None else {**source, EARLY_RULE_KEY: rule.to_metadata()}


def load_model(path: str | Path):
    """Read and validate a classifier's model file (see :func:`tactile_torch.robot.files.model_file.load_model_file`).

    Returns a :class:`tactile_torch.robot.files.model_file.ModelFile`; nothing in it is unpickled.
    """
    from .robot.files.model_file import load_model_file

    return load_model_file(path, kind="classifier")


__all__ = [
    "METHODS",
    "TrainedModel",
    "held_out_folds",
    "load_model",
    "save_model",
    "train_classifier",
    "write_classifier_file",
]
