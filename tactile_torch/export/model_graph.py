"""Whole inference pipelines (raw input → label and scores) as torch modules, and their ONNX export.

This module builds graphs only: the default bundles are trained in :mod:`tactile_torch.default_bundles`,
model files are written by their owners (:mod:`tactile_torch.training`,
:mod:`tactile_torch.clustering_model`) through :mod:`tactile_torch.robot.files.model_file`, and the names the
graph and its metadata carry are :mod:`tactile_torch.robot.contract`'s.

Three pipelines, each one :class:`InferencePipeline` = a front end (features, scaling) and a head that
returns ``(labels, scores)``:

========================  ==========================  ===============================================
pipeline                  raw input                   graph
========================  ==========================  ===============================================
``image-<method>``        frames ``(B, T, 3, H, W)``  :class:`~tactile_torch.image.ExplorationFeatures`
                          uint8 RGB                   → feature scale → SVM (hierarchical or not)
``vibration-<method>``    windows ``(B, 3, W)`` in g  :class:`~tactile_torch.signal.WindowFeatures`
                                                      → feature scale → SVM
``vibration-pyp``         windows ``(B, 3, W)`` in g  window features → :class:`~tactile_torch.signal.
                                                      ClusteringProjection` → Pitman-Yor component, novelty
``features-<method>``     features ``(B, F)``         feature scale → SVM, or → PYP component
========================  ==========================  ===============================================

Build them from the model files the command line writes: :func:`pipeline_from_model` reads a
classifier written by ``tactile-torch train --out model.npz`` (:func:`tactile_torch.training.save_model`)
or a clustering written by ``tactile-torch cluster``
(:func:`tactile_torch.clustering_model.save_clustering_model`); model files
are read and validated by :mod:`tactile_torch.robot.files.model_file` (no pickle). :func:`export_pipeline`
writes the pipeline to one ``.onnx`` file with a dynamic batch size and the metadata that
:class:`tactile_torch.robot.runtime.OnnxPipeline` reads (class names, input shape, window size, sample
rate, sensor range, thresholds, feature scale, library version).

Labels index :attr:`InferencePipeline.class_names`; scores are the SVM's per-class scores
(:class:`~tactile_torch.svm.SVMInference`) or the mixture's log responsibilities.

Examples
--------
>>> model = load_model_file("model.npz")                     # doctest: +SKIP
>>> pipe = pipeline_from_model(model)                        # doctest: +SKIP
>>> export_pipeline(pipe, "model.onnx")                      # doctest: +SKIP
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch
from torch import nn

from ..exceptions import InputTypeError
from ..robot.contract import (
    CLASS_NAMES_KEY,
    DEFAULT_RANGE_G,
    EARLY_RULE_KEY,
    FEATURES_LAYOUT,
    FRAME_RATE_KEY,
    FRAMES_LAYOUT,
    INPUT_LAYOUT_KEY,
    INPUT_NAME,
    INPUT_SHAPE_KEY,
    LABELS_OUTPUT,
    NOVELTY_THRESHOLDS_KEY,
    PIPELINE_KEY,
    PRESSURE_LAYOUT,
    QUANTILE_KEY,
    RANGE_METADATA_KEY,
    SAMPLE_RATE_KEY,
    SCORES_OUTPUT,
    STEP_KEY,
    THRESHOLD_KEY,
    TOUCH_LEVELS_KEY,
    VALUE_RANGE_KEY,
    VERSION_KEY,
    WINDOW_SIZE_KEY,
    WINDOWS_LAYOUT,
    metadata_strings,
)
from ..robot.files.model_file import ModelFile, load_model_file


class InferencePipeline(nn.Module):
    """Raw input → ``(labels (B,) int64, scores (B, C))``: ``head(front(raw))``.

    Parameters
    ----------
    front : nn.Module
        Raw input → features (features, scaling); ``nn.Identity()`` for a feature-input pipeline.
    head : nn.Module
        Features → ``(labels, scores)`` (:class:`~tactile_torch.svm.SVMInference`,
        :class:`~tactile_torch.mixture.GaussianMixtureClassifier`).
    name : str
        What the graph does, e.g. ``"vibration-hmsvm"`` (metadata ``tactile_torch.pipeline``).
    input_shape : sequence of int or None
        Shape of the raw input; ``None`` marks the free batch dimension (first).
    input_layout : str
        Names of the input dimensions, e.g. ``"B,3,W"``.
    class_names : sequence of str
        Name of each label.
    metadata : dict, optional
        Further metadata (window size, sample rate, thresholds ...), JSON-serialisable values.
    """

    def __init__(
        self,
        front: nn.Module,
        head: nn.Module,
        *,
        name: str,
        input_shape: list[int | None],
        input_layout: str,
        class_names: list[str],
        metadata: dict | None = None,
    ) -> None:
        super().__init__()
        if len(input_shape) != len(input_layout.split(",")):
            raise ValueError(f"input_layout {input_layout!r} does not name the {len(input_shape)} input dims")
        self.front = front
        self.head = head
        self.name = name
        self.input_shape = list(input_shape)
        self.input_layout = input_layout
        self.class_names = [str(c) for c in class_names]
        self.extra_metadata = dict(metadata or {})

    def forward(self, raw: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return self.head(self.front(raw))

    @property
    def input_dtype(self) -> torch.dtype:
        """dtype of the raw input the graph takes: uint8 for image frames, float32 otherwise."""
        return torch.uint8 if self.input_layout == FRAMES_LAYOUT else torch.float32

    def example_input(self, batch: int = 2, *, random_state: int = 0) -> torch.Tensor:
        """Return a random input of the pipeline's shape and dtype with ``batch`` rows (for export)."""
        gen = torch.Generator().manual_seed(random_state)
        shape = [batch, *self.input_shape[1:]]
        if self.input_dtype == torch.uint8:
            return torch.randint(0, 256, shape, generator=gen, dtype=torch.uint8)
        return torch.rand(shape, generator=gen) - 0.5

    def metadata(self) -> dict[str, str]:
        """Return the ONNX metadata properties of this pipeline (string values; JSON where structured)."""
        from .. import __version__

        return metadata_strings(
            {
                PIPELINE_KEY: self.name,
                VERSION_KEY: __version__,
                INPUT_SHAPE_KEY: self.input_shape,
                INPUT_LAYOUT_KEY: self.input_layout,
                CLASS_NAMES_KEY: self.class_names,
                **self.extra_metadata,
            }
        )

    def extra_repr(self) -> str:
        return f"name={self.name!r}, input=({self.input_layout})={self.input_shape}, classes={len(self.class_names)}"


def _scaler(scale: np.ndarray, center: np.ndarray | None = None) -> nn.Module:
    from ..signal import ScaleFeatures

    scale = torch.as_tensor(np.asarray(scale, dtype=np.float32))
    center = (
        torch.zeros_like(scale) if center is None else torch.as_tensor(np.asarray(center, dtype=np.float32))
    )
    return ScaleFeatures(center, scale)


def _front_end(
    source: dict, sensor_range_g: float | None = None
) -> tuple[list[nn.Module], list[int | None], str, dict]:
    """Return (modules, input shape, layout, metadata) of the raw-input part described by ``source``."""
    kind = source.get("kind")
    if sensor_range_g is not None and kind != "vibration":
        raise ValueError(
            "sensor_range_g (tactile-torch export --sensor-range) applies to models of vibration windows "
            f"only, got a model of {kind} input"
        )
    if kind == "vibration":
        from ..signal import WindowFeatures

        window = int(source["window"])
        meta = {
            WINDOW_SIZE_KEY: window,
            STEP_KEY: int(source.get("step") or window),
            SAMPLE_RATE_KEY: float(source["rate_hz"]),
            # the range given at export, else the one declared at training (source), else the ADXL345's
            RANGE_METADATA_KEY: float(source.get("sensor_range_g", DEFAULT_RANGE_G))
            if sensor_range_g is None
            else sensor_range_g,
        }
        return [WindowFeatures(window)], [None, 3, window], WINDOWS_LAYOUT, meta
    if source.get("features") == "per-taxel" or kind == "pressure":  # each taxel's time series
        from ..features.transformers import TaxelFeatures

        rgb = kind == "image"
        meta = {"features": "per-taxel"}
        for key in (FRAME_RATE_KEY, TOUCH_LEVELS_KEY, EARLY_RULE_KEY, VALUE_RANGE_KEY):
            if key in source:
                meta[key] = source[key]
        shape = [None, *(int(v) for v in source["frame_shape"])]
        return [TaxelFeatures(rgb)], shape, FRAMES_LAYOUT if rgb else PRESSURE_LAYOUT, meta
    if kind == "image":
        from ..image import DEFAULT_EDGE_THRESHOLD, DEFAULT_EROSION, DEFAULT_THRESHOLD, ExplorationFeatures

        if "frame_shape" not in source:
            raise ValueError("the model's source does not record the frame shape (T, 3, H, W); retrain it")
        t, c, h, w = (int(v) for v in source["frame_shape"])
        fuse = bool(source.get("fuse", True))
        meta = {
            "fuse": fuse,
            "threshold": DEFAULT_THRESHOLD,
            "erosion": DEFAULT_EROSION,
            "edge_threshold": DEFAULT_EDGE_THRESHOLD,
        }
        threshold = float(source.get("threshold", DEFAULT_THRESHOLD))
        erosion = int(source.get("erosion", DEFAULT_EROSION))
        meta.update(threshold=threshold, erosion=erosion)
        # the live stream's frame rate and touch levels (model files written since they exist)
        for key in (FRAME_RATE_KEY, TOUCH_LEVELS_KEY, EARLY_RULE_KEY):
            if key in source:
                meta[key] = source[key]
        front = ExplorationFeatures(fuse=fuse, threshold=threshold, erosion=erosion)
        return [front], [None, t, c, h, w], FRAMES_LAYOUT, meta
    if kind == "features":
        n = int(source["n_features"])
        return [], [None, n], FEATURES_LAYOUT, {}
    raise ValueError(
        f"the model's source kind must be 'vibration', 'image', 'pressure' or 'features', got {kind!r}"
    )


def pipeline_from_model(
    model: ModelFile | str | Path, *, sensor_range_g: float | None = None
) -> InferencePipeline:
    """Build the inference pipeline of a model file (a :class:`~tactile_torch.robot.files.model_file.ModelFile`,
    or its path) written by ``tactile-torch train --out`` or ``tactile-torch cluster``.

    The torch modules are rebuilt from the file's arrays: the front end from ``source`` (window
    features, or exploration features), then the feature scale and the SVM's inference path, or the
    clustering transform and the MAP mixture.

    ``sensor_range_g`` (vibration models only; default :data:`~tactile_torch.robot.runtime.DEFAULT_RANGE_G`,
    5 g, the ADXL345 of the study) is the sensor's range, kept in the metadata (``sensor_range_g``):
    ``tactile-torch predict`` does not classify windows holding a sample beyond it and ``stream``
    rejects such samples. It must be finite and > 0.

    A clustering fitted to features standardised per session (header ``per_session``) is refused
    with ``ValueError``: the robot cannot standardise a session it has not seen.
    """
    if isinstance(model, str | Path):
        model = load_model_file(model)
    if not isinstance(model, ModelFile):
        raise InputTypeError(
            f"model must be a ModelFile (tactile_torch.robot.files.model_file.load_model_file(path)) or a path, "
            f"got {type(model).__name__}"
        )
    if sensor_range_g is not None:
        if isinstance(sensor_range_g, bool) or not isinstance(sensor_range_g, int | float | np.number):
            raise InputTypeError(f"sensor_range_g must be a number of g, got {type(sensor_range_g).__name__}")
        if not (math.isfinite(sensor_range_g) and sensor_range_g > 0):
            raise ValueError(f"sensor_range_g must be a finite number of g > 0, got {sensor_range_g!r}")
        sensor_range_g = float(sensor_range_g)
    if model.kind == "clustering":
        return _clustering_pipeline(model, sensor_range_g)
    source = model.source
    modules, shape, layout, meta = _front_end(source, sensor_range_g)
    head = model.header["head"]
    params = model.header.get("params", {})
    meta.update(method=model.method, feature_scale=[float(s) for s in model.arrays["scale"]])
    if head["type"] == "svm":
        meta.update(kernel=head["kernel"], gamma=float(head["gamma"]))
    if "C" in params:
        meta["C"] = float(params["C"])
    if model.header.get("test_accuracy") is not None:
        meta["test_accuracy"] = float(model.header["test_accuracy"])
    if "select" in model.arrays:
        from ..features.transformers import ColumnSelect

        modules.append(ColumnSelect(model.arrays["select"]))
    front = nn.Sequential(*modules, _scaler(model.arrays["scale"], model.arrays.get("center")))
    from .classifier_inference import decode_classifier

    classifier = decode_classifier(head, model.part("head"), len(model.class_names))
    ood = model.header.get("ood")
    if ood is not None:  # "unknown" as an answer: the graph also gives the distance to training
        from ..ood import WithDistance, distance_module

        classifier = WithDistance(classifier, distance_module(model.part("ood")))
        meta[THRESHOLD_KEY] = float(ood["threshold"])
        meta[QUANTILE_KEY] = float(ood["quantile"])
    return InferencePipeline(
        front,
        classifier,
        name=f"{source['kind']}-{model.method}",
        input_shape=shape,
        input_layout=layout,
        class_names=model.class_names,
        metadata=meta,
    )


def _clustering_pipeline(model: ModelFile, sensor_range_g: float | None) -> InferencePipeline:
    from ..mixture import GaussianMixtureClassifier

    if model.header.get("per_session"):
        raise ValueError(
            f"{model.path or 'model'}: fitted to features standardised per session, which a robot cannot "
            "do for a session it has not seen; cluster without per-session standardisation to export"
        )
    state = model.part("head")
    head = GaussianMixtureClassifier(
        state["means"],
        state["precisions_cholesky"],
        state["log_weights"],
        novelty_means=state.get("novelty_means"),
        novelty_precisions_cholesky=state.get("novelty_precisions_cholesky"),
        novelty_log_weight=float(state.get("novelty_log_weight", 0.0)),
        novelty_thresholds=state.get("novelty_thresholds"),
        density_means=state.get("density_means"),
        density_precisions_cholesky=state.get("density_precisions_cholesky"),
        density_log_weights=state.get("density_log_weights"),
        cluster_features=(model.header.get("head") or {}).get("cluster_features"),
    )
    source = model.source
    modules, shape, layout, meta = _front_end(source, sensor_range_g)
    spec = model.header.get("transform")
    if spec is not None:
        from ..signal import ClusteringProjection

        fitted = {name: torch.from_numpy(np.array(v)) for name, v in model.part("transform").items()}
        modules.append(
            ClusteringProjection(fitted["mean_"], fitted["scale_"], fitted["components_"], eps=spec["eps"])
        )
    meta["method"] = "pyp"
    if head.novelty_thresholds.shape[0]:  # calibrated: thresholds of the mean novelty over N windows
        meta[NOVELTY_THRESHOLDS_KEY] = [float(t) for t in head.novelty_thresholds]
        how = model.header.get("novelty") or {}
        calibrated = (
            f", set for {how['false_alarm']:.1%} false alarms on {how['calibration_rows']} held-out windows"
            if how
            else ""
        )
        meta["novelty_rule"] = (
            f"output 'novel' flags windows whose 'novelty' (minus the log density) exceeds "
            f"{float(head.novelty_thresholds[0]):.4g}{calibrated}; stream --discover N compares the mean "
            f"of the last N with threshold N of {NOVELTY_THRESHOLDS_KEY}"
        )
    else:
        meta["novelty_rule"] = (
            "output 'novel' flags windows that a new component explains better than every known one "
            "(not calibrated)"
        )
    k = int(np.asarray(state["means"]).shape[0])
    ks = model.header.get("k_summary")
    meta["k_exported"] = f"K = {k} components: the point estimate of the clustering" + (
        f" (posterior of K: mode {ks['mode']}, median {ks['median']:g}, 95% interval "
        f"[{ks['interval'][0]:g}, {ks['interval'][1]:g}]; MAP sample K = {ks['map']})"
        if ks
        else " of an older model file (its MAP sample)"
    )
    return InferencePipeline(
        nn.Sequential(*modules),
        head,
        name=f"{source['kind']}-pyp",
        input_shape=shape,
        input_layout=layout,
        class_names=model.class_names,
        metadata=meta,
    )


def export_pipeline(
    pipeline: InferencePipeline,
    path: str | Path,
    *,
    example_batch: int = 2,
    inputs: Sequence[str | Path] = (),
) -> Path:
    """Export ``pipeline`` to one ONNX file at ``path`` (dynamo exporter, dynamic batch, metadata); return it.

    The outputs are named ``labels`` and ``scores`` and the input ``raw``, as
    :class:`tactile_torch.robot.runtime.OnnxPipeline` expects; ``onnx.checker`` validates the file. The
    file is written atomically and never onto a directory, a device, a symbolic link or one of
    ``inputs`` (e.g. the model file it was built from): ``ValueError`` in one line.
    """
    from ._onnx import export_onnx

    if not isinstance(pipeline, InferencePipeline):
        raise InputTypeError(f"pipeline must be an InferencePipeline, got {type(pipeline).__name__}")
    example = pipeline.example_input(example_batch)
    extra = list(
        getattr(pipeline.head, "output_names", ())[2:]
    )  # the mixture's novelty flag, the OOD distance
    return export_onnx(
        pipeline.eval(),
        (example,),
        path,
        input_names=[INPUT_NAME],
        output_names=[LABELS_OUTPUT, SCORES_OUTPUT, *extra],
        metadata=pipeline.metadata(),
        inputs=inputs,
    )


def compare_with_runtime(pipeline: InferencePipeline, bundle: object, raw: np.ndarray) -> tuple[float, float]:
    """Run ``raw`` through the torch ``pipeline`` and its exported ``bundle`` (an ``OnnxPipeline``).

    Returns ``(agreement, difference)``: the share of identical labels and the largest score difference
    relative to ``max(|score|, 1)`` (the mixture's log responsibilities reach hundreds in float32).
    """
    raw = bundle.validate(raw)
    out = bundle.run(raw)  # the graph's own labels: no "unknown" applied
    labels, scores = np.asarray(out[LABELS_OUTPUT]), out[SCORES_OUTPUT]
    with torch.no_grad():
        t_labels, t_scores = pipeline(torch.from_numpy(raw))[:2]
    t_scores = t_scores.numpy()
    agreement = float((labels == t_labels.numpy()).mean())
    difference = float((np.abs(scores - t_scores) / np.maximum(np.abs(t_scores), 1.0)).max())
    return agreement, difference


__all__ = [
    "InferencePipeline",
    "compare_with_runtime",
    "export_pipeline",
    "pipeline_from_model",
]
