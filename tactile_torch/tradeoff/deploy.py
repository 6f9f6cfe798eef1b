"""Deploying a trade-off candidate: refit it on all the data, export it, write its model file.

The cross-validation measures a *procedure* (features, selection, scaling, classifier, and any tuning
inside it) on folds; what a robot runs is that procedure fitted once on all the data.
:func:`deploy_candidate` tunes the candidate as the folds did (its grid on inner folds of all the data,
:meth:`tactile_torch.engine.CVResult.final_model`), fits it with the chosen parameters on every sample
of its raw input and writes

* ``<name>.onnx``: raw input → labels and scores, with the metadata ``tactile-torch predict`` and
  ``stream`` read (one file, onnxruntime only); its labels are checked against the refitted
  pipeline's on up to :data:`CHECK_SAMPLES` samples;
* ``<name>.npz``: the same model as a model file (:mod:`tactile_torch.robot.model_file`, no pickle), which
  ``tactile-torch export`` turns into the same graph, for the feature sets a model file describes
  (vibration windows, RGB explorations, feature matrices, with or without a best-ranked subset);
  raw pressure maps and per-taxel features have no model-file form yet, said in one note.

``<name>`` is ``recommended`` for the recommended candidate, the candidate's slug otherwise.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from sklearn.base import clone

from ..robot.contract import (
    CLASS_NAMES_KEY,
    DEFAULT_RANGE_G,
    EARLY_RULE_KEY,
    FRAMES_LAYOUT,
    INPUT_LAYOUT_KEY,
    INPUT_SHAPE_KEY,
    PIPELINE_KEY,
    PRESSURE_LAYOUT,
    RANGE_METADATA_KEY,
    SAMPLE_RATE_KEY,
    STEP_KEY,
    WINDOW_SIZE_KEY,
)

CHECK_SAMPLES = 64
"""Samples on which the deployed ONNX file's labels are compared with the refitted pipeline's."""


def _slug(name: str) -> str:
    return "-".join("".join(ch if ch.isalnum() else " " for ch in name.lower()).split())


def _source(step: object, samples: object, rate_hz: float | None) -> dict | None:
    """The model file's ``source`` of a fitted ``features`` step, or ``None`` when it has no model-file form."""
    from ..image import DEFAULT_THRESHOLD
    from .transformers import FeaturePassthrough, ImageFeatureTransformer, WindowFeatureTransformer

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
    return None


def write_model_file(
    path: str | Path,
    model: object,
    class_names: tuple[str, ...],
    *,
    rate_hz: float | None,
    extra: dict | None = None,
) -> Path | None:
    """Write a fitted candidate ``Pipeline`` as a model file; return its path, or ``None`` if it has no form."""
    from ..training import write_classifier_file

    steps = model.named_steps
    source = _source(steps["features"], None, rate_hz)
    if source is None:
        return None
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
    )


def _json_params(params: dict) -> dict:
    out = {}
    for k, v in params.items():
        v = v.item() if isinstance(v, np.generic) else v
        out[k.split("__")[-1]] = v if isinstance(v, str | int | float | bool | type(None)) else repr(v)
    return out


def live_metadata(result: object, name: str, model: object) -> tuple[dict, list[str]]:
    """Return what a deployed frame bundle records for the live stream (``stream`` on taxel frames) and notes.

    The frame rate, the value range and the touch levels of the training explorations
    (:func:`tactile_torch.robot.touches.frame_metadata`; the contact direction and resting levels of a
    fitted :class:`~.transformers.PressureImageFeatures` when the candidate has one), and the
    early-decision rule calibrated on the study's held-out touches (:mod:`.touch_time`). ``{}`` for
    vibration windows and feature matrices.
    """
    from ..robot.touches import frame_metadata
    from .transformers import PressureImageFeatures

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


def deploy_candidate(
    result: object, name: str, out_dir: str | Path, pool: object, *, random_state: int = 0
) -> dict:
    """Refit candidate ``name`` of ``result`` on all its data; write ``<stem>.onnx`` (and ``<stem>.npz``).

    Parameters
    ----------
    result : TradeoffResult
    name : str
        A candidate of ``result`` (``ValueError`` naming the candidates otherwise).
    out_dir : path
    pool : ExportPool
        The study's pool (the feature graphs are already exported there).
    random_state : int
        Seeds the tuning on all the data (as the study's).

    Returns
    -------
    dict
        ``name``, ``onnx`` (path), ``model_file`` (path or ``None``), ``samples`` (fitted on),
        ``agreement`` (share of checked samples whose ONNX label equals the pipeline's), ``notes``.
    """
    from ..robot.runtime import OnnxPipeline
    from .evaluation import _head_modules, _stateless, features_key
    from .export import bind_head, export_fixed_head, export_front, export_head, head_key, join

    names = [r.candidate.name for r in result.results]
    if name not in names:
        raise ValueError(f"deploy must name a candidate of this study, got {name!r}; candidates: {names}")
    cand = result.result(name).candidate
    s = result.inputs[cand.input]
    data = result.data
    cv = result.result(name).cv
    params: dict = {}
    if cv is not None:  # tuned as in the folds, on inner folds of all the data, then fitted on all of it
        model, params = cv.final_model(s.X, s.y, s.groups, random_state=random_state)
    else:
        model = clone(cand.estimator).fit(s.X, s.y)
    stem = "recommended" if name == result.recommended else _slug(name)
    out = Path(out_dir)
    check = np.ascontiguousarray(
        s.X[np.linspace(0, len(s.y) - 1, min(CHECK_SAMPLES, len(s.y))).round().astype(int)]
    )
    from .learned import is_learned

    live, live_notes = live_metadata(result, name, model)
    if is_learned(model):  # a network or learned front end: its own graph, exported whole (docs/neural.md)
        return _deploy_learned(result, name, model, check, out / f"{stem}.onnx", len(s.y), live, live_notes)
    step = model.named_steps["features"]
    front = ("front", *features_key(cand))
    if not _stateless(step):
        front = (*front, "all data")
        pool.submit(front, export_front, step, check[:2], background=False)
    else:
        pool.submit(
            front, export_front, clone(step).fit(check[:2]), check[:2]
        )  # a no-op when already exported
    modules = _head_modules(model)
    n_features = int(step.transform(check[:1]).shape[1])
    head = ("head", *head_key(modules, n_features))
    pool.submit(head, export_head, modules, n_features, background=False)
    try:
        classifier = bind_head(pool.result(head), modules)
    except Exception:  # a structure that cannot be exported with free sizes
        plain = ("plain head", name, "all data")
        pool.submit(plain, export_fixed_head, modules, n_features, background=False)
        classifier = pool.result(plain)
    classes = model.named_steps["classifier"].classes_
    meta = {
        PIPELINE_KEY: f"tradeoff: {name}, fitted on all {len(s.y)} samples",
        INPUT_SHAPE_KEY: [None, *s.X.shape[1:]],
        INPUT_LAYOUT_KEY: s.layout,
        CLASS_NAMES_KEY: [data.class_names[int(c)] for c in classes],
    }
    if s.window is not None:
        meta.update({WINDOW_SIZE_KEY: s.window, STEP_KEY: s.window, SAMPLE_RATE_KEY: data.rate_hz})
        meta[RANGE_METADATA_KEY] = DEFAULT_RANGE_G
    meta.update(live)
    path = join(pool.result(front), classifier, out / f"{stem}.onnx", meta)
    agreement = float(np.mean(classes[OnnxPipeline(path).predict(check)] == model.predict(check)))
    notes = list(live_notes)
    model_file = write_model_file(
        out / f"{stem}.npz",
        model,
        data.class_names,
        rate_hz=data.rate_hz,
        extra={"tradeoff": {"candidate": name, "samples": len(s.y), "tuned": _json_params(params)}},
    )
    if model_file is None:
        notes.append(
            f"{stem}.npz not written: the feature set {cand.features!r} ({type(step).__name__}) has no model-file "
            f"form; {stem}.onnx is the deployable file"
        )
    return {
        "name": name,
        "onnx": str(path),
        "model_file": None if model_file is None else str(model_file),
        "samples": len(s.y),
        "params": _json_params(params),
        "agreement": agreement,
        "notes": notes,
    }


def _deploy_learned(
    result, name: str, model, check: np.ndarray, path: Path, samples: int, live: dict, live_notes: list[str]
) -> dict:
    """Export a learned candidate fitted on all the data (its int8 variant quantised as in the study)."""
    from ..neural import export_classifier
    from ..robot.runtime import OnnxPipeline
    from .int8 import quantise_bundle

    clf = model.steps[-1][1]
    s = result.inputs[result.result(name).candidate.input]
    meta = {PIPELINE_KEY: f"tradeoff: {name}, fitted on all {samples} samples"}
    if s.window is not None:
        meta.update({WINDOW_SIZE_KEY: s.window, STEP_KEY: s.window, SAMPLE_RATE_KEY: result.data.rate_hz})
    meta.update(live)
    names = [result.data.class_names[int(c)] for c in clf.classes_]
    path = export_classifier(clf, path, check[:2], class_names=names, metadata=meta)
    variant = result.result(name)
    if variant.quantisation is not None:
        quantised = path.with_name(f"{path.stem}-int8.onnx")
        quantise_bundle(path, quantised, calibration=check, mode=variant.quantisation)
        path = quantised.replace(path)
    agreement = float(np.mean(clf.classes_[OnnxPipeline(path).predict(check)] == model.predict(check)))
    notes = [
        *live_notes,
        f"{path.stem}.npz not written: a learned model has no model-file form; {path.name} is the deployable file",
    ]
    return {
        "name": name,
        "onnx": str(path),
        "model_file": None,
        "samples": samples,
        "params": {},
        "agreement": agreement,
        "notes": notes,
    }


__all__ = ["CHECK_SAMPLES", "deploy_candidate", "live_metadata", "write_model_file"]
