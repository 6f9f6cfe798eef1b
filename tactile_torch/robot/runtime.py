"""Run an exported tactile-torch pipeline with onnxruntime, without torch.

An exported bundle is one ``.onnx`` file holding the whole inference graph (raw exploration frames or
raw vibration windows in, ``labels`` and ``scores`` out) and its metadata in the model's
``metadata_props``. This module needs only numpy and onnxruntime, so it runs on a robot's computer
where torch is not installed; importing it never imports torch.

The names of the input, the outputs and the metadata keys are those of
:mod:`tactile_torch.robot.contract` (the one place that spells them). What the runtime does with the
metadata: ``input_shape``, ``input_layout`` and ``uint8_scale`` validate the input; vibration bundles'
``sensor_range_g`` (``tactile-torch export --sensor-range``, 5 g by default) makes windows holding a
sample beyond it "unknown" (label -1) in :meth:`OnnxPipeline.classify`, ``predict`` and
``tactile-torch predict``, and such samples are rejected by ``stream`` (:func:`sensor_range_g`,
:func:`beyond_range`); classifier bundles' ``ood_threshold`` makes samples whose ``ood_distance``
output (the distance of their features to the training data, :mod:`tactile_torch.ood`) exceeds it
"unknown". Other keys are kept in :attr:`OnnxPipeline.metadata` for the caller.

Examples
--------
>>> pipe = OnnxPipeline("vibration.onnx")            # doctest: +SKIP
>>> pipe.predict(windows)                            # doctest: +SKIP
array([3, 3, 17])
"""

from __future__ import annotations

import json
import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..exceptions import InputTypeError
from ..validation import check_count
from .contract import (
    BEYOND_RANGE,
    CLASS_NAMES_KEY,
    DEFAULT_RANGE_G,
    FEATURES_LAYOUT,
    FRAMES_LAYOUT,
    INPUT_LAYOUT_KEY,
    INPUT_SHAPE_KEY,
    LABELS_OUTPUT,
    NO_VIBRATION,
    NOT_FINITE,
    NOVEL_OUTPUT,
    OOD_OUTPUT,
    OUT_OF_DISTRIBUTION,
    PIPELINE_KEY,
    PRESSURE_LAYOUT,
    RANGE_METADATA_KEY,
    SAMPLE_RATE_KEY,
    SCORES_OUTPUT,
    STEP_KEY,
    THRESHOLD_KEY,
    UINT8_SCALE_KEY,
    UNKNOWN,
    UNKNOWN_NAME,
    WINDOW_SIZE_KEY,
    WINDOWS_LAYOUT,
)
from .files.labelled import LabelledInput
from .integrity import NotProtobufError, UnsealedBundleWarning, checked_bundle

_KIND_KEYS = {"image": "frames", "vibration": "signals", "features": "features"}
_WARNED_UNSEALED: set[str] = set()  # bundles without a digest already warned about (the warning only)
_ONNX_DTYPES = {"tensor(uint8)": "uint8", "tensor(float)": "float32", "tensor(double)": "float64"}


def sensor_range_g(metadata: Mapping[str, str], default: float = DEFAULT_RANGE_G) -> float:
    """Return the sensor range (g) a bundle's metadata declares (:data:`RANGE_METADATA_KEY`), else ``default``."""
    value = metadata.get(RANGE_METADATA_KEY)
    if value is None:
        return float(default)
    range_g = float(value)
    if not (math.isfinite(range_g) and range_g > 0):
        raise ValueError(f"metadata {RANGE_METADATA_KEY} must be a number > 0, got {value!r}")
    return range_g


def beyond_range(raw: np.ndarray, range_g: float) -> np.ndarray:
    """Return which samples of a batch hold a value beyond ``±range_g``: bool ``(B,)`` for ``raw`` ``(B, ...)``.

    A value ``v`` is in range when ``-range_g <= v <= range_g`` (inclusive, as the stream checks each
    sample it reads); NaN is never in range; ``range_g = math.inf`` lets every finite value through.
    For windows ``(B, 3, W)`` in g this flags the windows that hold a sample the sensor cannot have
    produced (a corrupted value, or data in other units), whose features would be meaningless.
    """
    values = np.asarray(raw).reshape(len(raw), -1)
    # reductions, not np.abs: no temporary as large as the batch
    return ~((values.max(axis=1) <= range_g) & (values.min(axis=1) >= -range_g))


@dataclass
class Prediction:
    """What :meth:`OnnxPipeline.classify` returns for a batch of ``B`` samples.

    Attributes
    ----------
    labels : ndarray of shape (B,) int64
        Class index, or ``-1`` ("unknown").
    scores : ndarray of shape (B, C) float32
        The graph's scores; NaN for samples beyond the sensor's range (not run).
    distance : ndarray of shape (B,) float32
        Distance of each sample to the training data (:mod:`tactile_torch.ood`); NaN when the bundle
        has none or the sample was not run.
    reasons : list of (str or None)
        Why each unknown sample is unknown (one line), ``None`` for classified samples.
    causes : list of (str or None)
        The same as one of :data:`~tactile_torch.robot.contract.UNKNOWN_CAUSES` (to count or branch on).
    novel : ndarray of shape (B,) bool or None
        Clustering bundles: the graph's ``novel`` output (a window of a surface the clustering
        did not see); False for samples not run; ``None`` when the bundle has no such output.
    """

    labels: np.ndarray
    scores: np.ndarray
    distance: np.ndarray
    reasons: list[str | None]
    causes: list[str | None]
    novel: np.ndarray | None = None


class NonFiniteScoresError(ValueError):
    """The graph gave NaN or infinite scores for some samples, so no label is returned for them.

    Attributes
    ----------
    rows : ndarray of int
        The samples (batch rows) whose scores are not all finite.
    """

    def __init__(self, rows: np.ndarray, batch: int) -> None:
        self.rows = rows
        shown = ", ".join(str(int(r)) for r in rows[:5]) + (", ..." if len(rows) > 5 else "")
        super().__init__(
            f"the bundle gave non-finite scores for {len(rows)} of {batch} sample(s) (rows {shown}), so no "
            "label is returned: values far outside the sensor's range (e.g. a corrupted 1e30 sample) "
            "overflow the features"
        )


def _onnx_error(path: Path, err: Exception) -> str:
    with path.open("rb") as f:
        head = f.read(4)
    if not head:
        return "empty file"
    if head.startswith(b"PK"):
        return "a .npz archive: a model file? export it first with 'tactile-torch export'"
    first = str(err).strip().splitlines()
    return first[0][:200] if first else type(err).__name__


class OnnxPipeline:
    """An exported pipeline loaded with onnxruntime: validate raw input, then predict labels and scores.

    Parameters
    ----------
    path : str or Path
        The ``.onnx`` bundle written by ``tactile-torch export``.
    intra_op_threads : int, default 1
        Threads onnxruntime may use inside one operator (1 gives the lowest latency jitter on a
        robot's computer that runs other processes; 0 lets onnxruntime choose).
    inter_op_threads : int, default 1
        Threads across operators.

    Attributes
    ----------
    metadata : dict of str to str
        Every metadata property of the model.
    class_names : list of str
        Name of each label.
    input_shape : tuple of (int or None)
        Expected input shape; ``None`` marks a free dimension (the batch).
    input_layout : str
        Names of the input dimensions, e.g. ``"B,T,3,H,W"``.
    input_dtype : numpy.dtype
        dtype the graph takes (uint8 for image frames, float32 for windows and features).
    sealed : bool
        Whether the bundle carries a digest (checked on load: a bundle whose bytes do not match it
        is refused with a ``ValueError``; one without a digest too, unless ``allow_unsealed``, which
        loads it with an :class:`~tactile_torch.robot.integrity.UnsealedBundleWarning`; docs/export.md,
        "Integrity").

    The bundle is checked in chunks and loaded by onnxruntime from the same open file: loading peaks
    at about twice the file's size (onnxruntime's parsed model, then its weights), not three times.
    """

    def __init__(
        self,
        path: str | Path,
        *,
        intra_op_threads: int = 1,
        inter_op_threads: int = 1,
        allow_unsealed: bool = False,
    ) -> None:
        import onnxruntime as ort

        from .files.npz import check_file, max_read_bytes

        path = check_file(path, "an exported .onnx bundle")
        limit = max_read_bytes()
        if path.stat().st_size > limit:  # onnxruntime holds the whole file (and its weights) in memory
            raise ValueError(
                f"{path}: the bundle is {path.stat().st_size / 2**20:,.1f} MiB, more than the read limit of "
                f"{limit / 2**20:,.0f} MiB (raise it with TACTILE_TORCH_MAX_READ_MB=MB if the file is trusted)"
            )
        intra_op_threads = check_count(intra_op_threads, "intra_op_threads", 0)
        inter_op_threads = check_count(inter_op_threads, "inter_op_threads", 0)
        options = ort.SessionOptions()
        options.intra_op_num_threads = intra_op_threads
        options.inter_op_num_threads = inter_op_threads
        options.log_severity_level = 3  # onnxruntime's own warnings (raw, coloured) stay off stderr
        self.path = path
        try:
            with checked_bundle(path, allow_unsealed=allow_unsealed) as (source, self.sealed):
                try:
                    self.session = ort.InferenceSession(source, options, providers=["CPUExecutionProvider"])
                except Exception as err:  # onnxruntime raises its own exception types, with long messages
                    raise ValueError(
                        f"{path}: not an ONNX bundle onnxruntime can load ({_onnx_error(path, err)})"
                    ) from None
        except NotProtobufError as err:
            raise ValueError(
                f"{path}: not an ONNX bundle onnxruntime can load ({_onnx_error(path, ValueError(err.detail))})"
            ) from None
        if not self.sealed and str(path.resolve()) not in _WARNED_UNSEALED:
            _WARNED_UNSEALED.add(str(path.resolve()))  # once per file and process: a program may reload it
            warnings.warn(
                f"{path}: the bundle has no digest (exported before tactile-torch wrote one, or by another tool): "
                "its integrity cannot be checked; export it again, or seal a copy you trust "
                "(tactile_torch.robot.integrity.seal_bundle)",
                UnsealedBundleWarning,
                stacklevel=2,
            )
        self.metadata: dict[str, str] = dict(self.session.get_modelmeta().custom_metadata_map)
        self._input = self.session.get_inputs()[0]
        self._outputs = [o.name for o in self.session.get_outputs()]
        missing = {LABELS_OUTPUT, SCORES_OUTPUT} - set(self._outputs)
        if missing:
            raise ValueError(
                f"{path} is not a tactile-torch bundle: outputs must include '{LABELS_OUTPUT}' and "
                f"'{SCORES_OUTPUT}', "
                f"got {self._outputs}"
            )
        self.input_shape = self._declared_shape()
        self.input_layout = self.metadata.get(INPUT_LAYOUT_KEY, ",".join("?" * len(self.input_shape)))
        names = self.metadata.get(CLASS_NAMES_KEY)
        self.class_names: list[str] = json.loads(names) if names else []
        scale = self.metadata.get(UINT8_SCALE_KEY)
        self._uint8_scale = float(scale) if scale else None
        self.input_dtype = np.dtype(_ONNX_DTYPES.get(self._input.type, "float32"))
        self._check_header()

    def _declared_shape(self) -> tuple[int | None, ...]:
        if INPUT_SHAPE_KEY in self.metadata:
            try:
                shape = json.loads(self.metadata[INPUT_SHAPE_KEY])
            except json.JSONDecodeError:
                shape = None
            if not isinstance(shape, list) or not all(
                d is None or (isinstance(d, int) and not isinstance(d, bool) and d >= 1) for d in shape
            ):
                raise ValueError(
                    f"{self.path}: metadata input_shape must be a JSON list of sizes >= 1 or null, "
                    f"got {self.metadata[INPUT_SHAPE_KEY]!r:.80}"
                )
            return tuple(shape)
        return tuple(d if isinstance(d, int) else None for d in self._input.shape)

    def _check_header(self) -> None:
        """Refuse metadata that disagree with the graph they describe (a crafted or mixed-up header)."""
        where = f"{self.path}: the bundle's metadata disagree with its graph"
        graph = tuple(d if isinstance(d, int) else None for d in self._input.shape)
        if len(graph) != len(self.input_shape):
            raise ValueError(f"{where}: input_shape {list(self.input_shape)}, graph input {list(graph)}")
        for axis, (want, got) in enumerate(zip(self.input_shape, graph, strict=True)):
            if got is not None and want != got:
                raise ValueError(f"{where}: input_shape axis {axis} is {want}, the graph takes {got}")
        if len(self.input_layout.split(",")) != len(self.input_shape):
            raise ValueError(
                f"{where}: input_layout {self.input_layout!r}, input_shape {list(self.input_shape)}"
            )
        if self.input_layout == WINDOWS_LAYOUT:
            if self.input_shape[1] != 3:
                raise ValueError(
                    f"{where}: windows of 3 channels (x, y, z), input_shape {list(self.input_shape)}"
                )
            meta = self.metadata
            for key, check in (
                (WINDOW_SIZE_KEY, lambda v: int(v) == self.input_shape[2]),
                (STEP_KEY, lambda v: int(v) >= 1),
                (SAMPLE_RATE_KEY, lambda v: math.isfinite(float(v)) and float(v) > 0),
            ):
                if key in meta:
                    try:
                        ok = check(meta[key])
                    except ValueError:
                        ok = False
                    if not ok:
                        raise ValueError(
                            f"{where}: {key} = {meta[key]!r:.40} (the graph takes windows of {self.input_shape[2]} samples)"
                        )
            sensor_range_g(meta)  # a number > 0
        if self.class_names:
            scores = self.session.get_outputs()[self._outputs.index(SCORES_OUTPUT)].shape
            if len(scores) == 2 and isinstance(scores[1], int) and scores[1] != len(self.class_names):
                raise ValueError(
                    f"{where}: {len(self.class_names)} class_names, the graph gives {scores[1]} scores"
                )

    @property
    def pipeline(self) -> str:
        """What the graph does (``tactile_torch.pipeline`` metadata), or ``"unknown"``."""
        return self.metadata.get(PIPELINE_KEY, "unknown")

    def validate(self, raw: object) -> np.ndarray:
        """Return ``raw`` in the graph's input dtype and shape, or raise a clear error.

        Bundles whose graph takes uint8 (image frames) take uint8 as is and float frames in [0, 1]
        rounded to the 256 levels. Float bundles cast float64 to float32 and scale uint8 input by the
        bundle's ``uint8_scale`` when it declares one. Other dtypes, a wrong rank or size, and NaN or
        inf values raise.
        """
        if not isinstance(raw, np.ndarray):
            raise InputTypeError(f"raw must be a numpy.ndarray, got {type(raw).__name__}")
        expected = "(" + ", ".join(self.input_layout.split(",")) + ")"
        fixed = tuple("B" if d is None else d for d in self.input_shape)
        if raw.ndim != len(self.input_shape) or any(
            want is not None and got != want for want, got in zip(self.input_shape, raw.shape, strict=False)
        ):
            raise ValueError(
                f"raw must have shape {expected} = {fixed} for this {self.pipeline} bundle, got {raw.shape}"
            )
        if raw.shape[0] == 0:
            raise ValueError(f"raw must hold at least one sample (batch size >= 1), got shape {raw.shape}")
        if self.input_dtype == np.uint8:
            return self._as_uint8(raw)
        if raw.dtype == np.uint8 and self._uint8_scale is not None:
            return raw.astype(np.float32) * np.float32(self._uint8_scale)
        if raw.dtype not in (np.float32, np.float64):
            accepted = "float32, float64" + (" or uint8" if self._uint8_scale is not None else "")
            raise InputTypeError(f"raw must have dtype {accepted}, got {raw.dtype}")
        raw = raw.astype(np.float32, copy=False)
        if not np.isfinite(raw).all():
            raise ValueError(f"raw must be finite, got {int((~np.isfinite(raw)).sum())} NaN/inf value(s)")
        return raw

    def _as_uint8(self, raw: np.ndarray) -> np.ndarray:
        # 8-bit bundles (image frames): uint8 passes as is; float frames in [0, 1] are quantised to the
        # nearest of the 256 levels (exact for frames that were uint8 / 255).
        if raw.dtype == np.uint8:
            return np.ascontiguousarray(raw)
        if raw.dtype not in (np.float32, np.float64):
            raise InputTypeError(
                f"raw must have dtype uint8 (0-255), float32 or float64 (in [0, 1]), got {raw.dtype}"
            )
        if not np.isfinite(raw).all():
            raise ValueError(f"raw must be finite, got {int((~np.isfinite(raw)).sum())} NaN/inf value(s)")
        lo, hi = float(raw.min()), float(raw.max())
        if lo < 0.0 or hi > 1.0:
            raise ValueError(
                f"raw float frames must be in [0, 1] (or uint8 0-255), got values in [{lo:g}, {hi:g}]"
            )
        return np.rint(raw * 255.0).astype(np.uint8)

    def run(self, raw: np.ndarray) -> Mapping[str, np.ndarray]:
        """Return every output of the graph for validated ``raw``, by name.

        Raises :class:`NonFiniteScoresError` when a sample's scores are not all finite: a label is
        never returned with a NaN or infinite score.
        """
        values = self.session.run(None, {self._input.name: self.validate(raw)})
        out = dict(zip(self._outputs, values, strict=True))
        scores = out[SCORES_OUTPUT]
        finite = np.isfinite(scores.reshape(len(scores), -1)).all(axis=1)
        if not finite.all():
            raise NonFiniteScoresError(np.flatnonzero(~finite), len(scores))
        return out

    @property
    def range_g(self) -> float:
        """The sensor range (g) samples are checked against: the bundle's, else 5; ``inf`` for other input."""
        return sensor_range_g(self.metadata) if self.input_layout == WINDOWS_LAYOUT else math.inf

    @property
    def ood_threshold(self) -> float | None:
        """The bundle's out-of-distribution threshold (:mod:`tactile_torch.ood`), ``None`` if it has none."""
        if OOD_OUTPUT not in self._outputs or THRESHOLD_KEY not in self.metadata:
            return None
        return float(self.metadata[THRESHOLD_KEY])

    def classify(self, raw: np.ndarray, *, range_g: float | None = None) -> Prediction:
        """Return the :class:`Prediction` of each sample, with ``-1`` ("unknown") and its reason where due.

        A sample is unknown when (checked in this order) it holds a value beyond ``±range_g`` (vibration
        windows; default :attr:`range_g`, the bundle's ``sensor_range_g``; ``math.inf``: no check), when
        it is a vibration window constant on every axis (no vibration to classify), when the graph's scores
        for it are not finite, or when its features lie further from the training data than the bundle's
        ``ood_threshold`` (bundles of model files written since the distance exists; :mod:`tactile_torch.ood`).
        Samples beyond the range are not run through the graph: their scores and distance are NaN.
        """
        x = self.validate(raw)
        limit = self.range_g if range_g is None else float(range_g)
        n = len(x)
        labels = np.full(n, UNKNOWN, dtype=np.int64)
        scores = np.full((n, max(len(self.class_names), 1)), np.nan, dtype=np.float32)
        distance = np.full(n, np.nan, dtype=np.float32)
        reasons: list[str | None] = [None] * n
        causes: list[str | None] = [None] * n
        novel = np.zeros(n, dtype=bool) if NOVEL_OUTPUT in self._outputs else None
        beyond = beyond_range(x, limit) if math.isfinite(limit) else np.zeros(n, dtype=bool)
        for i in np.flatnonzero(beyond):
            peak = float(np.abs(x[i]).max())
            reasons[i] = f"a sample of {peak:.3g} g, beyond the sensor's range ±{limit:g} g"
            causes[i] = BEYOND_RANGE
        if self.input_layout == WINDOWS_LAYOUT:
            # A window constant on every axis carries no vibration: its features are conventions
            # (zero variance, no crossings), not measurements, so it is not classified.
            flat = ~beyond & (x.max(axis=2) == x.min(axis=2)).all(axis=1)
            for i in np.flatnonzero(flat):
                reasons[i] = (
                    f"no vibration: every axis is constant ({', '.join(f'{v:g}' for v in x[i, :, 0])} g)"
                )
                causes[i] = NO_VIBRATION
            beyond = beyond | flat
        run = np.flatnonzero(~beyond)
        if len(run):
            values = self.session.run(None, {self._input.name: x[run]})
            out = dict(zip(self._outputs, values, strict=True))
            got = out[SCORES_OUTPUT].reshape(len(run), -1)
            if got.shape[1] != scores.shape[1]:
                scores = np.full((n, got.shape[1]), np.nan, dtype=np.float32)
            scores[run] = got
            labels[run] = np.asarray(out[LABELS_OUTPUT], dtype=np.int64)
            if novel is not None:
                novel[run] = np.asarray(out[NOVEL_OUTPUT], dtype=bool)
            finite = np.isfinite(got).all(axis=1)
            threshold = self.ood_threshold
            if threshold is not None:
                distance[run] = out[OOD_OUTPUT]
            for j, i in enumerate(run):
                if not finite[j]:
                    labels[i] = UNKNOWN
                    reasons[i] = (
                        "scores not finite (values far outside the sensor's range overflow the features)"
                    )
                    causes[i] = NOT_FINITE
                elif threshold is not None and not distance[i] <= threshold:
                    labels[i] = UNKNOWN
                    reasons[i] = (
                        f"out of distribution: distance {distance[i]:.3g} to the training data > {threshold:.3g}"
                    )
                    causes[i] = OUT_OF_DISTRIBUTION
        return Prediction(labels, scores, distance, reasons, causes, novel)

    def _raise_non_finite(self, prediction: Prediction) -> None:
        bad = np.array([c == NOT_FINITE for c in prediction.causes])
        if bad.any():
            raise NonFiniteScoresError(np.flatnonzero(bad), len(bad))

    def predict(self, raw: np.ndarray, *, range_g: float | None = None) -> np.ndarray:
        """Return the predicted label of each sample, shape ``(B,)`` int64; ``-1`` is "unknown".

        See :meth:`classify` for when a sample is unknown (and why; ``range_g`` as there). Raises
        :class:`NonFiniteScoresError` when a sample within the sensor's range gave non-finite scores.
        """
        prediction = self.classify(raw, range_g=range_g)
        self._raise_non_finite(prediction)
        return prediction.labels

    def predict_scores(
        self, raw: np.ndarray, *, range_g: float | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Return ``(labels, scores)``: labels ``(B,)`` int64 (``-1``: unknown) and scores ``(B, C)`` float32.

        Scores of samples beyond the sensor's range are NaN (they are not run through the graph).
        """
        prediction = self.classify(raw, range_g=range_g)
        self._raise_non_finite(prediction)
        return prediction.labels, prediction.scores

    def predict_names(self, raw: np.ndarray) -> list[str]:
        """Return the predicted class name of each sample (the label when the bundle has no names), ``"unknown"`` for -1."""
        return [self.label_name(int(label)) for label in self.predict(raw)]

    def label_name(self, label: int) -> str:
        """Return the name of ``label``: its class name, ``"unknown"`` for -1, else the label as a string."""
        if label == UNKNOWN:
            return UNKNOWN_NAME
        return self.class_names[label] if 0 <= label < len(self.class_names) else str(label)

    def read_npz(
        self, path: str | Path | Sequence[str | Path], *, allow_pickle: bool = False, options=None
    ) -> LabelledInput:
        """Read a data file into this bundle's raw input (:func:`tactile_torch.robot.files.formats.read_data`).

        Image explorations (``frames`` uint8 ``(N, T, H, W, 3)``) become ``(N, T, 3, H, W)``; vibration
        recordings (a ``.npz`` or CSV logs) are cut into windows of the bundle's ``window_size``
        every ``step`` samples (its metadata); a ``features`` matrix is passed as is. ``labels`` are
        mapped onto this bundle's class names through the file's ``class_names``; a class the
        bundle does not know gets -1. ``allow_pickle`` only serves old vibration files that stored
        recordings of different lengths as a pickled object array (trusted files only).

        Raises ``ValueError`` naming the file when it does not fit the bundle (e.g. recordings for
        an image bundle, recordings shorter than one window) or breaks the format (see
        ``docs/formats.md``). ``options`` (:class:`tactile_torch.robot.files.data_sources.DataOptions`, NumPy
        only) declares how CSV logs and ROS 2 bags are read (columns, units, time unit, topic).
        """
        from .files.formats import data_name, read_data
        from .stream.touches import fit_explorations
        from .stream.windows import window_recordings

        if options is None:
            data = read_data(path, allow_pickle=allow_pickle)
        else:
            from .files.data_sources import read_source

            data = read_source(path, options)
        where = data_name(path)
        layout, rate, note = self.input_layout, None, None
        if data.kind == "image" and layout == FRAMES_LAYOUT:
            if data.frames is None:
                raise ValueError(
                    f"{where}: frames must be uint8 RGB (N, T, H, W, 3) for this {self.pipeline} bundle, "
                    f"got float pressure maps {data.pressure.shape}: render them first "
                    "(tactile_torch.data.images.render_pressure)"
                )
            raw, labels = np.ascontiguousarray(data.frames.transpose(0, 1, 4, 2, 3)), data.labels
            raw, note = fit_explorations(raw, self.input_shape[1])
        elif data.kind == "image" and layout == PRESSURE_LAYOUT:
            if data.pressure is None:
                raise ValueError(
                    f"{where}: frames must be pressure maps (N, T, H, W) for this {self.pipeline} bundle, got "
                    f"RGB frames {data.frames.shape}"
                )
            (raw, note), labels = fit_explorations(data.pressure, self.input_shape[1]), data.labels
        elif data.kind == "vibration" and layout == WINDOWS_LAYOUT:
            if WINDOW_SIZE_KEY not in self.metadata:
                raise ValueError(f"{self.path}: no {WINDOW_SIZE_KEY} in the bundle's metadata")
            size = int(self.metadata[WINDOW_SIZE_KEY])
            try:
                step = int(self.metadata.get(STEP_KEY, size))
                cut = window_recordings(data.signals, size, step, gaps=getattr(data, "gaps", None))
            except ValueError as err:
                raise ValueError(f"{where}: {err}, the window of this {self.pipeline} bundle") from None
            raw, labels, rate = cut.windows, data.labels[cut.recording], data.rate_hz
        elif data.kind == "features" and layout == FEATURES_LAYOUT:
            raw, labels = data.features.astype(np.float32), data.labels
        else:
            raise ValueError(
                f"{where} holds {data.kind} data ({_KIND_KEYS[data.kind]}), which does not fit this "
                f"{self.pipeline} bundle (input {layout})"
            )
        names = list(data.class_names) if data.class_names is not None else None
        file_labels = labels
        if labels is not None and names is not None:
            index = {name: i for i, name in enumerate(self.class_names)}
            lookup = np.array([index.get(name, -1) for name in names], dtype=np.int64)
            labels = lookup[labels]
        return LabelledInput(raw, labels, names, rate, file_labels, note)

    def sample_rate_mismatch(self, rate_hz: float | None) -> str | None:
        """Return a one-line warning when data sampled at ``rate_hz`` do not match the bundle's rate.

        ``None`` when the rates agree within 1 %, or when either is unknown. Windows of data recorded
        at another rate span another duration and frequency band than the model was trained on, so
        its predictions may be meaningless; resample the data (``VibrationRecordings.resample``).
        """
        want = self.metadata.get(SAMPLE_RATE_KEY)
        if rate_hz is None or want is None:
            return None
        want = float(want)
        if abs(rate_hz / want - 1.0) <= 0.01:
            return None
        size = int(self.metadata.get(WINDOW_SIZE_KEY, 0))
        return (
            f"the data are sampled at {rate_hz:g} Hz but this {self.pipeline} bundle was trained at "
            f"{want:g} Hz (a window of {size} samples lasts {size / rate_hz:g} s here, {size / want:g} s "
            "in training); predictions may be meaningless: resample the data or retrain"
        )

    def __repr__(self) -> str:
        return (
            f"OnnxPipeline({str(self.path)!r}, pipeline={self.pipeline!r}, "
            f"input=({self.input_layout}), classes={len(self.class_names)})"
        )


__all__ = [
    "LabelledInput",
    "NonFiniteScoresError",
    "OnnxPipeline",
    "Prediction",
    "beyond_range",
    "sensor_range_g",
]
