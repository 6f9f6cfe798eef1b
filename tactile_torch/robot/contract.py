"""The ONNX bundle contract: tensor names, metadata keys and the "unknown" label, in one place.

Every exporter (:mod:`tactile_torch.inference_pipeline`, :mod:`tactile_torch.export.neural`,
:mod:`tactile_torch.export.parts`, :mod:`tactile_torch.ood`, the mixture's inference module) writes
bundles with these names, and :class:`tactile_torch.robot.runtime.OnnxPipeline` reads them: import
them from here rather than spelling them. A bundle is one ``.onnx`` file: input :data:`INPUT_NAME`, outputs
:data:`LABELS_OUTPUT` and :data:`SCORES_OUTPUT` (then optionally :data:`OOD_OUTPUT` or
:data:`NOVEL_OUTPUT`), and string metadata properties (JSON where structured, :func:`metadata_strings`).

Metadata the runtime reads
--------------------------
=========================  ======================================================================
key                        value
=========================  ======================================================================
``tactile_torch.pipeline`` what the graph does, e.g. ``"vibration-svm"`` (:data:`PIPELINE_KEY`)
``tactile_torch.version``  the library version that exported it (:data:`VERSION_KEY`)
``input_shape``            JSON list, one entry per input dimension: an int fixes the size,
                           ``null`` is free (the batch)
``input_layout``           the dimension names (:data:`LAYOUTS`), used in error messages
``class_names``            JSON list of the class (or component) names indexed by label
``uint8_scale``            optional: uint8 input is accepted and multiplied by it
``window_size``, ``step``  vibration bundles: samples per window and between window starts
``sample_rate_hz``         vibration bundles: the rate the model was trained at
``sensor_range_g``         vibration bundles: windows with a sample beyond it are unknown
``ood_threshold``          classifier bundles: a larger ``ood_distance`` is unknown
``ood_quantile``           the training quantile the threshold was set at (informative)
``frame_rate_hz``          frame bundles: the frames per second the model was trained at
``value_range``            frame bundles: JSON ``[low, high]``; a frame with a value outside is
                           rejected by ``stream``
``touch_levels``           frame bundles: JSON of the touch levels (onset, release, shortest
                           touch, resting level: :class:`~tactile_torch.robot.stream.touches.TouchLevels`)
``early_decision``         frame bundles: JSON of the calibrated early-decision rule
                           (:class:`~tactile_torch.robot.stream.early_decision.EarlyRule`)
``tactile_torch.sha256``   ``"sha256:<hex>"`` of the file without this property: checked on load
                           (:mod:`tactile_torch.robot.integrity`)
=========================  ======================================================================

Other keys an exporter writes (method, kernel, feature scale, test accuracy, ...) are kept in
:attr:`~tactile_torch.robot.runtime.OnnxPipeline.metadata` for the caller and read by no code.

Examples
--------
>>> metadata_strings({PIPELINE_KEY: "vibration-svm", WINDOW_SIZE_KEY: 800, CLASS_NAMES_KEY: ["cork"]})
{'tactile_torch.pipeline': 'vibration-svm', 'window_size': '800', 'class_names': '["cork"]'}
"""

from __future__ import annotations

import json
from collections.abc import Mapping

# ------------------------------------------------------------------------------------ tensors
INPUT_NAME = "raw"
"""The bundle's one input: raw frames, windows or features in :data:`LAYOUTS`' layouts."""
FEATURES_NAME = "features"
"""The tensor that joins a front-end graph to a head graph before they are merged into one bundle."""
LABELS_OUTPUT = "labels"
"""Output: the label of each sample, ``(B,)`` int64."""
SCORES_OUTPUT = "scores"
"""Output: the per-class scores of each sample, ``(B, C)`` float32."""
OOD_OUTPUT = "ood_distance"
"""Output of classifier bundles: the distance to the training data (:mod:`tactile_torch.ood`)."""
NOVEL_OUTPUT = "novel"
"""Output of clustering bundles: whether the sample is novel (the model's own rule, or the calibrated threshold)."""
NOVELTY_SCORE_OUTPUT = "novelty"
"""Output of clustering bundles: the novelty score of each sample, minus its log density under the mixture."""

# ------------------------------------------------------------------------------------ metadata keys
PIPELINE_KEY = "tactile_torch.pipeline"
VERSION_KEY = "tactile_torch.version"
DIGEST_KEY = "tactile_torch.sha256"
"""Metadata key of the bundle's digest, written by every exporter (:func:`tactile_torch.robot.integrity.seal`)."""
INPUT_SHAPE_KEY = "input_shape"
INPUT_LAYOUT_KEY = "input_layout"
CLASS_NAMES_KEY = "class_names"
UINT8_SCALE_KEY = "uint8_scale"
WINDOW_SIZE_KEY = "window_size"
STEP_KEY = "step"
SAMPLE_RATE_KEY = "sample_rate_hz"
RANGE_METADATA_KEY = "sensor_range_g"
"""Bundle metadata key that, when present, gives the sensor's range in g."""
THRESHOLD_KEY = "ood_threshold"
"""Metadata key of the distance beyond which a sample is unknown."""
QUANTILE_KEY = "ood_quantile"
"""Metadata key of the training quantile the threshold was set at."""
NOVELTY_THRESHOLDS_KEY = "novelty_thresholds"
"""Clustering bundles calibrated on known windows: JSON list of the thresholds of the mean novelty over N = 1, 2, ... windows."""

FRAME_RATE_KEY = "frame_rate_hz"
"""Frame bundles: the frame rate (frames/s) of the explorations the model was trained on."""
VALUE_RANGE_KEY = "value_range"
"""Frame bundles: JSON ``[low, high]`` of the values a frame may hold (others are rejected live)."""
TOUCH_LEVELS_KEY = "touch_levels"
"""Frame bundles: JSON of the levels that cut touches from frames (:mod:`tactile_torch.robot.stream.touches`)."""
EARLY_RULE_KEY = "early_decision"
"""Frame bundles: JSON of the calibrated early-decision rule (:mod:`tactile_torch.robot.stream.early_decision`)."""

# ------------------------------------------------------------------------------------ input layouts
WINDOWS_LAYOUT = "B,3,W"
FRAMES_LAYOUT = "B,T,3,H,W"
PRESSURE_LAYOUT = "B,T,H,W"
FEATURES_LAYOUT = "B,F"
LAYOUTS = (WINDOWS_LAYOUT, FRAMES_LAYOUT, PRESSURE_LAYOUT, FEATURES_LAYOUT)
"""Input layouts: vibration windows in g, RGB frames, pressure maps, feature matrices."""

# ------------------------------------------------------------------------------------ answers
UNKNOWN = -1
"""Label of a sample the bundle does not classify (beyond the sensor's range, or out of distribution)."""
UNKNOWN_NAME = "unknown"
"""Name printed for :data:`UNKNOWN`."""
BEYOND_RANGE = "beyond range"
"""Why a sample is unknown: it holds a value beyond the sensor's range (not run through the graph)."""
NO_VIBRATION = "no vibration"
"""Why a vibration window is unknown: every axis is constant (not run through the graph)."""
NOT_FINITE = "scores not finite"
"""Why a sample is unknown: the graph's scores for it are not finite."""
OUT_OF_DISTRIBUTION = "out of distribution"
"""Why a sample is unknown: its features lie beyond the bundle's distance threshold to the training data."""
UNKNOWN_CAUSES = (BEYOND_RANGE, NO_VIBRATION, NOT_FINITE, OUT_OF_DISTRIBUTION)
"""The causes of an unknown sample (:attr:`Prediction.causes`), in the order :meth:`OnnxPipeline.classify` checks them."""
DEFAULT_RANGE_G = 5.0
"""Range of the ADXL345 as configured in the vibration study (method 2), in g: the default sensor range."""


def metadata_strings(metadata: Mapping[str, object]) -> dict[str, str]:
    """Return ``metadata`` as ONNX metadata properties: strings kept, every other value as JSON."""
    return {
        str(key): value if isinstance(value, str) else json.dumps(value) for key, value in metadata.items()
    }


__all__ = [
    "BEYOND_RANGE",
    "CLASS_NAMES_KEY",
    "DEFAULT_RANGE_G",
    "DIGEST_KEY",
    "EARLY_RULE_KEY",
    "FEATURES_LAYOUT",
    "FEATURES_NAME",
    "FRAMES_LAYOUT",
    "FRAME_RATE_KEY",
    "INPUT_LAYOUT_KEY",
    "INPUT_NAME",
    "INPUT_SHAPE_KEY",
    "LABELS_OUTPUT",
    "LAYOUTS",
    "NOT_FINITE",
    "NOVELTY_SCORE_OUTPUT",
    "NOVELTY_THRESHOLDS_KEY",
    "NOVEL_OUTPUT",
    "NO_VIBRATION",
    "OOD_OUTPUT",
    "OUT_OF_DISTRIBUTION",
    "PIPELINE_KEY",
    "PRESSURE_LAYOUT",
    "QUANTILE_KEY",
    "RANGE_METADATA_KEY",
    "SAMPLE_RATE_KEY",
    "SCORES_OUTPUT",
    "STEP_KEY",
    "THRESHOLD_KEY",
    "TOUCH_LEVELS_KEY",
    "UINT8_SCALE_KEY",
    "UNKNOWN",
    "UNKNOWN_CAUSES",
    "UNKNOWN_NAME",
    "VALUE_RANGE_KEY",
    "VERSION_KEY",
    "WINDOWS_LAYOUT",
    "WINDOW_SIZE_KEY",
    "metadata_strings",
]
