"""The "unknown" rule of :mod:`tactile_torch.ood` as an ONNX branch beside an exported bundle.

:func:`distance_graph` joins a feature graph to the distance head (:class:`tactile_torch.ood.DistanceHead`)
and :func:`add_distance` adds that graph to a bundle, with the threshold in its metadata: the ONNX
surgery of the out-of-distribution score (the estimator and its torch modules are :mod:`tactile_torch.ood`'s).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import torch

from ..robot.contract import OOD_OUTPUT

if TYPE_CHECKING:
    from ..ood import DistanceHead


def distance_graph(front: object, head: DistanceHead, n_features: int) -> object:
    """Return the ONNX graph raw input → ``ood_distance``: a feature graph ``front`` (input ``raw``, output
    ``features``: the study's exported front, :func:`tactile_torch.export.parts.export_front`) joined
    to ``head`` exported for ``n_features`` features."""
    import tempfile

    from onnx import compose

    from ..robot.contract import FEATURES_NAME
    from ._onnx import export_onnx, unsealed

    with tempfile.TemporaryDirectory(prefix="tactile-torch-ood-") as scratch:
        import onnx

        path = export_onnx(
            head.eval(),
            (torch.zeros(2, n_features, dtype=torch.float32),),
            Path(scratch) / "distance.onnx",
            input_names=[FEATURES_NAME],
            output_names=[OOD_OUTPUT],
        )
        tail = compose.add_prefix(unsealed(onnx.load(str(path))), "head.", rename_outputs=False)
    # the parts were written sealed, each with its own digest: merge_models refuses two values of one key
    return compose.merge_models(unsealed(front), tail, io_map=[(FEATURES_NAME, f"head.{FEATURES_NAME}")])


def add_distance(bundle: str | Path, graph: object, rule: dict, *, out: str | Path | None = None) -> Path:
    """Add the "unknown" rule to an exported bundle: ``graph`` (raw input → ``ood_distance``,
    :func:`distance_graph`) as a float branch beside it, the threshold and quantile in its metadata;
    return the path written (``out``, default ``bundle`` itself).

    The bundle's own graph (labels and scores; an int8 one too) is left as it is: the branch's names are
    prefixed ``ood.`` and its nodes added to the bundle's graph, reading the same input.
    :class:`tactile_torch.robot.runtime.OnnxPipeline` then answers "unknown" beyond the threshold, as for
    a model file's bundle.

    Parameters
    ----------
    bundle : path
        An ``.onnx`` bundle (input ``raw``, outputs ``labels`` and ``scores``).
    graph : onnx.ModelProto
    rule : dict
        :func:`tactile_torch.ood.fit_rule`'s result (``threshold``, ``quantile``).
    """
    import onnx
    from onnx import compose

    from ..robot.contract import QUANTILE_KEY, THRESHOLD_KEY, metadata_strings
    from ._onnx import save_onnx, unsealed

    main = unsealed(onnx.load(str(bundle)))  # sealed again, with the branch, when saved
    side = compose.add_prefix(graph, "ood.", rename_inputs=False, rename_outputs=False)
    versions = {entry.domain: entry.version for entry in main.opset_import}
    for entry in side.opset_import:
        if versions.get(entry.domain, entry.version) != entry.version:
            side = onnx.version_converter.convert_version(side, versions[entry.domain])
            break
    merged = main.graph
    merged.node.extend(side.graph.node)
    merged.initializer.extend(side.graph.initializer)
    merged.value_info.extend(side.graph.value_info)
    merged.output.extend(side.graph.output)
    main.functions.extend(side.functions)
    known = {entry.domain for entry in main.opset_import}
    main.opset_import.extend(entry for entry in side.opset_import if entry.domain not in known)
    meta = metadata_strings({THRESHOLD_KEY: float(rule["threshold"]), QUANTILE_KEY: float(rule["quantile"])})
    kept = [(p.key, p.value) for p in main.metadata_props if p.key not in meta]
    del main.metadata_props[:]
    for key, value in [*kept, *meta.items()]:
        entry = main.metadata_props.add()
        entry.key, entry.value = key, value
    onnx.checker.check_model(main)
    return save_onnx(main, bundle if out is None else out)  # sealed: the digest covers the branch too


__all__ = ["add_distance", "distance_graph"]
