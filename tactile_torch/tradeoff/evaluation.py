"""Cross-validation, export and timing of every candidate of a trade-off study.

Stages (each with a progress bar):

1. **features**: a ``features`` step that learns nothing from the data (``stateless``) gives the same
   features whichever fold it is fitted on, so they are computed once per feature set for all
   samples, and its time is shared out over the samples. Steps that learn (the pressure maps'
   resting and pressed levels, a threshold from the histogram) are fitted on each training fold.
2. **cross-validation**: per fold, the rest of the pipeline is fitted on the training samples and
   scored on the test samples. *Fit time* = computing the training samples' features plus fitting
   the rest, averaged over folds.
3. **ONNX**: the first fold's fitted pipeline is exported (:mod:`.export`); its
   *latency* is the median time of ``OnnxPipeline.predict`` on one held-out sample (batch 1,
   onnxruntime on one thread, input validation included), its *size* the file's bytes, and its labels
   on the first fold's first :data:`PARITY_SAMPLES` test samples are compared with the pipeline's
   (``onnx_agreement``).
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from sklearn.base import clone
from sklearn.pipeline import Pipeline

from .candidates import Candidate
from .inputs import Samples

PARITY_SAMPLES = 8
"""Held-out samples on which each exported file's labels are compared with the pipeline's."""


@dataclass
class CandidateResult:
    """What was measured for one candidate (see the module notes for the definitions).

    Attributes
    ----------
    candidate : Candidate
    fold_accuracy : list of float
        Empty when fitting failed (see ``notes``).
    fit_s : float
    model : Pipeline or None
        Fitted on the first training fold (the exported one); ``None`` when fitting failed.
    latency_ms, size_bytes, decision_s, onnx_agreement : float or None
        ``None`` when the export failed (see ``notes``).
    onnx_file : str or None
    notes : list of str
        Warnings raised while fitting, export errors.
    parity_predictions : ndarray or None
        The first fold's predictions of its first :data:`PARITY_SAMPLES` test samples (what the
        exported file must reproduce).
    predictions : ndarray of shape (N,) or None
        Out-of-fold prediction of every sample of the candidate's raw input (``-1`` if never tested),
        for the per-unit accuracies of :mod:`.selection`.
    """

    candidate: Candidate
    fold_accuracy: list[float]
    fit_s: float
    model: Pipeline | None
    latency_ms: float | None = None
    size_bytes: int | None = None
    decision_s: float | None = None
    onnx_agreement: float | None = None
    onnx_file: str | None = None
    notes: list[str] = field(default_factory=list)
    parity_predictions: np.ndarray | None = field(default=None, repr=False)
    predictions: np.ndarray | None = field(default=None, repr=False)


def _stateless(step: object) -> bool:
    return bool(getattr(step, "stateless", False))


def _progress(items, desc: str, enabled: bool):
    if not enabled:
        return items
    from tqdm.auto import tqdm

    return tqdm(items, desc=desc, leave=False, dynamic_ncols=True)


def features_key(candidate: Candidate) -> tuple:
    """What the candidate's features depend on: its raw input and its ``features`` step (type, parameters)."""
    step = candidate.estimator.named_steps["features"]
    return candidate.input, type(step).__name__, repr(sorted(step.get_params().items()))


class _Features:
    """Features of every raw input and feature step, computed once (stateless) or per fold."""

    def __init__(self, samples: dict[str, Samples], precomputed: dict | None = None) -> None:
        self.samples = samples
        self._all: dict[tuple, tuple[np.ndarray, float]] = dict(precomputed or {})
        self._fold: dict[tuple, tuple[object, np.ndarray, np.ndarray, float]] = {}

    key = staticmethod(features_key)

    def precompute(self, candidate: Candidate) -> None:
        step = candidate.estimator.named_steps["features"]
        key = self.key(candidate)
        if _stateless(step) and key not in self._all:
            X = self.samples[candidate.input].X
            start = time.perf_counter()
            F = clone(step).fit(X).transform(X)
            self._all[key] = (F, time.perf_counter() - start)

    def fold(self, candidate: Candidate, k: int) -> tuple[object, np.ndarray, np.ndarray, float]:
        """Return ``(fitted step, train features, test features, seconds for the train features)``."""
        samples = self.samples[candidate.input]
        train, test = samples.folds[k]
        step = candidate.estimator.named_steps["features"]
        key = self.key(candidate)
        if _stateless(step):
            F, seconds = self._all[key]
            fitted = clone(step).fit(samples.X[train[:2]])  # learns the shape only
            return fitted, F[train], F[test], seconds * len(train) / len(samples.y)
        if (key, k) not in self._fold:
            start = time.perf_counter()
            fitted = clone(step).fit(samples.X[train])
            F_train = fitted.transform(samples.X[train])
            seconds = time.perf_counter() - start
            self._fold[(key, k)] = (fitted, F_train, fitted.transform(samples.X[test]), seconds)
        return self._fold[(key, k)]


def cross_validate(
    candidates: list[Candidate],
    samples: dict[str, Samples],
    *,
    precomputed: dict | None = None,
    progress: bool = True,
) -> list[CandidateResult]:
    """Stages 1 and 2 of the module notes for every candidate; return their results in order.

    ``precomputed`` maps :func:`features_key` to ``(features of every sample, seconds they took)`` for
    stateless steps whose features are already known (e.g. computed by an earlier report section).
    """
    features = _Features(samples, precomputed)
    for cand in _progress(candidates, "features", progress):
        features.precompute(cand)
    results = []
    for cand in _progress(candidates, "cross-validation", progress):
        s = samples[cand.input]
        accuracy, seconds, notes = [], [], set()
        model = None
        out_of_fold = np.full(len(s.y), -1, dtype=np.int64)
        try:
            for k, (train, test) in enumerate(s.folds):
                fitted_step, F_train, F_test, feature_s = features.fold(cand, k)
                tail = Pipeline([(name, clone(step)) for name, step in cand.estimator.steps[1:]])
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always")
                    start = time.perf_counter()
                    tail.fit(F_train, s.y[train])
                    seconds.append(feature_s + time.perf_counter() - start)
                    predicted = tail.predict(F_test)
                    accuracy.append(float(np.mean(predicted == s.y[test])))
                    out_of_fold[test] = predicted
                notes.update(f"{w.category.__name__}: {str(w.message).splitlines()[0]}" for w in caught)
                if k == 0:
                    model = Pipeline([("features", fitted_step), *tail.steps])
                    first_predictions = predicted[:PARITY_SAMPLES]
        except (
            ValueError,
            ArithmeticError,
            np.linalg.LinAlgError,
        ) as err:  # this candidate cannot learn here
            notes.add(f"fit failed: {type(err).__name__}: {str(err).splitlines()[0][:200]}")
            accuracy, model = [], None
        fit_s = float(np.mean(seconds)) if accuracy else float("nan")
        result = CandidateResult(cand, accuracy, fit_s, model, notes=sorted(notes))
        if model is not None:
            result.parity_predictions = first_predictions
            result.predictions = out_of_fold
        results.append(result)
    return results


def _head_modules(model: Pipeline) -> list:
    """The fitted steps after ``features`` as torch modules: selection, standardisation, classifier."""
    from ..baselines import inference_module
    from .export import Standardize, absorb_rbf_gamma, share_tree_depth
    from .transformers import ColumnSelect

    modules = []
    if "select" not in model.named_steps:  # an identity selection: heads with and without one share a graph
        n = model.named_steps["scale"].n_features_in_
        modules.append(ColumnSelect(np.arange(n)))
    for name, step in model.steps[1:]:
        if name == "classifier":
            head = inference_module(step)
            if modules and isinstance(modules[-1], Standardize):
                absorb_rbf_gamma(modules[-1], head)
            share_tree_depth(head)
            modules.append(head)
        elif hasattr(step, "to_module"):
            modules.append(step.to_module())
        elif hasattr(step, "scale_") and hasattr(step, "mean_"):  # StandardScaler
            modules.append(Standardize(step.mean_, step.scale_))
        else:
            raise TypeError(f"pipeline step {name!r} ({type(step).__name__}) has no export path")
    return modules


def submit_fronts(candidates: list[Candidate], samples: dict[str, Samples], pool: object) -> None:
    """Queue the export of every stateless feature graph (they do not depend on the folds) in ``pool``."""
    from .export import export_front

    for cand in candidates:
        step = cand.estimator.named_steps["features"]
        if _stateless(step):
            X = samples[cand.input].X
            pool.submit(("front", *features_key(cand)), export_front, clone(step).fit(X[:2]), X[:2])


def _slug(name: str) -> str:
    return "-".join("".join(ch if ch.isalnum() else " " for ch in name.lower()).split())


def export_and_time(
    results: list[CandidateResult],
    samples: dict[str, Samples],
    class_names: tuple[str, ...],
    out_dir: str | Path,
    pool: object,
    *,
    metadata: dict[str, object] | None = None,
    progress: bool = True,
) -> int:
    """Stage 3 of the module notes; fills ``latency_ms``, ``size_bytes``, ``decision_s``,
    ``onnx_agreement`` and ``onnx_file`` of every result. ``pool`` is an :class:`.export.ExportPool`.
    Returns the number of distinct exported parts the files join."""
    from ..metrics import time_per_sample
    from ..runtime import OnnxPipeline
    from .export import bind_head, export_fixed_head, export_front, export_head, head_key, join

    out_dir = Path(out_dir)
    plans, n_features_of = [], {}
    for res in results:  # queue every export first: the background process works while this one does
        cand, model = res.candidate, res.model
        if model is None:
            continue
        s = samples[cand.input]
        raw = np.ascontiguousarray(s.X[s.folds[0][1][:PARITY_SAMPLES]])
        step = model.named_steps["features"]
        front = ("front", *features_key(cand))
        if not _stateless(step):
            front = (*front, "fold 1")
            pool.submit(front, export_front, step, raw[:2])
        try:
            modules = _head_modules(model)
        except (TypeError, ValueError) as err:
            res.notes.append(f"no ONNX export: {err}")
            continue
        n_features = int(step.transform(raw[:1]).shape[1])
        n_features_of[cand.name] = n_features
        head = ("head", *head_key(modules, n_features))
        pool.submit(head, export_head, modules, n_features, background=False)
        plans.append((res, raw, front, head, modules))
    for res, raw, front, head, modules in _progress(plans, "ONNX export + latency", progress):
        cand, model = res.candidate, res.model
        s = samples[cand.input]
        classes = model.named_steps["classifier"].classes_
        meta = {
            "tactile_torch.pipeline": f"tradeoff: {cand.name}",
            "input_shape": [None, *s.X.shape[1:]],
            "input_layout": s.layout,
            "class_names": [class_names[int(c)] for c in classes],
            **(metadata or {}),
        }
        if s.window is not None:
            meta.update(window_size=s.window, step=s.window)
        try:
            try:
                classifier = bind_head(pool.result(head), modules)
            except Exception:  # a structure that cannot be exported with free sizes: this candidate alone
                plain = ("plain head", cand.name)
                pool.submit(plain, export_fixed_head, modules, n_features_of[cand.name], background=False)
                classifier = pool.result(plain)
            path = join(pool.result(front), classifier, out_dir / f"{_slug(cand.name)}.onnx", meta)
            pipe = OnnxPipeline(path)
            res.onnx_agreement = float(np.mean(classes[pipe.predict(raw)] == res.parity_predictions))
            res.latency_ms = 1e3 * time_per_sample(pipe.predict, raw[:1])
            res.size_bytes = int(path.stat().st_size)
            res.decision_s = s.acquisition_s + res.latency_ms / 1e3
            res.onnx_file = path.name
        except Exception as err:  # a failed export leaves the candidate out of the choice, said in its notes
            lines = [line for line in str(err).splitlines() if line.strip()]
            res.notes.append(f"ONNX export failed: {type(err).__name__}: {(lines or [''])[-1][:200]}")
    return len({key for plan in plans for key in plan[2:4]})


__all__ = [
    "PARITY_SAMPLES",
    "CandidateResult",
    "cross_validate",
    "export_and_time",
    "features_key",
    "submit_fronts",
]
