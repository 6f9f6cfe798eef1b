"""The "unknown" rule of a trade-off bundle, measured on what the bundle already computes.

Every file the study writes for a candidate (its timing file and, when deployed, ``recommended.onnx``)
carries the "unknown" rule of :mod:`tactile_torch.ood`: a Mahalanobis distance to the training data, as
an ``ood_distance`` output with its threshold in the metadata. It is measured on a tensor the bundle
computes anyway, so that the rule costs a few small matrix products and not a second pass over the
raw input:

* a **classical** candidate (features → selection → standardisation → classifier): on its own
  features, the front's ``features`` tensor, selected and standardised as its head does (as ``train``
  + ``export`` measure it);
* a **learned** candidate (a network, or a learned front end with a linear head): on its
  **embedding**, the input of its last linear layer (a network's pooled channels, a front end's
  standardised features), as Lee et al. (2018) measure the Mahalanobis distance on a network's
  penultimate layer. (Before this version a network got the distance on the reference features of its
  raw input, computed by a second feature graph beside it: the fused image features of a 4 x 4
  fingertip's 200 frames cost 70 times the taxel CNN itself.)

The distance part (selection, standardisation, :class:`~tactile_torch.ood.MahalanobisDistance`) is
exported once per structure with its fitted arrays as inputs and bound per candidate
(:func:`~tactile_torch.export.parts.bind_head`), then attached to the bundle reading that tensor (:func:`attach_distance`):
its nodes are prefixed ``ood.`` and stay in float in an int8 file (they are attached after
quantisation).
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from ..robot.contract import FEATURES_NAME, LABELS_OUTPUT, SCORES_OUTPUT

EMBEDDING_NAME = "embedding"
"""The tensor of a learned bundle the distance reads (an output of the exported network while it is
built, an inner tensor of the file written)."""
EMBEDDING_BATCH = 256
"""Samples per forward pass when the training embeddings are computed."""


class DistancePart(nn.Module):
    """Features ``(B, F)`` → ``ood_distance`` ``(B,)``: the chosen columns, standardised, and their distance.

    Parameters
    ----------
    rule : dict
        :func:`tactile_torch.ood.fit_rule`'s result on the chosen columns.
    columns : array of int
        The columns the rule was fitted on (all of them: ``arange(F)``).
    center, scale : array
        The standardisation the rule was fitted under (``(x - center) / scale``).
    """

    def __init__(self, rule: dict, *, columns: object, center: object, scale: object) -> None:
        super().__init__()
        from ..features.transformers import ColumnSelect
        from ..ood import distance_module
        from ..signal import ScaleFeatures

        self.select = ColumnSelect(columns)
        self.standardise = ScaleFeatures(
            torch.as_tensor(np.asarray(center, dtype=np.float32)),
            torch.as_tensor(np.asarray(scale, dtype=np.float32)),
        )
        self.distance = distance_module(rule)

    def forward(self, features: torch.Tensor) -> torch.Tensor:
        return self.distance(self.standardise(self.select(features).to(torch.float32)))


class EmbeddingGraph(nn.Module):
    """A learned graph (``embed`` and ``classify``) as raw input → ``(labels, scores, embedding)``.

    The graph's submodules and buffers are registered under their own names, so that the exported
    weights are named as in the graph alone (:func:`tactile_torch.tradeoff.comparison.rebind` binds another
    fold's weights by those names).
    """

    output_names = (LABELS_OUTPUT, SCORES_OUTPUT, EMBEDDING_NAME)

    def __init__(self, graph: nn.Module) -> None:
        super().__init__()
        for name, child in graph.named_children():
            self.add_module(name, child)
        for name, buffer in graph.named_buffers(recurse=False):
            self.register_buffer(name, buffer)
        object.__setattr__(self, "inner", graph)  # not a submodule: its weights are registered above

    def forward(self, raw: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        embedding = self.inner.embed(raw)
        labels, scores = self.inner.classify(embedding)
        return labels, scores, embedding


def classical_rule(model: object, features: np.ndarray, y: np.ndarray) -> tuple[dict, DistancePart]:
    """Return the rule of a fitted classical candidate and its distance part, from its training
    ``features`` ``(N, F)`` (the ``features`` step's output) and labels."""
    from ..ood import fit_rule

    features = np.asarray(features, dtype=np.float64)
    steps = model.named_steps
    columns = steps["select"].columns_ if "select" in steps else np.arange(features.shape[1])
    scaler = steps["scale"]
    rule = fit_rule(features[:, columns], y, scale=scaler.scale_, center=scaler.mean_)
    return rule, DistancePart(rule, columns=columns, center=scaler.mean_, scale=scaler.scale_)


def embeddings(graph: nn.Module, X: np.ndarray) -> np.ndarray:
    """Return ``graph.embed`` of raw input ``X`` ``(N, ...)`` as float64 ``(N, E)``, in batches."""
    out = []
    with torch.no_grad():
        for start in range(0, len(X), EMBEDDING_BATCH):
            x = np.ascontiguousarray(X[start : start + EMBEDDING_BATCH])
            x = torch.from_numpy(x if x.dtype == np.uint8 else x.astype(np.float32))
            out.append(graph.embed(x).double().numpy())
    return np.concatenate(out)


def embedding_rule(E: np.ndarray, y: np.ndarray) -> tuple[dict, DistancePart]:
    """Return the rule of a learned candidate fitted on its training embeddings ``E`` ``(N, E)`` (what its
    file computes for the training raw input) and labels, and its distance part (standardised on ``E``)."""
    from ..ood import fit_rule

    E = np.asarray(E, dtype=np.float64)
    center = E.mean(axis=0)
    scale = E.std(axis=0, ddof=1) if len(E) > 1 else np.ones(E.shape[1])
    scale = np.where(scale > 0, scale, 1.0)
    rule = fit_rule(E, y, scale=scale, center=center)
    return rule, DistancePart(rule, columns=np.arange(E.shape[1]), center=center, scale=scale)


def attach_distance(model: object, part: object, reads: str, rule: dict) -> object:
    """Return ``model`` (an ONNX ``ModelProto``) with the distance ``part`` reading its tensor ``reads``.

    ``part`` is an exported :class:`DistancePart` (input ``features``, output ``ood_distance``); its
    names are prefixed ``ood.`` and its input is the tensor ``reads`` of ``model`` (the front's
    ``features``, or a learned graph's ``embedding``, which stops being an output). The rule's threshold
    and quantile go into the metadata (:data:`~tactile_torch.robot.contract.THRESHOLD_KEY`,
    :data:`~tactile_torch.robot.contract.QUANTILE_KEY`). The model is changed in place and returned.
    """
    import onnx
    from onnx import compose

    from ..export import unsealed
    from ..robot.contract import QUANTILE_KEY, THRESHOLD_KEY, metadata_strings

    side = compose.add_prefix(unsealed(part), "ood.", rename_outputs=False)
    versions = {entry.domain: entry.version for entry in model.opset_import}
    for entry in side.opset_import:
        if versions.get(entry.domain, entry.version) != entry.version:
            side = onnx.version_converter.convert_version(side, versions[entry.domain])
            break
    source = f"ood.{FEATURES_NAME}"
    for node in side.graph.node:
        node.input[:] = [reads if name == source else name for name in node.input]
    graph = model.graph
    graph.node.extend(side.graph.node)
    graph.initializer.extend(side.graph.initializer)
    graph.value_info.extend(v for v in side.graph.value_info if v.name != source)
    kept = [o for o in graph.output if o.name != reads]
    del graph.output[:]
    graph.output.extend([*kept, *side.graph.output])
    model.functions.extend(side.functions)
    known = {entry.domain for entry in model.opset_import}
    model.opset_import.extend(entry for entry in side.opset_import if entry.domain not in known)
    meta = metadata_strings({THRESHOLD_KEY: float(rule["threshold"]), QUANTILE_KEY: float(rule["quantile"])})
    props = [(p.key, p.value) for p in model.metadata_props if p.key not in meta]
    del model.metadata_props[:]
    for key, value in [*props, *meta.items()]:
        entry = model.metadata_props.add()
        entry.key, entry.value = key, value
    onnx.checker.check_model(model)
    return model


__all__ = [
    "EMBEDDING_BATCH",
    "EMBEDDING_NAME",
    "DistancePart",
    "EmbeddingGraph",
    "attach_distance",
    "classical_rule",
    "embedding_rule",
    "embeddings",
]
