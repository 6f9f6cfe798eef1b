"""The "unknown" rule of :mod:`tactile_torch.ood` as a part of an exported bundle.

:func:`attach_distance` adds an exported distance part (:class:`tactile_torch.ood.DistanceHead`:
features → ``ood_distance``) to a bundle, reading a tensor the bundle computes anyway (a classical
bundle's ``features``, a network's ``embedding``: :class:`~tactile_torch.export.neural.EmbeddingGraph`),
with the rule's threshold in its metadata: the ONNX surgery of the out-of-distribution score (the
estimator and its torch modules are :mod:`tactile_torch.ood`'s). The part's names are prefixed ``ood.``;
added after any quantisation, it stays in float in an int8 file.
"""

from __future__ import annotations

from pathlib import Path

from ..robot.contract import FEATURES_NAME


def attach_distance(model: object, part: object, rule: dict, *, reads: str) -> object:
    """Return ``model`` (an ONNX ``ModelProto``) with the distance ``part`` reading its tensor ``reads``.

    ``part`` is a graph with one input and the output ``ood_distance``: an exported
    :class:`tactile_torch.ood.DistanceHead` (input ``features``), or a feature graph joined to one (input
    ``raw``: a rule measured on features the bundle does not compute, :func:`distance_branch`). Its input
    becomes the tensor ``reads`` of ``model`` (an input, or a tensor a node writes, which stops being an
    output when it was one), and the rule's threshold and quantile go into the metadata
    (:data:`~tactile_torch.robot.contract.THRESHOLD_KEY`, :data:`~tactile_torch.robot.contract.QUANTILE_KEY`),
    which :class:`tactile_torch.robot.runtime.OnnxPipeline` reads to answer "unknown" beyond the
    threshold. ``model`` is changed in place (its digest dropped: save it with
    :func:`tactile_torch.export.save_onnx`) and returned.

    Raises
    ------
    ValueError
        When no node of ``model`` writes ``reads``.
    """
    import onnx
    from onnx import compose

    from ..robot.contract import QUANTILE_KEY, THRESHOLD_KEY, metadata_strings
    from ._onnx import unsealed

    written = {name for node in model.graph.node for name in node.output} | {
        i.name for i in model.graph.input
    }
    if reads not in written:
        raise ValueError(f"reads must name a tensor the bundle computes, got {reads!r}")
    kept = [(p.key, p.value) for p in unsealed(model).metadata_props]
    side = compose.add_prefix(unsealed(part), "ood.", rename_outputs=False)
    versions = {entry.domain: entry.version for entry in model.opset_import}
    for entry in side.opset_import:
        if versions.get(entry.domain, entry.version) != entry.version:
            side = onnx.version_converter.convert_version(side, versions[entry.domain])
            break
    source = f"ood.{part.graph.input[0].name}"
    for node in side.graph.node:
        node.input[:] = [reads if name == source else name for name in node.input]
    graph = model.graph
    graph.node.extend(side.graph.node)
    graph.initializer.extend(side.graph.initializer)
    graph.value_info.extend(v for v in side.graph.value_info if v.name != source)
    outputs = [o for o in graph.output if o.name != reads]
    del graph.output[:]
    graph.output.extend([*outputs, *side.graph.output])
    model.functions.extend(side.functions)
    known = {entry.domain for entry in model.opset_import}
    model.opset_import.extend(entry for entry in side.opset_import if entry.domain not in known)
    meta = metadata_strings({THRESHOLD_KEY: float(rule["threshold"]), QUANTILE_KEY: float(rule["quantile"])})
    del model.metadata_props[:]
    for key, value in [*((k, v) for k, v in kept if k not in meta), *meta.items()]:
        entry = model.metadata_props.add()
        entry.key, entry.value = key, value
    onnx.checker.check_model(model)
    return model


def distance_branch(front: object, part: object) -> object:
    """Return a feature graph ``front`` (input ``raw``, output ``features``:
    :func:`tactile_torch.export.parts.export_front`) joined to a distance ``part`` (input ``features``): the
    rule of a model measured on features its own graph does not compute, for :func:`attach_distance`."""
    from onnx import compose

    from ._onnx import unsealed

    tail = compose.add_prefix(unsealed(part), "head.", rename_outputs=False)
    return compose.merge_models(unsealed(front), tail, io_map=[(FEATURES_NAME, f"head.{FEATURES_NAME}")])


def write_with_distance(bare: str | Path, part: object, rule: dict, path: str | Path, *, reads: str) -> Path:
    """Write the bundle file ``bare`` with the distance ``part`` reading its tensor ``reads``
    (:func:`attach_distance`) to ``path`` (sealed: :func:`tactile_torch.export.save_onnx`); return ``path``."""
    import onnx

    from ._onnx import save_onnx

    return save_onnx(attach_distance(onnx.load(str(bare)), part, rule, reads=reads), path)


__all__ = ["attach_distance", "distance_branch", "write_with_distance"]
