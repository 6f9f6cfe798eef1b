"""The file a trade-off candidate is deployed as, written the same way for timing and for deployment.

What a robot runs is what the study times: a candidate's timing file (its first fold's model) and its
deployed file (refitted on all the data, ``recommended.onnx``) are written by the same two steps,

1. :func:`bare_bundle`: the candidate's graph, raw input → labels and scores (a classical candidate's
   feature graph joined to its classifier head, :mod:`~tactile_torch.export.parts`; a learned one exported whole with its
   embedding as a third output, :class:`~tactile_torch.export.neural.EmbeddingGraph`), with the bundle's metadata (frame
   bundles: the live stream's touch levels and early-decision rule); an int8 variant quantises this
   file (:func:`~tactile_torch.export.int8.quantise_bundle`);
2. :func:`finish_bundle`: the "unknown" rule fitted on the model's training samples as the file computes
   them, its distance part attached to the tensor it reads (:mod:`.unknown`), sealed and saved.

So the latency, size and memory of a timing file are those of the deployed file of the same candidate
up to the fitted values (the deployed model is fitted on more samples: a kNN's neighbours and an SVM's
support vectors grow with them), and ``recommended.onnx`` is timed again when written
(:func:`tactile_torch.tradeoff.deploy.deploy_candidate`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..robot.contract import (
    CLASS_NAMES_KEY,
    DEFAULT_RANGE_G,
    FEATURES_NAME,
    INPUT_LAYOUT_KEY,
    INPUT_SHAPE_KEY,
    OOD_OUTPUT,
    PIPELINE_KEY,
    RANGE_METADATA_KEY,
    SAMPLE_RATE_KEY,
    STEP_KEY,
    WINDOW_SIZE_KEY,
)
from .candidates import Candidate, is_learned
from .inputs import Samples

RULE_SAMPLES = 2000
"""At most this many training samples (evenly spaced) fit a timing file's "unknown" rule."""


def evenly(n: int, k: int) -> np.ndarray:
    """Return ``min(k, n)`` indices evenly spaced over ``0 .. n - 1``."""
    return np.linspace(0, n - 1, min(k, n)).round().astype(int)


def bare_bundle(
    model: object,
    example: np.ndarray,
    path: str | Path,
    metadata: dict,
    pool: object,
    *,
    front: tuple,
    class_names: tuple[str, ...],
    layout: str,
) -> Path:
    """Write a fitted candidate's graph (no "unknown" rule yet) to ``path``; return it.

    Parameters
    ----------
    model : Pipeline
        A fitted candidate (``features``, ..., ``classifier``).
    example : ndarray
        At least two raw inputs (the export's example; the batch stays free).
    metadata : dict
        The bundle's metadata (pipeline, window, rate, touch levels ...).
    pool : ExportPool
        The study's exports (feature graphs and classifier structures, shared between candidates).
    front : tuple
        The pool key of the candidate's feature graph (submitted here when the step is fitted per fold).
    class_names : tuple of str
        The data's class names (labels index the classifier's ``classes_``).
    layout : str
        The raw input's layout (``"B,3,W"`` ...).
    """
    from sklearn.base import clone

    from ..export.parts import (
        bind_head,
        export_fixed_head,
        export_front,
        export_head,
        head_key,
        head_modules,
        join,
    )
    from ..model_selection import needs_fit

    path = Path(path)
    example = np.ascontiguousarray(example[:2])
    clf = model.steps[-1][1]
    names = [class_names[int(c)] for c in clf.classes_]
    if is_learned(model):
        from ..export.neural import EmbeddingGraph, export_classifier

        return export_classifier(
            clf, path, example, class_names=names, metadata=metadata, graph=EmbeddingGraph(clf.to_module())
        )
    step = model.named_steps["features"]
    if needs_fit(step):
        pool.submit(front, export_front, step, example, background=False)
    else:  # a no-op when already exported (the study submits every stateless front at its start)
        pool.submit(front, export_front, clone(step).fit(example), example)
    modules = head_modules(model)
    n_features = int(step.transform(example[:1]).shape[1])
    head = ("head", *head_key(modules, n_features))
    pool.submit(head, export_head, modules, n_features, background=False)
    try:
        classifier = bind_head(pool.result(head), modules)
    except Exception:  # a structure that cannot be exported with free sizes: this candidate alone
        plain = ("plain head", path.name)
        pool.submit(plain, export_fixed_head, modules, n_features, background=False)
        classifier = pool.result(plain)
    meta = {
        **metadata,
        INPUT_SHAPE_KEY: [None, *example.shape[1:]],
        INPUT_LAYOUT_KEY: layout,
        CLASS_NAMES_KEY: names,
    }
    return join(pool.result(front), classifier, path, meta)


def export_distance_part(part: object, n_inputs: int, path: Path) -> Path:
    """Export a distance part (:class:`tactile_torch.ood.DistanceHead`) for ``n_inputs`` features, its fitted
    arrays as inputs of dynamic size (:func:`tactile_torch.export.parts.export_head`); return ``path``."""
    from ..export.parts import export_head

    return export_head([part], n_inputs, path, output_names=(OOD_OUTPUT,))


def rule_key(model: object, features: np.ndarray, y: np.ndarray) -> str:
    """What a classical rule depends on, as a digest: features, labels, selected columns, standardisation."""
    import hashlib

    steps = model.named_steps
    digest = hashlib.sha256()
    for part in (
        np.ascontiguousarray(features, dtype=np.float64),
        np.asarray(y),
        np.asarray(steps["select"].columns_ if "select" in steps else []),
        np.asarray(steps["scale"].mean_),
        np.asarray(steps["scale"].scale_),
    ):
        digest.update(str(part.shape).encode())
        digest.update(np.ascontiguousarray(part).tobytes())
    return digest.hexdigest()


def finish_bundle(
    bare: str | Path,
    path: str | Path,
    model: object,
    X: np.ndarray,
    y: np.ndarray,
    pool: object,
    *,
    features: np.ndarray | None = None,
    distance: tuple | None = None,
    rules: dict | None = None,
    reference: object = None,
) -> tuple[Path, tuple]:
    """Fit the "unknown" rule of ``bare`` (a :func:`bare_bundle`, or its int8 copy) and write the bundle
    with it to ``path``; return the path and the rule's ``(rule, distance part, its number of inputs,
    the tensor it reads, the pool key of its own feature graph or None)``.

    The rule is fitted on the training raw input ``X`` and labels ``y`` of ``model`` (at most
    :data:`RULE_SAMPLES`, evenly spaced), on what the file computes (:mod:`.unknown`): a classical model's
    features (``features``: the ``features`` step's output for ``X`` when already known), a learned
    model's embedding as the file itself computes it for ``X`` (an int8 file's own), a 1-D CNN's
    ``reference`` features (a :class:`~.candidates.FeatureRecipe`: their graph, the study's, joins the
    file). ``distance``: a rule already fitted (an int8 file whose rule reads float features: its float
    twin's). ``rules``: a dict the caller keeps across calls, holding the classical rules fitted so far by
    what they depend on (features, labels, selected columns, standardisation): candidates that differ
    only in their classifier share one (a rule on 2400 per-frame features costs seconds to fit).
    """
    from ..export.neural import EMBEDDING_OUTPUT
    from ..export.ood_branch import distance_branch, write_with_distance
    from ..export.parts import bind_head, export_front, head_key
    from ..robot.contract import INPUT_NAME
    from ..robot.runtime import OnnxPipeline
    from .unknown import classical_rule, embedding_rule, on_reference_features, reference_rule

    keep = evenly(len(y), RULE_SAMPLES)
    X, y = X[keep], np.asarray(y)[keep]
    front = None
    if distance is not None:
        rule, part, n_inputs, reads, front = distance
    elif is_learned(model) and reference is not None and on_reference_features(model):
        step = reference.make().fit(X, y)
        rule, part, ref = reference_rule(step, X, y)
        front = ("front", reference.input, type(step).__name__, repr(sorted(step.get_params().items())))
        pool.submit(front, export_front, step, np.ascontiguousarray(X[:2]))  # the study's: already there
        reads, n_inputs = INPUT_NAME, ref.shape[1]
    elif is_learned(model):
        pipe = OnnxPipeline(bare)
        E = np.concatenate(
            [pipe.run(X[i : i + 256])[EMBEDDING_OUTPUT] for i in range(0, len(X), 256)]
        ).astype(np.float64)
        rule, part = embedding_rule(E, y)
        reads, n_inputs = EMBEDDING_OUTPUT, E.shape[1]
    else:
        features = model.named_steps["features"].transform(X) if features is None else features[keep]
        known = rule_key(model, features, y) if rules is not None else None
        if known is not None and known in rules:
            rule, part = rules[known]
        else:
            rule, part = classical_rule(model, features, y)
            if known is not None:
                rules[known] = (rule, part)
        reads, n_inputs = FEATURES_NAME, int(np.shape(features)[1])
    key = ("distance", *head_key([part], n_inputs))
    pool.submit(key, export_distance_part, part, n_inputs, background=False)
    bound = bind_head(pool.result(key), [part])
    if front is not None:
        bound = distance_branch(pool.result(front), bound)
    return write_with_distance(bare, bound, rule, path, reads=reads), (rule, part, n_inputs, reads, front)


def measure_file(path: str | Path, raw: np.ndarray, acquisition_s: float) -> dict:
    """The study's timing harness: ``latency_ms`` (median time of ``OnnxPipeline.predict`` on one raw input,
    batch 1, input validation and the "unknown" rule included), ``size_bytes`` and ``decision_s``
    (``acquisition_s`` + latency) of the bundle ``path``."""
    from ..metrics import time_per_sample
    from ..robot.runtime import OnnxPipeline

    pipe = OnnxPipeline(path)
    latency = 1e3 * time_per_sample(pipe.predict, np.ascontiguousarray(raw[:1]))
    return {
        "latency_ms": latency,
        "size_bytes": int(Path(path).stat().st_size),
        "decision_s": acquisition_s + latency / 1e3,
    }


def timing_metadata(cand: Candidate, s: Samples, rate_hz: float | None) -> dict:
    """The metadata a candidate's file carries (as its deployed file: window, rate, range; frame bundles'
    touch levels), but for the early-decision rule, calibrated only for what is deployed."""
    from ..robot.contract import FRAMES_LAYOUT, PRESSURE_LAYOUT
    from .bundle import window_metadata

    meta: dict = {PIPELINE_KEY: f"tradeoff: {cand.name}", **window_metadata(s, rate_hz)}
    if s.layout in (PRESSURE_LAYOUT, FRAMES_LAYOUT):
        from ..robot.stream.touches import frame_metadata

        meta.update(frame_metadata(s.X, frame_rate_hz=rate_hz, rgb=s.layout == FRAMES_LAYOUT)[0])
    return meta


def window_metadata(samples: object, rate_hz: float | None) -> dict:
    """The metadata of a vibration bundle's windows (window, step, sample rate, sensor range); ``{}`` otherwise."""
    if samples.window is None:
        return {}
    return {
        WINDOW_SIZE_KEY: samples.window,
        STEP_KEY: samples.window,
        SAMPLE_RATE_KEY: rate_hz,
        RANGE_METADATA_KEY: DEFAULT_RANGE_G,
    }


def touch_cost(latency_ms: float, early_rule: dict | None, samples: object) -> float | None:
    """Milliseconds of inference one touch costs a frame bundle at most: the end of the touch and, with an
    early-decision rule that can decide, each of its checkpoints (``None`` for windows and features)."""
    from ..robot.contract import FRAMES_LAYOUT, PRESSURE_LAYOUT

    if samples.layout not in (PRESSURE_LAYOUT, FRAMES_LAYOUT):
        return None
    checkpoints = 0
    if early_rule is not None and early_rule.get("threshold") is not None:
        checkpoints = len(early_rule.get("checkpoints") or ())
    return latency_ms * (1 + checkpoints)


__all__ = [
    "RULE_SAMPLES",
    "bare_bundle",
    "evenly",
    "export_distance_part",
    "finish_bundle",
    "measure_file",
    "rule_key",
    "timing_metadata",
    "touch_cost",
    "window_metadata",
]
