"""int8 variants of exported candidates, with onnxruntime's quantisation tools (no torch).

:func:`quantise_bundle` writes an int8 copy of a candidate's ``.onnx`` file:

* **static** (``mode="static"``, the default when calibration data is given): weights *and*
  activations in int8 (QDQ format, per-tensor, min-max calibration). The activation ranges are
  measured by running the float graph on ``calibration``, raw inputs drawn from the *training* fold
  (never the held-out samples the variant is scored on);
* **dynamic** (``mode="dynamic"``): int8 weights of the matrix products and convolutions, activations
  quantised on the fly; needs no calibration data. Used where static does not apply (no calibration
  data) or failed.

What is quantised depends on the graph: the convolutions and matrix products of the neural
candidates and the linear heads; graphs made of other operators (the image ops, distances of the SVM
kernels) keep them in float, so the int8 file may be barely smaller. The metadata (class names, input
shape ...) is copied, plus ``quantisation`` = the mode used. The caller measures the variant
(accuracy, latency, size, memory) like any other candidate.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

MODES = ("static", "dynamic")
QUANTISED_OPS = ("Conv", "MatMul", "Gemm")
"""Operators given int8 weights (per output channel) and int8 inputs: the layers that carry the
parameters. The input normalisation, the feature ops and the softmax stay in float (quantising the raw
input's range per tensor cost label agreement on spiky vibration windows)."""


class _Calibration:
    """onnxruntime's ``CalibrationDataReader`` protocol over raw inputs, a few samples per batch."""

    def __init__(self, input_name: str, raw: np.ndarray, batch: int = 8) -> None:
        self._batches = iter([{input_name: raw[i : i + batch]} for i in range(0, len(raw), batch)])

    def get_next(self) -> dict | None:
        return next(self._batches, None)

    def rewind(self) -> None:  # pragma: no cover - onnxruntime may call it
        pass


CLASSIFIER_PREFIX = "head."
"""The names of a joined classical bundle's classifier nodes (:func:`tactile_torch.export.parts.join`):
what its int8 variant quantises. The feature graph stays in float: int8 activations of a window's
spectrum lose the small high-frequency vibration the features measure."""
QUANTISED_NODE_TYPES = (
    "QuantizeLinear",
    "DequantizeLinear",
    "MatMulInteger",
    "ConvInteger",
    "DynamicQuantizeLinear",
)


def quantised_nodes(path: str | Path) -> int:
    """Return how many int8 (quantise, dequantise, integer matrix) nodes the ONNX file ``path`` holds."""
    import onnx

    return sum(n.op_type in QUANTISED_NODE_TYPES for n in onnx.load(str(path)).graph.node)


def _copy_metadata(source: object, target_path: Path, mode: str) -> None:
    import onnx

    from ..robot.contract import DIGEST_KEY
    from ._onnx import save_onnx

    model = onnx.load(str(target_path))
    del model.metadata_props[:]
    for prop in source.metadata_props:
        if prop.key != DIGEST_KEY:  # the source's digest: the int8 file gets its own (save_onnx)
            entry = model.metadata_props.add()
            entry.key, entry.value = prop.key, prop.value
    entry = model.metadata_props.add()
    entry.key, entry.value = "quantisation", mode
    save_onnx(model, target_path)


def quantise_bundle(
    path: str | Path,
    out: str | Path,
    *,
    calibration: np.ndarray | None = None,
    mode: str | None = None,
    only_prefix: str | None = None,
) -> tuple[Path, str]:
    """Write an int8 copy of the bundle ``path`` to ``out``; return ``(out, mode used)``.

    Parameters
    ----------
    path : path
        A float ``.onnx`` bundle (input ``raw``, outputs ``labels`` and ``scores``).
    out : path
    calibration : ndarray, optional
        Raw inputs from the training data, in the graph's dtype (static mode).
    mode : {"static", "dynamic"}, optional
        Default: static when ``calibration`` is given, else dynamic. A static quantisation that fails
        falls back to dynamic (the returned mode says which).
    only_prefix : str, optional
        Quantise only the nodes whose names start with this (a joined classical bundle's classifier,
        ``"head."``); the others stay in float.

    Raises
    ------
    ValueError
        For an unknown ``mode``, or ``mode="static"`` without calibration data.
    """
    import onnx

    if mode is None:
        mode = "static" if calibration is not None and len(calibration) else "dynamic"
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    if mode == "static" and (calibration is None or not len(calibration)):
        raise ValueError("calibration must hold at least one raw input for mode='static'")
    path, out = Path(path), Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    source = onnx.load(str(path))
    # onnxruntime's quantiser logs advice on the root logger ("consider pre-processing"): not ours to show.
    root = logging.getLogger()
    level = root.level
    root.setLevel(logging.ERROR)
    import tempfile

    try:
        with tempfile.TemporaryDirectory(prefix="tactile-torch-int8-") as tmp:
            exclude = (
                []
                if only_prefix is None
                else [n.name for n in source.graph.node if not n.name.startswith(only_prefix)]
            )
            used = _quantise(
                _single_opsets(source, path, Path(tmp)),
                out,
                source.graph.input[0].name,
                calibration,
                mode,
                exclude,
            )
    finally:
        root.setLevel(level)
    _copy_metadata(source, out, used)
    return out, used


def _single_opsets(model: object, path: Path, tmp: Path) -> Path:
    """``path``, or a copy with one opset import per domain (the highest version) when the file lists a
    domain twice, as a model joined by ``onnx.compose.merge_models`` does; onnxruntime's quantiser needs one."""
    import onnx

    versions: dict[str, int] = {}
    for entry in model.opset_import:
        versions[entry.domain] = max(versions.get(entry.domain, 0), entry.version)
    if len(versions) == len(model.opset_import):
        return path
    copy = onnx.ModelProto()
    copy.CopyFrom(model)
    del copy.opset_import[:]
    copy.opset_import.extend(
        onnx.helper.make_opsetid(domain, version) for domain, version in versions.items()
    )
    fixed = tmp / path.name
    onnx.save(copy, str(fixed))
    return fixed


def _quantise(
    path: Path, out: Path, input_name: str, calibration: np.ndarray | None, mode: str, exclude: list[str]
) -> str:
    from onnxruntime.quantization import QuantFormat, QuantType, quantize_dynamic, quantize_static

    if mode == "static":
        try:
            quantize_static(
                str(path),
                str(out),
                _Calibration(input_name, np.ascontiguousarray(calibration)),
                quant_format=QuantFormat.QDQ,
                activation_type=QuantType.QUInt8,
                weight_type=QuantType.QInt8,
                per_channel=True,
                op_types_to_quantize=list(QUANTISED_OPS),
                nodes_to_exclude=exclude,
            )
            return "static"
        except Exception:  # an operator static quantisation cannot handle: weights only
            pass
    quantize_dynamic(
        str(path),
        str(out),
        weight_type=QuantType.QInt8,
        op_types_to_quantize=list(QUANTISED_OPS),
        nodes_to_exclude=exclude,
    )
    return "dynamic"
