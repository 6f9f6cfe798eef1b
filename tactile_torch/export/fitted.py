"""The torch graph and the ONNX bundle of any fitted model the trade-off compares: a network, a learned
front end, or a classical ``Pipeline`` (features step with ``to_module`` → head modules).

:func:`graph_of` builds the graph (raw input → labels, scores), :func:`export_model` writes it as a
bundle (:func:`tactile_torch.export.export_classifier`), :func:`rebind` writes another fold's weights
into an exported bundle of the same architecture (a dynamo export costs seconds), and
:func:`n_parameters` counts the learned numbers. Used by the learned-model comparison
(:func:`tactile_torch.tradeoff.comparison.compare_models`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


class _PipelineGraph:
    """Builds the torch graph of a fitted classical ``Pipeline``: features → head modules."""

    @staticmethod
    def module(model: object) -> object:
        from torch import nn

        from .parts import head_modules

        return nn.Sequential(model.steps[0][1].to_module(), *head_modules(model)).eval()


def graph_of(model: object) -> object:
    """Return the torch inference graph (raw → labels, scores) of a fitted model of a
    :class:`~tactile_torch.tradeoff.comparison.ModelSpec`."""
    if hasattr(model, "to_module") and not hasattr(model, "steps"):
        return model.to_module()
    return _PipelineGraph.module(model)


def model_classes(model: object) -> np.ndarray:
    """Return the classes of a fitted model (its own ``classes_``, or its last step's)."""
    return np.asarray(model.classes_ if hasattr(model, "classes_") else model.steps[-1][1].classes_)


def n_parameters(model: object) -> int | None:
    """Return the learned numbers of a fitted model or ``Pipeline``: a network's trained scalars (plus its
    learned front-end settings), or the numbers a classical classifier stores (support vectors,
    coefficients, class means ...); ``None`` for a classifier with no inference graph to count."""
    classifier = model.steps[-1][1] if hasattr(model, "steps") else model
    if hasattr(classifier, "n_parameters_"):
        return int(classifier.n_parameters_)
    from .parts import head_modules

    try:
        return int(sum(b.numel() for m in head_modules(model) for b in m.buffers()))
    except (TypeError, ValueError, KeyError):
        return None


def export_model(model: object, path: str | Path, example: np.ndarray, class_names: list[str]) -> Path:
    """Write a fitted model's graph to the ONNX bundle ``path`` (see :func:`tactile_torch.export.export_classifier`)."""
    from .neural import export_classifier

    class _Fitted:  # the attributes export_classifier reads
        def __init__(self) -> None:
            self.classes_ = model_classes(model)
            self.input_shape_ = tuple(example.shape[1:])
            self.n_parameters_ = n_parameters(model)

        def to_module(self) -> object:
            return graph_of(model)

    fitted = _Fitted()
    names = [class_names[int(c)] for c in fitted.classes_]
    return export_classifier(fitted, path, example, class_names=names)


def rebind(template: Path, model: object, raw: np.ndarray, path: str | Path) -> Path | None:
    """Write ``template`` (an exported model of the same architecture) with ``model``'s weights to ``path``.

    Every initializer named after a tensor of the model's graph (``state_dict``) takes that tensor's
    value. A dynamo export costs seconds, mostly fixed overhead, and the folds of one model share their
    architecture. The result is checked against the torch graph on ``raw`` (labels equal, scores within
    1e-4); ``None`` when it does not match (a tensor the export folded into another constant), so that
    the caller exports afresh.
    """
    import onnx
    import torch
    from onnx import numpy_helper

    from ..robot.runtime import OnnxPipeline
    from ._onnx import save_onnx

    graph = graph_of(model)
    state = {k: v.detach().cpu().numpy() for k, v in graph.state_dict().items()}
    proto = onnx.load(str(template))
    for init in proto.graph.initializer:
        if init.name in state:
            old = numpy_helper.to_array(init)
            value = state[init.name]
            if old.shape != value.shape:
                return None
            init.CopyFrom(numpy_helper.from_array(value.astype(old.dtype), init.name))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    save_onnx(proto, path)  # sealed anew: the template's digest covered its own weights
    labels, scores = OnnxPipeline(path).predict_scores(raw)
    with torch.no_grad():
        t_labels, t_scores = graph(torch.from_numpy(np.ascontiguousarray(raw)))
    if np.array_equal(labels, t_labels.numpy()) and np.allclose(scores, t_scores.numpy(), atol=1e-4, rtol=0):
        return path
    return None


__all__ = ["export_model", "graph_of", "model_classes", "n_parameters", "rebind"]
