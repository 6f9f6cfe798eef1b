"""Export torch modules to ONNX with the dynamo exporter, and run ONNX models with onnxruntime.

Shared by the parity tests of every exported op and by the pipeline export. The batch dimension
(dim 0 of every input) is dynamic by default, so a model exported with a batch of 2 runs on any batch.
"""

from __future__ import annotations

import contextlib
import io
import logging
import tempfile
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import torch


def export_onnx(
    module: torch.nn.Module,
    example_inputs: Sequence[torch.Tensor],
    path: str | Path,
    *,
    input_names: Sequence[str] | None = None,
    output_names: Sequence[str] | None = None,
    dynamic_batch: bool = True,
    metadata: Mapping[str, str] | None = None,
    opset_version: int | None = None,
    dynamic_shapes: object | None = None,
    inputs: Sequence[str | Path] = (),
) -> Path:
    """Export ``module(*example_inputs)`` to ``path`` with ``torch.onnx.export(..., dynamo=True)``.

    Dimension 0 of every input is a dynamic batch size unless ``dynamic_batch=False``;
    ``dynamic_shapes`` (``torch.export``'s, structured like ``forward``'s arguments) replaces that
    default when given. ``metadata`` goes into the model's ``metadata_props``. The exported model is
    checked with ``onnx.checker`` and written atomically (:func:`save_onnx`: never onto a directory, a
    device, a symbolic link or one of ``inputs``). Returns ``path``.
    """
    import onnx

    from ..robot.files.safe_write import check_output_path

    path = check_output_path(path, inputs=inputs)  # refuse before the (slow) export, not after
    example_inputs = tuple(example_inputs)
    if dynamic_shapes is None and dynamic_batch:
        batch = torch.export.Dim("batch", min=1, max=1 << 20)
        dynamic_shapes = tuple({0: batch} for _ in example_inputs)
    module = module.eval()
    # The exporter reports its progress and optional-dependency notes on stdout and the log; keep the
    # caller's output clean and surface only real errors (raised).
    quiet = logging.getLogger("torch.onnx")
    level = quiet.level
    quiet.setLevel(logging.ERROR)
    try:
        with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
            warnings.simplefilter("ignore")
            program = torch.onnx.export(
                module,
                example_inputs,
                dynamo=True,
                dynamic_shapes=dynamic_shapes,
                input_names=list(input_names) if input_names else None,
                output_names=list(output_names) if output_names else None,
                opset_version=opset_version,
                optimize=True,
                verbose=False,
            )
    finally:
        quiet.setLevel(level)
    with tempfile.TemporaryDirectory() as scratch:  # the exporter writes a path; ours is written atomically
        program.save(str(Path(scratch) / "model.onnx"))
        model = onnx.load(str(Path(scratch) / "model.onnx"))
    drop_unused_initializers(model)
    if metadata:
        for key, value in metadata.items():
            entry = model.metadata_props.add()
            entry.key, entry.value = str(key), str(value)
    onnx.checker.check_model(model, full_check=True)
    return save_onnx(model, path, inputs=inputs)


def save_onnx(model: object, path: str | Path, *, inputs: Sequence[str | Path] = ()) -> Path:
    """Write an ``onnx.ModelProto`` to ``path`` atomically and sealed, refusing unsafe targets; return ``path``.

    The file gets its digest (:func:`tactile_torch.robot.integrity.seal`: SHA-256 of the file without
    the digest's own metadata property, replacing any digest the model carried), which
    :class:`~tactile_torch.robot.runtime.OnnxPipeline` checks on load: every exporter writes through
    here. A directory, a device, a symbolic link or one of ``inputs`` at ``path`` is refused in one
    line (:func:`tactile_torch.robot.files.safe_write.write_atomic`); the file appears under its name only
    complete. The exporter's per-node metadata is removed from ``model`` first (:func:`strip_node_metadata`).
    """
    from ..robot.files.safe_write import write_atomic
    from ..robot.integrity import seal

    strip_node_metadata(model)  # every file written carries no build machine's paths
    data = seal(model.SerializeToString())
    return write_atomic(path, lambda f: f.write(data), inputs=inputs)


def unsealed(model: object) -> object:
    """Return a copy of an ``onnx.ModelProto`` without its digest property (to change or merge it)."""
    import onnx

    from ..robot.contract import DIGEST_KEY

    copy = onnx.ModelProto()
    copy.CopyFrom(model)
    kept = [(p.key, p.value) for p in copy.metadata_props if p.key != DIGEST_KEY]
    del copy.metadata_props[:]
    for key, value in kept:
        entry = copy.metadata_props.add()
        entry.key, entry.value = key, value
    return copy


def _used_names(graph) -> set[str]:
    """Names read by the nodes of ``graph`` and of its subgraphs, and the graph's outputs."""
    used = {out.name for out in graph.output}
    for node in graph.node:
        used.update(node.input)
        for attr in node.attribute:
            subgraphs = list(attr.graphs) + ([attr.g] if attr.HasField("g") else [])
            for sub in subgraphs:
                used |= _used_names(sub)
    return used


def strip_node_metadata(model) -> int:
    """Remove the exporter's per-node metadata (``pkg.torch.onnx.*``: stack traces with the build
    machine's source paths, module names); return how many entries went.

    They carry nothing onnxruntime uses, make a bundle's bytes depend on where it was built and reveal
    that machine's paths in a file shipped to a robot.
    """
    removed = 0
    graphs = [model.graph, *(f for f in model.functions)]
    while graphs:
        graph = graphs.pop()
        for node in graph.node:
            removed += len(node.metadata_props)
            del node.metadata_props[:]
            for attribute in node.attribute:
                if attribute.HasField("g"):
                    graphs.append(attribute.g)
                graphs.extend(attribute.graphs)
    return removed


def drop_unused_initializers(model) -> int:
    """Remove the main graph's initializers that no node reads (in place); return how many.

    A module's buffers that inference does not need (e.g. the one-vs-one SVM's ``n_support``, kept for
    its model file) would otherwise be stored in the file and make onnxruntime log a warning at every
    session start.
    """
    graph = model.graph
    used = _used_names(graph)
    unused = [init for init in graph.initializer if init.name not in used]
    for init in unused:
        graph.initializer.remove(init)
    return len(unused)


def run_onnx(path: str | Path, *inputs: np.ndarray | torch.Tensor, threads: int = 1) -> list[np.ndarray]:
    """Run an ONNX model with onnxruntime on ``inputs`` (in the model's input order); return its outputs."""
    import onnxruntime as ort

    options = ort.SessionOptions()
    options.intra_op_num_threads = threads
    options.inter_op_num_threads = 1
    session = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
    feeds = {
        arg.name: (x.detach().cpu().numpy() if isinstance(x, torch.Tensor) else np.asarray(x))
        for arg, x in zip(session.get_inputs(), inputs, strict=True)
    }
    return session.run(None, feeds)
