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
   on every test sample of the first fold are compared with the fold model's (``onnx_agreement``; the
   tests require every candidate's to be 1 on three data sets).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from sklearn.base import clone
from sklearn.pipeline import Pipeline

from ..model_selection import Backend, CVResult, needs_fit, progress_bar, signature
from ..model_selection import cross_validate as engine_cross_validate
from ..robot.contract import PIPELINE_KEY
from ..robot.files.naming import slug
from .bundle import measure_file, timing_metadata
from .candidates import Candidate, CandidateResult, features_key
from .inputs import Samples


def _stateless(step: object) -> bool:
    return not needs_fit(step)


def _merge(into: CVResult, more: CVResult) -> None:
    """Add the folds of ``more`` (the same model, other folds of the same samples) to ``into``."""
    if into.error is not None:
        return
    if more.error is not None:  # as the engine does: a model that fails on one fold has no result
        into.error = more.error
        into.fold_accuracy, into.fit_seconds, into.tune_seconds, into.models = [], [], [], []
        into.feature_seconds, into.params, into.tuning_notes = [], [], []
        into.predictions[:] = -1
        into.fold[:] = -1
        return
    tested = more.fold >= 0
    into.predictions[tested] = more.predictions[tested]
    into.fold[tested] = more.fold[tested]
    for name in (
        "fold_accuracy",
        "fit_seconds",
        "tune_seconds",
        "feature_seconds",
        "params",
        "tuning_notes",
        "models",
    ):
        getattr(into, name).extend(getattr(more, name))
    into.notes = sorted({*into.notes, *more.notes})


class FoldwiseCV:
    """Stages 1 and 2 of the module notes, one fold at a time: every running candidate is tested on fold
    ``k`` before any on fold ``k + 1``, so that the study can stop early the candidates that cannot be
    recommended (:mod:`.stopping`) and estimate the time left (:mod:`.progress`).

    The results do not depend on how the folds are cut into calls (each task's seed comes from the
    candidate's name and the fold's number, ``fold_ids`` of :func:`tactile_torch.model_selection.cross_validate`),
    nor on the backend.

    Parameters
    ----------
    candidates : list of Candidate
    samples : dict of str to Samples
    precomputed : dict, optional
        :func:`features_key` → ``(features of every sample, seconds they took)`` for steps that need no
        fit whose features are already known (e.g. computed by an earlier report section).
    progress : bool
    backend : Backend
    random_state : int
    """

    def __init__(
        self,
        candidates: list[Candidate],
        samples: dict[str, Samples],
        *,
        precomputed: dict | None = None,
        progress: bool = True,
        backend: Backend | None = None,
        random_state: int = 0,
    ) -> None:
        from ..model_selection import as_backend

        self.candidates = list(candidates)
        self.samples = samples
        self.progress = progress
        self.runner = as_backend(backend)
        self.random_state = random_state
        self.by_input: dict[str, list[Candidate]] = {}
        for cand in self.candidates:
            self.by_input.setdefault(cand.input, []).append(cand)
        self.caches: dict[str, dict] = {key: {} for key in self.by_input}
        for cand in self.candidates:
            known = (precomputed or {}).get(features_key(cand))
            if known is not None:
                self.caches[cand.input][signature(cand.estimator.named_steps["features"])] = known
        self.cv: dict[str, CVResult] = {}
        self.train_features: dict[str, object] = {}
        self.folds_done: dict[str, int] = {c.name: 0 for c in self.candidates}

    @property
    def n_folds(self) -> int:
        """The most folds of any raw input."""
        return max(len(self.samples[key].folds) for key in self.by_input)

    def run_fold(self, k: int, names: set[str] | list[str]) -> dict[str, float]:
        """Test the candidates ``names`` on fold ``k`` (those whose raw input has it); return each one's
        seconds on it (features of its training samples, tuning and fit)."""
        wanted = set(names)
        seconds = {}
        for key, cands in self.by_input.items():
            s = self.samples[key]
            run = [c for c in cands if c.name in wanted and k < len(s.folds) and self.folds_done[c.name] == k]
            if not run:
                continue
            features_out: dict = {}
            done = engine_cross_validate(
                {c.name: c.estimator for c in run},
                s.X,
                s.y,
                [s.folds[k]],
                groups=s.groups,
                tuning={c.name: c.tuning for c in run},
                cache=self.caches[key],
                backend=self.runner,
                random_state=self.random_state,
                keep_models=True,
                progress=self.progress,
                desc=f"{key}, fold {k + 1}: ",
                features_out=features_out if k == 0 else None,
                fold_ids=[k],
            )
            for cand in run:
                res = done[cand.name]
                self.folds_done[cand.name] = k + 1
                seconds[cand.name] = float(sum(res.fit_seconds))
                if k == 0:
                    self.cv[cand.name] = res
                    step = features_out.get(signature(cand.estimator.named_steps["features"]))
                    if isinstance(step, list):
                        self.train_features[cand.name] = step[0][1]
                else:
                    _merge(self.cv[cand.name], res)
        return seconds

    def result(self, cand: Candidate, into: CandidateResult | None = None) -> CandidateResult:
        """Return the :class:`CandidateResult` of ``cand`` from its folds so far (``into`` updated in place)."""
        res = self.cv[cand.name]
        notes = list(res.notes)
        if res.error is not None:
            notes.append(f"fit failed: {res.error[:200]}")
            if into is None:
                return CandidateResult(cand, [], float("nan"), None, notes=sorted(notes), cv=res)
            into.fold_accuracy, into.model, into.cv = [], None, res
            into.notes = sorted({*into.notes, *notes})
            return into
        if cand.tuning is not None:
            for how in sorted(set(res.tuning_notes)):
                notes.append(how if how.startswith("not tuned") else f"tuned on {how} of each training fold")
        if into is None:
            test = self.samples[cand.input].folds[0][1]
            into = CandidateResult(cand, [], 0.0, res.models[0], cv=res)
            into.parity_predictions = res.predictions[test]
            into.train_features = self.train_features.pop(cand.name, None)
        into.fold_accuracy = list(res.fold_accuracy)
        into.fit_s, into.tune_s, into.params = res.fit_s, res.tune_s, list(res.params)
        into.predictions = np.asarray(res.predictions)
        into.notes = sorted({*into.notes, *notes})
        return into


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
    """Stages 1 and 2 of the module notes for every candidate on every fold; return their results in order.

    ``precomputed`` maps :func:`features_key` to ``(features of every sample, seconds they took)`` for
    steps that need no fit whose features are already known. ``backend``, ``n_jobs`` and ``scheduler``
    say where the engine's tasks run (:class:`tactile_torch.model_selection.Backend`); the results do not depend
    on them. (The study itself runs :class:`FoldwiseCV` fold by fold, to stop candidates early.)
    """
    from ..model_selection import as_backend

    runner = as_backend(backend, n_jobs, scheduler)
    with runner:
        folds = FoldwiseCV(
            candidates,
            samples,
            precomputed=precomputed,
            progress=progress,
            backend=runner,
            random_state=random_state,
        )
        for k in range(folds.n_folds):
            folds.run_fold(k, [c.name for c in candidates])
    return [folds.result(c) for c in candidates]


def submit_fronts(candidates: list[Candidate], samples: dict[str, Samples], pool: object) -> None:
    """Queue the export of every stateless feature graph (they do not depend on the folds) in ``pool``."""
    from ..export.parts import export_front

    for cand in candidates:
        step = cand.estimator.named_steps["features"]
        if _stateless(step):
            X = samples[cand.input].X
            pool.submit(("front", *features_key(cand)), export_front, clone(step).fit(X[:2]), X[:2])


def export_and_time(
    results: list[CandidateResult],
    samples: dict[str, Samples],
    class_names: tuple[str, ...],
    out_dir: str | Path,
    pool: object,
    *,
    rate_hz: float | None = None,
    references: dict | None = None,
    progress: bool = True,
) -> int:
    """Stage 3 of the module notes; fills ``latency_ms``, ``size_bytes``, ``decision_s``,
    ``onnx_agreement`` and ``onnx_file`` of every result. ``pool`` is an :class:`~tactile_torch.export.parts.ExportPool`.

    Each timing file is what deploying the candidate's first-fold model would write
    (:func:`~.bundle.bare_bundle`, then :func:`~.bundle.finish_bundle`: its "unknown" rule fitted on the
    fold's training samples); the file without the rule stays in ``out_dir / "parts"`` for the int8
    variants (:func:`~.learned.add_int8_and_memory`). ``references``: per raw input, its reference feature
    set (the rule of a 1-D CNN on windows, :mod:`.unknown`). Returns the number of distinct exported parts."""
    from ..export.fitted import n_parameters
    from .bundle import bare_bundle, finish_bundle
    from .candidates import is_learned

    out_dir = Path(out_dir)
    parts = out_dir / "parts"
    chosen = []
    for res in results:
        if res.model is None:
            continue
        res.n_parameters = n_parameters(res.model)
        if is_learned(res.model):
            from .. import catalogue

            res.family = catalogue.entry(res.candidate.key).family
        chosen.append(res)
    # the classical ones first: their heads are exported here while the feature graphs finish in the
    # background process
    chosen.sort(key=lambda r: is_learned(r.model))
    before = pool.exports
    rules: dict = {}  # candidates that differ only in their classifier share their "unknown" rule
    ready = queue_classical_parts([r for r in chosen if not is_learned(r.model)], samples, pool, rules)
    for res in progress_bar(chosen, "ONNX export + latency", progress):
        cand, model = res.candidate, res.model
        s = samples[cand.input]
        train, test = s.folds[0]
        raw = np.ascontiguousarray(s.X[test[:2]])
        front = ("front", *features_key(cand))
        if needs_fit(model.named_steps["features"]):
            front = (*front, "fold 1")
        try:
            bare = bare_bundle(
                model,
                raw,
                parts / f"{slug(cand.name)}.bare.onnx",
                timing_metadata(cand, s, rate_hz),
                pool,
                front=front,
                class_names=class_names,
                layout=s.layout,
            )
            path, res.distance = finish_bundle(
                bare, out_dir / f"{slug(cand.name)}.onnx", model, s.X[train], s.y[train], pool,
                features=res.train_features, rules=rules, reference=(references or {}).get(cand.input),
                distance=ready.get(cand.name),
            )  # fmt: skip
            res.bare_file = bare
            res.onnx_agreement = agreement(path, model, s.X[test], res.parity_predictions)
            for key, value in measure_file(path, raw, s.acquisition_s).items():
                setattr(res, key, value)
            res.onnx_file = path.name
        except Exception as err:  # a failed export leaves the candidate out of the choice, said in its notes
            lines = [line for line in str(err).splitlines() if line.strip()]
            res.notes.append(f"ONNX export failed: {type(err).__name__}: {(lines or [''])[-1][:200]}")
        res.train_features = None  # what the rule needed: not kept
    return pool.exports - before


def queue_classical_parts(results: list, samples: dict, pool: object, rules: dict) -> dict:
    """Fit the "unknown" rule of every classical first-fold model and queue the export of every distinct
    classifier head and distance part, every other one to the pool's background process, so that the two
    processes export side by side (a dynamo export costs seconds; they were made one after another).
    Returns each candidate's rule as :func:`~.bundle.finish_bundle` takes it (``distance``); a candidate
    whose parts cannot be made is left to the per-candidate path, which says why in its notes."""
    from ..export.parts import export_head, head_key, head_modules
    from ..robot.contract import FEATURES_NAME
    from .bundle import RULE_SAMPLES, evenly, export_distance_part, rule_key
    from .unknown import classical_rule

    jobs: dict = {}
    ready = {}
    for res in results:
        model = res.model
        s = samples[res.candidate.input]
        train = s.folds[0][0]
        try:
            keep = evenly(len(train), RULE_SAMPLES)
            features = res.train_features
            features = model.named_steps["features"].transform(s.X[train]) if features is None else features
            features, y = np.asarray(features)[keep], s.y[train][keep]
            known = rule_key(model, features, y)
            if known not in rules:
                rules[known] = classical_rule(model, features, y)
            rule, part = rules[known]
            modules = head_modules(model)
        except Exception:  # said by the per-candidate path
            continue
        n = int(features.shape[1])
        jobs.setdefault(("head", *head_key(modules, n)), (export_head, modules, n))
        jobs.setdefault(("distance", *head_key([part], n)), (export_distance_part, part, n))
        ready[res.candidate.name] = (rule, part, n, FEATURES_NAME, None)
    for i, (key, (fn, *args)) in enumerate(jobs.items()):
        pool.submit(key, fn, *args, background=i % 2 == 1)
    return ready


AGREEMENT_BATCH = 32
"""Samples per run when a file's labels are compared with its model's."""


def agreement(path: str | Path, model: Pipeline, raw: np.ndarray, expected: np.ndarray) -> float:
    """Return the share of ``raw`` on which the bundle's labels equal ``expected`` (the fitted model's)."""
    from ..robot.contract import LABELS_OUTPUT
    from ..robot.runtime import OnnxPipeline

    pipe = OnnxPipeline(path)
    classes = model.steps[-1][1].classes_
    labels = np.concatenate(
        [
            np.asarray(
                pipe.run(pipe.validate(np.ascontiguousarray(raw[i : i + AGREEMENT_BATCH])))[LABELS_OUTPUT]
            )
            for i in range(0, len(raw), AGREEMENT_BATCH)
        ]
    ).astype(np.int64)
    return float(np.mean(classes[labels] == expected))


def classical_fold_file(
    pool: object, candidate: Candidate, samples: Samples, class_names: tuple[str, ...], metadata: dict
):
    """Return ``fold_file(model, path)``: writes a classical fold model of ``candidate`` to one ONNX file
    without its "unknown" rule (its stateless feature graph from ``pool``, its head bound to the fold's
    tensors: :func:`~.bundle.bare_bundle`); ``None`` for a features step fitted per fold (its graph would
    be exported once per fold)."""
    from .bundle import bare_bundle

    def fold_file(model: Pipeline, path: Path) -> Path | None:
        if needs_fit(model.named_steps["features"]):
            return None
        return bare_bundle(
            model,
            samples.X[:2],
            path,
            {PIPELINE_KEY: f"tradeoff: {candidate.name}", **metadata},
            pool,
            front=("front", *features_key(candidate)),
            class_names=class_names,
            layout=samples.layout,
        )

    return fold_file


__all__ = [
    "AGREEMENT_BATCH",
    "CandidateResult",
    "FoldwiseCV",
    "agreement",
    "classical_fold_file",
    "cross_validate",
    "export_and_time",
    "submit_fronts",
]
