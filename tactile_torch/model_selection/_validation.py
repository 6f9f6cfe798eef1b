"""Cross-validation of raw-input models with shared feature steps, nested tuning and parallel tasks."""

from __future__ import annotations

import time
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from sklearn.base import clone
from sklearn.pipeline import Pipeline

from ._models import Folds, Models, needs_fit, seed_of, take
from ._tasks import Backend, as_backend
from ._tuning import Tuning, tune


@dataclass
class CVResult:
    """What :func:`cross_validate` measured for one model.

    Attributes
    ----------
    name : str
    estimator : estimator
        The unfitted model (with its default parameters).
    tuning : Tuning or None
    predictions : ndarray of shape (N,)
        Every sample's out-of-fold prediction (from the fold that tested it); ``-1`` (or the labels'
        missing value) where untested or where the model failed.
    fold : ndarray of shape (N,), int
        Index of the fold that tested each sample; ``-1`` where untested.
    groups : ndarray of shape (N,)
        Each sample's group (recording, session, object; the sample itself without groups): the unit of
        group-level intervals.
    fold_accuracy : list of float
        Test accuracy per fold; empty when the model could not be fitted (``error``).
    fit_seconds, tune_seconds, feature_seconds : list of float
        Per fold: the whole fit (``feature_seconds`` for the training samples' features + tuning + the
        final fit), the tuning alone (inner folds), and the features alone.
    params : list of dict
        Per fold: the parameters tuning chose (``{}`` without tuning).
    tuning_notes : list of str
        Per fold: how the inner folds were made.
    models : list of Pipeline
        Per fold: the fitted model (features step included), when asked for (``keep_models``).
    notes : list of str
        Warnings raised while fitting (one line each, deduplicated).
    error : str or None
        Why the model could not be fitted, or ``None``.
    """

    name: str
    estimator: Any
    tuning: Tuning | None
    predictions: np.ndarray
    fold: np.ndarray
    groups: np.ndarray
    fold_accuracy: list[float] = field(default_factory=list)
    fit_seconds: list[float] = field(default_factory=list)
    tune_seconds: list[float] = field(default_factory=list)
    feature_seconds: list[float] = field(default_factory=list)
    params: list[dict] = field(default_factory=list)
    tuning_notes: list[str] = field(default_factory=list)
    models: list = field(default_factory=list, repr=False)
    notes: list[str] = field(default_factory=list)
    error: str | None = None

    @property
    def accuracy(self) -> float:
        """Mean test accuracy over the folds (NaN when the model failed)."""
        return float(np.mean(self.fold_accuracy)) if self.fold_accuracy else float("nan")

    @property
    def fit_s(self) -> float:
        """Mean seconds of one fold's fit, tuning included (NaN when the model failed)."""
        return float(np.mean(self.fit_seconds)) if self.fold_accuracy else float("nan")

    @property
    def tune_s(self) -> float:
        """Mean seconds of one fold's tuning (NaN when the model failed)."""
        return float(np.mean(self.tune_seconds)) if self.fold_accuracy else float("nan")

    def make_model(self, params: Mapping[str, Any] | None = None) -> Any:
        """Return an unfitted copy of the model with ``params`` set (default: its own parameters)."""
        return clone(self.estimator).set_params(**dict(params or {}))

    def final_model(
        self, X: Any, y: Any, groups: Any = None, *, random_state: int = 0, threads: int | None = None
    ) -> tuple[Any, dict]:
        """Return the model fitted on all of ``X``, tuned as in the folds, and the parameters chosen.

        Tuning (when the model has some) runs on inner folds of the whole set, with the protocol and
        grid of the cross-validation (grouped by ``groups`` where they allow), then the best parameters
        are fitted on all of ``X``: the model to deploy. A pipeline's slice after ``features`` keeps its
        step names, so the chosen names (``"classifier__C"``) apply to the whole model.
        """
        y = np.asarray(y)
        params: dict = {}
        if self.tuning is not None:
            step, rest = _split(self.estimator)
            Z = X if step is None else clone(step).fit(X, y).transform(X)
            g = None if groups is None else np.asarray(groups)
            params, _ = tune(
                rest, Z, y, g, self.tuning, seed_of(random_state, self.name, "final"), threads=threads
            )
        return self.make_model(params).fit(X, y), params


def _split(model: Any) -> tuple[Any, Any]:
    if isinstance(model, Pipeline) and model.steps[0][0] == "features" and len(model.steps) > 1:
        return model.steps[0][1], model[1:]
    return None, model


def _features_task(step: Any, X: Any, y: np.ndarray, train: np.ndarray | None, test: np.ndarray | None):
    """Fit a features step (on ``train``, or on all rows when ``train`` is None) and transform.

    Returns ``(fitted step, Z_train or Z_all, Z_test or None, seconds)`` or the exception."""
    start = time.perf_counter()
    try:
        if train is None:
            fitted = clone(step).fit(X, y)
            return fitted, fitted.transform(X), None, time.perf_counter() - start
        fitted = clone(step)
        Z_train = fitted.fit_transform(take(X, train), y[train])
        seconds = time.perf_counter() - start
        return fitted, Z_train, fitted.transform(take(X, test)), seconds
    except Exception as err:  # a degraded input may break the features step: the models say so
        return err


def _fit_task(rest, Z_train, y_train, g_train, Z_test, tuning, seed, threads):
    """Tune (inner folds) and fit a model rest on one fold's training features, predict its test ones."""
    from threadpoolctl import threadpool_limits

    out: dict[str, Any] = {"params": {}, "tune_s": 0.0, "how": "", "notes": []}
    # One BLAS thread: a task's matrices are small, and on a busy machine two BLAS threads made one
    # small SVD inside LDA's fit 30 times slower (the studies' serial_blas); tasks run side by side instead.
    with warnings.catch_warnings(record=True) as caught, threadpool_limits(limits=1, user_api="blas"):
        warnings.simplefilter("always")
        try:
            start = time.perf_counter()
            if tuning is not None:
                out["params"], out["how"] = tune(
                    rest, Z_train, y_train, g_train, tuning, seed, threads=threads
                )
            tuned = time.perf_counter()
            model = clone(rest).set_params(**out["params"]).fit(Z_train, y_train)
            out["fit_s"] = time.perf_counter() - tuned
            out["tune_s"] = tuned - start if tuning is not None else 0.0
            out["predicted"] = np.asarray(model.predict(Z_test))
            out["model"] = model
        except Exception as err:  # a degraded input may break any estimator in any way: record it
            lines = [line.strip() for line in str(err).splitlines() if line.strip()]
            out["error"] = f"{type(err).__name__}: {(lines or [''])[0]}"[:300]
    out["notes"] = sorted({f"{w.category.__name__}: {str(w.message).splitlines()[0][:200]}" for w in caught})
    return out


def cross_validate(  # noqa: PLR0913
    models: Mapping[str, Any],
    X: Any,
    y: Any,
    folds: Folds,
    *,
    groups: Any = None,
    tuning: Mapping[str, Tuning | None] | None = None,
    cache: Mapping[str, tuple[Any, float]] | None = None,
    backend: Backend | str | None = None,
    n_jobs: int | None = None,
    scheduler: str | None = None,
    random_state: int = 0,
    keep_models: bool = False,
    progress: bool = False,
    desc: str = "",
    features_out: dict | None = None,
    fold_ids: list[int] | None = None,
) -> dict[str, CVResult]:
    """Cross-validate raw-input models over ``folds``; return one :class:`CVResult` per model, in order.

    Stages (each a list of independent tasks run on ``backend``, with a progress bar):

    1. **features**: models whose first step is a ``Pipeline`` step named ``"features"`` share it with
       every model whose step has the same class and parameters. A step that needs no fit
       (scikit-learn's ``requires_fit`` tag is False) is computed once on all samples; its seconds are
       shared out over the samples. Any other step is fitted on each training fold.
    2. **fit**: per model and fold, the rest of the model is tuned on inner folds of the training part
       (``tuning[name]``; see :func:`~tactile_torch.model_selection.tune`), fitted with the chosen parameters and
       tested on the fold's test part.

    Parameters
    ----------
    models : mapping of name to estimator, or Models
        Clone-able scikit-learn classifiers on the raw input ``X`` (or already split, e.g. with a
        parameter of their feature steps changed).
    X : ndarray or tensor
        Raw input, ``(N, ...)``.
    y : array-like of shape (N,)
    folds : list of (train, test) index arrays
        Folds that keep groups apart (e.g. :func:`~tactile_torch.model_selection.make_folds`).
    groups : array-like of shape (N,), optional
        Group of each sample; inner tuning folds keep them apart too. Default: every sample its own.
    tuning : mapping of name to Tuning or None, optional
        Models not named (or ``None``) run at their own parameters.
    cache : mapping, optional
        Whole-set features of steps that need no fit, by :func:`~tactile_torch.model_selection.signature`:
        ``(Z, seconds)``; used instead of computing them. A ``dict`` given is filled with those computed
        here, so that a later call on other folds of the same samples reuses them.
    backend, n_jobs, scheduler
        Where the tasks run (:class:`~tactile_torch.model_selection.Backend`); results do not depend on them.
    random_state : int
        Seeds the inner folds (one seed per model and fold, derived from the names, not the order).
    keep_models : bool
        Keep every fold's fitted model (``CVResult.models``).
    progress : bool
    desc : str
        Prefix of the progress bars.
    features_out : dict, optional
        Filled with the features by signature: per fold ``(fitted step, Z_train, Z_test)``, or the
        exception of a step that failed (for sweeps that reuse them).
    fold_ids : list of int, optional
        The number of each of ``folds`` in a larger set (default ``0 .. len(folds) - 1``): a caller that
        runs the folds of one cross-validation a few at a time (to stop models early) gets the seeds,
        and ``CVResult.fold``, of the whole run.
    """
    y = np.asarray(y)
    group_ids = np.arange(len(y)) if groups is None else np.asarray(groups)
    runner = as_backend(backend, n_jobs, scheduler)
    split = models if isinstance(models, Models) else Models(models)
    tuning = dict(tuning or {})
    ids = list(range(len(folds))) if fold_ids is None else [int(k) for k in fold_ids]
    if len(ids) != len(folds):
        raise ValueError(f"fold_ids must name each of the {len(folds)} folds, got {len(ids)}")
    with runner:
        features = _FoldFeatures(split, X, y, folds)
        features.compute(runner, dict(cache or {}), desc, progress)
        if isinstance(cache, dict):  # the caller's cache gains the features computed on all samples
            cache.update((key, value) for key, value in features.whole.items() if key not in cache)
        if features_out is not None:
            features_out.update(features.export())
        by_model = _fit_stage(
            split, features, y, folds, groups, tuning, runner, random_state, desc, progress, ids
        )
    return {
        name: _result(
            name, split, features, by_model.get(name, {}), X, y, folds, group_ids, tuning, keep_models, ids
        )
        for name in split.names
    }


class _FoldFeatures:
    """Stage 1 of :func:`cross_validate`: the features of every distinct ``features`` step, per fold."""

    def __init__(self, split: Models, X: Any, y: np.ndarray, folds: Folds) -> None:
        self.split, self.X, self.y, self.folds = split, X, y, folds
        self.whole: dict[str, Any] = {}
        self.per_fold: dict[str, list] = {}
        self.failed: dict[str, str] = {}

    def compute(self, runner: Backend, cache: dict, desc: str, progress: bool) -> None:
        """Fit or compute every step not in ``cache`` (once on all samples when it needs no fit)."""
        tasks, where = [], []
        for key, step in self.split.steps.items():
            if step is None or key in cache:
                continue
            if needs_fit(step):
                for k, (tr, te) in enumerate(self.folds):
                    tasks.append((step, self.X, self.y, tr, te))
                    where.append((key, k))
            else:
                tasks.append((step, self.X, self.y, None, None))
                where.append((key, None))
        done = runner.map(_features_task, tasks, desc=f"{desc}features".strip(), progress=progress)
        self.whole = dict(cache)
        for (key, k), value in zip(where, done, strict=True):
            if isinstance(value, Exception):
                self.failed[key] = f"features: {type(value).__name__}: {value}"
            elif k is None:
                self.whole[key] = (value[1], value[3])
            else:
                self.per_fold.setdefault(key, [None] * len(self.folds))[k] = value

    def fold(self, key: str, k: int) -> tuple[Any, Any, Any, float]:
        """``(fitted step, Z_train, Z_test, seconds)`` of step ``key`` on fold ``k``."""
        tr, te = self.folds[k]
        step = self.split.steps[key]
        if step is None:
            return None, take(self.X, tr), take(self.X, te), 0.0
        if key in self.whole:
            Z, seconds = self.whole[key]
            return step, take(Z, tr), take(Z, te), seconds * len(tr) / len(self.y)
        return self.per_fold[key][k]

    def export(self) -> dict:
        """Per step: per fold ``(fitted step, Z_train, Z_test)``, or the error of a step that failed."""
        return {
            key: self.failed[key]
            if key in self.failed
            else [self.fold(key, k)[:3] for k in range(len(self.folds))]
            for key in self.split.steps
        }


def _fit_stage(split, features, y, folds, groups, tuning, runner, random_state, desc, progress, ids) -> dict:
    """Stage 2 of :func:`cross_validate`: tune, fit and test every model on every fold; ``{name: {k: out}}``."""
    threads = 1 if runner.parallel else None
    inner_groups = None if groups is None else np.asarray(groups)
    tasks, where = [], []
    for name in split.names:
        if name in split.errors or split.signature[name] in features.failed:
            continue
        for k, (tr, _) in enumerate(folds):
            _, Z_tr, Z_te, _ = features.fold(split.signature[name], k)
            g_tr = None if inner_groups is None else inner_groups[tr]
            seed = seed_of(random_state, name, ids[k])
            tasks.append((split.rest[name], Z_tr, y[tr], g_tr, Z_te, tuning.get(name), seed, threads))
            where.append((name, k))
    done = runner.map(_fit_task, tasks, desc=f"{desc}fit".strip(), progress=progress)
    by_model: dict[str, dict[int, dict]] = {}
    for (name, k), value in zip(where, done, strict=True):
        by_model.setdefault(name, {})[k] = value
    return by_model


def _result(name, split, features, outs, X, y, folds, group_ids, tuning, keep_models, ids) -> CVResult:
    """Stage 3 of :func:`cross_validate`: one model's :class:`CVResult` from its folds' outputs."""
    missing = -1 if np.issubdtype(y.dtype, np.integer) else None
    res = CVResult(
        name=name,
        estimator=split.models[name],
        tuning=tuning.get(name),
        predictions=np.full(len(y), missing, dtype=y.dtype if missing is not None else object),
        fold=np.full(len(y), -1, dtype=np.int64),
        groups=group_ids,
    )
    key = split.signature.get(name)
    res.error = split.errors.get(name) or features.failed.get(key)
    if res.error is not None:
        return res
    notes: set[str] = set()
    for k, (_, te) in enumerate(folds):
        out = outs[k]
        notes.update(out["notes"])
        if "error" in out:
            res.error = out["error"]
            break
        fitted_step, _, _, feature_s = features.fold(key, k)
        res.predictions[te] = out["predicted"]
        res.fold[te] = ids[k]
        res.fold_accuracy.append(float(np.mean(out["predicted"] == y[te])))
        res.feature_seconds.append(float(feature_s))
        res.tune_seconds.append(float(out["tune_s"]))
        res.fit_seconds.append(float(feature_s + out["tune_s"] + out["fit_s"]))
        res.params.append(dict(out["params"]))
        res.tuning_notes.append(out["how"])
        if keep_models:
            rest = out["model"]
            if fitted_step is None:
                res.models.append(rest)
            else:
                if not needs_fit(fitted_step):
                    fitted_step = clone(fitted_step).fit(take(X, te[:2]))  # learns the shapes only
                res.models.append(Pipeline([("features", fitted_step), *rest.steps]))
    if res.error is not None:
        res.fold_accuracy, res.fit_seconds, res.tune_seconds, res.models = [], [], [], []
        res.feature_seconds, res.params, res.tuning_notes = [], [], []
        res.predictions[:] = missing
        res.fold[:] = -1
    res.notes = sorted(notes)
    return res
