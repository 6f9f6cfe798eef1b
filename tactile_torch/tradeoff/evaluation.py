"""Cross-validation, export and timing of every candidate of a trade-off study.

Stages (each with a progress bar):

1. **features** and 2. **cross-validation** run on the evaluation engine
   (:func:`tactile_torch.model_selection.cross_validate`), one raw input at a time, on the backend the caller
   chose (in this process, joblib's workers or a Dask cluster). A ``features`` step that needs no fit
   (scikit-learn's ``requires_fit`` tag is False) gives the same features whichever fold it is fitted
   on, so they are computed once per feature set for all samples, and its time is shared out over the
   samples; steps that learn (the pressure maps' resting and pressed levels, a threshold from the
   histogram) are fitted on each training fold. Per fold, each candidate is tuned on inner folds of the
   training part (:attr:`~.candidates.Candidate.tuning`), refitted with the chosen parameters and
   scored on the test part. *Fit time* = the training samples' features + tuning + the final fit,
   averaged over folds; *tuning time* is shown on its own too.
3. **ONNX**: the first fold's fitted pipeline is exported (:mod:`~tactile_torch.export.parts`); its
   *latency* is the median time of ``OnnxPipeline.predict`` on one held-out sample (batch 1,
   onnxruntime on one thread, input validation included), its *size* the file's bytes, and its labels
   on the first fold's first :data:`PARITY_SAMPLES` test samples are compared with the pipeline's
   (``onnx_agreement``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from sklearn.base import clone
from sklearn.pipeline import Pipeline

from ..model_selection import Backend, CVResult, needs_fit, progress_bar, signature
from ..model_selection import cross_validate as engine_cross_validate
from ..robot.contract import (
    CLASS_NAMES_KEY,
    INPUT_LAYOUT_KEY,
    INPUT_SHAPE_KEY,
    PIPELINE_KEY,
    STEP_KEY,
    WINDOW_SIZE_KEY,
)
from ..robot.files.naming import slug
from .candidates import Candidate, CandidateResult
from .inputs import Samples

PARITY_SAMPLES = 8
"""Held-out samples on which each exported file's labels are compared with the pipeline's."""


def _stateless(step: object) -> bool:
    return not needs_fit(step)


def features_key(candidate: Candidate) -> tuple:
    """What the candidate's features depend on: its raw input and its ``features`` step (type, parameters)."""
    step = candidate.estimator.named_steps["features"]
    return candidate.input, type(step).__name__, repr(sorted(step.get_params().items()))


def cross_validate(
    candidates: list[Candidate],
    samples: dict[str, Samples],
    *,
    precomputed: dict | None = None,
    progress: bool = True,
    backend: Backend | str | None = None,
    n_jobs: int | None = None,
    scheduler: str | None = None,
    random_state: int = 0,
) -> list[CandidateResult]:
    """Stages 1 and 2 of the module notes for every candidate; return their results in order.

    ``precomputed`` maps :func:`features_key` to ``(features of every sample, seconds they took)`` for
    steps that need no fit whose features are already known (e.g. computed by an earlier report
    section). ``backend``, ``n_jobs`` and ``scheduler`` say where the engine's tasks run
    (:class:`tactile_torch.model_selection.Backend`); the results do not depend on them.
    """
    from ..model_selection import as_backend

    runner = as_backend(backend, n_jobs, scheduler)
    by_input: dict[str, list[Candidate]] = {}
    for cand in candidates:
        by_input.setdefault(cand.input, []).append(cand)
    cv: dict[str, CVResult] = {}
    with runner:
        for key, cands in by_input.items():
            s = samples[key]
            cache = {}
            for cand in cands:
                known = (precomputed or {}).get(features_key(cand))
                if known is not None:
                    cache[signature(cand.estimator.named_steps["features"])] = known
            cv.update(
                engine_cross_validate(
                    {c.name: c.estimator for c in cands},
                    s.X,
                    s.y,
                    s.folds,
                    groups=s.groups,
                    tuning={c.name: c.tuning for c in cands},
                    cache=cache,
                    backend=runner,
                    random_state=random_state,
                    keep_models=True,
                    progress=progress,
                    desc=f"{key}: ",
                )
            )
    results = []
    for cand in candidates:
        res = cv[cand.name]
        notes = list(res.notes)
        if res.error is not None:
            notes.append(f"fit failed: {res.error[:200]}")
            results.append(CandidateResult(cand, [], float("nan"), None, notes=sorted(notes), cv=res))
            continue
        if cand.tuning is not None:
            for how in sorted(set(res.tuning_notes)):
                notes.append(how if how.startswith("not tuned") else f"tuned on {how} of each training fold")
        test = samples[cand.input].folds[0][1]
        result = CandidateResult(
            cand,
            list(res.fold_accuracy),
            res.fit_s,
            res.models[0],
            notes=sorted(notes),
            tune_s=res.tune_s,
            params=list(res.params),
            cv=res,
        )
        result.parity_predictions = res.predictions[test[:PARITY_SAMPLES]]
        result.predictions = np.asarray(res.predictions)
        results.append(result)
    return results


def submit_fronts(candidates: list[Candidate], samples: dict[str, Samples], pool: object) -> None:
    """Queue the export of every stateless feature graph (they do not depend on the folds) in ``pool``."""
    from ..export.parts import export_front

    for cand in candidates:
        step = cand.estimator.named_steps["features"]
        if _stateless(step):
            X = samples[cand.input].X
            pool.submit(("front", *features_key(cand)), export_front, clone(step).fit(X[:2]), X[:2])


def export_and_time(  # noqa: PLR0915
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
    ``onnx_agreement`` and ``onnx_file`` of every result. ``pool`` is an :class:`~tactile_torch.export.parts.ExportPool`.
    Returns the number of distinct exported parts the files join."""
    from ..export.fitted import n_parameters
    from ..export.parts import (
        bind_head,
        export_fixed_head,
        export_front,
        export_head,
        head_key,
        head_modules,
        join,
    )
    from ..metrics import time_per_sample
    from ..robot.runtime import OnnxPipeline
    from .learned import export_learned, is_learned

    out_dir = Path(out_dir)
    plans, n_features_of, learned = [], {}, []
    for res in results:  # queue every export first: the background process works while this one does
        cand, model = res.candidate, res.model
        if model is None:
            continue
        res.n_parameters = n_parameters(model)
        if is_learned(model):
            from .. import catalogue

            res.family = catalogue.entry(cand.key).family
            learned.append(res)
            continue
        s = samples[cand.input]
        raw = np.ascontiguousarray(s.X[s.folds[0][1][:PARITY_SAMPLES]])
        step = model.named_steps["features"]
        front = ("front", *features_key(cand))
        if not _stateless(step):
            front = (*front, "fold 1")
            pool.submit(front, export_front, step, raw[:2])
        try:
            modules = head_modules(model)
        except (TypeError, ValueError) as err:
            res.notes.append(f"no ONNX export: {err}")
            continue
        n_features = int(step.transform(raw[:1]).shape[1])
        n_features_of[cand.name] = n_features
        head = ("head", *head_key(modules, n_features))
        pool.submit(head, export_head, modules, n_features, background=False)
        plans.append((res, raw, front, head, modules))
    for res, raw, front, head, modules in progress_bar(plans, "ONNX export + latency", progress):
        cand, model = res.candidate, res.model
        s = samples[cand.input]
        classes = model.named_steps["classifier"].classes_
        meta = {
            PIPELINE_KEY: f"tradeoff: {cand.name}",
            INPUT_SHAPE_KEY: [None, *s.X.shape[1:]],
            INPUT_LAYOUT_KEY: s.layout,
            CLASS_NAMES_KEY: [class_names[int(c)] for c in classes],
            **(metadata or {}),
        }
        if s.window is not None:
            meta.update({WINDOW_SIZE_KEY: s.window, STEP_KEY: s.window})
        try:
            try:
                classifier = bind_head(pool.result(head), modules)
            except Exception:  # a structure that cannot be exported with free sizes: this candidate alone
                plain = ("plain head", cand.name)
                pool.submit(plain, export_fixed_head, modules, n_features_of[cand.name], background=False)
                classifier = pool.result(plain)
            path = join(pool.result(front), classifier, out_dir / f"{slug(cand.name)}.onnx", meta)
            pipe = OnnxPipeline(path)
            res.onnx_agreement = float(np.mean(classes[pipe.predict(raw)] == res.parity_predictions))
            res.latency_ms = 1e3 * time_per_sample(pipe.predict, raw[:1])
            res.size_bytes = int(path.stat().st_size)
            res.decision_s = s.acquisition_s + res.latency_ms / 1e3
            res.onnx_file = path.name
        except Exception as err:  # a failed export leaves the candidate out of the choice, said in its notes
            lines = [line for line in str(err).splitlines() if line.strip()]
            res.notes.append(f"ONNX export failed: {type(err).__name__}: {(lines or [''])[-1][:200]}")
    for res in progress_bar(learned, "ONNX export (learned models)", progress):
        s = samples[res.candidate.input]
        raw = np.ascontiguousarray(s.X[s.folds[0][1][:PARITY_SAMPLES]])
        try:
            path = export_learned(
                res, s, class_names, out_dir / f"{slug(res.candidate.name)}.onnx", metadata or {}
            )
            pipe = OnnxPipeline(path)
            classes = res.model.steps[-1][1].classes_
            res.onnx_agreement = float(np.mean(classes[pipe.predict(raw)] == res.parity_predictions))
            res.latency_ms = 1e3 * time_per_sample(pipe.predict, raw[:1])
            res.size_bytes = int(path.stat().st_size)
            res.decision_s = s.acquisition_s + res.latency_ms / 1e3
            res.onnx_file = path.name
        except Exception as err:
            lines = [line for line in str(err).splitlines() if line.strip()]
            res.notes.append(f"ONNX export failed: {type(err).__name__}: {(lines or [''])[-1][:200]}")
    return len({key for plan in plans for key in plan[2:4]}) + len(learned)


def classical_fold_file(
    pool: object, candidate: Candidate, samples: Samples, class_names: tuple[str, ...], metadata: dict
):
    """Return ``fold_file(model, path)``: writes a classical fold model of ``candidate`` to one ONNX file
    (its stateless feature graph from ``pool``, its head bound to the fold's tensors); ``None`` for a
    features step fitted per fold (its graph would be exported once per fold)."""
    from ..export.parts import bind_head, export_head, head_key, head_modules, join

    def fold_file(model: Pipeline, path: Path) -> Path | None:
        step = model.named_steps["features"]
        if not _stateless(step):
            return None
        modules = head_modules(model)
        n_features = int(step.transform(samples.X[:1]).shape[1])
        head = ("head", *head_key(modules, n_features))
        pool.submit(head, export_head, modules, n_features, background=False)
        classes = model.named_steps["classifier"].classes_
        meta = {
            PIPELINE_KEY: f"tradeoff: {candidate.name}",
            INPUT_SHAPE_KEY: [None, *samples.X.shape[1:]],
            INPUT_LAYOUT_KEY: samples.layout,
            CLASS_NAMES_KEY: [class_names[int(c)] for c in classes],
            **metadata,
        }
        front = pool.result(("front", *features_key(candidate)))
        return join(front, bind_head(pool.result(head), modules), path, meta)

    return fold_file


__all__ = [
    "PARITY_SAMPLES",
    "CandidateResult",
    "classical_fold_file",
    "cross_validate",
    "export_and_time",
    "features_key",
    "submit_fronts",
]
