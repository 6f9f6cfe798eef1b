"""Deploying a trade-off candidate: refit it on all the data, export it with its "unknown" rule, write its
model file.

The cross-validation measures a *procedure* (features, selection, scaling, classifier, and any tuning
inside it) on folds; what a robot runs is that procedure fitted once on all the data.
:func:`deploy_candidate` takes every sample of the candidate's raw input (the study's cap of samples per
class does not apply: at most :data:`DEPLOY_MAX_PER_CLASS` per class and about :data:`DEPLOY_MAX_SAMPLES`
in all, evenly spaced, said when it cuts), tunes
the candidate as the folds did (its grid on inner folds of those samples,
:meth:`tactile_torch.model_selection.CVResult.final_model`), fits it with the chosen parameters and writes

* ``<name>.onnx``: raw input → labels and scores, with the metadata ``tactile-torch predict`` and
  ``stream`` read (one file, onnxruntime only), written as the study's timing files are
  (:mod:`.bundle`); an int8 variant is quantised as in the study (its float twin refitted, then
  quantised, calibrated on training samples). Every file carries the "unknown" rule of
  :mod:`tactile_torch.ood` (the ``ood_distance`` output and its threshold, fitted on the same samples),
  measured on what the file computes anyway (:mod:`.unknown`): a classical model's on its own
  standardised features, a learned model's on its embedding. Its labels are checked against the
  refitted pipeline's on up to :data:`CHECK_SAMPLES` samples, and it is timed again (latency, size,
  memory: what the recommendation line, ``tradeoff.json`` and the charts then show);
* ``<name>.npz``: the same (float) model as a model file (:mod:`tactile_torch.robot.files.model_file`, no
  pickle) with the same rule, which ``tactile-torch export`` turns into the same graph, for the feature
  sets a model file describes (vibration windows, RGB explorations, feature matrices, with or without a
  best-ranked subset, per-taxel features of pressure maps or RGB frames, with the live stream's frame
  rate, touch levels and early rule); the image features of raw pressure maps and learned models have no
  model-file form yet, said in one note.

``<name>`` is ``recommended`` for the recommended candidate, the candidate's slug otherwise.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from sklearn.base import clone

from ..robot.contract import (
    EARLY_RULE_KEY,
    FRAMES_LAYOUT,
    LABELS_OUTPUT,
    PIPELINE_KEY,
    PRESSURE_LAYOUT,
)
from ..robot.files.naming import slug
from .bundle import touch_cost, window_metadata

CHECK_SAMPLES = 64
"""Samples on which the deployed ONNX file's labels are compared with the refitted pipeline's."""
DEPLOY_MAX_PER_CLASS = 1000
"""At most this many samples per class train the deployed model (evenly spaced; the study itself keeps
at most 60 with ``--quick``, 300 without): more data for the model the robot runs, at a bounded cost."""
DEPLOY_MAX_SAMPLES = 8000
"""And at most about this many in all (an SVM's kernel grows with the square): the full study's own size
on the bundled 28 surfaces (300 per class). The study's cap per class, when larger, is kept."""


def _source(step: object, rate_hz: float | None) -> dict | None:
    """The model file's ``source`` of a fitted ``features`` step, or ``None`` when it has no model-file form."""
    from ..features.transformers import (
        FeaturePassthrough,
        ImageFeatureTransformer,
        TaxelFeatureTransformer,
        WindowFeatureTransformer,
    )
    from ..image import DEFAULT_THRESHOLD

    if isinstance(step, WindowFeatureTransformer):
        return {
            "kind": "vibration",
            "window": int(step.window_size_),
            "step": int(step.window_size_),
            "rate_hz": float(rate_hz),
        }
    if isinstance(step, FeaturePassthrough):
        return {"kind": "features", "n_features": int(step.n_features_in_)}
    if isinstance(step, ImageFeatureTransformer):
        source = {
            "kind": "image",
            "fuse": bool(step.fuse),
            "frame_shape": [int(v) for v in step.frame_shape_],
        }
        if step.threshold_ != DEFAULT_THRESHOLD:
            source["threshold"] = float(step.threshold_)
        source["erosion"] = int(step.erosion_)
        return source
    if isinstance(step, TaxelFeatureTransformer):  # each taxel's time series: frames (RGB) or pressure maps
        shape = [int(v) for v in step.frame_shape_]
        if step.rgb_:
            return {"kind": "image", "features": "per-taxel", "fuse": True, "frame_shape": shape}
        return {"kind": "pressure", "features": "per-taxel", "frame_shape": shape}
    return None


def write_model_file(
    path: str | Path,
    model: object,
    class_names: tuple[str, ...],
    *,
    rate_hz: float | None,
    extra: dict | None = None,
    ood: dict | None = None,
    live: dict | None = None,
) -> Path | None:
    """Write a fitted candidate ``Pipeline`` as a model file; return its path, or ``None`` if it has no form.

    ``ood``: its "unknown" rule (:func:`tactile_torch.ood.fit_rule` on the model's standardised features);
    ``live``: frame models' metadata for the live stream (:func:`live_metadata`), kept in the source so that
    ``tactile-torch export`` writes the bundle the study deployed.
    """
    from ..training import write_classifier_file

    steps = model.named_steps
    source = _source(steps["features"], rate_hz)
    if source is None:
        return None
    source.update(live or {})
    scaler, classifier = steps["scale"], steps["classifier"]
    select = steps["select"].columns_ if "select" in steps else None
    return write_classifier_file(
        path,
        classifier,
        class_names=[class_names[int(c)] for c in classifier.classes_],
        source=source,
        scale=scaler.scale_,
        center=scaler.mean_,
        select=select,
        extra=extra,
        ood=ood,
    )


def _json_params(params: dict) -> dict:
    out = {}
    for k, v in params.items():
        v = v.item() if isinstance(v, np.generic) else v
        out[k.split("__")[-1]] = v if isinstance(v, str | int | float | bool | type(None)) else repr(v)
    return out


def deployment_samples(result: object, key: str) -> tuple[object, int]:
    """Return the samples of raw input ``key`` the deployed model is fitted on, and how many the data hold.

    Every sample (window, exploration, row) of the data, at most :data:`DEPLOY_MAX_PER_CLASS` per class
    and about :data:`DEPLOY_MAX_SAMPLES` in all (never fewer per class than the study had), evenly spaced,
    grouped as the study's folds are (sessions, recordings, time blocks, the file's groups) for the
    tuning's inner folds."""
    from .inputs import exploration_samples, vibration_samples

    s = result.inputs[key]
    data = result.data
    n_folds = len(s.folds)
    studied = int(np.bincount(s.y).max())
    cap = max(studied, min(DEPLOY_MAX_PER_CLASS, DEPLOY_MAX_SAMPLES // len(data.class_names)))
    if data.kind == "vibration":
        full = vibration_samples(
            data.recordings, s.window, n_folds=n_folds, max_per_class=cap, random_state=0
        )
        total = int(sum(len(signal) // s.window for signal in data.recordings.signals))
    else:
        full = exploration_samples(data, n_folds=n_folds, max_per_class=cap, random_state=0)
        total = len(data.labels)
    return full, total


def _evenly(n: int, k: int) -> np.ndarray:
    return np.linspace(0, n - 1, min(k, n)).round().astype(int)


def live_metadata(result: object, name: str, model: object) -> tuple[dict, list[str]]:
    """Return what a deployed frame bundle records for the live stream (``stream`` on taxel frames) and notes.

    The frame rate, the value range and the touch levels of the training explorations
    (:func:`tactile_torch.robot.stream.touches.frame_metadata`; the contact direction and resting levels of a
    fitted :class:`~tactile_torch.features.transformers.PressureImageFeatures` when the candidate has one), and the
    early-decision rule calibrated on the study's held-out touches (:mod:`.touch_time`). ``{}`` for
    vibration windows and feature matrices.
    """
    from ..features.transformers import PressureImageFeatures
    from ..robot.stream.touches import frame_metadata

    cand = result.result(name).candidate
    s = result.inputs[cand.input]
    if s.layout not in (PRESSURE_LAYOUT, FRAMES_LAYOUT):
        return {}, []
    step = model.steps[0][1]
    sign = rest = None
    contact = "raises"
    if isinstance(step, PressureImageFeatures):
        sign, rest = step.sign_, step.resting_
    else:  # the direction the study was told (its pressure-image candidates carry it)
        for other in result.results:
            first = other.candidate.estimator.steps[0][1]
            if other.candidate.input == cand.input and isinstance(first, PressureImageFeatures):
                contact = "raises" if first.contact == "auto" else first.contact
                break
    meta, note = frame_metadata(
        s.X,
        frame_rate_hz=result.data.rate_hz,
        rgb=s.layout == FRAMES_LAYOUT,
        contact=contact,
        sign=sign,
        rest=rest,
        levels=result.data.touch_levels,  # a hand's recordings: the levels their touches were cut at
    )
    notes = [note] if note else []
    curve = result.touch_time.get(name)
    if curve is None and result.result(name).cv is not None and result.result(name).cv.models:
        from .touch_time import touch_time

        curve = touch_time(result.result(name), s, result.data.rate_hz, quick=True)
    if curve is not None and curve.rule is not None:
        meta[EARLY_RULE_KEY] = curve.rule.to_metadata()
        notes.append(f"early decisions: {curve.rule.describe()}")
    return meta, notes


def _quantised_bare(bare: Path, quantised: Path, s: object, mode: str, learned: bool) -> Path:
    """Quantise the deployed file without its rule ``bare`` into ``quantised`` as the study did (its mode; a
    classical file's classifier only), calibrated on evenly spaced samples of ``s``; ``bare`` is removed."""
    from ..export.int8 import CLASSIFIER_PREFIX, quantise_bundle
    from ..robot.runtime import OnnxPipeline
    from .learned import CALIBRATION_SAMPLES

    calibration = OnnxPipeline(bare).validate(
        np.ascontiguousarray(s.X[_evenly(len(s.y), CALIBRATION_SAMPLES)])
    )
    prefix = None if learned else CLASSIFIER_PREFIX  # as in the study (tactile_torch.tradeoff.learned)
    try:
        quantise_bundle(bare, quantised, calibration=calibration, mode=mode, only_prefix=prefix)
    finally:
        bare.unlink(missing_ok=True)
    return quantised


def deploy_candidate(
    result: object, name: str, out_dir: str | Path, pool: object, *, random_state: int = 0
) -> dict:
    """Refit candidate ``name`` of ``result`` on all its data; write ``<stem>.onnx`` (and ``<stem>.npz``).

    Parameters
    ----------
    result : TradeoffResult
    name : str
        A candidate of ``result`` (``ValueError`` naming the candidates otherwise); an int8 variant
        deploys its float twin's procedure, quantised as in the study.
    out_dir : path
    pool : ExportPool
        The study's pool (the feature graphs are already exported there).
    random_state : int
        Seeds the tuning on all the data (as the study's).

    Returns
    -------
    dict
        ``name``, ``onnx`` (path), ``model_file`` (path or ``None``), ``samples`` (fitted on),
        ``available`` (samples the data hold), ``agreement`` (share of checked samples whose ONNX label
        equals the pipeline's), ``ood_threshold``, ``params``, the file's ``latency_ms``, ``size_bytes``,
        ``decision_s`` and ``memory_mib`` (the study's harness), ``touch_ms`` (frame bundles: inference per
        touch at most, :func:`touch_cost`), ``notes``.
    """
    from ..robot.runtime import OnnxPipeline
    from .bundle import bare_bundle, finish_bundle
    from .candidates import features_key, is_learned

    names = [r.candidate.name for r in result.results]
    if name not in names:
        raise ValueError(f"deploy must name a candidate of this study, got {name!r}; candidates: {names}")
    variant = result.result(name)
    base = result.result(variant.variant_of) if variant.variant_of is not None else variant
    cand = base.candidate
    s, available = deployment_samples(result, cand.input)
    params: dict = {}
    if base.cv is not None:  # tuned as in the folds, on inner folds of all the data, then fitted on all of it
        model, params = base.cv.final_model(s.X, s.y, s.groups, random_state=random_state)
    else:
        model = clone(cand.estimator).fit(s.X, s.y)
    stem = "recommended" if name == result.recommended else slug(name)
    out = Path(out_dir)
    check = np.ascontiguousarray(s.X[_evenly(len(s.y), CHECK_SAMPLES)])
    samples = (
        f"all {len(s.y)}"
        if len(s.y) == available
        else f"{len(s.y)} of {available} (evenly spaced: at most {DEPLOY_MAX_PER_CLASS} per class, about {DEPLOY_MAX_SAMPLES} in all)"
    )
    meta = {PIPELINE_KEY: f"tradeoff: {name}, fitted on {samples} samples"}
    meta.update(window_metadata(s, result.data.rate_hz))
    live, live_notes = live_metadata(result, name, model)  # frame bundles: rate, touch levels, early rule
    meta.update(live)
    learned = is_learned(model)
    path = out / f"{stem}.onnx"
    bare = out / f".{stem}.bare.onnx"
    front = ("front", *features_key(cand), *(() if _stateless(model) else ("all data",)))
    bare_bundle(
        model,
        check,
        bare,
        meta,
        pool,
        front=front,
        class_names=result.data.class_names,
        layout=s.layout,
    )
    notes = list(live_notes)
    if variant.quantisation is not None:
        bare = _quantised_bare(bare, out / f".{stem}.bare-int8.onnx", s, variant.quantisation, learned)
    try:
        path, (rule, *_) = finish_bundle(
            bare, path, model, s.X, s.y, pool, reference=result.references.get(cand.input)
        )
    finally:
        bare.unlink(missing_ok=True)
    pipe = OnnxPipeline(path)
    classes = model.steps[-1][1].classes_
    graph_labels = np.asarray(pipe.run(pipe.validate(check))[LABELS_OUTPUT], dtype=np.int64)
    agreement = float(np.mean(classes[graph_labels] == model.predict(check)))
    model_file = None
    if not learned:
        model_file = write_model_file(
            out / f"{stem}.npz",
            model,
            result.data.class_names,
            rate_hz=result.data.rate_hz,
            extra={"tradeoff": {"candidate": name, "samples": len(s.y), "tuned": _json_params(params)}},
            ood=rule,
            live=live,
        )
    if model_file is None:
        what = "a learned model" if learned else f"the feature set {cand.features!r}"
        notes.append(
            f"{stem}.npz not written: {what} has no model-file form; {stem}.onnx is the deployable file"
        )
    elif variant.quantisation is not None:
        notes.append(
            f"{stem}.npz holds the float model ({cand.name}): tactile-torch export writes its float graph; "
            f"{stem}.onnx is the int8 file"
        )
    from .bundle import measure_file
    from .memory import peak_memory_mib

    cost = measure_file(path, check[:1], s.acquisition_s)  # the study's harness, on the file written
    try:
        cost["memory_mib"] = peak_memory_mib(path, pipe.validate(check[:1]))
    except Exception as err:  # a late measurement: the file is written all the same
        cost["memory_mib"] = None
        notes.append(f"memory of {stem}.onnx not measured: {type(err).__name__}: {str(err)[:200]}")
    return {
        "name": name,
        "onnx": str(path),
        "model_file": None if model_file is None else str(model_file),
        "samples": len(s.y),
        "available": available,
        "params": _json_params(params),
        "agreement": agreement,
        "ood_threshold": float(rule["threshold"]),
        **cost,
        "touch_ms": touch_cost(cost["latency_ms"], live.get(EARLY_RULE_KEY), s),
        "notes": notes,
    }


def _stateless(model: object) -> bool:
    from ..model_selection import needs_fit

    return not needs_fit(model.named_steps["features"])


__all__ = [
    "CHECK_SAMPLES",
    "DEPLOY_MAX_PER_CLASS",
    "DEPLOY_MAX_SAMPLES",
    "deploy_candidate",
    "deployment_samples",
    "live_metadata",
    "write_model_file",
]
