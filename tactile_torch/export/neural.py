"""ONNX export of a fitted neural classifier (or learned front end) as a tactile-torch bundle.

The graph is the estimator's :meth:`to_module` (raw input → ``labels``, ``scores``), exported with the
project's exporter (:func:`tactile_torch.export.export_onnx`: ``torch.onnx.export(..., dynamo=True)``,
dynamic batch, ``onnx.checker``) with the metadata :class:`tactile_torch.robot.runtime.OnnxPipeline` reads.
Labels index the estimator's ``classes_`` (metadata ``class_names``).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch

from ..robot.contract import (
    CLASS_NAMES_KEY,
    FRAMES_LAYOUT,
    INPUT_LAYOUT_KEY,
    INPUT_NAME,
    INPUT_SHAPE_KEY,
    LABELS_OUTPUT,
    PIPELINE_KEY,
    PRESSURE_LAYOUT,
    SCORES_OUTPUT,
    VERSION_KEY,
    WINDOWS_LAYOUT,
    metadata_strings,
)
from ._onnx import export_onnx

LAYOUTS = {3: WINDOWS_LAYOUT, 4: PRESSURE_LAYOUT, 5: FRAMES_LAYOUT}
"""Input layout by the raw input's number of dimensions."""
EMBEDDING_OUTPUT = "embedding"
"""A learned bundle's embedding (:class:`EmbeddingGraph`): an output while the bundle is built, the tensor
its "unknown" rule reads once attached (:func:`tactile_torch.export.ood_branch.attach_distance`)."""


class EmbeddingGraph(torch.nn.Module):
    """A learned model's graph (``embed`` and ``classify``) as raw input → ``(labels, scores, embedding)``.

    ``graph`` is a ``to_module()`` of the networks or the learned front ends
    (:class:`tactile_torch.neural.networks.ClassifierGraph`,
    :class:`tactile_torch.neural.front_end.HardFrontEndGraph`). Its submodules and buffers are registered
    under their own names, so that the exported weights are named as in the graph alone
    (:func:`tactile_torch.tradeoff.comparison.rebind` binds another fold's weights by those names).
    """

    output_names = (LABELS_OUTPUT, SCORES_OUTPUT, EMBEDDING_OUTPUT)

    def __init__(self, graph: torch.nn.Module) -> None:
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


def export_classifier(
    estimator: object,
    path: str | Path,
    example: np.ndarray,
    *,
    class_names: Sequence[str] | None = None,
    metadata: dict[str, object] | None = None,
    graph: torch.nn.Module | None = None,
) -> Path:
    """Write ``estimator``'s inference graph to the ONNX bundle ``path``; return the path.

    Parameters
    ----------
    estimator : fitted neural classifier
        Anything with ``to_module()``, ``classes_`` and ``input_shape_``.
    path : path
    example : ndarray of shape (B, ...)
        Raw input of the graph's dtype (uint8 frames, float32 windows or maps) for the trace; the batch
        size stays free.
    class_names : sequence of str, optional
        Name of each class of ``classes_`` (default: the classes as strings).
    metadata : dict, optional
        Further metadata (window size, sample rate ...); JSON for non-strings.
    graph : torch.nn.Module, optional
        The graph to export instead of ``estimator.to_module()`` (the same raw input; its outputs are
        named by its ``output_names`` attribute when it has one, e.g. :class:`EmbeddingGraph`'s third).
    """
    from .. import __version__

    example = np.ascontiguousarray(example)
    if example.ndim not in LAYOUTS:
        raise ValueError(f"example must have 3, 4 or 5 dimensions (B, ...), got shape {example.shape}")
    names = list(class_names) if class_names is not None else [str(c) for c in estimator.classes_]
    meta = metadata_strings(
        {
            PIPELINE_KEY: f"neural: {type(estimator).__name__}",
            VERSION_KEY: __version__,
            INPUT_SHAPE_KEY: [None, *estimator.input_shape_],
            INPUT_LAYOUT_KEY: LAYOUTS[example.ndim],
            CLASS_NAMES_KEY: names,
            "n_parameters": str(getattr(estimator, "n_parameters_", "")),
            **(metadata or {}),
        }
    )
    module = estimator.to_module() if graph is None else graph
    return export_onnx(
        module,
        (torch.from_numpy(example),),
        path,
        input_names=[INPUT_NAME],
        output_names=list(getattr(module, "output_names", (LABELS_OUTPUT, SCORES_OUTPUT))),
        metadata=meta,
    )


__all__ = ["EMBEDDING_OUTPUT", "LAYOUTS", "EmbeddingGraph", "export_classifier"]
