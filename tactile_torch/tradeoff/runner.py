"""``run_tradeoff``: a data file → candidates → accuracy, speed and size → the recommended model."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..export.parts import ExportPool
from ..robot.contract import SAMPLE_RATE_KEY
from .candidates import build_candidates, feature_sets
from .evaluation import export_and_time, submit_fronts
from .inputs import (
    WINDOW_SIZES,
    Samples,
    TradeoffData,
    allowed_windows,
    exploration_samples,
    load_tradeoff_data,
    vibration_samples,
)
from .selection import unit_accuracy
from .summary import TradeoffResult, _unit_warnings, baseline_rows, summarise
from .validation import check_finite, check_folds_fit, check_target, check_two_classes

STUDY_WINDOW = 800
"""The vibration study's reference window (samples)."""
WHITE_SHARE = 0.10
"""RGB explorations: the study's threshold (240/255) is used when at least this share of the pixels is
white (>= 240/255, a pressure-mapping display's background); else Otsu's threshold of the histogram."""
MAX_PER_CLASS = {"quick": 60, "full": 300}
"""At most this many samples (windows) per class and raw input, evenly spaced in time."""


def _white_share(frames: np.ndarray) -> float:
    import torch

    from ..image import DEFAULT_THRESHOLD, to_grayscale

    sample = frames[:: max(1, len(frames) // 16), :: max(1, frames.shape[1] // 10)]
    gray = to_grayscale(torch.from_numpy(np.ascontiguousarray(sample)))
    return float((gray >= DEFAULT_THRESHOLD).float().mean())


def _resolve_threshold(data: TradeoffData, threshold: float | str, notes: list[str]) -> float | str:
    from ..image import DEFAULT_THRESHOLD

    if data.kind != "image" or threshold != "auto":
        return threshold
    share = _white_share(data.raw)
    if share >= WHITE_SHARE:
        notes.append(
            f"threshold: the study's 240/255 ({share:.0%} of the pixels are white, a display background)"
        )
        return DEFAULT_THRESHOLD
    notes.append(
        f"threshold: from each training fold's histogram (Otsu): only {share:.0%} of the pixels are white, "
        "so the study's 240/255 does not fit this display (threshold= to set one)"
    )
    return "otsu"


def _vibration_inputs(
    data: TradeoffData,
    *,
    window: int | None,
    windows: Sequence[int] | None,
    quick: bool,
    n_folds: int,
    cap: int | None,
    random_state: int,
    notes: list[str],
) -> tuple[list[int], dict[str, Samples]]:
    rec = data.recordings
    if window is not None:  # raises, naming the window, when it does not fit the recordings
        vibration_samples(rec, window, n_folds=n_folds, max_per_class=2 * n_folds)
    tried = list(windows) if windows is not None else sorted({*WINDOW_SIZES, *([window] if window else [])})
    allowed, reasons = allowed_windows(rec, tried, n_folds=n_folds)
    notes.extend(reasons)
    if window is not None and window not in allowed:
        allowed.append(window)
    if not allowed:
        longest = max(len(s) for s in rec.signals)
        raise ValueError(
            f"window: none of the window sizes {tried} fits the recordings (longest {longest} samples at "
            f"{rec.rate_hz:g} Hz) with {n_folds} folds; pass window="
        )
    if window is None:
        shorter = [w for w in allowed if w <= STUDY_WINDOW]
        window = max(shorter) if shorter else min(allowed)
    others = [w for w in allowed if w != window]
    if quick and others:
        others = [min(others)]
    chosen = [window, *others]
    inputs = {}
    for w in chosen:
        s = vibration_samples(rec, w, n_folds=n_folds, max_per_class=cap, random_state=random_state)
        inputs[s.key] = s
    return chosen, inputs


@dataclass
class TradeoffPlan:
    """What :func:`plan_tradeoff` decided: the raw inputs with their folds and the candidates.

    Attributes
    ----------
    data : TradeoffData
    inputs : dict of str to Samples
    candidates : list of Candidate
    notes : list of str
    precomputed : dict
        Features already known (see :attr:`TradeoffData.precomputed`), by features key.
    seconds : float
        Time spent planning.
    quick : bool
    references : dict of str to FeatureRecipe
        Per raw input, its reference feature set (all features: the 21 at the window, fused 12, all
        columns), on which a learned model's "unknown" rule is measured (:mod:`.deploy`).
    """

    data: TradeoffData
    inputs: dict[str, Samples]
    candidates: list
    notes: list[str]
    precomputed: dict = field(default_factory=dict)
    seconds: float = 0.0
    quick: bool = False
    references: dict = field(default_factory=dict)


def plan_tradeoff(
    data: str | Path | Sequence[str | Path] | TradeoffData,
    *,
    quick: bool = False,
    n_folds: int = 5,
    window: int | None = None,
    windows: Sequence[int] | None = None,
    frame_rate_hz: float | None = None,
    threshold: float | str = "auto",
    erosion: int | str = "relative",
    contact: str = "raises",
    max_per_class: int | str | None = "auto",
    classifiers: Sequence[str] | None = None,
    features: Sequence[str] | None = None,
    learned: bool = True,
    random_state: int = 0,
    allow_pickle: bool = False,
    csv_session: str = "number",
    exact_folds: bool = False,
    tune: bool = True,
    progress: bool = True,
    log: Callable[[str], None] = print,
) -> TradeoffPlan:
    """Read the data, cut the raw inputs, make the folds and the candidates.

    Parameters
    ----------
    data : path(s) or TradeoffData
        See :func:`~.inputs.load_tradeoff_data`.
    quick : bool
        Fewer candidates (every classifier on the reference feature set, HM-SVM and LDA on the others;
        two window sizes; one best-ranked subset) and at most 60 samples per class.
    n_folds : int
        Cross-validation folds (fewer when a class has fewer samples or groups).
    window : int, optional
        Vibration: the reference window (default: the study's 800 samples, or the largest allowed
        below it); ``windows`` overrides the list of sizes tried (default 200, 400, 800, 1600).
    frame_rate_hz : float, optional
        Explorations: frames per second (default 10, the study's).
    threshold : "auto", "otsu", "display" or float
        Image pipeline's pressed threshold. RGB frames: ``"auto"`` takes the study's 240/255 for
        displays with a white background, Otsu's threshold of each training fold's histogram
        otherwise; a float is a gray level in (0, 1]. Raw pressure maps: ``"auto"`` is ``"display"``
        (see :class:`~tactile_torch.features.transformers.PressureImageFeatures`); a float is a fraction of the pressure scale.
    erosion : "relative" or int
    contact : {"raises", "lowers", "auto"}
        Raw pressure maps: which way contact moves a reading.
    max_per_class : int, None or "auto"
        Samples kept per class and raw input (evenly spaced); ``"auto"``: 60 (quick) or 300.
    classifiers : sequence of str, optional
        Only these of :data:`~.candidates.CLASSIFIERS`.
    features : sequence of str, optional
        Only the feature sets whose name starts with one of these (e.g. ``["fused", "per-taxel"]``).
    learned : bool
        Add the learned models on the raw input (:mod:`.learned`; ``False``: the classical ones only).
    random_state : int
    allow_pickle : bool
    csv_session : {"number", "file"}
        CSV logs: session from the file name's trailing number, or one per file
        (:func:`~.inputs.load_tradeoff_data`).
    exact_folds : bool
        Raise ``ValueError`` when the data allow fewer than ``n_folds`` folds (default: use fewer,
        said in the split's description).
    tune : bool
        Tune every candidate inside each training fold (nested, :mod:`.candidates`); ``False`` runs them
        at the catalogue's defaults (for comparison; ``--no-tune``).
    progress : bool
        The learned models' progress bars over their epochs (the study's own bars are
        :func:`execute_plan`'s).
    log : callable
        Receives one line per stage.

    Returns
    -------
    TradeoffPlan

    Raises
    ------
    ValueError
        One line naming the argument: ``n_folds`` below 2 or above what the data allow (a class with
        fewer samples, groups or time blocks), ``max_per_class`` below 2, ``frame_rate_hz`` not
        positive and finite, ``window`` not a positive integer; data of a single class.
    """
    from ..model_selection import needs_fit
    from ..validation import check_positive
    from .candidates import features_key

    start = time.perf_counter()
    check_positive(n_folds, "n_folds", integer=True)
    if n_folds < 2:
        raise ValueError(f"n_folds must be >= 2, got {n_folds}")
    if window is not None:
        check_positive(window, "window", integer=True)
    if max_per_class not in ("auto", None) and (
        isinstance(max_per_class, bool)
        or not isinstance(max_per_class, int | np.integer)
        or max_per_class < 2
    ):
        raise ValueError(
            f"max_per_class must be 'auto' or a whole number >= 2 (two samples of every class "
            f"in every training fold), got {max_per_class!r}"
        )
    if frame_rate_hz is not None and not (
        isinstance(frame_rate_hz, int | float) and np.isfinite(frame_rate_hz) and frame_rate_hz > 0
    ):
        raise ValueError(
            f"frame_rate_hz must be a positive finite number of frames per second, got {frame_rate_hz!r}"
        )
    if not isinstance(data, TradeoffData):
        data = load_tradeoff_data(
            data, frame_rate_hz=frame_rate_hz, allow_pickle=allow_pickle, csv_session=csv_session
        )
    check_two_classes(data)
    check_finite(data)
    cap = MAX_PER_CLASS["quick" if quick else "full"] if max_per_class == "auto" else max_per_class
    notes = list(data.notes)
    log(f"[tradeoff] {data.description}")
    if data.kind == "vibration":
        chosen, inputs = _vibration_inputs(
            data,
            window=window,
            windows=windows,
            quick=quick,
            n_folds=n_folds,
            cap=cap,
            random_state=random_state,
            notes=notes,
        )
        sets, more = feature_sets("vibration", (), windows=chosen, quick=quick)
    else:
        s = exploration_samples(data, n_folds=n_folds, max_per_class=cap, random_state=random_state)
        inputs = {s.key: s}
        resolved = _resolve_threshold(data, threshold, notes)
        sets, more = feature_sets(
            data.kind,
            s.X.shape[1:],
            n_features=s.X.shape[1] if data.kind == "features" else None,
            quick=quick,
            threshold=resolved,
            erosion=erosion,
            contact=contact,
        )
    notes.extend(more)
    references: dict = {}  # per raw input, its reference feature set (all features; the first listed)
    for fs in sets:
        if fs.select is None:
            references.setdefault(fs.input, fs)
    if features is not None:
        kept = [fs for fs in sets if any(fs.name.startswith(prefix) for prefix in features)]
        if not kept:
            raise ValueError(
                f"features must start some of the feature sets {[fs.name for fs in sets]}, got {list(features)}"
            )
        notes.extend(f"feature set {fs.name!r} left out (features=)" for fs in sets if fs not in kept)
        sets = kept
    check_folds_fit(n_folds, inputs)
    if exact_folds:
        fewest = min(inputs.values(), key=lambda s: len(s.folds))
        if len(fewest.folds) < n_folds:
            raise ValueError(
                f"n_folds: {n_folds} folds asked, but the data allow {len(fewest.folds)} "
                f"({fewest.key}: {fewest.split}); ask for {len(fewest.folds)} or fewer"
            )
    candidates = build_candidates(
        sets, quick=quick, classifiers=classifiers, random_state=random_state, tune=tune
    )
    if learned and sets and data.kind in ("vibration", "image", "pressure"):
        from .learned import learned_candidates

        reference = sets[0].input
        candidates += learned_candidates(
            data.kind,
            reference,
            quick=quick,
            classifiers=classifiers,
            random_state=random_state,
            threshold=resolved if data.kind == "image" else "auto",
            window=inputs[reference].window,
            progress=progress,
        )
    if not candidates:
        raise ValueError(f"classifiers {list(classifiers)} leave no candidate in this mode (quick={quick})")
    precomputed = {}
    for cand in candidates:
        known = data.precomputed.get(cand.features)
        step = cand.estimator.named_steps["features"]
        if known is not None and not needs_fit(step):
            index = inputs[cand.input].index
            F, seconds = known
            precomputed[features_key(cand)] = (F[index], seconds * len(index) / len(F))
    return TradeoffPlan(
        data, inputs, candidates, notes, precomputed, time.perf_counter() - start, quick, references
    )


def execute_plan(
    plan: TradeoffPlan,
    pool: ExportPool,
    *,
    out_dir: str | Path,
    target: float | None = None,
    progress: bool = True,
    log: Callable[[str], None] = print,
    backend: str | None = None,
    n_jobs: int | None = None,
    scheduler: str | None = None,
    random_state: int = 0,
    exhaustive: bool = False,
    breaking: bool = False,
) -> TradeoffResult:
    """Cross-validate, export and time the candidates of ``plan`` (fronts already submitted to ``pool``).

    Fold by fold (:class:`~.evaluation.FoldwiseCV`): after the first fold every candidate's first-fold
    model is written as it would be deployed and timed (``out_dir / "timing"``: latency and size only,
    not for deployment), and after each fold but the last the candidates that cannot be recommended
    stop (:mod:`.stopping`; ``exhaustive=True``: none). ``target``: the accuracy a deployment needs
    (:func:`~.selection.choose`). ``backend``, ``n_jobs`` and ``scheduler`` say where the
    cross-validation tasks run (:class:`tactile_torch.model_selection.Backend`: ``"loky"``, ``"threading"``,
    ``"dask"`` with a scheduler address ...); the results do not depend on them. ``breaking``: the
    breaking points follow (only the estimate of the time left counts them).
    """
    from ..model_selection import as_backend
    from .evaluation import FoldwiseCV
    from .progress import RemainingTime, minutes
    from .stopping import EarlyStopping

    check_target(target)
    start = time.perf_counter()
    data, inputs = plan.data, plan.inputs
    submit_fronts(plan.candidates, inputs, pool)
    runner = as_backend(backend, n_jobs, scheduler)
    folds = FoldwiseCV(
        plan.candidates,
        inputs,
        precomputed=plan.precomputed,
        progress=progress,
        backend=runner,
        random_state=random_state,
    )
    n_folds = folds.n_folds
    units = {k: len(np.unique(s.units)) for k, s in inputs.items()}
    stopping = EarlyStopping(units, n_folds, target=target, enabled=not exhaustive)
    clock = RemainingTime()
    clock.plan(_planned_tasks(plan))
    log(
        f"[tradeoff] {len(plan.candidates)} candidates, {len(inputs)} raw input(s); cross-validating fold by fold "
        + (
            "(every candidate on every fold: exhaustive)"
            if exhaustive
            else "(candidates that cannot be recommended stop early)"
        )
    )
    by_name = {c.name: c for c in plan.candidates}
    results: dict[str, object] = {}
    cv_seconds = export_seconds = 0.0
    parts = 0
    with runner:
        for k in range(n_folds):
            stage = time.perf_counter()
            running = [c.name for c in plan.candidates if c.name not in stopping.stopped]
            for name, seconds in folds.run_fold(k, running).items():
                clock.finish((name, k), seconds)
                res = folds.result(by_name[name], results.get(name))
                results[name] = res
                if res.cv.error is None:
                    s = inputs[by_name[name].input]
                    test = s.folds[k][1]
                    ids, correct, count = unit_accuracy(s.y[test], res.cv.predictions[test], s.units[test])
                    stopping.record(name, by_name[name].input, [s.unit_name(i) for i in ids], correct, count)
            cv_seconds += time.perf_counter() - stage
            if k == 0:
                stage = time.perf_counter()
                meta_rate = data.rate_hz if data.kind in ("vibration", "image", "pressure") else None
                firsts = [results[c.name] for c in plan.candidates if c.name in results]
                parts = export_and_time(
                    firsts,
                    inputs,
                    data.class_names,
                    Path(out_dir) / "timing",
                    pool,
                    rate_hz=meta_rate,
                    progress=progress,
                )
                for res in firsts:
                    stopping.set_cost(res.candidate.name, res.decision_s if res.model is not None else None)
                    stop = stopping.stopped.get(res.candidate.name)
                    if stop is not None and res.model is not None:
                        res.stopped = stop.reason
                        clock.drop([(res.candidate.name, j) for j in range(1, n_folds)])
                export_seconds = time.perf_counter() - stage
                clock.finish(("exports",), export_seconds)
            if k < n_folds - 1:
                for name, stop in stopping.check(k + 1).items():
                    results[name].stopped = stop.reason
                    clock.drop([(name, j) for j in range(k + 1, n_folds)])
            clock.plan(_later_stages(plan, results, breaking=breaking, exhaustive=exhaustive))
            log(
                f"[tradeoff] fold {k + 1} of {n_folds}: {len(running)} candidates tested, "
                f"{len(stopping.stopped)} stopped early so far; {minutes(clock.remaining())} left"
            )
        # a candidate stopped by one that did not end above the baseline runs its other folds after all
        while True:
            rows, _, _ = summarise(
                [results[c.name] for c in plan.candidates if c.name in results], inputs, target=target
            )
            adequate = {r["name"]: bool(r["adequate"]) for r in rows if not r.get("stopped")}
            resume = stopping.to_resume(adequate)
            if not resume:
                break
            log(
                f"[tradeoff] {len(resume)} candidate(s) stopped early by one that ended below the baseline: running their other folds"
            )
            for name in resume:
                results[name].stopped = None
            for k in range(1, n_folds):
                for name in folds.run_fold(k, resume):
                    results[name] = folds.result(by_name[name], results[name])
    ordered = [results[c.name] for c in plan.candidates if c.name in results]
    log(
        f"[tradeoff] cross-validation: {cv_seconds:.1f} s; ONNX export and timing of the first folds' models "
        f'(written as deployed, with their "unknown" rule): {export_seconds:.1f} s ({parts} exported parts)'
    )
    stage = time.perf_counter()
    from .evaluation import classical_fold_file
    from .learned import add_int8_and_memory, measure_memory

    meta = {SAMPLE_RATE_KEY: data.rate_hz} if data.kind == "vibration" else {}

    def fold_file(cand, model, path):
        return classical_fold_file(pool, cand, inputs[cand.input], data.class_names, meta)(model, path)

    models_dir = Path(out_dir) / "timing"
    add_int8_and_memory(
        ordered,
        inputs,
        models_dir,
        fold_file=fold_file,
        pool=pool,
        quick=plan.quick,
        progress=progress,
        notes=plan.notes,
    )
    rows, recommended, runner_up = summarise(ordered, inputs, target=target)
    only = {r["name"] for r in rows if not r.get("stopped")}
    if plan.quick:  # a child process per file: the front, the learned and the int8 ones
        only = {
            r["name"]
            for r in rows
            if r["name"] in only and (r["pareto"] or r["family"] != "classical" or r["quantisation"])
        }
    measure_memory(ordered, inputs, models_dir, only=only, progress=progress)
    memory = {res.candidate.name: res.memory_mib for res in ordered}
    for row in rows:
        row["memory_mib"] = memory.get(row["name"])
    log(f"[tradeoff] int8 variants and memory: {time.perf_counter() - stage:.1f} s")
    baselines = baseline_rows(inputs)
    for b in baselines.values():
        b.pop("_units")
    result = TradeoffResult(
        data=data,
        results=ordered,
        rows=rows,
        recommended=recommended,
        runner_up=runner_up,
        splits={k: s.split for k, s in inputs.items()},
        notes=plan.notes,
        seconds=plan.seconds + time.perf_counter() - start,
        exports=parts,
        study_model=_study_model(plan),
        inputs=inputs,
        target=target,
        chance=1.0 / len(data.class_names),
        baselines=baselines,
        warnings=_unit_warnings(inputs),
        references=plan.references,
    )
    result.early_stopping = stopping
    if data.kind in ("image", "pressure"):  # how long the hand must hold (docs/tradeoff.md)
        from .touch_time import accuracy_vs_time

        stage = time.perf_counter()
        result.touch_time = accuracy_vs_time(result, quick=plan.quick, log=log)
        result.seconds += time.perf_counter() - stage
    return result


def _later_stages(plan: TradeoffPlan, results: dict, *, breaking: bool, exhaustive: bool) -> list:
    """The stages after the cross-validation, as tasks whose seconds come from the folds so far: the
    deployment (tuning and a fit on all the data: about two folds of the leading candidate) and the
    breaking points (:func:`~.breaking.refits` fits of the leader and of the study's model)."""
    from ..robustness.sweeps import infer_kind
    from .breaking import refits
    from .progress import Task

    done = [r for r in results.values() if r.fold_accuracy and r.model is not None and not r.stopped]
    if not done:
        return []
    leader = max(done, key=lambda r: float(np.mean(r.fold_accuracy)))

    def fit(res: object) -> float:
        return float(np.mean(res.cv.fit_seconds)) if res is not None and res.cv.fit_seconds else 0.0

    tasks = [Task(("deploy",), "deploy", "deploy", expected=2.0 * fit(leader))]
    if breaking:
        study = results.get(plan.candidates[0].name) if plan.candidates else None
        kind = infer_kind(plan.inputs[leader.candidate.input].X)
        n = refits(kind, quick=plan.quick or not exhaustive)
        tasks.append(Task(("breaking",), "breaking", "breaking", expected=n * (fit(leader) + fit(study))))
    return tasks


def _planned_tasks(plan: TradeoffPlan) -> list:
    """The study's cross-validation and export tasks, for the estimate of the time left (:mod:`.progress`)."""
    from .. import catalogue
    from .progress import Task

    tasks = []
    for cand in plan.candidates:
        s = plan.inputs[cand.input]
        family = (
            catalogue.entry(cand.key).family
            if cand.key in catalogue.LEARNED
            else ("svm" if cand.key in ("hmsvm", "svc") else "classical")
        )
        for k, (train, _) in enumerate(s.folds):
            tasks.append(Task((cand.name, k), cand.name, family, float(len(train))))
    tasks.append(Task(("exports",), "exports", "export", float(len(plan.candidates))))
    return tasks


def measured_on_deployed(row: dict, deployed: dict) -> None:
    """Put the costs measured on a deployed file into its candidate's row (``tradeoff.json``, the lines and
    the charts then show what the robot runs); the timing file's stay as ``timing_latency_ms`` and
    ``timing_size_bytes``. The choice was made on the timing files: a deployed model fitted on more
    samples (a kNN's neighbours, an SVM's support vectors) may cost more, said in a note."""
    from pathlib import Path as _Path

    row["timing_latency_ms"], row["timing_size_bytes"] = row["latency_ms"], row["size_bytes"]
    for key in ("latency_ms", "size_bytes", "decision_s", "memory_mib", "touch_ms"):
        if deployed.get(key) is not None:
            row[key] = deployed[key]
    row["measured_on"] = _Path(deployed["onnx"]).name
    before, after = row["timing_latency_ms"], row["latency_ms"]
    if before and after and after > 1.5 * before:
        row["notes"].append(
            f"{row['measured_on']} (fitted on {deployed['samples']} samples) runs in {after:.3g} ms against "
            f"{before:.3g} ms for its first-fold timing file: the model grows with its training samples"
        )


def _study_model(plan: TradeoffPlan) -> str | None:
    reference = plan.candidates[0].features if plan.candidates else None
    for cand in plan.candidates:
        if cand.classifier == "HM-SVM" and cand.features == reference:
            return cand.name
    return None


def run_tradeoff(
    data: str | Path | Sequence[str | Path] | TradeoffData,
    *,
    out_dir: str | Path,
    progress: bool = True,
    background: bool = True,
    deploy: str | Sequence[str] | None = "recommended",
    log: Callable[[str], None] = print,
    backend: str | None = None,
    n_jobs: int | None = None,
    scheduler: str | None = None,
    **options: object,
) -> TradeoffResult:
    """Evaluate every candidate model on a data file and recommend the simplest that does the job.

    Plans the study (:func:`plan_tradeoff`, which takes ``data`` and ``options``: ``quick``,
    ``n_folds``, ``window``, ``windows``, ``frame_rate_hz``, ``threshold``, ``erosion``, ``contact``,
    ``max_per_class``, ``classifiers``, ``features``, ``random_state``, ``allow_pickle``, ``tune``), then
    cross-validates (on ``backend``), exports and times the candidates (:func:`execute_plan`).

    Parameters
    ----------
    data : path(s) or TradeoffData
        See :func:`~.inputs.load_tradeoff_data`.
    out_dir : path
        The candidates' timing ``.onnx`` files (fitted on the first training fold: latency and size
        only, not for deployment) go to ``out_dir / "timing"``; the deployed model to
        ``out_dir / "recommended.onnx"`` and ``out_dir / "recommended.npz"`` (see ``deploy``). Required: nothing is written anywhere else
        (e.g. into the working directory).
    progress : bool
        Progress bars (stderr).
    background : bool
        Export the feature graphs in a second process while cross-validating.
    deploy : str, sequence of str or None
        ``"recommended"`` (default): refit the recommended candidate (if any) on all the data and write
        ``recommended.onnx`` and its model file ``recommended.npz`` (:mod:`.deploy`); a candidate's
        name: that one too (``<slug>.onnx``, ``<slug>.npz``); ``None``: nothing.
    log : callable
        Receives one line per stage.
    backend : {"sequential", "loky", "threading", "multiprocessing", "dask"} or None
        Where the cross-validation tasks (candidate x fold) run; default: in this process, or ``"loky"``
        worker processes when ``n_jobs`` is not 1. ``"dask"`` needs the optional extra ``dask``.
    n_jobs : int or None
        Workers (-1: every core or every worker of the cluster).
    scheduler : str or None
        ``backend="dask"``: the address of a running ``dask.distributed`` scheduler; ``None`` starts a
        local cluster for the run. Results do not depend on the backend or the number of workers.
    **options
        See :func:`plan_tradeoff`, ``target`` (the accuracy a deployment needs, in (0, 1]),
        ``exhaustive`` (evaluate every candidate on every fold: no early stops, :mod:`.stopping`) and
        ``estimate_breaking`` (the breaking points follow, :func:`~.job.run_tradeoff_job`: the estimate
        of the time left counts them).

    Returns
    -------
    TradeoffResult
    """
    from ..model_selection import Backend

    runner = Backend(backend, n_jobs, scheduler)  # checked before any work
    target = options.pop("target", None)
    check_target(target)
    exhaustive = bool(options.pop("exhaustive", False))
    breaking = bool(options.pop("estimate_breaking", False))
    plan = plan_tradeoff(data, log=log, progress=progress, **options)
    seed = int(options.get("random_state", 0))
    wanted = [deploy] if isinstance(deploy, str) else list(deploy or ())
    known = [c.name for c in plan.candidates]
    # an int8 variant (``NAME (int8)``, as tradeoff.json names it) is made after the cross-validation
    unknown = [d for d in wanted if d != "recommended" and d.removesuffix(" (int8)") not in known]
    if unknown:
        raise ValueError(
            f"deploy must name a candidate of this study, got {unknown[0]!r}; candidates: {known} "
            "(or their int8 variants, 'NAME (int8)')"
        )
    from ..exceptions import internal_stage

    # The input is accepted from here on: an error below is a bug (status 1), whatever its class.
    with ExportPool(Path(out_dir) / "timing" / "parts", background=background) as pool, runner:
        with internal_stage("cross-validation, export and timing"):
            result = execute_plan(
                plan,
                pool,
                out_dir=out_dir,
                target=target,
                progress=progress,
                log=log,
                backend=runner,
                random_state=seed,
                exhaustive=exhaustive,
                breaking=breaking,
            )
        names = [result.recommended if d == "recommended" else d for d in wanted]
        measured = {r.candidate.name for r in result.results}
        for name in dict.fromkeys(n for n in names if n is not None):
            from .deploy import deploy_candidate

            if name not in measured:  # an int8 variant the study did not make: the data's, not a bug
                result.notes.append(
                    f"deploy= {name!r} not written: the study made no such int8 variant (a quick study makes "
                    "them of the learned models only; a classical file with nothing to quantise has none)"
                )
                continue
            stage = time.perf_counter()
            try:
                deployed = deploy_candidate(result, name, out_dir, pool, random_state=seed)
                result.deployed.append(deployed)
                measured_on_deployed(result.row(name), deployed)
            except Exception as err:  # a late stage: the measured candidates are written all the same
                result.mark_incomplete(f"deployment of {name}", err)
                continue
            result.seconds += time.perf_counter() - stage
            log(
                f"[tradeoff] {name} refitted (tuned) on all the data and exported: "
                f"{time.perf_counter() - stage:.1f} s"
            )
        return result


__all__ = [
    "MAX_PER_CLASS",
    "STUDY_WINDOW",
    "TradeoffPlan",
    "check_target",
    "execute_plan",
    "plan_tradeoff",
    "run_tradeoff",
]
