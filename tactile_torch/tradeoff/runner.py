"""``run_tradeoff``: a data file → candidates → accuracy, speed and size → the recommended model.

:func:`plan_tradeoff` reads the data and makes the candidates; :func:`~.execution.execute_plan` evaluates
them; :func:`run_tradeoff` does both and deploys the recommended model."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from ..export.parts import ExportPool
from .candidates import build_candidates, feature_sets
from .execution import TradeoffPlan, execute_plan
from .inputs import (
    WINDOW_SIZES,
    Samples,
    TradeoffData,
    allowed_windows,
    exploration_samples,
    load_tradeoff_data,
    vibration_samples,
)
from .summary import TradeoffResult
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


def plan_tradeoff(  # noqa: PLR0913
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
        Explorations: frames per second (default: the file's ``frame_rate_hz``; refused when it states none).
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
        data = load_tradeoff_data(data, frame_rate_hz=frame_rate_hz, allow_pickle=allow_pickle)
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
    "check_target",
    "plan_tradeoff",
    "run_tradeoff",
]
