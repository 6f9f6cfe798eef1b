"""Whole inference pipelines (raw input → label and scores) as torch modules, and their ONNX export.

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
or a clustering written by ``tactile-torch cluster`` (:func:`save_clustering_model`); model files
are read and validated by :mod:`tactile_torch.model_file` (no pickle). :func:`export_pipeline`
writes the pipeline to one ``.onnx`` file with a dynamic batch size and the metadata that
:class:`tactile_torch.runtime.OnnxPipeline` reads (class names, input shape, window size, sample
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

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn

from .model_file import FORMAT, ModelFile, load_model_file
from .runtime import DEFAULT_RANGE_G, LABELS_OUTPUT, RANGE_METADATA_KEY, SCORES_OUTPUT

CLUSTERING_FORMAT = FORMAT
"""``format`` of model files (:data:`tactile_torch.model_file.FORMAT`); kept for old imports."""


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
        return torch.uint8 if self.input_layout == "B,T,3,H,W" else torch.float32

    def example_input(self, batch: int = 2, *, random_state: int = 0) -> torch.Tensor:
        """Return a random input of the pipeline's shape and dtype with ``batch`` rows (for export)."""
        gen = torch.Generator().manual_seed(random_state)
        shape = [batch, *self.input_shape[1:]]
        if self.input_dtype == torch.uint8:
            return torch.randint(0, 256, shape, generator=gen, dtype=torch.uint8)
        return torch.rand(shape, generator=gen) - 0.5

    def metadata(self) -> dict[str, str]:
        """Return the ONNX metadata properties of this pipeline (string values; JSON where structured)."""
        from . import __version__

        meta = {
            "tactile_torch.pipeline": self.name,
            "tactile_torch.version": __version__,
            "input_shape": json.dumps(self.input_shape),
            "input_layout": self.input_layout,
            "class_names": json.dumps(self.class_names),
        }
        for key, value in self.extra_metadata.items():
            meta[key] = value if isinstance(value, str) else json.dumps(value)
        return meta

    def extra_repr(self) -> str:
        return f"name={self.name!r}, input=({self.input_layout})={self.input_shape}, classes={len(self.class_names)}"


def _scaler(scale: np.ndarray, center: np.ndarray | None = None) -> nn.Module:
    from .signal import ScaleFeatures

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
        from .signal import WindowFeatures

        window = int(source["window"])
        meta = {
            "window_size": window,
            "step": int(source.get("step") or window),
            "sample_rate_hz": float(source["rate_hz"]),
            # the range given at export, else the one declared at training (source), else the ADXL345's
            RANGE_METADATA_KEY: float(source.get("sensor_range_g", DEFAULT_RANGE_G))
            if sensor_range_g is None
            else sensor_range_g,
        }
        return [WindowFeatures(window)], [None, 3, window], "B,3,W", meta
    if kind == "image":
        from .image import DEFAULT_EDGE_THRESHOLD, DEFAULT_EROSION, DEFAULT_THRESHOLD, ExplorationFeatures

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
        front = ExplorationFeatures(fuse=fuse, threshold=threshold, erosion=erosion)
        return [front], [None, t, c, h, w], "B,T,3,H,W", meta
    if kind == "features":
        n = int(source["n_features"])
        return [], [None, n], "B,F", {}
    raise ValueError(f"the model's source kind must be 'vibration', 'image' or 'features', got {kind!r}")


def pipeline_from_model(
    model: ModelFile | str | Path, *, sensor_range_g: float | None = None
) -> InferencePipeline:
    """Build the inference pipeline of a model file (a :class:`~tactile_torch.model_file.ModelFile`,
    or its path) written by ``tactile-torch train --out`` or ``tactile-torch cluster``.

    The torch modules are rebuilt from the file's arrays: the front end from ``source`` (window
    features, or exploration features), then the feature scale and the SVM's inference path, or the
    clustering transform and the MAP mixture.

    ``sensor_range_g`` (vibration models only; default :data:`~tactile_torch.runtime.DEFAULT_RANGE_G`,
    5 g, the ADXL345 of the study) is the sensor's range, kept in the metadata (``sensor_range_g``):
    ``tactile-torch predict`` does not classify windows holding a sample beyond it and ``stream``
    rejects such samples. It must be finite and > 0.
    """
    if isinstance(model, str | Path):
        model = load_model_file(model)
    if not isinstance(model, ModelFile):
        raise TypeError(
            f"model must be a ModelFile (tactile_torch.model_file.load_model_file(path)) or a path, "
            f"got {type(model).__name__}"
        )
    if sensor_range_g is not None:
        if isinstance(sensor_range_g, bool) or not isinstance(sensor_range_g, int | float | np.number):
            raise TypeError(f"sensor_range_g must be a number of g, got {type(sensor_range_g).__name__}")
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
        from .tradeoff.transformers import ColumnSelect

        modules.append(ColumnSelect(model.arrays["select"]))
    front = nn.Sequential(*modules, _scaler(model.arrays["scale"], model.arrays.get("center")))
    classifier = _classifier_head(head, model.part("head"), len(model.class_names))
    ood = model.header.get("ood")
    if ood is not None:  # "unknown" as an answer: the graph also gives the distance to training
        from .ood import QUANTILE_KEY, THRESHOLD_KEY, MahalanobisDistance, WithDistance

        state = model.part("ood")
        classifier = WithDistance(
            classifier, MahalanobisDistance(state["means"], state["precision_cholesky"])
        )
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


def _classifier_head(settings: dict, arrays: dict[str, np.ndarray], n_classes: int) -> nn.Module:
    """The classifier's inference module from a model file's ``head`` (SVM, linear or nearest neighbours)."""
    from .baselines import LinearInference, NeighboursInference

    if settings["type"] == "linear":
        return LinearInference(arrays["coef"], arrays["intercept"])
    if settings["type"] == "neighbours":
        return NeighboursInference(
            arrays["samples"],
            arrays["labels"],
            n_classes,
            n_neighbors=settings["n_neighbors"],
            weights=settings["weights"],
            p=settings["p"],
        )
    return _svm_head(settings, arrays)


def _svm_head(settings: dict, arrays: dict[str, np.ndarray]) -> nn.Module:
    """The SVM's inference module from a model file's ``head`` settings and arrays."""
    from .svm import SVMInference

    tensors = {name: torch.from_numpy(np.array(value)) for name, value in arrays.items()}
    core = ("support_vectors", "dual_coef", "intercept")
    return SVMInference(
        *(tensors.pop(name) for name in core),
        kernel=settings["kernel"],
        gamma=settings["gamma"],
        mode=settings["mode"],
        tree=tensors or None,
        depth=settings["depth"],
    )


def save_clustering_model(
    path: str | Path,
    mixture: object,
    *,
    source: dict,
    transform: nn.Module | None = None,
) -> Path:
    """Write a fitted :class:`~tactile_torch.mixture.PitmanYorGMM` (and the transform before it) to a model file.

    The file (:mod:`tactile_torch.model_file`, no pickle) holds the MAP mixture's arrays, the
    fitted transform's, ``source`` and the posterior summary.

    Parameters
    ----------
    path : str or Path
    mixture : PitmanYorGMM
        Fitted; its point estimate's components (and novelty flag) are what the exported pipeline
        classifies with (:meth:`~tactile_torch.mixture.PitmanYorGMM.to_module`).
    source : dict
        How the mixture's input is made: ``{"kind": "vibration", "window", "step", "rate_hz"}`` (raw
        windows → :class:`~tactile_torch.signal.WindowFeatures` → ``transform``) or
        ``{"kind": "features", "n_features"}``.
    transform : ClusteringTransform, optional
        Required for ``kind="vibration"``.
    """
    from .model_file import save_model_file

    if source.get("kind") == "vibration" and transform is None:
        raise ValueError("a vibration clustering needs the fitted ClusteringTransform (transform=)")
    module = mixture.to_module()
    k = int(module.means.shape[0])
    header = {
        "kind": "clustering",
        "method": "pyp",
        "class_names": [f"component {i}" for i in range(k)],
        "source": dict(source),
        "head": {"type": "gaussian-mixture"},
        "summary": mixture.summary(),
        "k_summary": {
            k: (list(v) if isinstance(v, tuple) else v) for k, v in mixture.n_clusters_summary_.items()
        },
    }
    arrays = {f"head.{name}": buf.numpy() for name, buf in module.named_buffers()}
    if transform is not None:
        header["transform"] = {
            "type": "clustering",
            "n_components": int(transform.n_components),
            "standardize": bool(transform.standardize),
            "eps": float(transform.eps),
        }
        fitted = ("mean_", "scale_", "components_", "explained_variance_", "explained_variance_ratio_")
        arrays.update({f"transform.{name}": getattr(transform, name) for name in fitted})
    return save_model_file(path, header, arrays)


def _clustering_pipeline(model: ModelFile, sensor_range_g: float | None) -> InferencePipeline:
    from .mixture import GaussianMixtureClassifier

    state = model.part("head")
    head = GaussianMixtureClassifier(
        state["means"],
        state["precisions_cholesky"],
        state["log_weights"],
        novelty_means=state.get("novelty_means"),
        novelty_precisions_cholesky=state.get("novelty_precisions_cholesky"),
        novelty_log_weight=float(state.get("novelty_log_weight", 0.0)),
        novelty_thresholds=state.get("novelty_thresholds"),
    )
    source = model.source
    modules, shape, layout, meta = _front_end(source, sensor_range_g)
    spec = model.header.get("transform")
    if spec is not None:
        from .signal import ClusteringProjection

        fitted = {name: torch.from_numpy(np.array(v)) for name, v in model.part("transform").items()}
        modules.append(
            ClusteringProjection(fitted["mean_"], fitted["scale_"], fitted["components_"], eps=spec["eps"])
        )
    meta["method"] = "pyp"
    if head.novelty_thresholds.shape[0]:  # calibrated: thresholds of the mean novelty over N windows
        meta["novelty_thresholds"] = [float(t) for t in head.novelty_thresholds]
    k = int(np.asarray(state["means"]).shape[0])
    ks = model.header.get("k_summary")
    meta["k_exported"] = f"K = {k} components: the point estimate of the clustering" + (
        f" (posterior of K: mode {ks['mode']}, median {ks['median']:g}, 95% interval "
        f"[{ks['interval'][0]:g}, {ks['interval'][1]:g}]; MAP sample K = {ks['map']}); output 'novel' flags "
        "windows that a new component explains better"
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
    :class:`tactile_torch.runtime.OnnxPipeline` expects; ``onnx.checker`` validates the file. The
    file is written atomically and never onto a directory, a device, a symbolic link or one of
    ``inputs`` (e.g. the model file it was built from): ``ValueError`` in one line.
    """
    from ._onnx import export_onnx

    if not isinstance(pipeline, InferencePipeline):
        raise TypeError(f"pipeline must be an InferencePipeline, got {type(pipeline).__name__}")
    example = pipeline.example_input(example_batch)
    extra = list(
        getattr(pipeline.head, "output_names", ())[2:]
    )  # the mixture's novelty flag, the OOD distance
    return export_onnx(
        pipeline.eval(),
        (example,),
        path,
        input_names=["raw"],
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


@dataclass
class Bundle:
    """One exported default pipeline (see :func:`build_default_bundles`).

    Attributes
    ----------
    pipeline : InferencePipeline
        The torch pipeline that was exported.
    path : Path
        Its ``.onnx`` file.
    raw : ndarray
        Held-out raw input of the pipeline's shape (uint8 frames, float32 windows).
    labels : ndarray of shape (N,) int64
        True class of each row of ``raw`` (index into the data set's classes).
    """

    pipeline: InferencePipeline
    path: Path
    raw: np.ndarray
    labels: np.ndarray


def build_default_bundles(
    out_dir: str | Path,
    *,
    quick: bool = False,
    random_state: int = 0,
    kinds: tuple[str, ...] = ("vibration-hmsvm", "vibration-pyp", "image-hmsvm"),
    log=print,
) -> dict[str, Bundle]:
    """Train the three default pipelines on the bundled synthetic data, export them, return them by name.

    ``vibration-hmsvm``: 28 synthetic surfaces, 60 s each at 800 Hz (``quick``: 10 s), W = 800
    windows, odd windows held out, HM-SVM with C = 16 and gamma ``"scale"`` on unit-std features.
    ``vibration-pyp``: the same windows → unsupervised transform (3 components) → Pitman-Yor mixture
    (300 sweeps, ``quick``: 40). ``image-hmsvm``: 20 synthetic explorations per class (``quick``: 8)
    of 100 frames of 96 x 96, half held out. Writes ``<name>.npz`` (the model file) and
    ``<name>.onnx`` to ``out_dir``.
    """
    from .training import FeatureSet, save_model, train_classifier

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    built: dict[str, Bundle] = {}
    if any(k.startswith("vibration") for k in kinds):
        from .data.stylus import make_vibration_recordings
        from .model_selection import odd_even_split
        from .signal import window_features

        rec = make_vibration_recordings(28, duration_s=10 if quick else 60, random_state=random_state)
        ds = rec.windows(800)
        X = window_features(ds.windows).double().numpy()
        fit_on, held_out = odd_even_split(ds.position)  # the study's split: even-numbered windows held out
        source = {"kind": "vibration", "window": 800, "step": 800, "rate_hz": rec.rate_hz}
        raw, labels = ds.windows[held_out].numpy(), ds.labels[held_out].numpy()
        if "vibration-hmsvm" in kinds:
            train = FeatureSet(X[fit_on], ds.labels.numpy()[fit_on], ds.class_names, source)
            model = train_classifier(train, "hmsvm", n_folds=2, random_state=random_state)
            path = save_model(out / "vibration-hmsvm.npz", model, train)
            built["vibration-hmsvm"] = Bundle(pipeline_from_model(load_model_file(path)), path, raw, labels)
        if "vibration-pyp" in kinds:
            from .mixture import PitmanYorGMM
            from .signal import ClusteringTransform

            transform = ClusteringTransform(3).fit(X[fit_on])
            pcs = transform.transform(X[fit_on])
            sweeps = 40 if quick else 300
            mixture = PitmanYorGMM(
                n_iter=sweeps, burn_in=sweeps // 4, random_state=random_state, progress=False
            )
            path = save_clustering_model(
                out / "vibration-pyp.npz", mixture.fit(pcs), source=source, transform=transform
            )
            built["vibration-pyp"] = Bundle(pipeline_from_model(load_model_file(path)), path, raw, labels)
    if "image-hmsvm" in kinds:
        from .data.images import make_explorations
        from .image import exploration_features

        data = make_explorations(8 if quick else 20, random_state=random_state)
        X = exploration_features(data.frames).double().numpy()
        held_out = np.arange(len(X)) % 2 == 1
        source = {"kind": "image", "fuse": True, "frame_shape": list(data.frames.shape[1:])}
        train = FeatureSet(X[~held_out], data.labels.numpy()[~held_out], data.class_names, source)
        model = train_classifier(train, "hmsvm", n_folds=2, random_state=random_state)
        path = save_model(out / "image-hmsvm.npz", model, train)
        raw = data.frames[held_out].numpy()
        built["image-hmsvm"] = Bundle(
            pipeline_from_model(load_model_file(path)), path, raw, data.labels[held_out].numpy()
        )
    for name, bundle in built.items():
        bundle.path = export_pipeline(bundle.pipeline, out / f"{name}.onnx")
        log(f"[bundles] {name}: {bundle.path} ({bundle.path.stat().st_size / 1024:.0f} KiB)")
    return built


__all__ = [
    "CLUSTERING_FORMAT",
    "Bundle",
    "InferencePipeline",
    "build_default_bundles",
    "compare_with_runtime",
    "export_pipeline",
    "load_model_file",
    "pipeline_from_model",
    "save_clustering_model",
]
